"""The CartPole environment of a graded run, played on the trusted side: ``gym.make`` in the sandbox.

A TODO may play its episodes through ``run_policy``, through its own ``gym.make("CartPole-v1")``
environment (``reset(seed=...)``, ``step`` until done), or by reusing one environment
(gymnasium's idiom: seed the first reset, continue unseeded). Every one of them must be played
where the grader records it, never in the sandbox, whose word about episodes is not believed. So
in a worker whose TODO may call ``run_policy`` (``served.plan``), ``gymnasium.make`` of a
CartPole id returns a ``ServedCartPole``: its ``reset`` and ``step`` are calls the grader
answers (``broker.py`` checks and records them) with an environment that the reference server
holds (``Table``, a real ``gym.make`` environment there). ``run_policy(policy, seed, env)`` with
such an ``env`` sends the environment's key, and the server plays the episode in that
environment (a continuation when ``seed`` is None).

| call        | args            | answer                                    |
|-------------|-----------------|-------------------------------------------|
| env_make    | id              | the environment's key (an int)            |
| env_reset   | env, seed       | the start observation (float32, shape (4,)) |
| env_step    | env, action     | [observation, reward, terminated, truncated] |
| env_close   | env             | None                                      |

Three sides share this file (copied into every kit as ``_hwgrade/served_env.py``): the worker
(``install``), the grader (``check``: what a call may carry, on the decoded message) and the
server (``Table``, ``StartRecorder``). Standard library and numpy; gymnasium is imported only in
the sandboxed processes.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from .served import Served

ENV_IDS = ("CartPole-v1",)
ENTRIES = {name: Served(name, "gymnasium", "CartPole", attribute, None, frozenset(), params)
           for name, attribute, params in (("env_make", "make", ("id",)), ("env_reset", "reset", ("env", "seed")),
                                           ("env_step", "step", ("env", "action")), ("env_close", "close", ("env",)))}
MAX_SEED = 2**62
SERVER_ENVS = 64  # environments a server keeps (the least recently used one goes first)


def _integer(value):
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def is_action(value):
    """True if ``env.step`` takes ``value`` (gymnasium's ``Discrete(2).contains``): an int (a bool
    too), a numpy integer or a 0-d integer array, equal to 0 or 1."""
    if isinstance(value, np.ndarray) and value.shape == () and value.dtype.kind in "iu":
        value = value.item()
    if not isinstance(value, (int, np.integer)) or isinstance(value, np.bool_):
        return False
    return int(value) in (0, 1)


# --------------------------------------------------------------------------------------------
# The grader: what a call may carry
# --------------------------------------------------------------------------------------------


def check(name, args):
    """None if ``args`` is what call ``name`` may carry, else why not (the grader's words)."""
    entry = ENTRIES[name]
    if not isinstance(args, dict) or set(args) != set(entry.params):
        return f"{entry.where} takes the arguments {', '.join(entry.params)}"
    if name == "env_make":
        return None if args["id"] in ENV_IDS else \
            f"in grading, gym.make makes only {', '.join(ENV_IDS)}, got {str(args['id'])[:40]!r}"
    if not _integer(args["env"]):
        return "not an environment of this check"
    if name == "env_reset" and args["seed"] is not None and not (_integer(args["seed"]) and 0 <= args["seed"] < MAX_SEED):
        return "Seed must be a non-negative integer or omitted"
    if name == "env_step" and not is_action(args["action"]):
        return (f"the action {str(args['action'])[:40]} is not one env.step takes: the int 0 or 1 (a Python bool "
                "or a numpy integer works too)")
    return None


# --------------------------------------------------------------------------------------------
# The worker: gym.make of CartPole gives an environment whose reset and step the grader answers
# --------------------------------------------------------------------------------------------


def install(call):
    """Make ``gymnasium.make`` (and ``gymnasium.envs.registration.make``) return a ``ServedCartPole``
    for a CartPole id. ``call(entry, args, state)`` is the worker's served call (``runtime.call``)."""
    import gymnasium  # noqa: PLC0415 - the kit's own dependency, there in the sandbox
    from gymnasium.envs import registration  # noqa: PLC0415

    real_make = registration.make
    spaces = {}

    class ServedCartPole(gymnasium.Env):
        """CartPole whose every reset and step the grader answers and records (see the module docstring)."""

        metadata = {"render_modes": []}

        def __init__(self, env_id):
            if env_id not in spaces:
                real = real_make(env_id)
                spaces[env_id] = (real.observation_space, real.action_space)
                real.close()
            self.observation_space, self.action_space = spaces[env_id]
            self.spec = registration.spec(env_id)
            self.key = call(ENTRIES["env_make"], {"id": env_id}, {})[0]
            self.closed = False

        def reset(self, *, seed=None, options=None):
            value, _ = call(ENTRIES["env_reset"], {"env": self.key, "seed": seed}, {})
            return np.asarray(value, dtype=np.float32), {}

        def step(self, action):
            (obs, reward, terminated, truncated), _ = call(ENTRIES["env_step"], {"env": self.key, "action": action}, {})
            return np.asarray(obs, dtype=np.float32), float(reward), bool(terminated), bool(truncated), {}

        def close(self):
            if not self.closed:
                self.closed = True
                call(ENTRIES["env_close"], {"env": self.key}, {})

    def make(id, *args, **kwargs):  # noqa: A002 - gymnasium's own name
        name = getattr(id, "id", id)
        if name not in ENV_IDS:
            return real_make(id, *args, **kwargs)
        unknown = sorted(set(kwargs) - {"render_mode"})
        if args or unknown:
            raise TypeError(f"in grading, gym.make({name!r}) takes no other arguments than render_mode, got "
                            f"{', '.join(unknown) or 'positional ones'}")
        return ServedCartPole(name)

    make.__doc__, make.__name__ = real_make.__doc__, "make"
    gymnasium.make = registration.make = make
    return ServedCartPole


def env_key(env, served_class):
    """The key of ``env`` for ``run_policy(..., env=env)``: None, or the key of a ``ServedCartPole``."""
    if env is None:
        return None
    if type(env) is not served_class or env.closed:
        raise TypeError("in grading, run_policy(..., env=env) plays in an environment made by "
                        "gym.make('CartPole-v1') (or hwlib.cartpole.make_env()) and not closed; got a "
                        f"{type(env).__name__}")
    return env.key


# --------------------------------------------------------------------------------------------
# The server: the environments themselves
# --------------------------------------------------------------------------------------------


class StartRecorder:
    """An environment that passes ``reset`` and ``step`` on to ``env`` and keeps the start state."""

    def __init__(self, env):
        self.env, self.start = env, np.full(4, np.nan)

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.start = np.array(obs, dtype=np.float64).reshape(4)
        return obs, info

    def step(self, action):
        return self.env.step(action)


class Table:
    """The server's environments by key, at most ``SERVER_ENVS`` of them; ``scratch`` plays the
    episodes of ``run_policy`` without an environment (always with a seed)."""

    def __init__(self, make):
        self.make, self.envs, self._scratch = make, OrderedDict(), None

    def get(self, key):
        if key not in self.envs:
            raise RuntimeError("this environment was closed by the grader (too many open at once)")
        self.envs.move_to_end(key)
        return self.envs[key]

    def scratch(self):
        if self._scratch is None:
            self._scratch = self.make("CartPole-v1")
        return self._scratch

    def execute(self, name, args):
        if name == "env_make":
            self.envs[args["env"]] = self.make(args["id"])
            while len(self.envs) > SERVER_ENVS:
                self.envs.popitem(last=False)[1].close()
            return None
        if name == "env_close":
            env = self.envs.pop(args["env"], None)
            if env is not None:
                env.close()
            return None
        env = self.get(args["env"])
        if name == "env_reset":
            obs, _ = env.reset(seed=None if args["seed"] is None else int(args["seed"]))
            return np.asarray(obs, dtype=np.float32)
        obs, reward, terminated, truncated, _ = env.step(int(np.asarray(args["action"]).item()))
        return [np.asarray(obs, dtype=np.float32), float(reward), bool(terminated), bool(truncated)]
