"""How the kit plays many CartPole episodes at once.

``play_batch(params, seeds)`` plays one episode per row of ``params``, all at once, with the
kit's own NumPy port of gymnasium's vectorised CartPole step (``play``): each episode starts exactly where
``reset(seed=...)`` puts a single environment (the start state is read from a single environment)
and moves by the vector environment's equations, so the rewards are those of the one-by-one loop.

The batch computes actions with its own copy of equation (1) (``batch_actions``). It may do so
for a policy only after ``agrees_with_equation_one`` has compared that copy with the policy's own
``__call__``: once per ``__call__`` function on many random parameters and states (the tie at zero
included), then for every parameter vector on two probe states. A policy that disagrees is
played step by step with its ``__call__`` (``play_from``); a policy whose ``__call__`` is still a
TODO stub raises its ``TodoNotDone`` from here.

``run_episodes(params, seeds)`` is that for the reward landscape (``hwlib/landscape.py``) and the
tests: one episode of ``CartPoleLinearPolicy(params[k])`` per row, batched where it may be.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from hwlib.cartpole import ENV_ID, NUM_OBSERVATIONS, CartPoleLinearPolicy, make_env, play_episode
from hwlib.machinery.progress import Progress
from hwlib.machinery.todos import TodoNotDone
from hwlib.machinery.validation import check_params_batch, check_seeds

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


def start_state(seed):
    """``start_states`` of one seed (an int), float64 (4,)."""
    state = _START_STATES.get(seed)
    return start_states([seed])[0] if state is None else state


def starts_of(seeds_or_states):
    """The start states (float64 (K, 4)) of episodes named by a seed (int) or by a start state (its
    float64 bytes: an unseeded episode of a kit run, see ``batch.py``)."""
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
    all played at once with the kit's port of the vectorised step (``play``). The caller has checked them."""
    starts = start_states(seeds) if starts is None else starts
    return play(params, starts, constants())


# --- CartPole's step for many episodes at once ----------------------------------------------------

CONSTANTS = ("gravity", "masspole", "total_mass", "length", "polemass_length", "force_mag", "tau",
             "theta_threshold_radians", "x_threshold", "max_episode_steps")


def play(params, starts, c):
    """Total reward of one episode of equation (1) per row of ``params`` (float64 (K, 4)) from the
    start state ``starts[k]`` (float64 (K, 4)); ``c`` holds CartPole's ``CONSTANTS``.

    The step is the kit's NumPy port of gymnasium's vectorised CartPole step
    (``CartPoleVectorEnv.step``: the same equations, constants and order of operations), without its per-step checks and auto-reset,
    and in place: the rewards are those of ``env.step``, bit for bit (``tests/unit/test_cartpole.py``
    compares it with gymnasium's vector environment and with the one-by-one loop). An episode
    that has ended is still stepped (its reward is kept) until a quarter of those stepped have
    ended; then the rest go on alone.
    """
    x, x_dot, theta, theta_dot = (np.array(row, dtype=np.float64) for row in starts.T)  # copies, stepped in place
    p0, p1, p2, p3 = (np.ascontiguousarray(params[:, j]) for j in range(NUM_OBSERVATIONS))
    rewards = np.zeros(len(params))
    rows, going, num_going, steps = np.arange(len(params)), np.ones(len(params), dtype=bool), len(params), 0
    while num_going:
        # Equation (1) on what env.step returns (float32), as batch_actions computes it.
        score = p0 * x.astype(np.float32)
        score += p1 * x_dot.astype(np.float32)
        score += p2 * theta.astype(np.float32)
        score += p3 * theta_dot.astype(np.float32)
        force = (score < 0) * (2.0 * c.force_mag) - c.force_mag  # +force_mag where score < 0, else -force_mag
        costheta, sintheta = np.cos(theta), np.sin(theta)
        temp = np.square(theta_dot)  # temp = (force + polemass_length * theta_dot**2 * sintheta) / total_mass
        temp *= c.polemass_length
        temp *= sintheta
        temp += force
        temp /= c.total_mass
        below = np.square(costheta)  # length * (4/3 - masspole * costheta**2 / total_mass)
        below *= c.masspole
        below /= c.total_mass
        np.subtract(4.0 / 3.0, below, out=below)
        below *= c.length
        thetaacc = c.gravity * sintheta  # (gravity * sintheta - costheta * temp) / below
        thetaacc -= costheta * temp
        thetaacc /= below
        xacc = c.polemass_length * thetaacc  # temp - polemass_length * thetaacc * costheta / total_mass
        xacc *= costheta
        xacc /= c.total_mass
        np.subtract(temp, xacc, out=xacc)
        x += c.tau * x_dot  # Euler: the positions move with the old velocities
        xacc *= c.tau
        x_dot += xacc
        theta += c.tau * theta_dot
        thetaacc *= c.tau
        theta_dot += thetaacc
        steps += 1  # +1 reward for every step, the last one included
        if steps >= c.max_episode_steps:  # truncated
            rewards[rows[going]] = steps
            break
        ended = np.abs(x) > c.x_threshold
        ended |= np.abs(theta) > c.theta_threshold_radians
        ended &= going
        if ended.any():
            rewards[rows[ended]] = steps
            going &= ~ended
            num_going -= int(np.count_nonzero(ended))
            if 4 * num_going < 3 * len(rows):
                rows, x, x_dot, theta, theta_dot = rows[going], x[going], x_dot[going], theta[going], theta_dot[going]
                p0, p1, p2, p3 = p0[going], p1[going], p2[going], p3[going]
                going = np.ones(len(rows), dtype=bool)
    return rewards


