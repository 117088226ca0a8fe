"""CartPole with a linear policy (handout 1.1).

The environment is gymnasium's ``CartPole-v1``; the homework only talks to it through
``reset`` and ``step``.

| what               | value                                                              |
|--------------------|--------------------------------------------------------------------|
| observation space  | ``Box(4,)``: cart position, cart velocity, pole angle, pole angular velocity |
| action space       | ``Discrete(2)``: 0 pushes the cart left, 1 pushes it right         |
| reward             | +1 for every step, the last one included                           |
| episode end        | pole angle beyond +-12 degrees (0.2095 rad) or cart beyond +-2.4: terminated; ``settings.MAX_EPISODE_STEPS`` (500) steps: truncated |
| start state        | each of the 4 components uniform in [-0.05, 0.05], drawn by ``reset(seed=...)`` |

The policy of the handout's equation (1) is linear: action 1 when ``params @ obs < 0``, else 0.
Writing its ``__call__`` is TODO 1.1.1.

``run_policy`` plays one episode through a single ``gym.make`` environment: the handout's loop,
and all the homework's code ever calls. ``random_policy_rewards`` is handout 1.1.3.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import gymnasium as gym
import numpy as np

from hwlib.settings import MAX_EPISODE_STEPS as MAX_EPISODE_REWARD  # +1 per step: the cap is the best reward
from hwlib.machinery.todos import TodoNotDone  # noqa: F401 - the TODO's starting code raises it until you write it
from hwlib.machinery.validation import check_count, check_params, check_policy, check_seed

ENV_ID = "CartPole-v1"
NUM_OBSERVATIONS = 4
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
        action = 0
        ### BEGIN SOLUTION 1.1.1
        ### HINT: equation (1): action 1 when the dot product of self.params and obs is negative, else 0
        action = int(np.dot(self.params, obs) < 0)
        ### END SOLUTION 1.1.1
        return action

    def __repr__(self):
        return f"CartPoleLinearPolicy(params={np.round(self.params, 4).tolist()})"


def _register_episode_cap():
    """Make every ``gym.make(ENV_ID)`` (the kit's, a student's own, the grader's) end episodes after
    ``settings.MAX_EPISODE_STEPS`` steps: gymnasium's registration of ``CartPole-v1`` with that cap."""
    spec = gym.spec(ENV_ID)
    if spec.max_episode_steps != MAX_EPISODE_REWARD:
        gym.envs.registration.registry[ENV_ID] = replace(spec, max_episode_steps=MAX_EPISODE_REWARD)


_register_episode_cap()


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
    """Play one episode of ``policy`` (any callable obs -> action) from ``reset(seed=seed)`` and record
    every state. ``seed=None`` starts from a random state; pass ``env`` to reuse an environment."""
    check_policy(policy)
    seed = None if seed is None else check_seed(seed, "seed")
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

    ``seed=None`` starts from a random state; pass ``env`` to reuse an environment.
    """
    return play_episode(policy, seed, env).total_reward


def episode_seeds(num_episodes, seed):
    """``num_episodes`` episode seeds drawn from one master ``seed``."""
    num_episodes, seed = check_count(num_episodes, "num_episodes"), check_seed(seed, "seed")
    return np.random.default_rng(seed).integers(0, SEED_BOUND, size=num_episodes)


def sample_random_params(num_policies, seed):
    """``num_policies`` parameter vectors with entries uniform in [-1, 1), seeded."""
    num_policies, seed = check_count(num_policies, "num_policies"), check_seed(seed, "seed")
    return np.random.default_rng(seed).uniform(-1.0, 1.0, size=(num_policies, NUM_OBSERVATIONS))


def random_policy_rewards(num_policies=1000, seed=0):
    """Handout 1.1.3: rewards of ``num_policies`` random linear policies (entries uniform in [-1, 1]).

    Policy i is a ``CartPoleLinearPolicy`` (your 1.1.1) and plays one episode with ``run_policy``
    from ``reset(seed=episode_seeds(num_policies, seed + 1)[i])``. Returns ``(params, rewards)``,
    shapes (num_policies, 4) and (num_policies,).
    """
    params = sample_random_params(num_policies, seed)
    env = make_env()
    rewards = [run_policy(CartPoleLinearPolicy(p), seed=int(s), env=env)
               for p, s in zip(params, episode_seeds(num_policies, seed + 1))]
    return params, np.array(rewards)
