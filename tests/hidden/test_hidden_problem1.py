"""Hidden tests of problem 1: instructor-only, left out of the student edition.

They ask the same questions as the visible tests on inputs the students never see (other
seeds, other shapes, other step sizes), so a solution tuned to the visible tests loses points.
"""

import numpy as np
import pytest

from hwlib import CartPoleLinearPolicy, run_policy
from hwlib.cartpole import linear_policy_actions
from hwlib.finite_diff import batched_finite_diff, scalar_finite_diff
from hwlib.policy_search import (
    DEFAULT_LEARNING_RATE,
    eval_params_batch,
    learning_rate_sweep,
    train_cartpole_policies,
)

pytestmark = pytest.mark.hidden


@pytest.mark.todo("1.1.1")
def test_actions_match_equation_one_on_random_states():
    rng = np.random.default_rng(2024)
    params = rng.normal(size=(500, 4))
    observations = rng.normal(size=(500, 4))
    expected = (np.einsum("ij,ij->i", params, observations) < 0).astype(np.int64)
    actions = linear_policy_actions(params, observations)
    assert actions.dtype == np.int64
    np.testing.assert_array_equal(actions, expected)
    single = [CartPoleLinearPolicy(p)(o) for p, o in zip(params[:50], observations[:50])]
    assert single == expected[:50].tolist()


@pytest.mark.todo("1.2.1")
def test_central_difference_of_a_cubic_has_the_known_error():
    # For f(x) = sum a_i x_i^3 the central difference is exactly 3 a_i x_i^2 + a_i h_i^2;
    # a forward difference would add 3 a_i x_i h_i as well.
    rng = np.random.default_rng(7)
    coefficients = rng.uniform(0.5, 2.0, size=7)
    x = rng.uniform(-2.0, 2.0, size=7)
    steps = rng.uniform(0.05, 0.6, size=7)
    gradient = scalar_finite_diff(lambda v: float(np.sum(coefficients * v**3)), x, steps)
    np.testing.assert_allclose(gradient, 3 * coefficients * x**2 + coefficients * steps**2, rtol=1e-9, atol=1e-9)


@pytest.mark.todo("1.2.1")
def test_batched_gradients_of_many_points_in_one_call():
    rng = np.random.default_rng(11)
    points = rng.normal(size=(9, 5))
    matrix = rng.normal(size=(5, 5))
    calls = []

    def f_batch(perturbed):
        calls.append(perturbed.shape)
        return np.einsum("...i,ij,...j->...", perturbed, matrix, perturbed)

    gradients = batched_finite_diff(f_batch, points, 0.3)
    np.testing.assert_allclose(gradients, points @ (matrix + matrix.T), rtol=1e-9, atol=1e-9)
    assert calls == [(9, 10, 5)]


@pytest.mark.todo("1.3.1")
def test_eval_params_batch_with_other_shapes():
    rng = np.random.default_rng(5)
    params = rng.uniform(-1, 1, size=(3, 4))
    seeds = rng.integers(0, 10_000, size=(3, 6))
    expected = [np.mean([run_policy(CartPoleLinearPolicy(p), seed=int(s)) for s in row]) for p, row in zip(params, seeds)]
    np.testing.assert_allclose(eval_params_batch(params, seeds), expected)


@pytest.mark.todo("1.3.2")
def test_two_iterations_follow_equation_four_from_a_non_zero_start():
    start = np.array([0.05, -0.1, -0.2, 0.0])
    learning_rate, fd_step, num_rollouts, seed = 0.002, 0.3, 3, 21
    params, rewards = train_cartpole_policies(
        start[None, :], [learning_rate], [seed], num_training_iterations=2, num_rollouts_per_eval=num_rollouts, fd_step=fd_step
    )
    rng = np.random.default_rng(seed)

    def g(theta, seeds):
        return np.mean([run_policy(CartPoleLinearPolicy(theta), seed=int(s)) for s in seeds])

    theta, expected_rewards = start, []
    for _ in range(2):
        seeds = rng.integers(0, 2**31 - 1, size=num_rollouts)
        expected_rewards.append(g(theta, seeds))
        gradient = np.array([(g(theta + fd_step * e, seeds) - g(theta - fd_step * e, seeds)) / (2 * fd_step) for e in np.eye(4)])
        theta = theta + learning_rate * gradient
    expected_rewards.append(g(theta, rng.integers(0, 2**31 - 1, size=num_rollouts)))
    np.testing.assert_allclose(params[0], theta)
    np.testing.assert_allclose(rewards[0], expected_rewards)


@pytest.mark.todo("1.3.3")
def test_default_learning_rate_converges_for_unseen_seeds():
    sweep = learning_rate_sweep([DEFAULT_LEARNING_RATE], num_seeds=10, first_seed=100, num_training_iterations=10)
    assert sweep.converged_fraction[0] >= 0.9
