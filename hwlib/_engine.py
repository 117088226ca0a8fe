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


def batch_actions(params, observations):
    """The batch engine's own copy of equation (1) for K episodes at once: row k of ``params``
    (K, 4) acts on row k of ``observations`` (K, 4). Returns K int64 actions."""
    return (np.einsum("kj,kj->k", params, observations) < 0).astype(np.int64)


def play_batch(params, seeds):
    """Total reward of one episode of equation (1) per row of ``params`` (float64, (K, 4)) from
    ``reset(seed=seeds[k])`` (int64, (K,)), all played at once. The caller has checked both.

    The step is gymnasium's own vectorised CartPole step (``CartPoleVectorEnv.step``: the same
    equations, constants and order of operations, the constants read from gymnasium's
    environment), without its per-step checks and auto-reset, on the episodes still running
    only: the rewards are those of ``env.step``, bit for bit (``tests/test_cartpole.py`` compares
    it with gymnasium's vector environment and with the one-by-one loop).
    """
    c = _physics()
    x, x_dot, theta, theta_dot = (row.copy() for row in start_states(seeds).T)
    rewards = np.zeros(len(params))
    rows, row_params, steps = np.arange(len(params)), params, 0
    while rows.size:
        observations = np.empty((rows.size, NUM_OBSERVATIONS), dtype=np.float32)  # what env.step returns
        observations[:, 0], observations[:, 1], observations[:, 2], observations[:, 3] = x, x_dot, theta, theta_dot
        force = np.where(batch_actions(row_params, observations) == 1, c.force_mag, -c.force_mag)
        costheta, sintheta = np.cos(theta), np.sin(theta)
        temp = (force + c.polemass_length * np.square(theta_dot) * sintheta) / c.total_mass
        thetaacc = (c.gravity * sintheta - costheta * temp) / (
            c.length * (4.0 / 3.0 - c.masspole * np.square(costheta) / c.total_mass))
        xacc = temp - c.polemass_length * thetaacc * costheta / c.total_mass
        x, x_dot = x + c.tau * x_dot, x_dot + c.tau * xacc
        theta, theta_dot = theta + c.tau * theta_dot, theta_dot + c.tau * thetaacc
        steps += 1  # +1 reward for every step, the last one included
        if steps >= c.max_episode_steps:  # truncated
            rewards[rows] = steps
            break
        ended = (x < -c.x_threshold) | (x > c.x_threshold) | (theta < -c.theta_threshold_radians) | (
            theta > c.theta_threshold_radians)
        if ended.any():
            rewards[rows[ended]] = steps
            going = ~ended
            rows, row_params = rows[going], row_params[going]
            x, x_dot, theta, theta_dot = x[going], x_dot[going], theta[going], theta_dot[going]
    return rewards


class _Physics:
    """CartPole's constants, as gymnasium's environment has them."""

    NAMES = ("gravity", "masspole", "total_mass", "length", "polemass_length", "force_mag", "tau",
             "theta_threshold_radians", "x_threshold")

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


def _physics():
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
