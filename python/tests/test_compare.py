"""deepcontact.compare: the CLI's comparison, its numbers, Python providers, Ctrl-C."""

import _thread
import json
import os
import pathlib
import signal
import subprocess
import threading
import time

import pytest

import deepcontact
from conftest import carried, zeros

SEEDS = [12345, 12346]
STEPS = 60  # the first contacts come after ~35 steps: 30 steps would compare only zeros
# Columns that are wall times (and ratios of them): everything else must match exactly.
TIMING = {"warm_start_ms", "solve_ms", "step_ms", "speedup_vs_none", "speedup_vs_builtin"}
ROOT = pathlib.Path(__file__).resolve().parents[2]


def numbers(row):
    return {k: v for k, v in row.items() if k not in TIMING and k != "warm_start"}


@pytest.fixture(scope="module")
def rows():
    return deepcontact.compare(
        ["none", "builtin", carried, zeros], seeds=SEEDS, steps=STEPS, as_frame=False
    )


def test_summary_rows(rows):
    assert [r["warm_start"] for r in rows] == ["none", "builtin", "carried", "zeros"]
    columns = list(rows[0])
    assert columns[:4] == ["solver", "warm_start", "seeds", "steps"]
    assert rows[0]["steps"] == len(SEEDS) * STEPS and rows[0]["contact_steps"] > 0
    assert rows[1]["mean_iterations"] < rows[0]["mean_iterations"]


def test_python_providers_give_the_registry_numbers(rows):
    none, builtin, carried_row, zeros_row = rows
    assert numbers(carried_row) == numbers(builtin)
    assert numbers(zeros_row) == numbers(none)


def cli():
    """The CLI binary. Without it the CLI comparisons skip, unless DEEPCONTACT_CLI names it
    (as CI does): then a missing binary is a failure, not a green run that compared nothing."""
    named = os.environ.get("DEEPCONTACT_CLI")
    path = named or str(ROOT / "target" / "release" / "deepcontact")
    if not os.path.exists(path):
        if named:
            pytest.fail(f"DEEPCONTACT_CLI={named} does not exist")
        pytest.skip(f"no CLI binary at {path} (cargo build --release, or set DEEPCONTACT_CLI)")
    return path


def test_same_numbers_as_the_cli(rows, tmp_path):
    out = tmp_path / "cli"
    subprocess.run(
        [cli(), "compare", "--seeds", "12345..12347", "--steps", str(STEPS),
         "--warm-starts", "none,builtin", "--out", str(out)],
        check=True, stdout=subprocess.DEVNULL,
    )
    summary = json.loads((out / "summary.json").read_text())["summary"]
    assert [r["warm_start"] for r in summary] == ["none", "builtin"]
    for ours, theirs in zip(rows[:2], summary):
        assert numbers(ours) == numbers(theirs)


@pytest.mark.parametrize("spec, provider", [("builtin", carried), ("none", zeros)])
def test_same_iterations_per_step_as_cli_simulate(spec, provider):
    steps = 80
    lines = subprocess.run(
        [cli(), "simulate", "--seed", "12345", "--steps", str(steps), "--warm-start", spec,
         "--json"],
        check=True, capture_output=True, text=True,
    ).stdout.splitlines()
    theirs = [json.loads(line)["velocity_iterations"] for line in lines if line.startswith("{")]
    assert len(theirs) == steps and sum(theirs) > 0
    for warm_start in (spec, provider):
        world = deepcontact.World.pile(seed=12345, bodies=100)
        assert [r.iterations for r in world.run(steps, warm_start=warm_start)] == theirs


def test_outputs_are_the_cli_files(tmp_path):
    rows = deepcontact.compare(["none", carried], seeds=SEEDS[:1], steps=40, out=tmp_path,
                               as_frame=False)
    assert {p.name for p in tmp_path.iterdir()} >= {
        "steps.csv", "curves.csv", "summary.csv", "summary.md", "summary.json"
    }
    written = json.loads((tmp_path / "summary.json").read_text())["summary"]
    assert [numbers(r) for r in written] == [numbers(r) for r in rows]


