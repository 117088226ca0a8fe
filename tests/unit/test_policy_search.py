import numpy as np
import pytest

from hwlib import CartPoleLinearPolicy, eval_params, iterations_to_converge, run_policy, settings, train_cartpole_policy
from hwlib import TodoNotDone, policy_search
from hwlib.cartpole import MAX_EPISODE_REWARD
from hwlib.policy_search import converged_within

TOP = MAX_EPISODE_REWARD
from hwlib.training import learning_rate_sweep, run_training


@pytest.mark.todo("1.3.1")
def test_eval_params_is_the_mean_of_the_episodes_its_docstring_names():
    params = np.array([0.2, -0.4, -0.8, -0.1])
    expected = np.mean([run_policy(CartPoleLinearPolicy(params), seed=11 + k) for k in range(5)])
    assert eval_params(params, num_rollouts=5, seed=11) == pytest.approx(expected)
    assert isinstance(eval_params(params, num_rollouts=5, seed=11), float)


@pytest.mark.todo("1.3.1")
def test_eval_params_of_a_balancing_policy_is_the_maximum(balancing_params):
    assert eval_params(balancing_params, num_rollouts=5, seed=0) == MAX_EPISODE_REWARD


@pytest.mark.todo("1.3.1")
def test_eval_params_uses_its_number_of_rollouts():
    params = np.array([0.1, 0.0, -0.5, 0.0])
    one = [run_policy(CartPoleLinearPolicy(params), seed=seed) for seed in range(3)]
    assert eval_params(params, num_rollouts=1, seed=0) == one[0]
    assert eval_params(params, num_rollouts=3, seed=0) == pytest.approx(np.mean(one))


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


@pytest.mark.todo("1.3.3")
def test_training_with_the_defaults_converges_within_seven_iterations():
    run = run_training(seed=settings.TRAINING_SEED, progress=False)  # your train_cartpole_policy, as the notebook runs it
    assert run.rewards.shape == (settings.NUM_TRAINING_ITERATIONS + 1,)
    assert converged_within(run.rewards, settings.CONVERGENCE_DEADLINE)
    assert run.rewards[0] < MAX_EPISODE_REWARD  # it really learned: the start policy (zeros) is "always left"
    assert eval_params(run.policy.params, num_rollouts=20, seed=12345) == MAX_EPISODE_REWARD


@pytest.mark.todo("1.3.2")
def test_training_is_deterministic_for_a_seed():
    first = train_cartpole_policy(num_training_iterations=4, seed=3)
    second = train_cartpole_policy(num_training_iterations=4, seed=3)
    np.testing.assert_array_equal(first.rewards, second.rewards)
    np.testing.assert_array_equal(first.params_history, second.params_history)


@pytest.mark.todo("1.3.2")
def test_each_iteration_takes_the_step_of_equation_four(monkeypatch):
    # On a known objective (a concave quadratic, for which central differences are exact),
    # every update must be theta + learning_rate * gradient and the reward recorded after it g(theta).
    peak = np.array([1.0, -2.0, 0.5, 3.0])

    def quadratic(params, num_rollouts=20, seed=0):
        return float(-np.sum((np.asarray(params) - peak) ** 2))

    monkeypatch.setattr(policy_search, "eval_params", quadratic)
    learning_rate = 0.1
    run = train_cartpole_policy(3, 4, learning_rate, fd_step=0.5, seed=7)
    theta = np.zeros(4)
    for t in range(1, 4):
        theta = theta + learning_rate * (-2.0 * (theta - peak))
        np.testing.assert_allclose(run.params_history[t], theta)
        assert run.rewards[t] == pytest.approx(quadratic(theta))
    np.testing.assert_allclose(run.policy.params, theta)


@pytest.mark.todo("1.3.2")
def test_a_real_run_improves_on_always_left():
    run = train_cartpole_policy(3, 8, 0.0003, fd_step=0.5, seed=7)
    assert run.rewards.shape == (4,) and run.params_history.shape == (4, 4)
    assert run.rewards[-1] > run.rewards[0]
    assert not np.allclose(run.params_history[-1], 0.0)


