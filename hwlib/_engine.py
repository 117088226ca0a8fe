"""How the kit plays many CartPole episodes at once. Students need not read this.

``play_batch(params, seeds)`` plays one episode per row of ``params`` in gymnasium's vectorised
CartPole: each episode starts exactly where ``reset(seed=...)`` puts a single environment (the
start state is read from a single environment) and from then on every reward comes from the
vector environment's ``step``, so the rewards are those of the one-by-one loop.

The batch computes actions with its own copy of equation (1) (``batch_actions``). It may do so
for a policy only after ``agrees_with_equation_one`` has compared that copy with the policy's own
``__call__``: once per ``__call__`` function on many random parameters and states, then for every
parameter vector on a few probe states (the tie at zero included). A policy that disagrees is
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

_route = threading.local()  # .play: the callable run_policy hands its episodes to, in this thread


def current_route():
    """What ``run_policy`` should hand ``(policy, seed)`` to in this thread, or None (play it itself)."""
    return getattr(_route, "play", None)


def set_route(play):
    """Make ``play(policy, seed) -> reward`` the route of this thread (None: none); returns the previous one."""
    previous = getattr(_route, "play", None)
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
        for seed in missing:
            env.reset(seed=seed)
            _START_STATES[seed] = np.array(env.unwrapped.state, dtype=np.float64)
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
    ``reset(seed=seeds[k])`` (int64, (K,)), all played at once. The caller has checked both."""
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


# --- may the batch play a policy with its own copy of equation (1)? ----------------------------

# Probe states for every parameter vector: the tie (all zeros), two like CartPole's start states,
# two farther out.
PROBE_STATES = np.array([
    [0.0, 0.0, 0.0, 0.0],
    [0.031, -0.017, 0.042, -0.008],
    [-0.044, 0.023, -0.012, 0.037],
    [0.8, -1.3, 0.11, 1.7],
    [-1.2, 0.9, -0.15, -1.1],
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
