"""Studies on a Ray cluster: comparisons, training data and evaluations as Ray tasks.

Needs the optional extra (``pip install "./python[ray]"``); ``import deepcontact`` alone never
imports Ray. Every node of the cluster needs the same ``deepcontact`` package installed (and,
for :func:`generate` and :func:`map_tasks` callers that run the CLI, the CLI at the same
path).

* :func:`compare` — one task per seed (every solver and warm start of that seed in one task,
  stepped in lockstep as on one machine); the parts are merged into exactly the files and rows
  of :func:`deepcontact.compare` on one machine (the timing columns, the wall time and the
  thread count aside).
* :func:`generate` — one task per seed running ``deepcontact generate`` into a shared
  directory; files are written under a temporary name and renamed, complete files are
  skipped, so a rerun resumes; ``manifest.json`` lists the finished files.
* :func:`map_tasks` — any function over a list of arguments as tasks, results in the order of
  the arguments (what ``models/train/relax.py --cluster`` uses for its candidates).

Faults: a task whose worker dies is retried (``max_retries``, default 3) and each seed's result
is taken once; an interrupted driver (Ctrl-C, a kill) has written nothing half-done; an address
nobody answers at raises :class:`ClusterError` within ``connect_timeout`` seconds.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import socket
import subprocess
import sys
import time
from typing import Any, Callable, Iterable, List, Optional, Sequence, Union

from ._deepcontact import CompareArgs as _CompareArgs
from ._deepcontact import DeepContactError
from ._deepcontact import compare_merge as _compare_merge
from ._deepcontact import compare_part as _compare_part

__all__ = ["ClusterError", "compare", "connect", "generate", "map_tasks", "MANIFEST"]

#: Seconds to wait for the cluster's address to answer before :class:`ClusterError`.
CONNECT_TIMEOUT = 5.0
#: Name of the manifest :func:`generate` writes into its output directory.
MANIFEST = "manifest.json"
#: The ``format`` field of that manifest.
MANIFEST_FORMAT = "deepcontact-generate-manifest/1"


class ClusterError(DeepContactError):
    """The cluster cannot be reached, Ray is not installed, or a task's input cannot travel to
    the workers (the message says which and why)."""


def _ray():
    try:
        import ray
    except ImportError as e:
        raise ClusterError(
            'running on a cluster needs Ray: pip install "./python[ray]" (or "ray[default]")'
        ) from e
    return ray


def _host_port(address: str):
    """(host, port) of a Ray address, or None where Ray resolves it itself."""
    if address.startswith("ray://"):
        address = address[len("ray://") :]
    host, sep, port = address.rpartition(":")
    if not sep or not port.isdigit():
        return None
    return host.strip("[]") or "127.0.0.1", int(port)


def connect(address: str, *, connect_timeout: float = CONNECT_TIMEOUT):
    """Connects this process to the Ray cluster at ``address`` (as ``ray.init(address=...)``
    takes it: ``"127.0.0.1:6379"``, ``"ray://head:10001"``, ``"auto"``) and returns the ``ray``
    module. Already connected: the connection is kept as it is.

    Raises :class:`ClusterError` when Ray is missing or nothing answers at the address within
    ``connect_timeout`` seconds (Ray itself would retry for minutes)."""
    ray = _ray()
    if ray.is_initialized():
        return ray
    if address == "auto":
        resolved = os.environ.get("RAY_ADDRESS")
        if not resolved:
            try:
                from ray._private.services import canonicalize_bootstrap_address

                resolved = canonicalize_bootstrap_address("auto")
            except (ConnectionError, ImportError, RuntimeError, ValueError) as e:
                raise ClusterError(f"no Ray cluster found for address 'auto': {e}") from e
        target = _host_port(resolved or "")
    else:
        target = _host_port(address)
        if target is None:
            raise ClusterError(f"cluster address {address!r}: expected HOST:PORT, ray://HOST:PORT or 'auto'")
    if target is not None:
        try:
            socket.create_connection(target, timeout=connect_timeout).close()
        except OSError as e:
            raise ClusterError(
                f"cannot reach the Ray cluster at {address!r} ({target[0]}:{target[1]}) within "
                f"{connect_timeout} s: {e}"
            ) from e
    try:
        ray.init(address=address, logging_level="WARNING", configure_logging=True)
    except Exception as e:  # Ray raises ConnectionError, RuntimeError or its own types
        raise ClusterError(f"cannot connect to the Ray cluster at {address!r}: {e}") from e
    return ray


def _gather(ray, refs: List[Any]) -> List[Any]:
    """The results of ``refs`` in their order; on Ctrl-C the tasks are cancelled."""
    try:
        return ray.get(refs)
    except BaseException as e:
        for ref in refs:
            ray.cancel(ref, force=True)
        if isinstance(e, ray.exceptions.RayError):
            raise ClusterError(f"a cluster task failed: {e}") from e
        raise


def _travel(ray, what: str, value: Any) -> None:
    """Makes ``value`` travel to the workers (modules outside installed packages by value) or
    raises :class:`ClusterError` saying why it cannot."""
    cloudpickle = ray.cloudpickle
    module = getattr(value, "__module__", None) or getattr(type(value), "__module__", None)
    loaded = sys.modules.get(module or "")
    path = getattr(loaded, "__file__", None) or ""
    # A script's, a test file's or a notebook's module is not importable on the workers.
    if loaded is not None and module != "__main__" and "-packages" not in path:
        cloudpickle.register_pickle_by_value(loaded)
    try:
        cloudpickle.dumps(value)
    except Exception as e:
        raise ClusterError(
            f"{what} cannot travel to the cluster's workers (it does not pickle: {e}); define it "
            "at module level, without open files, locks or native handles, or run it on one machine"
        ) from e


def compare(
    warm_starts: Sequence[Any],
    seeds: Iterable[int],
    steps: int,
    *,
    cluster: str,
    solvers: Sequence[str] = ("pgs",),
    bodies: int = 100,
    scene: str = "pile",
    tolerance: float = 1e-4,
    max_iterations: int = 1000,
    norm: str = "inf",
    guard: str = "fallback",
    threads: int = 0,
    out: Optional[Union[str, "os.PathLike[str]"]] = None,
    figures: bool = False,
    same_problems: Optional[str] = None,
    max_retries: int = 3,
    connect_timeout: float = CONNECT_TIMEOUT,
) -> list:
    """:func:`deepcontact.compare` with one Ray task per seed on the cluster at ``cluster``;
    returns the summary rows as dicts (``deepcontact.compare(..., cluster=...)`` wraps it).

    A task steps every (solver, warm start) world of its seed in lockstep on one worker (1
    CPU); its runs come back as exact bytes and are merged, once every seed is in, into the
    one-machine files (``threads`` is recorded in the config as given; the summary reports the
    cluster's CPUs as its threads and the driver's wall time). A task whose worker dies is run
    again, up to ``max_retries`` times."""
    seeds = [int(s) for s in seeds]
    if len(set(seeds)) != len(seeds):
        raise ValueError("seeds: each seed at most once on a cluster")
    ray = connect(cluster, connect_timeout=connect_timeout)
    for ws in warm_starts:
        if not isinstance(ws, str):
            name = getattr(ws, "name", None) or getattr(ws, "__name__", None) or type(ws).__name__
            _travel(ray, f"the Python provider {name!r}", ws)
    common = (
        list(warm_starts), int(steps), list(solvers), int(bodies), scene, float(tolerance),
        int(max_iterations), norm, guard,
    )
    shared = ray.put(common)
    task = ray.remote(num_cpus=1, max_retries=max_retries)(_compare_task)
    t0 = time.perf_counter()
    parts = _gather(ray, [task.remote(shared, seed, same_problems) for seed in seeds])
    wall = time.perf_counter() - t0
    cpus = int(ray.cluster_resources().get("CPU", 0))
    args = _CompareArgs(
        common[0], seeds, *common[1:], int(threads), None if out is None else os.fspath(out),
        bool(figures), same_problems,
    )
    return _compare_merge(args, parts, cpus, wall)


def _compare_task(common, seed, same_problems):
    """One seed's comparison on a worker, as bytes (one thread: the task holds one CPU)."""
    warm_starts, steps, solvers, bodies, scene, tolerance, max_iterations, norm, guard = common
    return _compare_part(
        _CompareArgs(
            warm_starts, [seed], steps, solvers, bodies, scene, tolerance, max_iterations, norm,
            guard, 1, same_problems=same_problems,
        )
    )