class _Constants:
    """CartPole's constants, as gymnasium's environment has them."""

    NAMES = tuple(name for name in CONSTANTS if name != "max_episode_steps")  # that one: from the spec

    def __init__(self):
        env = gym.make(ENV_ID)
        raw = env.unwrapped
        if getattr(raw, "kinematics_integrator", "euler") != "euler" or getattr(raw, "_sutton_barto_reward", False):
            raise RuntimeError(f"{ENV_ID} is not the CartPole this engine plays (Euler steps, +1 per step)")
        for name in self.NAMES:
            setattr(self, name, float(getattr(raw, name)))
        self.max_episode_steps = int(env.spec.max_episode_steps)
        env.close()


_CONSTANTS = []


def constants():
    """CartPole's constants (``CONSTANTS``), read once from gymnasium."""
    if not _CONSTANTS:
        _CONSTANTS.append(_Constants())
    return _CONSTANTS[0]


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
            if not is_action(action) or int(action) != want:
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
    return all(is_action(action) for action in actual) and [int(action) for action in actual] == expected.tolist()


def is_action(action):
    # Python ints (bools included) and numpy integers are what env.step accepts.
    return isinstance(action, (int, np.integer))


def linear_params(policy):
    """The float64 parameters (4,) of a ``CartPoleLinearPolicy`` (or a subclass), or None for any
    other callable (or parameters that are not 4 numbers: it is then played step by step)."""
    if not isinstance(policy, CartPoleLinearPolicy):
        return None
    params = policy.params
    if type(params) is np.ndarray and params.dtype == np.float64 and params.shape == (NUM_OBSERVATIONS,):
        return params
    try:  # the policy's params were replaced after it was made: read them as they are now
        return np.array(params, dtype=np.float64).reshape(NUM_OBSERVATIONS)
    except (TypeError, ValueError):
        return None


# --- one by one, and many at once ---------------------------------------------------------------


class _StartsAt(gym.Wrapper):
    """An environment whose next ``reset`` puts CartPole in the given start state."""

    def __init__(self, env, start):
        super().__init__(env)
        self.start = start

    def reset(self, *, seed=None, options=None):
        _, info = self.env.reset()
        self.env.unwrapped.state = np.array(self.start, dtype=np.float64)
        return np.array(self.start, dtype=np.float32), info


def play_from(policy, start, env):
    """Total reward of one plain episode of ``policy`` (its own ``__call__``, step by step) from a
    seed (int) or a start state (its float64 bytes: an unseeded episode of a kit run), in ``env``."""
    if isinstance(start, bytes):
        return play_episode(policy, None, _StartsAt(env, np.frombuffer(start, dtype=np.float64))).total_reward
    return play_episode(policy, start, env).total_reward


def run_episodes(params, seeds, batched=True, progress=None):
    """Total reward of one episode of ``CartPoleLinearPolicy(params[k])`` from ``reset(seed=seeds[k])``, for every row k.

    ``params`` has shape (K, 4), ``seeds`` K entries. With ``batched`` (the default) the episodes
    of every parameter vector on which ``__call__`` gives the actions of equation (1) are played
    all at once, the others one by one with its ``__call__``; ``batched=False`` plays every episode
    one by one. The rewards are the same. ``progress`` names the work for a progress bar in the
    notebook (None: no bar). Returns a float64 array of K rewards.
    """
    params = check_params_batch(params, "params")
    seeds = check_seeds(seeds, "seeds")
    if len(seeds) != len(params):
        raise ValueError(f"seeds must hold one seed per row of params ({len(params)}), got {len(seeds)}")
    if not isinstance(batched, bool):
        raise TypeError(f"batched must be True or False, got {batched!r}")
    rewards = np.zeros(len(params))
    with Progress(progress, len(params), "episodes") as bar:
        if batched:
            unique, inverse = np.unique(params, axis=0, return_inverse=True)
            inverse = inverse.reshape(-1)
            trusted = np.array([agrees_with_equation_one(CartPoleLinearPolicy(p), p) for p in unique])
            batch_rows = np.flatnonzero(trusted[inverse])
            if batch_rows.size:
                rewards[batch_rows] = play_batch(params[batch_rows], seeds[batch_rows])
                bar.advance(batch_rows.size)
            one_by_one = np.flatnonzero(~trusted[inverse])
        else:
            one_by_one = np.arange(len(params))
        env = make_env() if one_by_one.size else None
        for row in one_by_one:
            rewards[row] = play_from(CartPoleLinearPolicy(params[row]), int(seeds[row]), env)
            bar.advance(1)
    return rewards