@pytest.mark.parametrize("learning_rate", [np.nan, np.inf, -0.1, 0.0, "fast"])
def test_training_rejects_a_learning_rate_that_is_not_a_finite_positive_number(learning_rate):
    with pytest.raises((ValueError, TypeError), match="learning_rate must be"):
        train_cartpole_policy(1, learning_rate=learning_rate)


def test_training_without_a_learning_rate_says_where_to_set_it(monkeypatch):
    monkeypatch.setattr(settings, "LEARNING_RATE", None)
    with pytest.raises(TodoNotDone, match=r"TODO 1\.3\.3 is not done yet: LEARNING_RATE in hwlib/settings\.py"):
        train_cartpole_policy(1)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"num_training_iterations": 0}, "num_training_iterations must be a positive integer"),
        ({"num_rollouts_per_eval": 2.5}, "num_rollouts_per_eval must be a positive integer"),
        ({"fd_step": 0.0}, "fd_step must be a finite number > 0"),
        ({"initial_params": [0.0, 0.0, np.nan, 0.0]}, "initial_params must hold only finite numbers"),
        ({"initial_params": [0.0, 0.0]}, r"initial_params must have shape \(4,\)"),
        ({"seed": -1}, "seed must be a non-negative integer"),
    ],
)
def test_training_rejects_bad_settings(kwargs, message):
    with pytest.raises(ValueError, match=message):
        train_cartpole_policy(**kwargs)


def test_iterations_to_converge():
    assert iterations_to_converge([10, 20, TOP, TOP]) == 2
    assert iterations_to_converge([TOP, TOP - 1, TOP, TOP]) == 2
    assert iterations_to_converge([TOP, TOP]) == 0
    assert iterations_to_converge([10, TOP, TOP - 100]) is None
    assert converged_within([10, 20, 30, 40, 50, 60, 70, 80, TOP], 7) is False
    assert converged_within([10, 20, 30, 40, 50, 60, 70, TOP, TOP], 7) is True
    with pytest.raises(ValueError, match="rewards must be a non-empty 1-d array"):
        iterations_to_converge([])


@pytest.mark.todo("1.3.3")  # it trains with settings.LEARNING_RATE
def test_learning_rate_sweep_reports_a_fraction_per_rate():
    sweep = learning_rate_sweep([1e-6, settings.LEARNING_RATE], num_seeds=3, num_training_iterations=8)
    assert sweep.rewards.shape == (2, 3, 9)
    # A vanishing learning rate never leaves "always left"; the default converges.
    np.testing.assert_array_equal(sweep.converged_fraction, [0.0, 1.0])


def test_the_sweep_runs_are_the_separate_training_runs():
    sweep = learning_rate_sweep([0.0004, 0.003], num_seeds=2, first_seed=5, num_training_iterations=3)
    for rate_index, rate in enumerate([0.0004, 0.003]):
        for seed_index, seed in enumerate([5, 6]):
            alone = train_cartpole_policy(3, learning_rate=rate, seed=seed)
            np.testing.assert_array_equal(sweep.rewards[rate_index, seed_index], alone.rewards)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"learning_rates": [0.02, -1.0]}, "learning_rates must be a finite number > 0"),
        ({"learning_rates": []}, "learning_rates must be a non-empty 1-d array"),
        ({"num_seeds": 0}, "num_seeds must be a positive integer"),
        ({"first_seed": -2}, "first_seed must be a non-negative integer"),
        ({"deadline": 0}, "deadline must be a positive integer"),
    ],
)
def test_learning_rate_sweep_rejects_bad_arguments(kwargs, message):
    with pytest.raises(ValueError, match=message):
        learning_rate_sweep(**{"learning_rates": [0.02], "num_seeds": 1, **kwargs})


