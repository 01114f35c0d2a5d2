#!/usr/bin/env python3
"""Fit the relaxation policy of `learned-sor` (deepcontact-relax) on the simulator itself.

The policy maps six features of a contact point to its over-relaxation factor,
omega_i = 1 + span * sigmoid(w . g_i) (warmstart/relax/src/policy.rs). Its six weights are
fitted by an evolution strategy (weighted recombination of the best half of each generation,
a step size that grows after an improvement and shrinks otherwise) that minimises the work
of a step: the over-relaxed sweeps of the step's slowest island (the provider's,
`mean_sweeps_slowest_island`) plus the world's PGS iterations (`mean_iterations`), as
`deepcontact compare` reports them.

Seeds: each generation draws `--batch` seeds from the training seeds 0-99 (the same seeds for
every candidate of that generation); the means of the last `--select` generations are then
run on the tuning seeds 100-109 and the best of them is written, with the whole history, to
`--out`. The report seeds 12345-12354 are never used. Standard library only; the simulator is
the release CLI (`cargo build --release`).

    python models/train/relax.py --out models/learned-sor.json

With `--cluster ADDRESS` (a Ray address: `127.0.0.1:6379`, `auto`; needs the Python package
with its Ray extra, `pip install "./python[ray]"`) every evaluation of a generation is a Ray
task on that cluster (the CLI at the same path on every node). The random numbers are drawn
here and the results taken in a fixed order, so the same `--seed` gives the same policy on
one worker or many.
"""

import argparse
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import time

FEATURES = ["one", "abs_normal_y", "log_carried_normal", "new", "wall", "log_island_points"]
FORMAT = "deepcontact-relax/1"


def policy_file(weights, span, training=None):
    return {
        "format": FORMAT,
        "features": FEATURES,
        "weights": [float(w) for w in weights],
        "omega_span": span,
        "training": training or {},
    }


def work(cli, weights, span, seeds, scratch, threads):
    """Mean over contact steps of slowest-island sweeps + world iterations, and the row.
    With `scratch` None, in a temporary directory of its own (a cluster task's)."""
    if scratch is None:
        with tempfile.TemporaryDirectory() as own:
            return work(cli, weights, span, seeds, own, threads)
    fd, path = tempfile.mkstemp(suffix=".json", dir=scratch)
    with os.fdopen(fd, "w") as f:
        json.dump(policy_file(weights, span), f)
    out = tempfile.mkdtemp(dir=scratch)
    seed_list = ",".join(str(s) for s in seeds)
    cmd = [cli, "compare", "--seeds", seed_list, "--warm-starts", f"learned-sor:path={path}",
           "--no-plots", "--quiet", "--out", out]
    if threads:
        cmd += ["--threads", str(threads)]
    subprocess.run(cmd, check=True, capture_output=True)
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    row = summary["summary"][0]
    sweeps = [d["values"]["mean_sweeps_slowest_island"] for d in summary["diagnostics"]]
    return row["mean_iterations"] + sum(sweeps) / len(sweeps), row


