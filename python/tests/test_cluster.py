"""deepcontact.cluster against a real local Ray cluster: a head and a worker node on 127.0.0.1
(one CPU each), started here, or the cluster at $DEEPCONTACT_RAY_ADDRESS (as .ci/run starts
it). Skipped without Ray (pip install "./python[ray]")."""

import csv
import io
import json
import os
import pathlib
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

import pytest

ray = pytest.importorskip("ray")

import deepcontact  # noqa: E402
from deepcontact import cluster  # noqa: E402
from conftest import carried  # noqa: E402
from test_compare import TIMING, cli  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]
RAY = str(pathlib.Path(sys.executable).with_name("ray"))
NODE = ["--num-cpus=1", "--object-store-memory=100000000", "--disable-usage-stats"]
# Columns of steps.csv after the first 14 are wall times.
STEPS_NUMBERS = 14


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(condition, seconds, what):
    end = time.time() + seconds
    while time.time() < end:
        if condition():
            return
        time.sleep(0.2)
    raise TimeoutError(f"no {what} after {seconds} s")


def stop(process):
    """Ends a `ray start --block` and the Ray processes it started (its process group; a
    worker process leaves when its node's raylet is gone)."""
    for sig, wait in ((signal.SIGTERM, 15), (signal.SIGKILL, None)):
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            break
        try:
            process.wait(timeout=wait)
        except subprocess.TimeoutExpired:
            pass