def test_python_provider_errors_in_compare():
    def broken(island):
        raise ValueError("no luck")

    rows = deepcontact.compare(["none", broken], seeds=SEEDS[:1], steps=STEPS, as_frame=False)
    assert rows[1]["fallbacks"] > 0 and numbers(rows[1])["mean_iterations"] == rows[0]["mean_iterations"]
    with pytest.raises(deepcontact.WarmStartError, match="no luck"):
        deepcontact.compare([broken], seeds=SEEDS[:1], steps=STEPS, guard="error")


def test_same_problems_solves_every_start_on_the_drivers_world(rows):
    same = deepcontact.compare(
        ["none", "builtin", carried], seeds=SEEDS, steps=STEPS, same_problems="builtin", as_frame=False
    )
    # The driver's numbers are the ordinary comparison's; a Python provider copying the
    # carried impulses on the driver's world is the driver, step for step.
    assert numbers(same[1]) == numbers(rows[1])
    assert numbers(same[2]) == numbers(rows[1])
    assert same[0]["mean_contacts"] == same[1]["mean_contacts"]
    assert numbers(same[0]) != numbers(rows[0])
    with pytest.raises(ValueError, match="not one of the warm starts"):
        deepcontact.compare(["none"], seeds=SEEDS[:1], steps=5, same_problems="builtin")


def test_names_and_bad_arguments():
    def builtin(island):
        return island.carried

    with pytest.raises(ValueError, match="registry provider"):
        deepcontact.compare([builtin], seeds=SEEDS[:1], steps=5)
    builtin.name = "mine"
    rows = deepcontact.compare([builtin], seeds=SEEDS[:1], steps=5, as_frame=False)
    assert rows[0]["warm_start"] == "mine"
    with pytest.raises(ValueError, match="listed twice"):
        deepcontact.compare(["none", "none"], seeds=SEEDS[:1], steps=5)
    with pytest.raises(ValueError, match="unknown warm start"):
        deepcontact.compare(["nope"], seeds=SEEDS[:1], steps=5)


def test_keyboard_interrupt_stops_a_long_compare(tmp_path):
    def slow(island):
        time.sleep(0.001)
        return island.carried

    # Ctrl-C raises KeyboardInterrupt only under Python's own handler; a process started in
    # the background of a non-interactive shell inherits SIGINT ignored, where
    # `interrupt_main` does nothing. The test installs the handler for its duration.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    t0 = time.perf_counter()
    try:
        with pytest.raises(KeyboardInterrupt):
            # about 75 s on 2 cores if it ran to the end
            deepcontact.compare(
                [slow, "none"], seeds=range(12345, 12445), steps=250, out=tmp_path
            )
    finally:
        timer.join()
        signal.signal(signal.SIGINT, previous)
    assert time.perf_counter() - t0 < 10.0
    assert list(tmp_path.iterdir()) == []  # nothing half-written
    # the process is fine and the next comparison runs
    assert len(deepcontact.compare(["none"], seeds=SEEDS[:1], steps=5, as_frame=False)) == 1


def test_registry_lists_providers_and_solvers():
    providers, solvers = deepcontact.registry()
    assert {"none", "builtin", "copy"} <= {name for name, _ in providers}
    assert {"pgs", "newton"} <= {name for name, _ in solvers}


def test_python_providers_are_deterministic_across_threads():
    # One worker against two, both named (the default, 0, is one per core: two on a
    # two-core machine, the same as the other run).
    one, two = (
        deepcontact.compare(["none", "builtin", carried, zeros], seeds=SEEDS, steps=STEPS,
                            threads=threads, as_frame=False)
        for threads in (1, 2)
    )
    assert [numbers(r) for r in two] == [numbers(r) for r in one]


def test_bad_compare_arguments_are_value_errors():
    with pytest.raises(ValueError, match="no seed"):
        deepcontact.compare(["none"], seeds=[], steps=5)
    with pytest.raises(ValueError, match="steps"):
        deepcontact.compare(["none"], seeds=SEEDS, steps=0)
    with pytest.raises(ValueError, match="MAX_BODIES"):
        deepcontact.compare(["none"], seeds=SEEDS, steps=5, bodies=10**9)
