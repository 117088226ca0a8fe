"""CartPole with a linear policy (handout 1.1).

The environment is gymnasium's ``CartPole-v1``; the homework only talks to it through
``reset`` and ``step``.

| what               | value                                                              |
|--------------------|--------------------------------------------------------------------|
| observation space  | ``Box(4,)``: cart position, cart velocity, pole angle, pole angular velocity |
| action space       | ``Discrete(2)``: 0 pushes the cart left, 1 pushes it right         |
| reward             | +1 for every step, the last one included                           |
| episode end        | pole angle beyond +-12 degrees (0.2095 rad) or cart beyond +-2.4: terminated; 500 steps: truncated |
| start state        | each of the 4 components uniform in [-0.05, 0.05], drawn by ``reset(seed=...)`` |

The policy of the handout's equation (1) is linear: action 1 when ``params @ obs < 0``, else 0.
Writing its ``__call__`` is TODO 1.1.1.

``run_policy`` plays one episode through a single ``gym.make`` environment, the handout's loop,
and it is all the homework's code ever calls. The kit makes that loop fast without the student
noticing: inside ``eval_params`` (and the learning-rate sweep) ``run_policy`` hands its episode to
a batcher (``hwlib/_batch.py``) that plays many episodes at once in gymnasium's vectorised
CartPole (``run_episodes``). Each batched episode starts exactly where ``reset(seed=...)`` puts a
single environment and every reward comes from ``step``, so the rewards are the same as one by
one: the batch is only faster, never different.
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from hwlib import _batch
from hwlib._checks import check_count, check_observation, check_params, check_params_batch, check_seed, check_seeds

ENV_ID = "CartPole-v1"
NUM_OBSERVATIONS = 4
MAX_EPISODE_REWARD = 500
SEED_BOUND = 2**31 - 1  # episode seeds are drawn from [0, SEED_BOUND)
OBSERVATION_NAMES = ("cart position", "cart velocity", "pole angle", "pole angular velocity")
X_THRESHOLD = 2.4
THETA_THRESHOLD_RADIANS = 12 * 2 * np.pi / 360

# Two presets of the slider panel (1.1.2 asks students to find a balancing one themselves).
ALWAYS_LEFT_PARAMS = (0.0, 0.0, 0.0, 0.0)
ALWAYS_RIGHT_PARAMS = (0.0, -1.0, 0.0, 1.0)


class CartPoleLinearPolicy:
    """The linear policy of equation (1), called on one observation at a time: ``policy(obs)``."""

    def __init__(self, params):
        self.params = check_params(params, "params")  # float64, shape (4,)

    def __call__(self, obs):
        """The action for one observation ``obs`` (4 numbers): 1 (push right) or 0 (push left)."""
        obs = check_observation(obs, "obs")  # float64, shape (4,)
        action = 0
        ### BEGIN SOLUTION 1.1.1
        ### HINT: equation (1): action 1 when the dot product of self.params and obs is negative, else 0
        action = int(np.dot(self.params, obs) < 0)
        ### END SOLUTION 1.1.1
        return action

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
    return _play(policy, _check_episode_arguments(policy, seed), env)


def _check_episode_arguments(policy, seed):
    """The door of the episode functions: a callable policy, and a seed or None."""
    if not callable(policy):
        raise TypeError(f"policy must be callable as policy(obs) -> action, got {type(policy).__name__}")
    return None if seed is None else check_seed(seed, "seed")


def _play(policy, seed, env):
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
    """Total reward of one episode of ``policy`` from ``reset(seed=seed)``: the handout's loop.

    Inside ``eval_params`` or the learning-rate sweep the episode may be played in a batch with
    others (same reward, see the module docstring); pass ``env`` to force a plain loop in it.
    """
    seed = _check_episode_arguments(policy, seed)
    batcher = _batch.current_batcher()
    if batcher is not None and env is None and seed is not None and isinstance(policy, CartPoleLinearPolicy):
        return batcher.reward(policy, seed)
    return _play(policy, seed, env).total_reward


_START_STATES = {}  # seed -> the start state reset(seed=seed) gives; seeds repeat a lot in training


def start_states(seeds):
    """The start state ``reset(seed=s)`` gives a single CartPole, for every seed in ``seeds``.

    Read from the environment itself (not re-derived), so it stays right if gymnasium changes
    how it draws start states. Returns a float64 array of shape (len(seeds), 4).
    """
    seeds = check_seeds(seeds, "seeds")
    missing = [int(seed) for seed in np.unique(seeds) if int(seed) not in _START_STATES]
    if missing:
        env = make_env()
        for seed in missing:
            env.reset(seed=seed)
            _START_STATES[seed] = np.array(env.unwrapped.state, dtype=np.float64)
        env.close()
        if len(_START_STATES) > 1_000_000:
            _START_STATES.clear()
    return np.array([_START_STATES[int(seed)] for seed in seeds]).reshape(len(seeds), NUM_OBSERVATIONS)


def batch_actions(params, observations):
    """The batch engine's own copy of equation (1) for K episodes at once: row k of ``params``
    (K, 4) acts on row k of ``observations`` (K, 4). Returns K int64 actions.

    The batcher only uses it for a policy after checking it against that policy's own
    ``__call__`` (``hwlib/_batch.py``); any other policy is played with ``policy(obs)`` step by step.
    """
    return (np.einsum("kj,kj->k", params, observations) < 0).astype(np.int64)


def run_episodes(params, seeds, batched=True):
    """Total reward of one episode of the linear policy per row of ``params``: the batch engine.

    Row k of ``params`` (shape (K, 4)) plays from the start state of ``reset(seed=seeds[k])``.
    All K episodes run at once in gymnasium's vectorised CartPole, whose start states are set
    once after ``reset`` (from then on rewards come only from ``step``). ``batched=False`` plays
    them one by one with ``run_policy`` and ``CartPoleLinearPolicy`` instead. Both give the same
    rewards when ``CartPoleLinearPolicy`` follows equation (1). Returns a float64 array of K rewards.
    """
    params = check_params_batch(params, "params")
    seeds = check_seeds(seeds, "seeds")
    if len(seeds) != len(params):
        raise ValueError(f"seeds must hold one seed per row of params ({len(params)}), got {len(seeds)}")
    if not batched:
        env = make_env()
        return np.array([run_policy(CartPoleLinearPolicy(p), seed=int(s), env=env) for p, s in zip(params, seeds)])
    return _play_batch(params, seeds)


def _play_batch(params, seeds):
    num_episodes = len(params)
    env = _vector_env(num_episodes, int(seeds[0]))
    env.unwrapped.state = start_states(seeds).T.copy()
    observations = env.unwrapped.state.T.astype(np.float32)

    total_rewards = np.zeros(num_episodes)
    rows = np.arange(num_episodes)  # the episode each env of the vector env plays
    row_params, row_rewards = params, np.zeros(num_episodes)
    running = np.ones(num_episodes, dtype=bool)
    while running.any():
        if 2 * running.sum() <= len(running) and len(running) >= 64:
            # Most episodes have ended: go on with a smaller vector env that carries on exactly
            # where the running ones are (their states and step counts), so fewer envs are stepped.
            total_rewards[rows] = row_rewards
            keep = np.flatnonzero(running)
            smaller = _vector_env(len(keep), int(seeds[0]))
            smaller.unwrapped.state = env.unwrapped.state[:, keep].copy()
            smaller.unwrapped.steps = env.unwrapped.steps[keep].copy()
            env.close()
            env, rows, observations, running = smaller, rows[keep], observations[keep], running[keep]
            row_params, row_rewards = params[rows], row_rewards[keep]
        actions = batch_actions(row_params, observations)
        observations, rewards, terminated, truncated, _ = env.step(actions)
        # Under NEXT_STEP autoreset an env that just ended is reset on the following step and
        # reports reward 0 then; the mask stops counting it right away all the same.
        row_rewards += np.where(running, rewards, 0.0)
        running &= ~(terminated | truncated)
    env.close()
    total_rewards[rows] = row_rewards
    return total_rewards


def _vector_env(num_envs, seed):
    env = gym.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point")
    env.reset(seed=seed)
    return env


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


def random_policy_rewards(num_policies=1000, seed=0):
    """Handout 1.1.3: rewards of ``num_policies`` random linear policies (entries uniform in [-1, 1]).

    Policy i is a ``CartPoleLinearPolicy`` (your 1.1.1) and plays one episode with ``run_policy``
    from ``reset(seed=episode_seeds[i])``. Returns ``(params, rewards)``, shapes (num_policies, 4)
    and (num_policies,).
    """
    params = sample_random_params(num_policies, seed)
    seeds = episode_seeds(num_policies, seed + 1)
    env = make_env()
    rewards = np.array([run_policy(CartPoleLinearPolicy(p), seed=int(s), env=env) for p, s in zip(params, seeds)])
    return params, rewards
