"""The episode batcher (hwlib/_batch.py): faster, never different."""

import numpy as np
import pytest

from hwlib import CartPoleLinearPolicy, _batch, eval_params, run_policy
from hwlib.cartpole import play_episode


def plain_mean(policy, seeds):
    return float(np.mean([play_episode(policy, seed=seed).total_reward for seed in seeds]))


def test_eval_params_plays_its_rollouts_in_one_batch():
    params = [0.1, -0.3, -0.9, -0.2]

    def task():
        value = eval_params(params, num_rollouts=6, seed=40)
        return value, _batch.current_batcher().rounds, _batch.current_batcher().episodes_played

    [(value, rounds, played)] = _batch.run_together([task])
    assert (rounds, played) == (1, 6)
    assert value == plain_mean(CartPoleLinearPolicy(params), range(40, 46))


def test_code_that_asks_for_other_seeds_still_gets_the_right_rewards():
    policy = CartPoleLinearPolicy([0.2, 0.1, -1.0, -0.3])
    rewards = _batch.run_together([lambda seed=seed: run_policy(policy, seed=seed) for seed in (3, 99, 3, 7)])
    assert rewards == [play_episode(policy, seed=seed).total_reward for seed in (3, 99, 3, 7)]


class MirroredPolicy(CartPoleLinearPolicy):
    """Not equation (1): the batch engine's copy of it must not be used for this policy."""

    def __call__(self, obs):
        return int(np.dot(self.params, obs) > 0)


class TieBreakingPolicy(CartPoleLinearPolicy):
    """Equation (1) but for the tie at zero, where it pushes right."""

    def __call__(self, obs):
        return int(np.dot(self.params, obs) <= 0)


@pytest.mark.parametrize("policy_class", [MirroredPolicy, TieBreakingPolicy])
def test_a_policy_that_is_not_equation_one_is_played_with_its_own_call(policy_class):
    params = [0.0, 0.0, 0.0, 0.0] if policy_class is TieBreakingPolicy else [0.3, -0.2, 0.8, 0.1]
    policy = policy_class(params)
    batched = _batch.run_together([lambda seed=seed: run_policy(policy, seed=seed) for seed in range(4)])
    assert batched == [play_episode(policy, seed=seed).total_reward for seed in range(4)]


def test_an_error_in_the_policy_reaches_the_caller():
    class Broken(CartPoleLinearPolicy):
        def __call__(self, obs):
            raise RuntimeError("broken policy")

    with pytest.raises(RuntimeError, match="broken policy"):
        _batch.run_together([lambda: run_policy(Broken([0.0, 0.0, 0.0, 0.0]), seed=1)])


def test_many_threads_asking_for_the_same_episodes_all_get_them():
    params = [0.1, -0.5, -0.6, -0.1]
    results = _batch.run_together([lambda: eval_params(params, num_rollouts=5, seed=2)] * 12)
    assert results == [plain_mean(CartPoleLinearPolicy(params), range(2, 7))] * 12


def test_run_together_keeps_the_order_and_raises_the_first_error():
    assert _batch.run_together([lambda value=value: value * 2 for value in range(5)]) == [0, 2, 4, 6, 8]
    assert _batch.run_together([]) == []

    def fails():
        raise ValueError("task failed")

    with pytest.raises(ValueError, match="task failed"):
        _batch.run_together([lambda: 1, fails])


def test_disabled_plays_every_episode_on_its_own():
    with _batch.disabled():
        assert _batch.current_batcher() is None
        value = eval_params([0.1, -0.3, -0.9, -0.2], num_rollouts=3, seed=0)
    assert value == eval_params([0.1, -0.3, -0.9, -0.2], num_rollouts=3, seed=0)
