"""How the kit plays many CartPole episodes at once. Students need not read this.

``play_batch(params, seeds)`` plays one episode per row of ``params``, all at once, with the
step of gymnasium's vectorised CartPole: each episode starts exactly where ``reset(seed=...)``
puts a single environment (the start state is read from a single environment) and moves by the
vector environment's equations, so the rewards are those of the one-by-one loop.

The batch computes actions with its own copy of equation (1) (``batch_actions``). It may do so
for a policy only after ``agrees_with_equation_one`` has compared that copy with the policy's own
``__call__``: once per ``__call__`` function on many random parameters and states (the tie at zero
included), then for every parameter vector on two probe states. A policy that disagrees is
played step by step with its ``__call__``; a policy whose ``__call__`` is still a TODO stub raises
its ``TodoNotDone`` from here.

``run_policy`` (``hwlib/cartpole.py``) hands its episode to ``current_route()`` when the kit's
batch engine (``hwlib/_batch.py``) has set one for this thread.
"""

from __future__ import annotations

import threading

import gymnasium as gym
import numpy as np

from hwlib import _physics
from hwlib._todo import TodoNotDone

ENV_ID = "CartPole-v1"
NUM_OBSERVATIONS = 4

class _Route(threading.local):
    play = None  # the callable run_policy hands its episodes to, in this thread


_route = _Route()


def current_route():
    """What ``run_policy`` should hand ``(policy, seed)`` to in this thread, or None (play it itself)."""
    return _route.play


def set_route(play):
    """Make ``play(policy, seed) -> reward`` the route of this thread (None: none); returns the previous one."""
    previous = _route.play
    _route.play = play
    return previous


_START_STATES = {}  # seed -> the start state reset(seed=seed) gives; seeds repeat a lot in training


def start_states(seeds):
    """The start state ``reset(seed=s)`` gives a single CartPole for every seed (int64 array), shape (K, 4).

    Read from the environment itself (not re-derived), so it stays right if gymnasium changes
    how it draws start states.
    """
    missing = [int(seed) for seed in np.unique(seeds) if int(seed) not in _START_STATES]
    if missing:
        env = gym.make(ENV_ID)
        raw = env.unwrapped  # its own reset draws the start state; the wrappers only check and count
        for seed in missing:
            raw.reset(seed=seed)
            _START_STATES[seed] = np.array(raw.state, dtype=np.float64)
        env.close()
        if len(_START_STATES) > 1_000_000:
            _START_STATES.clear()
    return np.array([_START_STATES[int(seed)] for seed in seeds]).reshape(len(seeds), NUM_OBSERVATIONS)


def starts_of(seeds_or_states):
    """The start states (float64 (K, 4)) of episodes named by a seed (int) or by a start state (its
    float64 bytes: an unseeded episode of a kit run, see ``hwlib/_batch.py``)."""
    if not any(isinstance(item, bytes) for item in seeds_or_states):
        return start_states(np.fromiter(seeds_or_states, dtype=np.int64, count=len(seeds_or_states)))
    from_seeds = iter(start_states(np.array([item for item in seeds_or_states if not isinstance(item, bytes)],
                                            dtype=np.int64)))
    return np.array([np.frombuffer(item, dtype=np.float64) if isinstance(item, bytes) else next(from_seeds)
                     for item in seeds_or_states]).reshape(len(seeds_or_states), NUM_OBSERVATIONS)


def batch_actions(params, observations):
    """The batch engine's own copy of equation (1) for K episodes at once: row k of ``params``
    (K, 4) acts on row k of ``observations`` (K, 4, the float32 numbers ``env.step`` returns).
    The score is summed left to right in float64, as ``play_batch`` does. Returns K int64 actions."""
    o = np.asarray(observations, dtype=np.float32).astype(np.float64)
    score = params[:, 0] * o[:, 0]
    for j in range(1, NUM_OBSERVATIONS):
        score += params[:, j] * o[:, j]
    return (score < 0).astype(np.int64)


def play_batch(params, seeds=None, starts=None):
    """Total reward of one episode of equation (1) per row of ``params`` (float64, (K, 4)) from
    ``reset(seed=seeds[k])`` (int64, (K,)), or from the start state ``starts[k]`` (float64 (K, 4)),
    all played at once with gymnasium's vectorised step (``hwlib/_physics.py``). The caller has
    checked them."""
    starts = start_states(seeds) if starts is None else starts
    return _physics.play(params, starts, physics())


class _Physics:
    """CartPole's constants, as gymnasium's environment has them."""

    NAMES = tuple(name for name in _physics.CONSTANTS if name != "max_episode_steps")  # that one: from the spec

    def __init__(self):
        env = gym.make(ENV_ID)
        raw = env.unwrapped
        if getattr(raw, "kinematics_integrator", "euler") != "euler" or getattr(raw, "_sutton_barto_reward", False):
            raise RuntimeError(f"{ENV_ID} is not the CartPole this engine plays (Euler steps, +1 per step)")
        for name in self.NAMES:
            setattr(self, name, float(getattr(raw, name)))
        self.max_episode_steps = int(env.spec.max_episode_steps)
        env.close()


