"""CartPole with a linear policy: one episode at a time, or many at once.

The environment is gymnasium's ``CartPole-v1``; the kit only talks to it through
``reset`` and ``step``.

| what               | value                                                              |
|--------------------|--------------------------------------------------------------------|
| observation space  | ``Box(4,)``: cart position, cart velocity, pole angle, pole angular velocity |
| action space       | ``Discrete(2)``: 0 pushes the cart left, 1 pushes it right         |
| reward             | +1 for every step, the last one included                           |
| episode end        | pole angle beyond +-12 degrees (0.2095 rad) or cart beyond +-2.4: terminated; 500 steps: truncated |
| start state        | each of the 4 components uniform in [-0.05, 0.05], drawn by ``reset(seed=...)`` |

The policy of the handout's equation (1) is linear: ``action = 1 if params @ obs < 0 else 0``.

``run_policy`` plays one episode through a single ``gym.make`` environment, the way the
handout does. ``run_episodes`` plays a whole batch of episodes, one per row of parameters,
through gymnasium's vectorised CartPole. Each episode of the batch starts from exactly the
state that ``reset(seed=episode_seed)`` gives a single environment, so for the same seeds both
functions return the same rewards: the batch is only faster, never different.
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from hwlib._checks import check_count, check_params, check_params_batch, check_seed, check_seeds

ENV_ID = "CartPole-v1"
NUM_OBSERVATIONS = 4
MAX_EPISODE_REWARD = 500
SEED_BOUND = 2**31 - 1  # episode seeds are drawn from [0, SEED_BOUND)
OBSERVATION_NAMES = ("cart position", "cart velocity", "pole angle", "pole angular velocity")
X_THRESHOLD = 2.4
THETA_THRESHOLD_RADIANS = 12 * 2 * np.pi / 360

# Hand-picked parameters for the slider panel's preset buttons (see the notebook for why).
ALWAYS_LEFT_PARAMS = (0.0, 0.0, 0.0, 0.0)
ALWAYS_RIGHT_PARAMS = (0.0, -1.0, 0.0, 1.0)
BALANCING_PARAMS = (-0.1, -0.5, -1.0, -0.5)


def linear_policy_actions(params, observations):
    """Actions of the linear policy, equation (1): 1 where ``params @ obs < 0``, else 0.

    ``params`` and ``observations`` broadcast along their leading axes: (4,) with (4,) gives
    one action, (K, 4) with (K, 4) gives K actions, each row of params acting on its own row
    of observations. Returns an int64 array (a 0-d array for a single observation).
    """
    ### BEGIN SOLUTION 1.1.1
    ### HINT: return equation (1) as int64 actions: 1 where the sum of params * observations over the last axis is < 0, else 0
    scores = np.sum(np.asarray(params) * np.asarray(observations), axis=-1)
    return (scores < 0).astype(np.int64)
    ### END SOLUTION 1.1.1


class CartPoleLinearPolicy:
    """The linear policy of equation (1), called on one observation at a time."""

    def __init__(self, params):
        self.params = check_params(params, "params")

    def __call__(self, obs):
        obs = np.asarray(obs, dtype=np.float64)
        if obs.shape != (NUM_OBSERVATIONS,):
            raise ValueError(f"obs must have shape (4,), got shape {obs.shape}")
        return int(linear_policy_actions(self.params, obs))

    def __repr__(self):
        return f"CartPoleLinearPolicy(params={np.round(self.params, 4).tolist()})"


def make_env(render_mode=None):
    """A fresh single ``CartPole-v1`` environment."""
    return gym.make(ENV_ID, render_mode=render_mode)


@dataclass(frozen=True)
class Episode:
    """One episode, step by step: ``states[t]`` is the observation the policy saw at step t,
    and the last row is the state the episode ended in."""

    states: np.ndarray  # (num_steps + 1, 4)
    actions: np.ndarray  # (num_steps,)
    total_reward: float

    @property
    def num_steps(self):
        return len(self.actions)


def play_episode(policy, seed=None, env=None) -> Episode:
    """Play one episode of ``policy`` (any callable obs -> action) and record every state.

    Only ``env.reset`` and ``env.step`` are used. Pass ``env`` to reuse an environment.
    """
    if not callable(policy):
        raise TypeError(f"policy must be callable as policy(obs) -> action, got {type(policy).__name__}")
    if seed is not None:
        seed = check_seed(seed, "seed")
    env = make_env() if env is None else env
    obs, _ = env.reset(seed=seed)
    states, actions, total_reward = [obs], [], 0.0
    done = False
    while not done:
        action = policy(obs)
        obs, reward, terminated, truncated, _ = env.step(action)
        states.append(obs)
        actions.append(action)
        total_reward += float(reward)
        done = terminated or truncated
    return Episode(np.array(states, dtype=np.float64), np.array(actions, dtype=np.int64), total_reward)


def run_policy(policy, seed=None, env=None):
    """Total reward of one episode of ``policy``, played through ``env.step`` (the handout's loop)."""
    return play_episode(policy, seed=seed, env=env).total_reward


def start_states(seeds):
    """The start state ``reset(seed=s)`` gives a single CartPole, for every seed in ``seeds``.

    Read from the environment itself (not re-derived), so it stays right if gymnasium changes
    how it draws start states. Returns a float64 array of shape (len(seeds), 4).
    """
    seeds = check_seeds(seeds, "seeds")
    env = make_env()
    states = np.empty((len(seeds), NUM_OBSERVATIONS))
    for row, seed in enumerate(seeds):
        env.reset(seed=int(seed))
        states[row] = env.unwrapped.state
    return states


def run_episodes(params, seeds, batched=True):
    """Total reward of one episode per row of ``params``.

    Row k of ``params`` (shape (K, 4)) plays from the start state of ``reset(seed=seeds[k])``.
    With ``batched=False`` the episodes are played one by one with ``run_policy``; by default
    they all run at once in gymnasium's vectorised CartPole, whose start states are set once
    after ``reset`` (from then on rewards come only from ``step``). Both give the same rewards.
    Returns a float64 array of K rewards.
    """
    params = check_params_batch(params, "params")
    seeds = check_seeds(seeds, "seeds")
    if len(seeds) != len(params):
        raise ValueError(f"seeds must hold one seed per row of params ({len(params)}), got {len(seeds)}")
    if not batched:
        env = make_env()
        return np.array([run_policy(CartPoleLinearPolicy(p), seed=int(s), env=env) for p, s in zip(params, seeds)])
    num_episodes = len(params)
    env = gym.make_vec(ENV_ID, num_envs=num_episodes, vectorization_mode="vector_entry_point")
    env.reset(seed=int(seeds[0]))
    # Batches often repeat seeds (common random numbers): read each start state only once.
    unique_seeds, seed_rows = np.unique(seeds, return_inverse=True)
    env.unwrapped.state = start_states(unique_seeds)[seed_rows].T.copy()
    observations = env.unwrapped.state.T.astype(np.float32)

    total_rewards = np.zeros(num_episodes)
    running = np.ones(num_episodes, dtype=bool)
    while running.any():
        actions = linear_policy_actions(params, observations)
        observations, rewards, terminated, truncated, _ = env.step(actions)
        # Under NEXT_STEP autoreset an env that just ended is reset on the following step and
        # reports reward 0 then; the mask stops counting it right away all the same.
        total_rewards += np.where(running, rewards, 0.0)
        running &= ~(terminated | truncated)
    env.close()
    return total_rewards


def sample_random_params(num_policies, seed, low=-1.0, high=1.0):
    """``num_policies`` parameter vectors with entries uniform in [low, high), seeded."""
    num_policies = check_count(num_policies, "num_policies")
    seed = check_seed(seed, "seed")
    if not (np.isfinite(low) and np.isfinite(high) and low < high):
        raise ValueError(f"low and high must be finite with low < high, got low={low}, high={high}")
    return np.random.default_rng(seed).uniform(low, high, size=(num_policies, NUM_OBSERVATIONS))


def episode_seeds(num_episodes, seed):
    """``num_episodes`` episode seeds drawn from one master ``seed``."""
    num_episodes = check_count(num_episodes, "num_episodes")
    seed = check_seed(seed, "seed")
    return np.random.default_rng(seed).integers(0, SEED_BOUND, size=num_episodes)


def random_policy_rewards(num_policies=1000, seed=0, batched=True):
    """Rewards of ``num_policies`` random linear policies (entries uniform in [-1, 1]).

    Policy i plays one episode from ``reset(seed=episode_seeds[i])``. ``batched=False`` plays
    them one by one with ``run_policy``; both give the same rewards.
    Returns ``(params, rewards)`` with shapes (num_policies, 4) and (num_policies,).
    """
    params = sample_random_params(num_policies, seed)
    return params, run_episodes(params, episode_seeds(num_policies, seed + 1), batched=batched)
