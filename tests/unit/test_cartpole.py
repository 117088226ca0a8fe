import gymnasium as gym
import numpy as np
import pytest

from hwlib import CartPoleLinearPolicy, play_episode, random_policy_rewards, run_policy
from hwlib.cartpole import MAX_EPISODE_REWARD, ALWAYS_LEFT_PARAMS, ALWAYS_RIGHT_PARAMS, episode_seeds, sample_random_params
from hwlib.machinery.episodes import batch_actions, run_episodes, start_states


@pytest.mark.todo("1.1.1")
def test_policy_follows_equation_one():
    policy = CartPoleLinearPolicy([1.0, 0.0, -2.0, 0.0])
    assert policy(np.array([0.0, 0.0, 0.1, 0.0])) == 1  # score -0.2 < 0
    assert policy(np.array([0.0, 0.0, -0.1, 0.0])) == 0  # score 0.2
    assert policy(np.array([0.2, 0.0, 0.1, 0.0])) == 0  # score exactly 0 is not < 0


@pytest.mark.todo("1.1.1")
def test_policy_returns_python_int_actions_the_env_accepts(balancing_params):
    action = CartPoleLinearPolicy(balancing_params)(np.zeros(4, dtype=np.float32))
    assert type(action) is int
    assert gym.make("CartPole-v1").action_space.contains(action)


def test_batch_engine_actions_pair_each_row_of_params_with_its_observation():
    params = np.array([[1.0, 0, 0, 0], [-1.0, 0, 0, 0], [0.0, 0, 0, 0]])
    observations = np.array([[1.0, 0, 0, 0], [1.0, 0, 0, 0], [0.3, 0.1, 0.0, 0.0]])
    np.testing.assert_array_equal(batch_actions(params, observations), [0, 1, 0])


@pytest.mark.parametrize("params", [[1.0, 2.0, 3.0], np.zeros((2, 4)), [1.0, 2.0, 3.0, np.nan], [0, 0, np.inf, 0]])
def test_policy_rejects_bad_params(params):
    with pytest.raises(ValueError, match="params must"):
        CartPoleLinearPolicy(params)


def test_policy_rejects_non_numeric_params():
    with pytest.raises(TypeError, match="params must be an array of numbers"):
        CartPoleLinearPolicy(["a", "b", "c", "d"])


@pytest.mark.todo("1.1.1")
def test_run_policy_is_deterministic_for_a_seed():
    policy = CartPoleLinearPolicy([0.3, -0.2, -0.9, -0.1])
    assert run_policy(policy, seed=5) == run_policy(policy, seed=5)


@pytest.mark.todo("1.1.1")
def test_presets_behave_as_named(balancing_params):
    left = play_episode(CartPoleLinearPolicy(ALWAYS_LEFT_PARAMS), seed=0)
    right = play_episode(CartPoleLinearPolicy(ALWAYS_RIGHT_PARAMS), seed=0)
    assert set(left.actions.tolist()) == {0}
    assert set(right.actions.tolist()) == {1}
    rewards = [run_policy(CartPoleLinearPolicy(balancing_params), seed=seed) for seed in range(5)]
    assert rewards == [float(MAX_EPISODE_REWARD)] * 5


@pytest.mark.todo("1.1.1")
def test_episode_records_every_state_and_ends_at_a_threshold_or_the_horizon():
    episode = play_episode(CartPoleLinearPolicy(ALWAYS_LEFT_PARAMS), seed=1)
    assert episode.states.shape == (episode.num_steps + 1, 4)
    assert episode.total_reward == episode.num_steps < MAX_EPISODE_REWARD
    final_x, _, final_angle, _ = episode.states[-1]
    assert abs(final_x) > 2.4 or abs(final_angle) > 12 * 2 * np.pi / 360


def test_run_policy_rejects_bad_arguments():
    with pytest.raises(TypeError, match="policy must be callable"):
        run_policy([0, 0, 0, 0])
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        run_policy(CartPoleLinearPolicy(ALWAYS_LEFT_PARAMS), seed=-1)
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        run_policy(CartPoleLinearPolicy(ALWAYS_LEFT_PARAMS), seed=1.5)


def test_start_states_are_those_reset_gives():
    env = gym.make("CartPole-v1")
    for seed, state in zip([0, 7, 123], start_states([0, 7, 123])):
        obs, _ = env.reset(seed=seed)
        np.testing.assert_array_equal(state.astype(np.float32), obs)


