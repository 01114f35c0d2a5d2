"""Wall time of one comparison on a 1-worker and on a 2-worker Ray cluster, alternating.

Start the clusters first (docs/CLUSTER.md, "Speedup"), then

    python python/examples/cluster_speedup.py --one 127.0.0.1:6401 --two 127.0.0.1:6402

Each run is a fresh driver process (a process connects to one cluster), so a run's time
includes connecting (~1-3 s) and the workers importing the package; the runs alternate
(one, two, one, two, ...) so that a slow spell of the machine touches both alike.
"""

import argparse
import statistics
import subprocess
import sys

RUN = """
import time, deepcontact
t0 = time.perf_counter()
deepcontact.compare(seeds=range(12345, 12345 + {seeds}), steps={steps}, cluster={address!r},
                    as_frame=False)
print(time.perf_counter() - t0)
"""


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--one", required=True, help="address of the 1-worker cluster")
    p.add_argument("--two", required=True, help="address of the 2-worker cluster")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--steps", type=int, default=250)
    a = p.parse_args()
    times = {"one": [], "two": []}
    for r in range(a.rounds):
        for label, address in (("one", a.one), ("two", a.two)):
            code = RUN.format(seeds=a.seeds, steps=a.steps, address=address)
            done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                  check=True)
            seconds = float(done.stdout.strip().splitlines()[-1])
            times[label].append(seconds)
            print(f"round {r}: {label} worker(s) {seconds:.1f} s", flush=True)
    one, two = statistics.median(times["one"]), statistics.median(times["two"])
    print(f"median: 1 worker {one:.1f} s, 2 workers {two:.1f} s, speedup {one / two:.2f}x")


if __name__ == "__main__":
    main()
