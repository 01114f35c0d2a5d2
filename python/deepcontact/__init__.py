"""deepcontact: 2D rigid-body contacts with pluggable warm starts, from Python.

A thin layer over the Rust workspace (``deepcontact._deepcontact``, built with PyO3 and
maturin): worlds of the standard scenes, steps with registry or Python warm-start providers,
the thesis comparison with the CLI's numbers, and islands as training data in memory.

>>> import deepcontact
>>> world = deepcontact.World.pile(seed=12345, bodies=100)
>>> report = world.step(warm_start="builtin")
>>> report.iterations >= 0
True
"""

from __future__ import annotations

import os
from typing import Any, Iterable, Optional, Sequence, Union

from ._deepcontact import (
    DeepContactError,
    Island,
    IslandProblem,
    StepReport,
    WarmStartError,
    World,
    __version__,
    CompareArgs as _CompareArgs,
    compare_summary as _compare_summary,
    registry,
)

__all__ = [
    "DeepContactError",
    "Island",
    "IslandProblem",
    "StepReport",
    "WarmStartError",
    "World",
    "__version__",
    "compare",
    "registry",
]


def compare(
    warm_starts: Sequence[Any] = ("none", "builtin"),
    seeds: Iterable[int] = range(12345, 12355),
    steps: int = 250,
    *,
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
    as_frame: Optional[bool] = None,
    cluster: Optional[str] = None,
) -> Any:
    """Run the warm-start comparison of ``deepcontact compare`` and return its summary.

    ``warm_starts`` mixes registry specs (``"none"``, ``"builtin"``, ``"random:seed=3"``, ...)
    and Python providers (a callable ``f(island) -> (n, 2) float64 array``, an object with
    ``warm_start`` and optional ``observe``/``reset``, or such a class, instantiated once per
    world). A Python provider is registered into the Rust registry under its ``name``
    attribute, else its ``__name__``, else its class name.

    Every (solver, warm start, seed) world of ``scene`` is stepped ``steps`` times on
    ``threads`` workers (0: one per core; the numbers do not depend on it, except timings).
    The GIL is released while Rust works and taken only for Python providers; Ctrl-C raises
    ``KeyboardInterrupt`` within a step of every running world. With ``out``, the CLI's files
    (``steps.csv``, ``curves.csv``, ``summary.{csv,md,json}``, and the figures with
    ``figures=True``) are written there, each file whole, after the comparison finished.

    With ``same_problems`` (the label of one of ``warm_starts``, e.g. ``"builtin"``) every
    provider starts and solves on a copy of that provider's world at every step, so the rows
    compare starts on identical problems rather than on the trajectories they lead to.

    With ``cluster`` (a Ray address as ``ray.init(address=...)`` takes it: ``"127.0.0.1:6379"``,
    ``"auto"``) the seeds run as Ray tasks on that cluster, one per seed, and are merged into
    the same rows and files, the timing columns aside (``deepcontact.cluster.compare``; needs
    ``pip install "./python[ray]"``).

    Returns one row per solver and warm start with the columns of the CLI's
    ``summary.json``: a pandas ``DataFrame`` when pandas is installed (``as_frame=None``) or
    requested (``as_frame=True``), else a list of dicts.
    """


    if isinstance(warm_starts, (str, bytes)) or callable(warm_starts):
        warm_starts = [warm_starts]
    if isinstance(solvers, str):
        solvers = [solvers]
    if cluster is not None:
        from . import cluster as _cluster

        rows = _cluster.compare(
            list(warm_starts), seeds, steps, cluster=cluster, solvers=list(solvers),
            bodies=bodies, scene=scene, tolerance=tolerance, max_iterations=max_iterations,
            norm=norm, guard=guard, threads=threads, out=out, figures=figures,
            same_problems=same_problems,
        )
        return _frame(rows, as_frame)
    rows = _compare_summary(
        _CompareArgs(
            list(warm_starts),
            [int(s) for s in seeds],
            int(steps),
            list(solvers),
            int(bodies),
            scene,
            float(tolerance),
            int(max_iterations),
            norm,
            guard,
            int(threads),
            None if out is None else os.fspath(out),
            bool(figures),
            same_problems,
        )
    )
    return _frame(rows, as_frame)


def _frame(rows: list, as_frame: Optional[bool]) -> Any:
    """``rows`` as a pandas DataFrame where pandas is there (``as_frame=None``) or asked for."""
    if as_frame is False:
        return rows
    try:
        import pandas
    except ImportError:
        if as_frame:
            raise
        return rows
    return pandas.DataFrame(rows)