@pytest.mark.todo("1.1.1")
def test_batched_episodes_equal_the_one_by_one_loop():
    params = sample_random_params(60, seed=4)
    seeds = episode_seeds(60, seed=9)
    batched = run_episodes(params, seeds)
    looped = [run_policy(CartPoleLinearPolicy(p), seed=int(s)) for p, s in zip(params, seeds)]
    np.testing.assert_array_equal(batched, looped)
    assert len(set(batched.tolist())) > 5  # a real mix of rewards, not one value


@pytest.mark.todo("1.1.1")
def test_batched_episodes_stop_counting_after_an_episode_ends(balancing_params):
    # Short episodes (always left, ~10 steps) next to full ones (500 steps): under NEXT_STEP
    # autoreset the short ones would keep collecting reward if they were not masked.
    params = np.array([ALWAYS_LEFT_PARAMS, balancing_params, ALWAYS_LEFT_PARAMS])
    rewards = run_episodes(params, [3, 3, 4])
    assert rewards[1] == MAX_EPISODE_REWARD
    assert rewards[0] == run_policy(CartPoleLinearPolicy(ALWAYS_LEFT_PARAMS), seed=3) < 20
    assert rewards[2] == run_policy(CartPoleLinearPolicy(ALWAYS_LEFT_PARAMS), seed=4) < 20


def test_run_episodes_rejects_bad_arguments():
    with pytest.raises(ValueError, match=r"params must have shape \(K, 4\)"):
        run_episodes(np.zeros(4), [0])
    with pytest.raises(ValueError, match="one seed per row of params"):
        run_episodes(np.zeros((2, 4)), [0])
    with pytest.raises(ValueError, match="seeds must be a non-empty 1-d sequence of non-negative integers"):
        run_episodes(np.zeros((1, 4)), [0.5])
    with pytest.raises(ValueError, match="params must hold only finite numbers"):
        run_episodes(np.full((1, 4), np.nan), [0])


@pytest.mark.todo("1.1.1")
def test_random_policies_are_seeded_and_equal_the_batch_engine():
    params, rewards = random_policy_rewards(40, seed=2)
    params_again, rewards_again = random_policy_rewards(40, seed=2)
    np.testing.assert_array_equal(params, params_again)
    np.testing.assert_array_equal(rewards, rewards_again)
    np.testing.assert_array_equal(rewards, run_episodes(params, episode_seeds(40, seed=3)))
    assert params.shape == (40, 4) and np.all(np.abs(params) <= 1)


def test_random_policy_count_is_validated():
    with pytest.raises(ValueError, match="num_policies must be a positive integer"):
        random_policy_rewards(0, seed=0)


def test_compacting_the_batch_keeps_every_reward(balancing_params):
    # 200 short episodes beside 100 full ones: the engine moves on with a smaller vector env once
    # most have ended, carrying states and step counts over; rewards must not change.
    params = np.concatenate([np.repeat(np.array(balancing_params)[None, :], 100, axis=0), sample_random_params(200, 5)])
    seeds = np.arange(300)
    batched = run_episodes(params, seeds)
    looped = run_episodes(params[::7], seeds[::7], batched=False)
    np.testing.assert_array_equal(batched[::7], looped)
    assert np.all(batched[:100] == MAX_EPISODE_REWARD)


def gymnasium_vector_rewards(params, seeds):
    """The reference for the batch engine: gymnasium's own vectorised CartPole, stepped until every
    episode has ended, each started where reset(seed=...) starts a single environment."""
    env = gym.make_vec("CartPole-v1", num_envs=len(params), vectorization_mode="vector_entry_point")
    env.reset(seed=0)
    env.unwrapped.state = start_states(seeds).T.copy()
    observations = env.unwrapped.state.T.astype(np.float32)
    rewards, running = np.zeros(len(params)), np.ones(len(params), dtype=bool)
    while running.any():
        observations, reward, terminated, truncated, _ = env.step(batch_actions(params, observations))
        rewards += np.where(running, reward, 0.0)
        running &= ~(terminated | truncated)
    env.close()
    return rewards


@pytest.mark.todo("1.1.1")
def test_the_batch_engine_steps_exactly_as_gymnasiums_vector_env(balancing_params):
    from hwlib.machinery.episodes import play_batch

    generator = np.random.default_rng(11)
    params = np.concatenate([np.array(balancing_params)[None, :] + generator.normal(0, 0.05, (150, 4)),
                             generator.uniform(-1, 1, (150, 4))])
    seeds = generator.integers(0, 2**31 - 1, size=len(params))
    rewards = play_batch(params, seeds)
    np.testing.assert_array_equal(rewards, gymnasium_vector_rewards(params, seeds))
    assert 0 < np.mean(rewards == MAX_EPISODE_REWARD) < 1 and len(set(rewards.tolist())) > 20  # long and short episodes, mixed
