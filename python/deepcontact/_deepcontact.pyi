"""Type stubs of the native module ``deepcontact._deepcontact`` (PyO3)."""

from os import PathLike
from typing import Any, Callable, List, Optional, Protocol, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
Bool = npt.NDArray[np.bool_]

class DeepContactError(Exception):
    """A failed step or comparison."""

class WarmStartError(DeepContactError):
    """A warm start rejected under ``guard="error"`` (``__cause__``: the provider's exception)."""

class IslandProblem:
    """One island's contact problem: n contact points, m bodies; fresh copies."""

    step: int
    island: int
    island_count: int
    dt: float
    gravity: F64
    carried: F64
    persisted: Bool
    points: F64
    normals: F64
    body_a: I64
    body_b: I64
    manifold: I64
    friction: F64
    separation: F64
    normal_mass: F64
    tangent_mass: F64
    body_index: I64
    positions: F64
    angles: F64
    velocities: F64
    angular_velocities: F64
    masses: F64
    inv_masses: F64
    inv_inertias: F64
    def __len__(self) -> int: ...

class ProviderObject(Protocol):
    """An object provider: ``warm_start`` required; ``observe``, ``reset`` and ``name`` optional."""

    def warm_start(self, island: IslandProblem) -> F64: ...

WarmStartArg = Union[str, Callable[[IslandProblem], F64], ProviderObject, type]

class StepReport:
    """What one step did."""

    step: int
    contacts: int
    islands: int
    iterations: int
    iterations_sum: int
    capped_islands: int
    residual_curve: F64
    residual_curve_l2: F64
    natural_residual: float
    mse_normal: float
    mse_tangent: float
    fallbacks: int
    position_iterations: int
    min_separation: float
    warm_start_seconds: float
    solve_seconds: float
    collide_seconds: float
    islands_seconds: float
    position_seconds: float
    step_seconds: float

class Island:
    """One island of a step: its problem, the start used, the solver's final impulses."""

    problem: IslandProblem
    start: F64
    solved: F64
    fell_back: bool
    iterations: int

class World:
    """A 2D world of one scene."""

    @staticmethod
    def pile(
        seed: int = 12345,
        bodies: int = 100,
        *,
        tolerance: float = 1e-4,
        max_iterations: int = 1000,
        norm: str = "inf",
        guard: str = "fallback",
        dt: float = 0.01,
    ) -> World: ...
    @staticmethod
    def thesis(
        seed: int = 12345,
        *,
        tolerance: float = 1e-4,
        max_iterations: int = 1000,
        norm: str = "inf",
        guard: str = "fallback",
        dt: float = 0.01,
    ) -> World: ...
    @staticmethod
    def pyramid(
        base: int = 10,
        *,
        tolerance: float = 1e-4,
        max_iterations: int = 1000,
        norm: str = "inf",
        guard: str = "fallback",
        dt: float = 0.01,
    ) -> World: ...
    @staticmethod
    def stack(
        count: int = 10,
        *,
        tolerance: float = 1e-4,
        max_iterations: int = 1000,
        norm: str = "inf",
        guard: str = "fallback",
        dt: float = 0.01,
    ) -> World: ...
    @staticmethod
    def resting_ball(
        *,
        tolerance: float = 1e-4,
        max_iterations: int = 1000,
        norm: str = "inf",
        guard: str = "fallback",
        dt: float = 0.01,
    ) -> World: ...
    @staticmethod
    def scene(
        name: str,
        seed: int = 12345,
        bodies: int = 100,
        *,
        tolerance: float = 1e-4,
        max_iterations: int = 1000,
        norm: str = "inf",
        guard: str = "fallback",
        dt: float = 0.01,
    ) -> World: ...
    def step(self, warm_start: Optional[WarmStartArg] = None, solver: str = "pgs") -> StepReport: ...
    def run(
        self, steps: int, warm_start: Optional[WarmStartArg] = None, solver: str = "pgs"
    ) -> List[StepReport]: ...
    def step_islands(
        self, warm_start: Optional[WarmStartArg] = None, solver: str = "pgs"
    ) -> Tuple[StepReport, List[Island]]: ...
    @property
    def scene_name(self) -> str: ...
    @property
    def step_index(self) -> int: ...
    @property
    def positions(self) -> F64: ...
    @property
    def angles(self) -> F64: ...
    @property
    def velocities(self) -> F64: ...
    @property
    def angular_velocities(self) -> F64: ...
    @property
    def masses(self) -> F64: ...
    @property
    def dynamic(self) -> Bool: ...
    def kinetic_energy(self) -> float: ...
    def __len__(self) -> int: ...

class CompareArgs:
    """The comparison's arguments, passed to compare_summary, compare_part and compare_merge."""
    def __init__(
        self,
        warm_starts: Sequence[Any],
        seeds: Sequence[int],
        steps: int,
        solvers: Sequence[str],
        bodies: int,
        scene: str,
        tolerance: float,
        max_iterations: int,
        norm: str,
        guard: str,
        threads: int,
        out: Optional[Union[str, PathLike[str]]] = None,
        figures: bool = False,
        same_problems: Optional[str] = None,
    ) -> None: ...

def compare_summary(args: CompareArgs) -> List[dict[str, Any]]: ...
def compare_part(args: CompareArgs) -> bytes: ...
def compare_merge(
    args: CompareArgs, parts: Sequence[bytes], total_threads: int, wall_seconds: float
) -> List[dict[str, Any]]: ...
def registry() -> Tuple[List[Tuple[str, str]], List[Tuple[str, str]]]: ...
