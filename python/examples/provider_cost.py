"""Cost of a warm-start provider written in Python, per island call, against Rust's builtin.

    python python/examples/provider_cost.py [--worlds 10] [--steps 250]

Steps the thesis pile (seeds 12345...) with `builtin` (Rust), a trivial NumPy provider
returning the carried impulses (the same numbers as builtin, so the same iterations) and one
returning zeros, and reports the time the step spent in the provider
(StepReport.warm_start_seconds) per island call, and the whole step per step.
"""

import argparse

import numpy as np

import deepcontact


def carried(island):
    return island.carried


def zeros(island):
    return np.zeros((len(island), 2))


def measure(warm_start, worlds, steps):
    provider_s = step_s = 0.0
    islands = iterations = 0
    for seed in range(12345, 12345 + worlds):
        world = deepcontact.World.pile(seed=seed, bodies=100)
        for report in world.run(steps, warm_start=warm_start):
            provider_s += report.warm_start_seconds
            step_s += report.step_seconds
            islands += report.islands
            iterations += report.iterations
    return provider_s / max(islands, 1) * 1e6, step_s / (worlds * steps) * 1e3, islands, iterations


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=10)
    parser.add_argument("--steps", type=int, default=250)
    args = parser.parse_args()
    print(f"{'provider':10} {'us/island call':>15} {'ms/step':>8} {'islands':>8} {'iterations':>10}")
    for name, ws in [("builtin", "builtin"), ("carried", carried), ("none", "none"), ("zeros", zeros)]:
        per_call, per_step, islands, iterations = measure(ws, args.worlds, args.steps)
        print(f"{name:10} {per_call:15.2f} {per_step:8.3f} {islands:8} {iterations:10}")


if __name__ == "__main__":
    main()
