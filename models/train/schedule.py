#!/usr/bin/env python3
"""Fit relaxation schedules under fixed pass budgets on the simulator itself.

A schedule gives each equal share of a run of sweeps its own factor omega. With `--target
provider` (the default) the sweeps are the `sor` provider's (`sor:schedule=1.8/1.5/1.2`;
warmstart/baselines/src/schedule.rs), the world's PGS running the rest of the budget from its
result; with `--target solver` they are the world's own PGS's first K - 1 sweeps, the last plain
(`pgs:sor=1.8/1.5/1.2`, solvers/pgs/src/velocity/over_relaxation.rs), from the carried impulses:
the schedules of the solver `learned-pgs`. For each budget K this
script fits `--factors` factors, omega_j = 1 + 0.98 sigmoid(z_j), by an evolution strategy
(weighted recombination of the best half of each generation; a step size that grows after an
improvement and shrinks otherwise) that minimises the mean over the training scenes of
log(p99 natural residual), the residual `deepcontact compare --budgets K` reports over contact
steps (the provider's own passes count against the budget).

Seeds: each generation draws `--batch` seeds from the training seeds 0-99 (the same seeds for
every candidate of that generation); the means of the last `--select` generations and the
constant factor `--start-omega` (the classical twin) are then run on the tuning seeds 100-109,
with `--start-from FILE` also that file's schedule of the budget (from which the search then
starts), and the best is written, with the whole history, to `--out`. The report seeds 12345-12354 are
never used. Standard library only; the simulator is the release CLI (`cargo build --release`).

    python3 models/train/schedule.py --budgets 8,16 --out models/learned-schedule.json
    python3 models/train/schedule.py --target solver --budgets 4,8,16,32 \
        --start-from models/learned-schedule.json --batch 20 --generations 20 --sigma 0.3 \
        --out /tmp/pgs-schedule.json
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

FORMAT = "deepcontact-schedule/1"
SPAN = 0.98


def omegas(z):
    return [round(1 + SPAN / (1 + math.exp(-x)), 4) for x in z]


def logit(omega):
    q = (omega - 1) / SPAN
    return math.log(q / (1 - q))


# Per target: the spec of a schedule, the compare flag the specs go to, the summary column
# that names them, and the flags that fix the other side.
TARGETS = {
    "provider": ("sor:schedule=", "--warm-starts", "warm_start", ["--solvers", "pgs"]),
    "solver": ("pgs:sor=", "--solvers", "solver", ["--warm-starts", "builtin"]),
}
BASELINE = {"provider": "builtin", "solver": "pgs"}


def spec_of(target, factors):
    return TARGETS[target][0] + "/".join(f"{w:.4f}" for w in factors)


def p99s(a, specs, budget, seeds, scratch):
    """Per spec, the p99 natural residual per scene (`compare --scenes ... --budgets K`),
    all specs in one run (one world per scene, seed and spec)."""
    _, flag, column, fixed = TARGETS[a.target]
    out = tempfile.mkdtemp(dir=scratch)
    cmd = [a.cli, "compare", "--scenes", ",".join(a.scenes), "--budgets", str(budget),
           flag, ",".join(specs), *fixed, "--seeds", ",".join(str(s) for s in seeds),
           "--no-plots", "--quiet", "--out", out]
    if a.threads:
        cmd += ["--threads", str(a.threads)]
    subprocess.run(cmd, check=True, capture_output=True)
    with open(os.path.join(out, "summary.json")) as f:
        rows = json.load(f)["summary"]
    table = {}
    for r in rows:
        table.setdefault(r[column], {})[r["scene"]] = r["natural_residual_p99"]
    return [[table[s][scene] for scene in a.scenes] for s in specs]


def score(p99):
    return sum(math.log(max(x, 1e-12)) for x in p99) / len(p99)


def fit(a, budget, rng, scratch):
    train, tuning = list(range(0, 100)), list(range(100, 110))
    start = a.start_schedules.get(str(budget))
    mean = [logit(w) for w in start] if start else [logit(a.start_omega)] * a.factors
    sigma, mu = a.sigma, a.population // 2
    ranks = [math.log(mu + 0.5) - math.log(i + 1) for i in range(mu)]
    ranks = [r / sum(ranks) for r in ranks]
    history, t0 = [], time.time()
    for gen in range(a.generations):
        seeds = sorted(rng.sample(train, a.batch))
        pop = [[m + sigma * rng.gauss(0, 1) for m in mean] for _ in range(a.population)]
        specs = [spec_of(a.target, omegas(mean))] + [spec_of(a.target, omegas(c)) for c in pop]
        results = p99s(a, specs, budget, seeds, scratch)
        before = score(results[0])
        scored = sorted((score(r), i) for i, r in enumerate(results[1:]))
        new = [sum(r * pop[i][k] for r, (_, i) in zip(ranks, scored)) for k in range(len(mean))]
        after = score(p99s(a, [spec_of(a.target, omegas(new))], budget, seeds, scratch)[0])
        sigma *= 1.1 if after < before else 0.8
        mean = new
        history.append({"generation": gen, "seeds": seeds, "score_before": before,
                        "best_candidate": scored[0][0], "score_after": after, "sigma": sigma,
                        "omegas": omegas(mean)})
        print(f"K={budget} gen {gen:2d}: score {before:.4f} -> {after:.4f} "
              f"(best candidate {scored[0][0]:.4f}), sigma {sigma:.3f}, omegas {omegas(mean)}  "
              f"[{time.time() - t0:.0f} s]", flush=True)
    candidates = [h["omegas"] for h in history[-a.select:]] + ([start] if start else [])
    twin = [a.start_omega]
    specs = [spec_of(a.target, c) for c in candidates + [twin]]
    results = p99s(a, specs + [BASELINE[a.target]], budget, tuning, scratch)
    tried = [{"omegas": c, "score": score(r), "residual_p99": dict(zip(a.scenes, r))}
             for c, r in zip(candidates + [twin], results)]
    for t in tried:
        print(f"K={budget} tuning seeds: score {t['score']:.4f}, omegas {t['omegas']}", flush=True)
    best = min(tried[:-1], key=lambda t: t["score"])
    return best, {"budget": budget, "seconds": round(time.time() - t0, 1),
                  "selected_on_tuning": best, "constant_on_tuning": tried[-1],
                  "builtin_on_tuning": {"residual_p99": dict(zip(a.scenes, results[-1]))},
                  "tuning_candidates": tried[:-1], "history": history}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cli", default="target/release/deepcontact")
    p.add_argument("--out", required=True)
    p.add_argument("--target", choices=sorted(TARGETS), default="provider",
                   help="whose sweeps the schedule sets: the sor provider's or the world's PGS's")
    p.add_argument("--budgets", default="8,16", help="comma-separated pass budgets K")
    p.add_argument("--scenes", default="pile,box-pile,polygon-pile", help="training scenes (registry specs)")
    p.add_argument("--factors", type=int, default=3, help="factors of a schedule (equal shares)")
    p.add_argument("--generations", type=int, default=15)
    p.add_argument("--population", type=int, default=8)
    p.add_argument("--batch", type=int, default=10, help="training seeds per generation")
    p.add_argument("--select", type=int, default=4, help="last generations' means tried on the tuning seeds")
    p.add_argument("--sigma", type=float, default=0.5, help="initial step size (in logits)")
    p.add_argument("--start-omega", type=float, default=1.5, help="constant factor of the first mean (the classical twin)")
    p.add_argument("--start-from", help="a schedule file whose factors for each budget are the first mean "
                   "(instead of --start-omega) and a tuning candidate")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    a.scenes = a.scenes.split(",")
    a.start_schedules = {}
    if a.start_from:
        with open(a.start_from) as f:
            a.start_schedules = json.load(f)["schedules"]
        if any(not 1 < w < 1 + SPAN for ws in a.start_schedules.values() for w in ws):
            sys.exit("--start-from: every factor must be in (1, 1.98)")
    if not 1 < a.start_omega < 1 + SPAN or not 1 <= a.factors <= 8:
        sys.exit("--start-omega must be in (1, 1.98) and --factors in 1..=8")
    rng = random.Random(a.seed)
    schedules, training = {}, []
    with tempfile.TemporaryDirectory() as scratch:
        for budget in [int(k) for k in a.budgets.split(",")]:
            best, log = fit(a, budget, rng, scratch)
            schedules[str(budget)] = best["omegas"]
            training.append(log)
    doc = {"format": FORMAT, "schedules": schedules,
           "training": {"method": "evolution strategy on the simulator (models/train/schedule.py)",
                        "target": a.target,
                        "objective": "mean over the training scenes of log(p99 natural residual) at budget K",
                        "training_seeds": "0..100 (a batch per generation)", "tuning_seeds": "100..110",
                        "arguments": vars(a), "budgets": training}}
    with open(a.out, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    print(f"wrote {a.out}: {schedules}")


if __name__ == "__main__":
    main()