def checks_made(function, *args, **kwargs):
    """Call ``function`` and count the argument checks of hwlib/machinery/validation.py it makes, by
    (check, argument name); a check that another check calls is not counted again."""
    import collections
    import sys

    import hwlib.machinery.validation

    checks_file = hwlib.machinery.validation.__file__
    counts = collections.Counter()

    def profile(frame, event, arg):
        if event == "call" and frame.f_code.co_filename == checks_file and frame.f_back.f_code.co_filename != checks_file:
            counts[(frame.f_code.co_name, frame.f_locals.get("name"))] += 1

    sys.setprofile(profile)
    try:
        value = function(*args, **kwargs)
    finally:
        sys.setprofile(None)
    return value, counts


@pytest.mark.todo("1.3.1")
def test_eval_params_checks_each_argument_once():
    params = [0.2, -0.4, -0.8, -0.1]
    value, counts = checks_made(eval_params, params, 5, seed=11)
    assert value > 0
    assert counts == {  # the policy's __call__ checks nothing: its door is the constructor
        ("check_params", "params"): 1,  # by CartPoleLinearPolicy(params), not by eval_params as well
        ("check_count", "num_rollouts"): 1,
        ("check_seed", "seed"): 1 + 5,  # eval_params' seed, then the seed of each run_policy call
        ("check_policy", "policy"): 5,  # each run_policy call
    }


def test_in_a_kit_run_each_pass_of_eval_params_checks_once_and_the_batch_checks_nothing_again():
    from hwlib.machinery import batch, episodes

    params = [0.2, -0.4, -0.8, -0.1]
    episodes.agrees_with_equation_one(CartPoleLinearPolicy(params), np.array(params))  # its once-per-__call__ check: before counting
    session = batch.Session()
    with session.replaying(policy_search, ("eval_params",), counted="eval_params"):
        [value], counts = checks_made(session.run, [lambda: policy_search.eval_params(params, 5, seed=11)])
    assert value == eval_params(params, 5, seed=11)
    assert counts[("check_params", "params")] == 2  # the recording pass and the real one
    assert counts[("check_seed", "seed")] == 2 * (1 + 5)
    assert not {check for check, _ in counts} & {"check_params_batch", "check_seeds", "check_count_batch"}


def test_in_a_kit_training_run_each_call_of_eval_params_checks_its_params_once(monkeypatch):
    from hwlib.machinery import episodes
    from hwlib.training import run_training

    calls, original = [], policy_search.eval_params

    def counted_eval_params(params, num_rollouts=5, seed=0):
        calls.append(seed)
        return original(params, num_rollouts, seed)

    episodes.agrees_with_equation_one(CartPoleLinearPolicy(np.zeros(4)), np.zeros(4))  # its once-per-__call__ check
    monkeypatch.setattr(policy_search, "eval_params", counted_eval_params)
    run, counts = checks_made(run_training, 4, 5, 0.001, seed=3, progress=False)
    # By CartPoleLinearPolicy(params) in each call of eval_params, and once for the policy the run returns;
    # the batch engine makes the policies of foreseen calls without checking their params again.
    assert counts[("check_params", "params")] == len(calls) + 1
    assert len(calls) < 2 * (1 + 9 * 4)  # most calls foreseen, not recorded first
    assert not {check for check, _ in counts} & {"check_params_batch", "check_seeds", "check_count_batch"}


def test_the_sweep_says_what_to_check_when_no_run_converges_and_which_rates_to_choose():
    from hwlib.training import SweepResult

    never = SweepResult(np.array([1e-4, 1e-3]), np.arange(2), np.full((2, 2, 21), 9.0), 7)
    assert "TODO 1.2.1" in never.advice() and "TODO 1.3.2" in never.advice() and "direction" in never.advice()
    curves = np.full((3, 2, 21), float(TOP))
    curves[0, 1, :] = 9.0  # one seed of the first rate never converges
    some = SweepResult(np.array([1e-4, 4e-4, 6e-4]), np.arange(2), curves, 7)
    assert some.advice().startswith("Every seed converged within 7 iterations with the learning rate 0.0004 or 0.0006:")
    curves[1:, 1, :] = 9.0
    assert "0.0001 did best (50%)" in SweepResult(np.array([1e-4, 4e-4, 6e-4]), np.arange(2), curves, 7).advice()
