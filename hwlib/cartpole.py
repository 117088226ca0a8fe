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
and it is all the homework's code ever calls. When the kit runs your training
(``hwlib/training.py``), it plays the episodes your code asks for many at a time; every one of
them starts where ``reset(seed=...)`` starts a single environment and plays your policy, so the
rewards are those of the plain loop. ``run_episodes`` plays many policies at once the same way
(the random policies of 1.1.3 and the reward landscape use it).
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from hwlib import _engine, _progress
from hwlib._checks import check_count, check_observation, check_params, check_params_batch, check_seed, check_seeds
from hwlib._engine import ENV_ID, NUM_OBSERVATIONS
from hwlib._todo import TodoNotDone  # noqa: F401 - the TODO's starting code raises it until you write it
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
    """The argument checks of the episode functions: a callable policy, and a seed or None."""
    if not callable(policy):
        raise TypeError(f"policy must be callable as policy(obs) -> action, got {type(policy).__name__}")
    return None if seed is None else check_seed(seed, "seed")


def _play(policy, seed, env, start=None):
    env = make_env() if env is None else env
    obs, _ = env.reset(seed=seed)
    if start is not None:  # the kit's runs: an unseeded episode starts where its run's env put it
        env.unwrapped.state = np.array(start, dtype=np.float64)
        obs = np.array(start, dtype=np.float32)
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

    ``seed=None`` starts from a random state. Inside the kit's training runs (``hwlib/training.py``)
    it is where the next ``reset()`` of the run's own environment (seeded once with the run's seed)
    starts, so the run is reproducible, and the episode may be played together with others (same
    reward); pass ``env`` to always play it here, in ``env``.
    """
    seed = _check_episode_arguments(policy, seed)
    route = _engine.current_route()
    if route is not None and env is None:
        return route(policy, seed)
    return _play(policy, seed, env).total_reward


def start_states(seeds):
    """The start state ``reset(seed=s)`` gives a single CartPole, for every seed in ``seeds``.

    Read from the environment itself (not re-derived), so it stays right if gymnasium changes
    how it draws start states. Returns a float64 array of shape (len(seeds), 4).
    """
    return _engine.start_states(check_seeds(seeds, "seeds"))


def run_episodes(params, seeds, batched=True, progress=None):
    """Total reward of one episode of ``CartPoleLinearPolicy(params[k])`` from ``reset(seed=seeds[k])``, for every row k.

    ``params`` has shape (K, 4), ``seeds`` K entries. With ``batched`` (the default) the episodes
    of every parameter vector on which your ``__call__`` gives the actions of equation (1) are
    played all at once in gymnasium's vectorised CartPole (``hwlib/_engine.py``), the others one
    by one with your ``__call__``; ``batched=False`` plays every episode one by one. The rewards
    are the same. ``progress`` names the work for a progress bar in the notebook (None: no bar).
    Returns a float64 array of K rewards.
    """
    params = check_params_batch(params, "params")
    seeds = check_seeds(seeds, "seeds")
    if len(seeds) != len(params):
        raise ValueError(f"seeds must hold one seed per row of params ({len(params)}), got {len(seeds)}")
    if not isinstance(batched, bool):
        raise TypeError(f"batched must be True or False, got {batched!r}")
    return _play_episodes(params, seeds, batched, progress)


def _play_episodes(params, seeds, batched, progress):
    rewards = np.zeros(len(params))
    with _progress.Progress(progress, len(params), "episodes") as bar:
        if batched:
            unique, inverse = np.unique(params, axis=0, return_inverse=True)
            inverse = inverse.reshape(-1)
            trusted = np.array([_engine.agrees_with_equation_one(CartPoleLinearPolicy(p), p) for p in unique])
            batch_rows = np.flatnonzero(trusted[inverse])
            if batch_rows.size:
                rewards[batch_rows] = _engine.play_batch(params[batch_rows], seeds[batch_rows])
                bar.advance(batch_rows.size)
            one_by_one = np.flatnonzero(~trusted[inverse])
        else:
            one_by_one = np.arange(len(params))
        env = make_env() if one_by_one.size else None
        for row in one_by_one:
            rewards[row] = _play(CartPoleLinearPolicy(params[row]), int(seeds[row]), env).total_reward
            bar.advance(1)
    return rewards


def sample_random_params(num_policies, seed, low=-1.0, high=1.0):
    """``num_policies`` parameter vectors with entries uniform in [low, high), seeded."""
    num_policies = check_count(num_policies, "num_policies")
    seed = check_seed(seed, "seed")
    if not (np.isfinite(low) and np.isfinite(high) and low < high):
        raise ValueError(f"low and high must be finite with low < high, got low={low}, high={high}")
    return _random_params(num_policies, seed, low, high)


def _random_params(num_policies, seed, low=-1.0, high=1.0):
    return np.random.default_rng(seed).uniform(low, high, size=(num_policies, NUM_OBSERVATIONS))


def episode_seeds(num_episodes, seed):
    """``num_episodes`` episode seeds drawn from one master ``seed``."""
    return _episode_seeds(check_count(num_episodes, "num_episodes"), check_seed(seed, "seed"))


def _episode_seeds(num_episodes, seed):
    return np.random.default_rng(seed).integers(0, SEED_BOUND, size=num_episodes)


def random_policy_rewards(num_policies=1000, seed=0):
    """Handout 1.1.3: rewards of ``num_policies`` random linear policies (entries uniform in [-1, 1]).

    Policy i is a ``CartPoleLinearPolicy`` (your 1.1.1) and plays one episode from
    ``reset(seed=episode_seeds[i])``: ``run_episodes`` plays them all, checked against your
    ``__call__``. Returns ``(params, rewards)``, shapes (num_policies, 4) and (num_policies,).
    """
    num_policies = check_count(num_policies, "num_policies")
    seed = check_seed(seed, "seed")
    params = _random_params(num_policies, seed)
    rewards = _play_episodes(params, _episode_seeds(num_policies, seed + 1), True, f"{num_policies} random policies")
    return params, rewards
