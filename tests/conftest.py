"""Fixtures shared by the unit tests of the homework (tests/unit/, which the student edition ships) and of the
kit's given code (tests/library/)."""

import numpy as np
import pytest

from hwlib.cartpole import MAX_EPISODE_REWARD, sample_random_params
from hwlib.machinery.episodes import run_episodes

BALANCING_SEEDS = tuple(range(5))


def find_balancing_params(seeds=BALANCING_SEEDS, search_seed=0):
    """A parameter vector that reaches the maximum reward from every start in ``seeds``, found by seeded random search.

    The kit ships no such vector (finding one is handout 1.1.2), so the tests look for one, with the
    kit's batch engine, which does not depend on any TODO.
    """
    candidates = sample_random_params(400, search_seed)
    rewards = run_episodes(np.repeat(candidates, len(seeds), axis=0), np.tile(seeds, len(candidates)))
    good = np.flatnonzero(np.all(rewards.reshape(len(candidates), len(seeds)) == MAX_EPISODE_REWARD, axis=1))
    assert good.size, "no random parameter vector balanced the pole on every seed"
    return tuple(float(value) for value in candidates[good[0]])


@pytest.fixture(scope="session")
def balancing_params():
    """Four weights with which the linear policy balances for every step (MAX_EPISODE_STEPS) from seeds 0-4."""
    return find_balancing_params()