@pytest.fixture(scope="module")
def address():
    given = os.environ.get("DEEPCONTACT_RAY_ADDRESS")
    if given:
        cluster.connect(given)
        wait_for(lambda: ray.cluster_resources().get("CPU", 0) >= 2, 120, "second node")
        yield given
        ray.shutdown()
        return
    port = free_port()
    temp = tempfile.mkdtemp(prefix="dcray-", dir="/tmp")  # Ray's socket paths must stay short
    log = open(os.path.join(temp, "nodes.log"), "w")
    start = dict(stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    nodes = [subprocess.Popen([RAY, "start", "--head", "--block", f"--port={port}",
                               "--include-dashboard=false", f"--temp-dir={temp}", *NODE], **start)]
    try:
        wait_for(lambda: _answers(port), 120, "head node")
        nodes.append(subprocess.Popen([RAY, "start", "--block", f"--address=127.0.0.1:{port}",
                                       *NODE], **start))
        addr = f"127.0.0.1:{port}"
        cluster.connect(addr)
        wait_for(lambda: ray.cluster_resources().get("CPU", 0) >= 2, 120, "second node")
        yield addr
    finally:
        ray.shutdown()
        for p in reversed(nodes):
            stop(p)
        log.close()
        shutil.rmtree(temp, ignore_errors=True)


def _answers(port):
    try:
        socket.create_connection(("127.0.0.1", port), timeout=1).close()
        return True
    except OSError:
        return False


def numbers_of(out):
    """The files of a comparison in `out` with the timing columns, the wall time and the
    thread count left out."""
    out = pathlib.Path(out)
    steps = [row[:STEPS_NUMBERS] for row in csv.reader(io.StringIO((out / "steps.csv").read_text()))]
    summary = [{k: v for k, v in r.items() if k not in TIMING}
               for r in csv.DictReader(io.StringIO((out / "summary.csv").read_text()))]
    meta = json.loads((out / "summary.json").read_text())
    for k in ("wall_seconds", "threads"):
        meta.pop(k)
    for row in meta["summary"]:
        for k in TIMING:
            row.pop(k)
    return {"steps": steps, "curves": (out / "curves.csv").read_bytes(), "summary": summary,
            "json": meta}


def test_compare_on_the_cluster_equals_one_machine(address, tmp_path):
    # 6 seeds x 60 steps x (none, builtin) in CI; the full check (docs/CLUSTER.md) sets 40
    # seeds x 250 steps x the CLI's default warm starts.
    n = int(os.environ.get("DEEPCONTACT_CLUSTER_SEEDS", "6"))
    steps = int(os.environ.get("DEEPCONTACT_CLUSTER_STEPS", "60"))
    specs = os.environ.get("DEEPCONTACT_CLUSTER_WARM_STARTS", "none,builtin").split(",")
    seeds = range(12345, 12345 + n)
    warm_starts = specs + [carried]  # a Python provider travels to the workers
    local = deepcontact.compare(warm_starts, seeds=seeds, steps=steps, out=tmp_path / "local",
                                as_frame=False)
    spread = deepcontact.compare(warm_starts, seeds=seeds, steps=steps, out=tmp_path / "cluster",
                                 as_frame=False, cluster=address)
    assert [{k: v for k, v in r.items() if k not in TIMING} for r in spread] == \
        [{k: v for k, v in r.items() if k not in TIMING} for r in local]
    a, b = numbers_of(tmp_path / "local"), numbers_of(tmp_path / "cluster")
    assert a == b
    assert len(a["steps"]) == 1 + (len(specs) + 1) * len(seeds) * steps
    # The cluster's two CPUs are the threads it reports.
    assert json.loads((tmp_path / "cluster" / "summary.json").read_text())["threads"] == 2


def task_processes(name):
    """Pids of the Ray worker processes running a task of function `name` now."""
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                if f.read().startswith(f"ray::{name}".encode()):
                    found.append(int(pid))
        except OSError:
            pass
    return found


def test_a_killed_worker_loses_no_row(address, tmp_path):
    seeds, steps = list(range(12345, 12349)), 200
    result, killed = {}, []

    def run():
        result["rows"] = deepcontact.compare(["none", "builtin"], seeds=seeds, steps=steps,
                                             out=tmp_path / "cluster", as_frame=False,
                                             cluster=address)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    wait_for(lambda: task_processes("_compare_task"), 120, "running compare task")
    victim = task_processes("_compare_task")[0]
    os.kill(victim, signal.SIGKILL)
    killed.append(victim)
    thread.join(timeout=600)
    assert killed and "rows" in result, "the run did not finish after its worker was killed"
    deepcontact.compare(["none", "builtin"], seeds=seeds, steps=steps, out=tmp_path / "local",
                        as_frame=False)
    a, b = numbers_of(tmp_path / "local"), numbers_of(tmp_path / "cluster")
    assert a == b  # every (warm start, seed, step) row once, with the one-machine numbers
    keys = [tuple(r[1:4]) for r in b["steps"][1:]]
    assert len(keys) == len(set(keys)) == 2 * len(seeds) * steps


def test_an_interrupted_driver_writes_nothing(address, tmp_path):
    out = tmp_path / "out"
    # A run launched in the background inherits SIGINT ignored, and Python then keeps it
    # ignored: the driver installs Python's own handler, as an interactive shell's child has.
    code = ("import signal; signal.signal(signal.SIGINT, signal.default_int_handler)\n"
            "import deepcontact\n"
            f"deepcontact.compare(seeds=range(12345, 12349), steps=200, out={str(out)!r}, "
            f"cluster={address!r})\n")
    driver = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
    wait_for(lambda: task_processes("_compare_task"), 120, "running compare task")
    driver.send_signal(signal.SIGINT)  # Ctrl-C
    output, _ = driver.communicate(timeout=60)
    assert "KeyboardInterrupt" in output, output
    assert not out.exists() or not any(out.iterdir())


def test_the_plain_package_does_not_import_ray():
    code = "import sys, deepcontact; print('ray' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"


def test_an_unreachable_cluster_is_a_clear_error_within_seconds():
    port = free_port()  # bound then released: nobody listens there
    code = ("import deepcontact\n"
            "from deepcontact.cluster import ClusterError\n"
            "try:\n"
            f"    deepcontact.compare(seeds=[1], steps=1, cluster='127.0.0.1:{port}')\n"
            "except ClusterError as e:\n"
            "    print('ClusterError:', e)\n")
    t0 = time.time()
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "ClusterError: cannot reach the Ray cluster" in done.stdout, done.stdout + done.stderr
    assert time.time() - t0 < 30
    assert issubclass(cluster.ClusterError, deepcontact.DeepContactError)


def test_a_provider_that_cannot_travel_is_named(address):
    class Locked:
        name = "locked"

        def __init__(self):
            self.lock = threading.Lock()

        def warm_start(self, island):
            return island.carried

    with pytest.raises(cluster.ClusterError, match="'locked' cannot travel"):
        deepcontact.compare([Locked()], seeds=[1], steps=1, cluster=address)


def generate_driver(address, out, seeds, options):
    """A separate driver process running the cluster's generate (to be killed)."""
    code = ("import sys\nfrom deepcontact import cluster\n"
            f"cluster.generate({seeds!r}, {str(out)!r}, cluster={address!r}, cli={cli()!r}, "
            f"options={options!r})\n")
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


def test_generate_resumed_after_a_kill_gives_the_one_machine_files(address, tmp_path):
    # Seeds long enough (300 steps, ~0.3 s each on one worker) that the kill lands while
    # most are still running: 60-step seeds all finished within one poll of the manifest.
    seeds, options = list(range(12)), ["--steps", "300", "--no-grids"]
    local, spread = tmp_path / "local", tmp_path / "cluster"
    subprocess.run([cli(), "generate", "--seeds", "0..12", "--out", str(local), "--quiet",
                    *options], check=True)
    driver = generate_driver(address, spread, seeds, options)
    manifest = spread / cluster.MANIFEST
    wait_for(lambda: manifest.exists(), 120, "first finished seed")
    driver.kill()
    driver.wait()
    first = json.loads(manifest.read_text())
    assert not first["complete"], "every seed finished before the kill: nothing to resume"
    done = {f["seed"] for f in first["files"]}
    # A dead writer's half file under the final name is not taken as done either.
    half = next(s for s in seeds if s not in done)
    name = f"pile-{half:05d}.safetensors"
    (spread / name).write_bytes((local / name).read_bytes()[:1000])
    again = cluster.generate(seeds, spread, cluster=address, cli=cli(), options=options)
    assert again["complete"] and [f["seed"] for f in again["files"]] == seeds
    for s in seeds:
        name = f"pile-{s:05d}.safetensors"
        assert (spread / name).read_bytes() == (local / name).read_bytes(), name
    assert json.loads(manifest.read_text()) == again


def relax(out, *extra):
    subprocess.run([sys.executable, str(ROOT / "models" / "train" / "relax.py"), "--cli", cli(),
                    "--generations", "2", "--population", "2", "--batch", "2", "--select", "1",
                    "--out", str(out), *extra], check=True, capture_output=True)
    policy = json.loads(out.read_text())
    for k in ("seconds", "arguments"):
        policy["training"].pop(k)
    return policy


def test_relax_on_the_cluster_gives_the_one_worker_policy(address, tmp_path):
    one = relax(tmp_path / "one.json")
    spread = relax(tmp_path / "cluster.json", "--cluster", address)
    assert len(spread["training"]["history"]) == 2
    assert spread == one
