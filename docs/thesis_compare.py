#!/usr/bin/env python3
"""The figures of docs/THESIS.md that compare a `deepcontact compare` run with the original
engine's per-world results (standard library only).

    python3 docs/thesis_compare.py RESULTS/steps.csv [ORIGINAL_DIR]

RESULTS/steps.csv: a compare run with `none` and `builtin` on seeds 12345-12354;
ORIGINAL_DIR: the folder with results_<method>_per_world.csv (default ../shared/thesis_original).
Prints, for none and builtin, mean iterations and contacts per 50-step window over the contact
steps of both, the first step with contacts per world, and builtin/none with its bootstrap
standard deviation over worlds (2 000 resamples of whole worlds, seed 1) for both engines.
"""
import csv
import random
import statistics
import sys
from pathlib import Path


def ours(path):
    d = {}
    for r in csv.DictReader(open(path)):
        d[(r["warm_start"].split(":")[0], int(r["seed"]), int(r["step"]))] = (
            int(r["iterations"]), int(r["contacts"]))
    return d


def original(folder, method):
    d = {}
    for r in csv.DictReader(open(Path(folder) / f"results_{method}_per_world.csv")):
        # The original numbers steps from 1.
        d[(method, int(r["seed"]), int(r["step"]) - 1)] = (
            int(r["velocity_iterations"]), int(r["contacts"]))
    return d


def ratio(d, seeds):
    def mean(m):
        it = [v[0] for (mm, s, _), v in d.items() if mm == m and s in seeds and v[1] > 0]
        return sum(it) / len(it)
    return mean("builtin") / mean("none")


def bootstrap(d, seeds):
    rng = random.Random(1)
    pools = {}
    for (m, s, _), v in d.items():
        if v[1] > 0:
            pools.setdefault((m, s), []).append(v[0])
    def pooled(sample):
        n = [x for s in sample for x in pools[("none", s)]]
        b = [x for s in sample for x in pools[("builtin", s)]]
        return (sum(b) / len(b)) / (sum(n) / len(n))
    return statistics.pstdev(pooled([rng.choice(seeds) for _ in seeds]) for _ in range(2000))


def main():
    mine = ours(sys.argv[1])
    folder = sys.argv[2] if len(sys.argv) > 2 else "../shared/thesis_original"
    orig = {**original(folder, "none"), **original(folder, "builtin")}
    seeds = sorted({s for (_, s, _) in orig})
    print("| method | steps | original it | ours it | original contacts | ours contacts |")
    print("|---|---|---:|---:|---:|---:|")
    for m in ["none", "builtin"]:
        for lo in range(0, 250, 50):
            keys = [k for k in orig if k[0] == m and lo <= k[2] < lo + 50 and orig[k][1] > 0]
            o = [orig[k] for k in keys]
            u = [mine[k] for k in keys]
            avg = lambda xs, i: sum(x[i] for x in xs) / len(xs)
            print(f"| {m} | {lo + 1}–{lo + 50} | {avg(o, 0):.1f} | {avg(u, 0):.1f} "
                  f"| {avg(o, 1):.1f} | {avg(u, 1):.1f} |")
    first = lambda d: [min(k[2] for k in d if k[:2] == ("none", s) and d[k][1] > 0) + 1
                       for s in seeds]
    print("first contact, original:", first(orig))
    print("first contact, ours:    ", first(mine))
    for name, d in [("original", orig), ("ours", mine)]:
        print(f"{name}: builtin/none {ratio(d, seeds):.3f}, bootstrap sd {bootstrap(d, seeds):.3f}")


if __name__ == "__main__":
    main()
