"""Worlds, steps, body state, settings and the islands as training data."""

import threading
import time

import numpy as np
import pytest

import deepcontact
from conftest import SEED, STEPS, iterations


def test_pile_steps_with_contacts_and_reports(builtin_iterations):
    assert sum(builtin_iterations) > 100, builtin_iterations
    world = deepcontact.World.pile(seed=SEED, bodies=100)
    reports = world.run(STEPS, warm_start="builtin")
    assert [r.iterations for r in reports] == builtin_iterations
    last = reports[-1]
    assert last.step == STEPS - 1 and world.step_index == STEPS
    assert last.contacts > 0 and last.islands > 0
    assert last.residual_curve.dtype == np.float64
    assert len(last.residual_curve) == last.iterations
    assert last.residual_curve[-1] < 1e-4 or last.capped_islands > 0
    assert last.natural_residual >= 0.0 and last.fallbacks == 0
    assert last.step_seconds >= last.solve_seconds >= 0.0
    stages = last.collide_seconds + last.islands_seconds + last.solve_seconds
    assert last.collide_seconds > 0.0 and last.position_seconds > 0.0
    assert last.step_seconds >= stages + last.position_seconds + last.warm_start_seconds


def test_same_seed_is_bit_identical():
    a = deepcontact.World.pile(seed=SEED, bodies=100)
    b = deepcontact.World.pile(seed=SEED, bodies=100)
    a.run(STEPS)
    b.run(STEPS)
    assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(a.velocities, b.velocities)
    assert np.array_equal(a.angular_velocities, b.angular_velocities)
    c = deepcontact.World.pile(seed=SEED + 1, bodies=100)
    c.run(STEPS)
    assert not np.array_equal(a.positions, c.positions)


def test_body_state_arrays():
    world = deepcontact.World.pile(seed=SEED, bodies=50)
    n = len(world)
    assert n == 50 + 4  # the circles and the box's four walls
    assert world.positions.shape == (n, 2) and world.velocities.shape == (n, 2)
    assert world.angles.shape == (n,) and world.angular_velocities.shape == (n,)
    assert world.dynamic.sum() == 50
    assert np.all(world.masses[world.dynamic] == pytest.approx(np.pi * 0.25))
    before = world.positions[world.dynamic, 1].copy()
    world.run(10)
    assert np.all(world.positions[world.dynamic, 1] < before)  # free fall
    assert world.kinetic_energy() > 0.0


def test_scenes():
    assert deepcontact.World.thesis(seed=12345).scene_name == "thesis"
    assert deepcontact.World.pyramid(base=4).step().contacts > 0
    assert len(deepcontact.World.stack(count=3)) == 4
    assert deepcontact.World.resting_ball().step().contacts == 1
    assert deepcontact.World.scene("pile", seed=7, bodies=40).scene_name == "pile"
    with pytest.raises(ValueError, match="unknown scene"):
        deepcontact.World.scene("nowhere")


def test_solver_settings_as_keywords(builtin_iterations):
    loose = iterations("builtin", tolerance=1e-2)
    assert sum(loose) < sum(builtin_iterations)
    capped = deepcontact.World.pile(seed=SEED, bodies=100, max_iterations=3)
    reports = capped.run(STEPS)
    assert max(r.iterations for r in reports) == 3
    assert any(r.capped_islands > 0 for r in reports)
    l2 = iterations("builtin", norm="l2")
    assert l2 != builtin_iterations
    with pytest.raises(ValueError, match="norm"):
        deepcontact.World.pile(norm="max")
    with pytest.raises(ValueError, match="max_iterations"):
        deepcontact.World.pile(max_iterations=0)
    with pytest.raises(ValueError, match="unknown solver"):
        deepcontact.World.pile().step(solver="nope")
    with pytest.raises(ValueError, match="unknown warm start"):
        deepcontact.World.pile().step(warm_start="nope")


def test_other_solvers_run():
    world = deepcontact.World.pile(seed=SEED, bodies=100)
    world.run(STEPS - 1)
    assert world.step(solver="newton").contacts > 0


def test_step_islands_gives_problems_and_solutions():
    world = deepcontact.World.pile(seed=SEED, bodies=100)
    world.run(STEPS - 1)
    report, islands = world.step_islands(warm_start="builtin")
    assert len(islands) == report.islands > 0
    assert sum(len(i.problem) for i in islands) == report.contacts
    assert max(i.iterations for i in islands) == report.iterations
    for island in islands:
        p = island.problem
        n, m = len(p), len(p.angles)
        assert island.solved.shape == island.start.shape == (n, 2)
        # builtin starts from the carried impulses
        assert np.array_equal(island.start, p.carried)
        assert np.all(island.solved[:, 0] >= 0.0)
        assert np.all(np.abs(island.solved[:, 1]) <= p.friction * island.solved[:, 0] + 1e-12)
        assert p.normals.shape == p.points.shape == (n, 2)
        assert np.allclose(np.linalg.norm(p.normals, axis=1), 1.0)
        assert p.body_a.max() < m and p.body_b.max() < m
        assert p.positions.shape == p.velocities.shape == (m, 2)
        assert np.all(p.normal_mass > 0.0) and np.all(p.tangent_mass > 0.0)
        assert np.all((p.inv_masses == 0.0) == np.isinf(p.masses))
        assert p.step == STEPS - 1 and p.dt == 0.01
        assert np.array_equal(p.gravity, [0.0, -9.81])
    # The training data does not change the simulation.
    twin = deepcontact.World.pile(seed=SEED, bodies=100)
    twin.run(STEPS)
    assert np.array_equal(twin.positions, world.positions)


def test_gil_is_released_while_rust_steps():
    counter = [0]
    done = threading.Event()

    def spin():
        while not done.is_set():
            counter[0] += 1

    thread = threading.Thread(target=spin)
    thread.start()
    try:
        world = deepcontact.World.pile(seed=SEED, bodies=100)
        time.sleep(0.01)
        before = counter[0]
        t0 = time.perf_counter()
        world.run(250)  # one call, ~0.5 s of Rust
        elapsed = time.perf_counter() - t0
        during = counter[0] - before
    finally:
        done.set()
        thread.join()
    # Holding the GIL for the whole call would leave the spinning thread at a few hundred
    # increments at most (one switch interval when the call starts).
    assert elapsed > 0.1
    assert during > 10000, (during, elapsed)
