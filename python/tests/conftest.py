"""Shared helpers of the deepcontact tests: small scenes, few steps, real behaviour."""

import numpy as np
import pytest

import deepcontact

# Seed 12345's pile: the circles first touch after ~35 steps; 80 steps give ~45 steps with
# contacts and a few hundred velocity iterations in total.
SEED = 12345
STEPS = 80


def carried(island):
    """The carried impulses: must reproduce 'builtin' exactly."""
    return island.carried


def zeros(island):
    """A cold start: must reproduce 'none' exactly."""
    return np.zeros((len(island), 2))


def iterations(warm_start, steps=STEPS, seed=SEED, **settings):
    world = deepcontact.World.pile(seed=seed, bodies=100, **settings)
    return [world.step(warm_start=warm_start).iterations for _ in range(steps)]


@pytest.fixture(scope="session")
def builtin_iterations():
    return iterations("builtin")


@pytest.fixture(scope="session")
def none_iterations():
    return iterations("none")
