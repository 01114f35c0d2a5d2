"""Warm-start providers written in Python, through the same guard as Rust ones."""

import numpy as np
import pytest

import deepcontact
from conftest import SEED, STEPS, carried, iterations, zeros


def test_carried_provider_reproduces_builtin_exactly(builtin_iterations):
    assert iterations(carried) == builtin_iterations


def test_zero_provider_reproduces_none_exactly(none_iterations, builtin_iterations):
    assert iterations(zeros) == none_iterations
    assert none_iterations != builtin_iterations


def test_same_world_state_as_builtin():
    a = deepcontact.World.pile(seed=SEED, bodies=100)
    b = deepcontact.World.pile(seed=SEED, bodies=100)
    ra = a.run(STEPS, warm_start="builtin")
    rb = b.run(STEPS, warm_start=carried)
    assert np.array_equal(a.positions, b.positions)
    assert [r.natural_residual for r in ra] == [r.natural_residual for r in rb]
    assert all(np.array_equal(x.residual_curve, y.residual_curve) for x, y in zip(ra, rb))


def test_views_of_foreign_memory_are_copied(builtin_iterations):
    buffer = np.zeros((4096, 2))

    def strided_view(island):
        n = len(island)
        buffer[: 2 * n : 2] = island.carried
        return buffer[: 2 * n : 2]  # a strided view into memory the provider keeps changing

    class Scribbler:
        """Overwrites the buffer it returned last time before answering again."""

        def warm_start(self, island):
            buffer[:] = np.nan
            return strided_view(island)

    assert iterations(strided_view) == builtin_iterations
    assert iterations(Scribbler()) == builtin_iterations


def test_object_provider_with_observe_and_reset():
    class Recorder:
        name = "recorder"

        def __init__(self):
            self.resets = 0
            self.calls = 0
            self.observed = []

        def reset(self):
            self.resets += 1

        def warm_start(self, island):
            self.calls += 1
            return island.carried * 0.5

        def observe(self, island, solved):
            assert solved.shape == (len(island), 2)
            self.observed.append((island.step, island.island, solved.copy()))

    provider = Recorder()
    world = deepcontact.World.pile(seed=SEED, bodies=100)
    reports = world.run(STEPS, warm_start=provider)
    assert provider.resets == 1
    assert provider.calls == sum(r.islands for r in reports) == len(provider.observed)
    assert all(r.fallbacks == 0 for r in reports)
    # the next step with the same object keeps it (no second reset)
    report, islands = world.step_islands(warm_start=provider)
    assert provider.resets == 1
    last = [o for o in provider.observed if o[0] == report.step]
    assert [o[1] for o in last] == [i.problem.island for i in islands]
    assert all(np.array_equal(o[2], i.solved) for o, i in zip(last, islands))


def test_a_class_is_instantiated_once_per_world(builtin_iterations):
    class Carried:
        instances = 0

        def __init__(self):
            type(self).instances += 1

        def warm_start(self, island):
            return island.carried.copy()

    assert iterations(Carried) == builtin_iterations
    assert Carried.instances == 1


BAD_OUTPUTS = {
    "raises": (lambda island: 1 / 0, "ZeroDivisionError"),
    "wrong_rows": (lambda island: np.zeros((len(island) + 1, 2)), "impulses for"),
    "wrong_columns": (lambda island: np.zeros((len(island), 3)), "shape"),
    "wrong_dtype": (lambda island: np.zeros((len(island), 2), dtype=np.float32), "dtype"),
    "not_an_array": (lambda island: [[0.0, 0.0]] * len(island), "numpy.ndarray"),
    "nan": (lambda island: np.full((len(island), 2), np.nan), "non-finite"),
    "negative_normal": (lambda island: -np.ones((len(island), 2)), "negative normal"),
}


@pytest.mark.parametrize("case", sorted(BAD_OUTPUTS))
def test_bad_output_falls_back_and_is_counted(case, none_iterations):
    provider, _ = BAD_OUTPUTS[case]
    world = deepcontact.World.pile(seed=SEED, bodies=100)
    reports = world.run(STEPS, warm_start=provider)
    # every island fell back to zeros: exactly the cold start's iterations
    assert [r.iterations for r in reports] == none_iterations
    assert [r.fallbacks for r in reports] == [r.islands for r in reports]
    assert sum(r.fallbacks for r in reports) > 0


@pytest.mark.parametrize("case", sorted(BAD_OUTPUTS))
def test_bad_output_raises_under_the_error_guard(case):
    provider, message = BAD_OUTPUTS[case]
    world = deepcontact.World.pile(seed=SEED, bodies=100, guard="error")
    with pytest.raises(deepcontact.WarmStartError, match=message) as caught:
        world.run(STEPS, warm_start=provider)
    assert "failed on island 0" in str(caught.value)
    if case == "raises":
        assert isinstance(caught.value.__cause__, ZeroDivisionError)


def test_keyboard_interrupt_in_a_provider_reaches_the_caller():
    calls = [0]

    def interrupted(island):
        calls[0] += 1
        if calls[0] == 3:
            raise KeyboardInterrupt
        return island.carried

    world = deepcontact.World.pile(seed=SEED, bodies=100)
    with pytest.raises(KeyboardInterrupt):
        world.run(STEPS, warm_start=interrupted)
    # the interrupted step completed (remaining islands started cold); the world goes on
    stepped = world.step_index
    assert 0 < stepped < STEPS
    assert world.step(warm_start="builtin").step == stepped


def test_exception_in_observe_is_raised_after_the_step():
    class BadObserver:
        def warm_start(self, island):
            return island.carried

        def observe(self, island, solved):
            raise RuntimeError("observer broke")

    world = deepcontact.World.pile(seed=SEED, bodies=100)
    with pytest.raises(RuntimeError, match="observer broke"):
        world.run(STEPS, warm_start=BadObserver())


def test_not_a_provider_is_a_type_error():
    with pytest.raises(TypeError, match="warm_start must be"):
        deepcontact.World.pile().step(warm_start=42)


def test_a_provider_touching_its_own_world_gets_an_error_not_a_deadlock(none_iterations):
    world = deepcontact.World.pile(seed=SEED, bodies=100)

    def peek(island):
        world.positions  # the world is mid-step: a ValueError, so the island falls back
        return island.carried

    reports = world.run(STEPS, warm_start=peek)
    assert [r.iterations for r in reports] == none_iterations
    assert sum(r.fallbacks for r in reports) == sum(r.islands for r in reports) > 0
    strict = deepcontact.World.pile(seed=SEED, bodies=100, guard="error")
    with pytest.raises(deepcontact.WarmStartError, match="world is busy"):
        strict.run(STEPS, warm_start=lambda island: strict.positions)