def map_tasks(
    function: Callable[..., Any],
    arguments: Sequence[Sequence[Any]],
    *,
    cluster: str,
    max_retries: int = 3,
    num_cpus: float = 1,
    connect_timeout: float = CONNECT_TIMEOUT,
) -> list:
    """``[function(*a) for a in arguments]`` with each call a Ray task on ``cluster``, the
    results in the order of ``arguments`` whatever order the tasks finish in (so a driver that
    draws its random numbers itself gets the same results on one worker or many). ``function``
    travels pickled (by value when its module is a script or test file)."""
    ray = connect(cluster, connect_timeout=connect_timeout)
    _travel(ray, f"the function {getattr(function, '__name__', function)!r}", function)
    task = ray.remote(num_cpus=num_cpus, max_retries=max_retries)(function)
    return _gather(ray, [task.remote(*a) for a in arguments])


def _seed_file(out: str, seed: int) -> str:
    return os.path.join(out, f"pile-{seed:05d}.safetensors")


def _write_json_atomic(path: str, value: Any) -> None:
    tmp = os.path.join(os.path.dirname(path), f".tmp-{os.getpid()}-{os.path.basename(path)}")
    with open(tmp, "w") as f:
        json.dump(value, f, indent=1)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def _generate_task(cli: str, seed: int, out: str, options: Sequence[str]):
    """One seed's training-data file on a worker: ``deepcontact generate`` writes it under a
    temporary name and renames it (a complete file is left as it is). Returns its entry in the
    manifest."""
    cmd = [cli, "generate", "--seeds", str(seed), "--out", out, "--quiet", "--jobs", "1", *options]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({done.returncode}): {done.stderr.strip()}")
    path = _seed_file(out, seed)
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return {"seed": seed, "file": os.path.basename(path), "bytes": os.path.getsize(path),
            "sha256": digest.hexdigest()}


