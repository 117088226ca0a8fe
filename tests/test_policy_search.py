import numpy as np
import pytest

from hwlib import CartPoleLinearPolicy, eval_params, iterations_to_converge, run_policy, train_cartpole_policy
from hwlib.cartpole import BALANCING_PARAMS, episode_seeds
from hwlib.policy_search import (
    DEFAULT_LEARNING_RATE,
    converged_within,
    eval_params_batch,
    learning_rate_sweep,
    train_cartpole_policies,
)


@pytest.mark.todo("1.3.1")
def test_eval_params_is_the_mean_of_single_episodes():
    params = np.array([0.2, -0.4, -0.8, -0.1])
    seeds = episode_seeds(5, seed=11)
    expected = np.mean([run_policy(CartPoleLinearPolicy(params), seed=int(s)) for s in seeds])
    assert eval_params(params, num_rollouts=5, seed=11) == pytest.approx(expected)


@pytest.mark.todo("1.3.1")
def test_eval_params_of_a_balancing_policy_is_the_maximum():
    assert eval_params(BALANCING_PARAMS, num_rollouts=8, seed=0) == 500.0


@pytest.mark.todo("1.3.1")
def test_eval_params_batch_scores_each_row_on_its_own_seeds():
    params = np.array([BALANCING_PARAMS, [0.0, 0.0, 0.0, 0.0]])
    seeds = np.array([[1, 2], [3, 4]])
    expected = [np.mean([run_policy(CartPoleLinearPolicy(p), seed=s) for s in row]) for p, row in zip(params, seeds)]
    np.testing.assert_allclose(eval_params_batch(params, seeds), expected)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"params": [1.0, 2.0]}, r"params must have shape \(4,\)"),
        ({"params": [np.nan, 0, 0, 0]}, "params must hold only finite numbers"),
        ({"params": [0, 0, 0, 0], "num_rollouts": 0}, "num_rollouts must be a positive integer"),
        ({"params": [0, 0, 0, 0], "seed": -3}, "seed must be a non-negative integer"),
    ],
)
def test_eval_params_rejects_bad_input(kwargs, message):
    with pytest.raises(ValueError, match=message):
        eval_params(**kwargs)


def test_eval_params_batch_rejects_mismatched_seeds():
    with pytest.raises(ValueError, match=r"rollout_seeds must have shape \(2, R\)"):
        eval_params_batch(np.zeros((2, 4)), np.zeros((3, 2), dtype=int))


@pytest.mark.todo("1.3.3")
def test_training_with_the_defaults_converges_within_seven_iterations():
    run = train_cartpole_policy(num_training_iterations=20, seed=0)
    assert run.rewards.shape == (21,)
    assert converged_within(run.rewards, 7)
    assert run.rewards[0] < 500  # it really learned: the start policy (zeros) is "always left"
    assert eval_params(run.policy.params, num_rollouts=20, seed=12345) == 500.0


@pytest.mark.todo("1.3.3")
def test_training_is_deterministic_for_a_seed():
    first = train_cartpole_policy(num_training_iterations=4, seed=3)
    second = train_cartpole_policy(num_training_iterations=4, seed=3)
    np.testing.assert_array_equal(first.rewards, second.rewards)
    np.testing.assert_array_equal(first.policy.params, second.policy.params)


@pytest.mark.todo("1.3.2")
def test_training_follows_the_gradient_ascent_update():
    # One iteration from zeros by hand: the same seeds, the same finite differences, one step.
    learning_rate, fd_step, num_rollouts, seed = 0.001, 0.5, 4, 7
    run = train_cartpole_policy(1, num_rollouts, learning_rate, fd_step=fd_step, seed=seed)
    rollout_seeds = np.random.default_rng(seed).integers(0, 2**31 - 1, size=num_rollouts)

    def g(theta):
        return np.mean([run_policy(CartPoleLinearPolicy(theta), seed=int(s)) for s in rollout_seeds])

    gradient = np.array([(g(fd_step * e) - g(-fd_step * e)) / (2 * fd_step) for e in np.eye(4)])
    np.testing.assert_allclose(run.policy.params, learning_rate * gradient)
    assert run.rewards[0] == pytest.approx(g(np.zeros(4)))


@pytest.mark.todo("1.3.2")
def test_many_runs_side_by_side_equal_separate_runs():
    starts = np.array([[0.0, 0.0, 0.0, 0.0], [0.1, -0.2, 0.3, -0.4]])
    params, rewards = train_cartpole_policies(starts, [0.001, 0.003], [5, 6], num_training_iterations=3)
    for row, (start, rate, seed) in enumerate(zip(starts, [0.001, 0.003], [5, 6])):
        alone = train_cartpole_policy(3, learning_rate=rate, initial_params=start, seed=seed)
        np.testing.assert_allclose(params[row], alone.policy.params)
        np.testing.assert_array_equal(rewards[row], alone.rewards)


@pytest.mark.parametrize("learning_rate", [np.nan, np.inf, -0.1, 0.0, "fast"])
def test_training_rejects_a_learning_rate_that_is_not_a_finite_positive_number(learning_rate):
    with pytest.raises((ValueError, TypeError), match="learning_rate must be"):
        train_cartpole_policy(1, learning_rate=learning_rate)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"num_training_iterations": 0}, "num_training_iterations must be a positive integer"),
        ({"num_rollouts_per_eval": 2.5}, "num_rollouts_per_eval must be a positive integer"),
        ({"fd_step": 0.0}, "fd_step must be a finite number > 0"),
        ({"initial_params": [0.0, 0.0, np.nan, 0.0]}, "initial_params must hold only finite numbers"),
        ({"initial_params": [0.0, 0.0]}, r"initial_params must have shape \(4,\)"),
    ],
)
def test_training_rejects_bad_settings(kwargs, message):
    with pytest.raises(ValueError, match=message):
        train_cartpole_policy(**kwargs)


def test_iterations_to_converge():
    assert iterations_to_converge([10, 200, 500, 500]) == 2
    assert iterations_to_converge([500, 499, 500, 500]) == 2
    assert iterations_to_converge([500, 500]) == 0
    assert iterations_to_converge([10, 500, 400]) is None
    assert converged_within([10, 20, 30, 40, 50, 60, 70, 80, 500], 7) is False
    assert converged_within([10, 20, 30, 40, 50, 60, 70, 500, 500], 7) is True
    with pytest.raises(ValueError, match="rewards must be a non-empty 1-d array"):
        iterations_to_converge([])


@pytest.mark.todo("1.3.3")
def test_learning_rate_sweep_reports_a_fraction_per_rate():
    sweep = learning_rate_sweep([1e-6, DEFAULT_LEARNING_RATE], num_seeds=3, num_training_iterations=8)
    assert sweep.rewards.shape == (2, 3, 9)
    # A vanishing learning rate never leaves "always left"; the default converges.
    np.testing.assert_array_equal(sweep.converged_fraction, [0.0, 1.0])
    with pytest.raises(ValueError, match="learning_rate must be a finite number > 0"):
        learning_rate_sweep([0.001, -1.0], num_seeds=2)
