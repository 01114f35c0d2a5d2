#!/usr/bin/env python3
"""Mean iterations (and builtin/none) of our engine on the perturbed thesis worlds written by `probe.py chaos`
(worlds_perturbed_<p>.csv: circle p's x one float32 ulp up; p = 0 unperturbed).

    python3 docs/thesis_original/ours_perturbed.py --bin target/release/deepcontact \
        --worlds DIR --out OUTDIR [-- EXTRA COMPARE OPTIONS]

Runs `deepcontact compare --preset thesis --scene file:DIR/worlds_perturbed_<p>.csv
--warm-starts none,builtin --no-plots --quiet EXTRA` (other methods with --warm-starts) for
every p and prints each method's mean iterations and builtin/none per perturbation, then the
ratio's mean and standard deviation over p >= 1.
"""
import argparse
import glob
import json
import os
import re
import statistics
import subprocess


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", required=True)
    ap.add_argument("--worlds", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--warm-starts", default="none,builtin",
                    help="compare's --warm-starts (the ratio needs none and builtin)")
    ap.add_argument("extra", nargs="*")
    args = ap.parse_args()
    files = sorted(glob.glob(os.path.join(args.worlds, "worlds_perturbed_*.csv")),
                   key=lambda f: int(re.findall(r"(\d+)\.csv$", f)[0]))
    ratios = {}
    for f in files:
        p = int(re.findall(r"(\d+)\.csv$", f)[0])
        out = os.path.join(args.out, "p%d" % p)
        subprocess.run([args.bin, "compare", "--preset", "thesis", "--scene", "file:" + f,
                        "--warm-starts", args.warm_starts, "--no-plots", "--quiet", "--out", out]
                       + args.extra, check=True, stdout=subprocess.DEVNULL)
        summary = json.load(open(os.path.join(out, "summary.json")))["summary"]
        mean = {r["warm_start"].split(":")[0]: r["mean_iterations"] for r in summary}
        line = " ".join("%s %.1f" % kv for kv in mean.items())
        if "none" in mean and "builtin" in mean:
            ratios[p] = mean["builtin"] / mean["none"]
            line += " ratio %.3f" % ratios[p]
        print("p=%d %s" % (p, line), flush=True)
    pert = [r for p, r in ratios.items() if p > 0]
    if len(pert) < 2:
        return
    print("perturbed: mean %.3f sd %.3f min %.3f max %.3f over %d" % (
        statistics.mean(pert), statistics.stdev(pert), min(pert), max(pert), len(pert)))


if __name__ == "__main__":
    main()