def generate(
    seeds: Iterable[int],
    out: Union[str, "os.PathLike[str]"],
    *,
    cluster: str,
    cli: Optional[str] = None,
    options: Sequence[str] = (),
    max_retries: int = 3,
    connect_timeout: float = CONNECT_TIMEOUT,
) -> dict:
    """``deepcontact generate`` of ``seeds`` into ``out`` with one Ray task per seed, and
    ``out/manifest.json``; returns the manifest.

    ``out`` must be a directory every node sees at the same path (a shared file system);
    ``cli`` the ``deepcontact`` binary on every node (default: ``$DEEPCONTACT_CLI``, else
    ``deepcontact`` on the driver's ``PATH``); ``options`` further ``generate`` options
    (``["--steps", "120", "--no-grids"]``). A seed's file appears only whole (temporary name,
    then rename) and complete files are skipped, so a rerun after a kill resumes. The manifest
    is rewritten (atomically) as seeds finish, sorted by seed, with ``"complete": true`` once
    every seed is in."""
    seeds = sorted({int(s) for s in seeds})
    out = os.path.abspath(os.fspath(out))
    cli = cli or os.environ.get("DEEPCONTACT_CLI") or shutil.which("deepcontact")
    if not cli:
        raise ClusterError("no deepcontact CLI: pass cli= or set DEEPCONTACT_CLI")
    cli = os.path.abspath(cli)
    os.makedirs(out, exist_ok=True)
    ray = connect(cluster, connect_timeout=connect_timeout)
    task = ray.remote(num_cpus=1, max_retries=max_retries)(_generate_task)
    refs = {task.remote(cli, seed, out, list(options)): seed for seed in seeds}
    manifest = {"format": MANIFEST_FORMAT, "cli_options": list(options), "seeds": seeds,
                "complete": False, "files": []}
    path = os.path.join(out, MANIFEST)
    pending = list(refs)
    try:
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            try:
                manifest["files"].append(ray.get(ready[0]))
            except ray.exceptions.RayError as e:
                raise ClusterError(f"generate of seed {refs[ready[0]]} failed: {e}") from e
            manifest["files"].sort(key=lambda f: f["seed"])
            manifest["complete"] = not pending
            _write_json_atomic(path, manifest)
    except BaseException:
        # Ctrl-C or a failed seed: the seeds still running are cancelled (their files were
        # never renamed into place); the manifest lists the finished ones.
        for ref in pending:
            ray.cancel(ref, force=True)
        raise
    return manifest
