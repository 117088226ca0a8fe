"""The grader's own records of the CartPole episodes and evaluations of one case, through any door.

An episode reaches the records in one of four ways (``door``), each played on the trusted side:

| door | how the TODO played it | what the grader knows |
|------|------------------------|-----------------------|
| ``RUN_POLICY``  | ``run_policy(policy, seed)`` | parameters, seed (its own when none), reward, start state |
| ``IN_ENV``      | ``run_policy(policy, seed, env)`` with a ``gym.make`` environment | the same; no seed: the environment's next episode |
| ``OWN_LOOP``    | ``env.reset(seed=...)`` and ``env.step`` until done | seed or none, start state, every (observation, action), reward |
| ``EVALUATION``  | inside a served ``eval_params`` (1.3.2) | parameters, seed, reward, start state |

``determined`` says whether the start state follows from a seed: a seeded reset, or a later
episode of an environment whose last seeded reset started its chain. ``Records.arrays()`` gives
the judges (``checks/p1_cartpole.py``) numpy arrays; an own loop's reset that no step followed is
not an episode (a reset to seed the environment, then ``reset()`` per episode, is gymnasium's
idiom). ``Environments`` keeps the state of each ``gym.make`` environment of one run.
Standard library and numpy only.
"""

from __future__ import annotations

import itertools
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

RUN_POLICY, IN_ENV, OWN_LOOP, EVALUATION = 0, 1, 2, 3
MAX_STEPS = 200_000  # steps of own loops recorded per run
MAX_ENVS = 2_000  # gym.make environments per run
MAX_OPEN_ENVS = 32  # open at once; beyond, the least recently used one is closed
_KEYS = itertools.count(1)  # environment keys, unique in this grader process (servers outlive runs)


@dataclass
class Episode:
    door: int
    params: np.ndarray  # NaN for an own loop (its actions are recorded instead)
    seed: int  # -1: none given
    seeded: bool  # the call gave a seed
    determined: bool  # the start state follows from a seed (see the module docstring)
    reward: float
    start: np.ndarray
    finished: bool = True  # an own loop: a step answered terminated or truncated
    env: int = -1
    steps: list = field(default_factory=list)  # an own loop: (observation before the step, action)


class Records:
    """What the trusted side saw during one case: episodes and evaluations (parameters, rollouts, seed, value)."""

    def __init__(self):
        self.episodes, self.evaluations, self.served = [], [], []  # served: the name of each function answered

    def arrays(self):
        kept = [e for e in self.episodes if e.door != OWN_LOOP or e.steps]
        ev = self.evaluations
        steps = [(index, obs, action) for index, e in enumerate(kept) for obs, action in e.steps]
        return {
            "episode_params": np.array([e.params for e in kept], dtype=np.float64).reshape(-1, 4),
            "episode_seeds": np.array([e.seed for e in kept], dtype=np.int64),
            "episode_seeded": np.array([e.seeded for e in kept], dtype=bool),
            "episode_determined": np.array([e.determined for e in kept], dtype=bool),
            "episode_rewards": np.array([e.reward for e in kept], dtype=np.float64),
            "episode_starts": np.array([e.start for e in kept], dtype=np.float64).reshape(-1, 4),
            "episode_doors": np.array([e.door for e in kept], dtype=np.int64),
            "episode_finished": np.array([e.finished for e in kept], dtype=bool),
            "episode_direct": np.array([e.door != EVALUATION for e in kept], dtype=bool),  # not inside eval_params
            "step_episode": np.array([s[0] for s in steps], dtype=np.int64),
            "step_obs": np.array([s[1] for s in steps], dtype=np.float64).reshape(-1, 4),
            "step_actions": np.array([s[2] for s in steps], dtype=np.int64),
            "evaluation_params": np.array([e[0] for e in ev], dtype=np.float64).reshape(-1, 4),
            "evaluation_rollouts": np.array([e[1] for e in ev], dtype=np.int64),
            "evaluation_seeds": np.array([e[2] for e in ev], dtype=np.int64),
            "evaluation_values": np.array([e[3] for e in ev], dtype=np.float64),
            "served": np.array(self.served, dtype=str),
        }


def start_of(value):
    """A start state as the grader keeps it: 4 float64 numbers, NaN where the server sent none."""
    try:
        start = np.asarray(value, dtype=np.float64).reshape(4)
    except (TypeError, ValueError):
        return np.full(4, np.nan)
    return start


@dataclass
class OpenEnv:
    key: int
    chain_seeded: bool = False  # its last seeded reset started the chain of its episodes
    last_obs: np.ndarray | None = None
    episode: Episode | None = None  # the own-loop episode in progress


class Environments:
    """The ``gym.make`` environments of one run: keys, which are open, their episode in progress."""

    def __init__(self):
        self.open, self.made, self.steps = OrderedDict(), 0, 0

    def make(self):
        """(key, the key of an environment to close first or None), or None beyond MAX_ENVS."""
        if self.made >= MAX_ENVS:
            return None
        self.made += 1
        key = next(_KEYS)
        self.open[key] = OpenEnv(key)
        evicted = self.open.popitem(last=False)[0] if len(self.open) > MAX_OPEN_ENVS else None
        return key, evicted

    def get(self, key):
        env = self.open.get(key)
        if env is not None:
            self.open.move_to_end(key)
        return env

    def close(self, key):
        self.open.pop(key, None)

    def reset(self, env, seed, obs):
        """The own-loop episode that ``env.reset(seed=seed)`` starts at ``obs``."""
        env.chain_seeded = seed is not None or env.chain_seeded
        env.last_obs = start_of(obs)
        env.episode = Episode(OWN_LOOP, np.full(4, np.nan), -1 if seed is None else int(seed), seed is not None,
                              env.chain_seeded, 0.0, env.last_obs, finished=False, env=env.key)
        return env.episode

    def step(self, env, action, answer):
        """Record one answered step ([obs, reward, terminated, truncated]) of ``env``'s episode."""
        obs, reward, terminated, truncated = answer
        episode = env.episode
        if episode is not None and not episode.finished and env.last_obs is not None:
            self.steps += 1
            episode.steps.append((env.last_obs, int(np.asarray(action).item())))
            episode.reward += float(reward)
            episode.finished = bool(terminated) or bool(truncated)
        env.last_obs = start_of(obs)

    def played(self, env, seed):
        """``run_policy`` played a whole episode in ``env``: its chain and whether it is determined."""
        env.chain_seeded = seed is not None or env.chain_seeded
        env.episode, env.last_obs = None, None
        return env.chain_seeded
