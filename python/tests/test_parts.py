"""Comparison parts (what a cluster task returns) merged without a cluster: the merge gives the
one-machine rows, and refuses a run missing, doubled or foreign, or a damaged part."""

import pytest

import deepcontact
from deepcontact._deepcontact import CompareArgs, compare_merge, compare_part

SEEDS = [12345, 12346, 12347]
STEPS = 50
# warm starts, steps, solvers, bodies, scene, tolerance, max_iterations, norm, guard
ARGS = (["none", "builtin"], STEPS, ["pgs"], 100, "pile", 1e-4, 1000, "inf", "fallback")
TIMING = {"warm_start_ms", "solve_ms", "step_ms", "speedup_vs_none", "speedup_vs_builtin"}


def part(seed):
    return compare_part(CompareArgs(ARGS[0], [seed], *ARGS[1:], 1))


def merge(parts, seeds=SEEDS):
    return compare_merge(CompareArgs(ARGS[0], seeds, *ARGS[1:], 0), parts, 1, 0.0)


@pytest.fixture(scope="module")
def parts():
    return [part(s) for s in SEEDS]


def numbers(rows):
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


def test_parts_in_any_order_merge_into_the_one_machine_rows(parts):
    local = deepcontact.compare(ARGS[0], seeds=SEEDS, steps=STEPS, as_frame=False)
    assert numbers(merge(parts[::-1])) == numbers(local)
    assert local[0]["contact_steps"] > 0


def test_a_doubled_run_is_refused(parts):
    with pytest.raises(deepcontact.DeepContactError, match="came twice"):
        merge(parts + [parts[0]], seeds=SEEDS)


def test_a_missing_run_is_refused(parts):
    with pytest.raises(deepcontact.DeepContactError, match="4 runs of the 6"):
        merge(parts[:2])


def test_a_foreign_seed_is_refused(parts):
    with pytest.raises(deepcontact.DeepContactError, match="seed 12347 is not in the comparison"):
        merge(parts, seeds=SEEDS[:2])


def test_a_damaged_part_is_refused(parts):
    with pytest.raises(deepcontact.DeepContactError, match="part 1: truncated"):
        merge([parts[0], parts[1][:-9], parts[2]])
    with pytest.raises(deepcontact.DeepContactError, match="part 0: not a comparison part"):
        merge([b"x" * 64] + parts[1:])