_PHYSICS = []


def physics():
    """CartPole's constants (``hwlib/_physics.py``'s ``CONSTANTS``), read once from gymnasium."""
    if not _PHYSICS:
        _PHYSICS.append(_Physics())
    return _PHYSICS[0]


# --- may the batch play a policy with its own copy of equation (1)? ----------------------------

# Probe states for every parameter vector: one like CartPole's start states, one farther out. (The
# tie at zero does not depend on the parameters: the wider check, once per __call__, covers it.)
PROBE_STATES = np.array([
    [0.031, -0.017, 0.042, -0.008],
    [0.8, -1.3, 0.11, 1.7],
], dtype=np.float32)
_WIDE_CHECK = 48  # random parameter vectors the wider check plays each __call__ function on
_FUNCTION_VERDICTS = {}  # a policy class's __call__ -> whether it follows equation (1) on the wider check


def agrees_with_equation_one(policy, params):
    """Whether ``policy`` (built with ``params``, float64 (4,)) gives exactly the actions of
    ``batch_actions``: its ``__call__`` on the wider check, ``policy`` itself on the probe states.

    An action must be a Python or numpy integer (what ``env.step`` accepts). A policy that raises
    is not trusted (playing it step by step shows its error where the plain loop would), except
    ``TodoNotDone``, which is raised here.
    """
    function = type(policy).__call__
    verdict = _FUNCTION_VERDICTS.get(function)
    if verdict is None:
        verdict = _FUNCTION_VERDICTS[function] = _wider_check(type(policy))
        if len(_FUNCTION_VERDICTS) > 1000:
            _FUNCTION_VERDICTS.clear()
    return verdict and _agrees(policy, params, PROBE_STATES)


def first_disagreement(policy_class):
    """``(params, obs, action, expected)`` where ``policy_class(params)(obs)`` leaves equation (1), or None."""
    for params, states in _wider_cases():
        try:
            policy = policy_class(params)
            actions = [policy(state) for state in states]
        except TodoNotDone:
            raise
        except Exception as error:  # noqa: BLE001 - reported as the disagreement
            return params, states[0], error, int(batch_actions(params[None, :], states[:1])[0])
        expected = batch_actions(np.repeat(params[None, :], len(states), axis=0), states)
        for state, action, want in zip(states, actions, expected):
            if not _is_action(action) or int(action) != want:
                return params, state, action, int(want)
    return None


def _wider_check(policy_class):
    try:
        return first_disagreement(policy_class) is None
    except TodoNotDone:
        raise
    except Exception:  # noqa: BLE001 - e.g. a subclass whose __init__ takes other arguments
        return False


def _wider_cases():
    generator = np.random.default_rng(20260)
    for index in range(_WIDE_CHECK):
        scale = (0.1, 1.0, 10.0)[index % 3]
        params = generator.uniform(-scale, scale, NUM_OBSERVATIONS)
        states = np.vstack([np.zeros((1, NUM_OBSERVATIONS)), generator.uniform(-0.05, 0.05, (2, NUM_OBSERVATIONS)),
                            generator.uniform(-2.0, 2.0, (2, NUM_OBSERVATIONS))]).astype(np.float32)
        yield params, states


def _agrees(policy, params, states):
    expected = batch_actions(np.repeat(params[None, :], len(states), axis=0), states)
    try:
        actual = [policy(state) for state in states]
    except TodoNotDone:
        raise
    except Exception:  # noqa: BLE001 - the step-by-step play shows the policy's own error
        return False
    return all(_is_action(action) for action in actual) and [int(action) for action in actual] == expected.tolist()


def _is_action(action):
    # Python ints (bools included) and numpy integers are what env.step accepts.
    return isinstance(action, (int, np.integer))


def linear_params(policy, linear_class):
    """The float64 parameters (4,) of a policy of ``linear_class`` and their bytes, or (None, None)
    for any other callable (or parameters that are not 4 finite numbers)."""
    if not isinstance(policy, linear_class):
        return None, None
    params = policy.params
    if type(params) is not np.ndarray or params.dtype != np.float64 or params.shape != (NUM_OBSERVATIONS,):
        try:  # the policy's params were replaced after it was made: read them as they are now
            params = np.array(params, dtype=np.float64).reshape(NUM_OBSERVATIONS)
        except (TypeError, ValueError):
            return None, None
    data = params.tobytes()
    if data not in FINITE_PARAMS:
        if not np.isfinite(params).all():
            return None, None
        if len(FINITE_PARAMS) > 500_000:
            FINITE_PARAMS.clear()
        FINITE_PARAMS.add(data)
    return params, data


FINITE_PARAMS = set()  # the bytes of parameter vectors known to be finite
