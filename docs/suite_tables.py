#!/usr/bin/env python3
"""The compact tables of docs/SUITE.md from a suite run's summary.csv.

    python3 docs/suite_tables.py results/suite/summary.csv [--budgets 8,tolerance]

Per scene one Markdown table: the hard-contact PGS with each provider, and the soft step
with `builtin` (the soft step with other providers is in the run's own summary.md).
"""

import argparse
import csv
import sys


def fmt(x, spec):
    return "" if x == "" else format(float(x), spec)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("summary", help="summary.csv of `deepcontact compare --scenes ...`")
    parser.add_argument("--budgets", default="8,tolerance", help="budgets to show, comma-separated")
    args = parser.parse_args()
    budgets = args.budgets.split(",")
    rows = list(csv.DictReader(open(args.summary, newline="")))
    scenes = []
    for r in rows:
        if r["scene"] not in scenes:
            scenes.append(r["scene"])
    out = sys.stdout
    for scene in scenes:
        out.write(f"\n### `{scene}`\n\n")
        out.write(
            "| budget | solver + warm start | passes (provider + solver) | residual p99 (N·s) "
            "| residual max, builtin converged | penetration max (m) | vn error mean (m/s) "
            "| final KE (J) | step (ms) | vs builtin |\n"
        )
        out.write("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n")
        for budget in budgets:
            for r in rows:
                if r["scene"] != scene or r["budget"] != budget:
                    continue
                if r["solver"] != "pgs" and r["warm_start"] != "builtin":
                    continue
                passes = f"{float(r['provider_passes']):.1f} + {float(r['solver_passes']):.1f}"
                out.write(
                    f"| {budget} | {r['solver']} + {r['warm_start']} | {passes} "
                    f"| {fmt(r['natural_residual_p99'], '.2e')} "
                    f"| {fmt(r['natural_residual_max_builtin_converged'], '.2e')} "
                    f"| {fmt(r['penetration_max'], '.2e')} "
                    f"| {fmt(r['normal_velocity_error_mean'], '.2e')} "
                    f"| {fmt(r['final_kinetic_energy'], '.2e')} | {fmt(r['step_ms'], '.3f')} "
                    f"| {fmt(r['step_vs_builtin'], '.2f')} |\n"
                )


if __name__ == "__main__":
    main()