def evaluate(a, candidates, seeds, scratch):
    """`work` of every weight vector in `candidates` on `seeds`, in the order of `candidates`:
    one after another here, or as Ray tasks on `--cluster` (results in the same order)."""
    if not a.cluster:
        return [work(a.cli, c, a.span, seeds, scratch, a.threads) for c in candidates]
    from deepcontact.cluster import map_tasks

    cli = os.path.abspath(a.cli)
    # A task holds one CPU, so its CLI runs on one thread unless --threads says otherwise.
    args = [(cli, c, a.span, seeds, None, a.threads or 1) for c in candidates]
    return [tuple(r) for r in map_tasks(work, args, cluster=a.cluster)]


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cli", default="target/release/deepcontact")
    p.add_argument("--out", required=True)
    p.add_argument("--generations", type=int, default=20)
    p.add_argument("--population", type=int, default=8)
    p.add_argument("--batch", type=int, default=20, help="training seeds per generation")
    p.add_argument("--select", type=int, default=6, help="last generations' means tried on the tuning seeds")
    p.add_argument("--sigma", type=float, default=0.4, help="initial step size")
    p.add_argument("--start-omega", type=float, default=1.7, help="uniform omega of the first mean (sor's)")
    p.add_argument("--span", type=float, default=0.95)
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--cluster", help="Ray address: evaluate each generation's candidates as Ray tasks there")
    a = p.parse_args()
    if not (0 < a.span < 1 and 1 < a.start_omega < 1 + a.span):
        sys.exit("--span must be in (0, 1) and --start-omega in (1, 1 + span)")
    rng = random.Random(a.seed)
    train, tuning = list(range(0, 100)), list(range(100, 110))
    q = (a.start_omega - 1) / a.span
    mean = [math.log(q / (1 - q))] + [0.0] * (len(FEATURES) - 1)
    sigma, mu = a.sigma, a.population // 2
    ranks = [math.log(mu + 0.5) - math.log(i + 1) for i in range(mu)]
    ranks = [r / sum(ranks) for r in ranks]
    history, t0 = [], time.time()
    with tempfile.TemporaryDirectory() as scratch:
        for gen in range(a.generations):
            seeds = sorted(rng.sample(train, a.batch))
            pop = [[m + sigma * rng.gauss(0, 1) for m in mean] for _ in range(a.population)]
            (before, _), *pop_work = evaluate(a, [mean] + pop, seeds, scratch)
            scored = sorted((w, c) for (w, _), c in zip(pop_work, pop))
            new = [sum(r * c[k] for r, (_, c) in zip(ranks, scored)) for k in range(len(mean))]
            (after, _), = evaluate(a, [new], seeds, scratch)
            sigma *= 1.1 if after < before else 0.8
            mean = new
            history.append({"generation": gen, "seeds": seeds, "work_before": before,
                            "best_candidate": scored[0][0], "work_after": after,
                            "sigma": sigma, "weights": mean})
            print(f"gen {gen:2d}: work {before:7.1f} -> {after:7.1f} (best candidate {scored[0][0]:7.1f}), "
                  f"sigma {sigma:.3f}, weights {[round(w, 3) for w in mean]}  [{time.time() - t0:.0f} s]",
                  flush=True)
        candidates = [h["weights"] for h in history[-a.select:]]
        candidates.append([math.log(q / (1 - q))] + [0.0] * (len(FEATURES) - 1))  # sor, for reference
        tried = []
        for c, (w, row) in zip(candidates, evaluate(a, candidates, tuning, scratch)):
            tried.append({"weights": c, "work": w, "mean_iterations": row["mean_iterations"],
                          "capped_steps": row["capped_steps"],
                          "natural_residual_max": row["natural_residual_max"]})
            print(f"tuning seeds: work {w:7.1f}, iterations {row['mean_iterations']:.1f}, weights {[round(x, 3) for x in c]}", flush=True)
    best = min(tried[:-1], key=lambda t: t["work"])
    training = {
        "method": "evolution strategy on the simulator (models/train/relax.py)",
        "objective": "mean over contact steps of the slowest island's over-relaxed sweeps + the world's PGS iterations",
        "training_seeds": "0..100 (a batch per generation)", "tuning_seeds": "100..110",
        "arguments": vars(a), "seconds": round(time.time() - t0, 1),
        "uniform_start_on_tuning": tried[-1], "selected_on_tuning": best,
        "tuning_candidates": tried[:-1], "history": history,
    }
    with open(a.out, "w") as f:
        json.dump(policy_file(best["weights"], a.span, training), f, indent=1)
        f.write("\n")
    print(f"wrote {a.out}: weights {[round(x, 4) for x in best['weights']]}, tuning work {best['work']:.1f} "
          f"(uniform omega {a.start_omega}: {tried[-1]['work']:.1f})")


if __name__ == "__main__":
    main()
