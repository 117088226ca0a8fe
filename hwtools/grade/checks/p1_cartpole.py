"""The checks of problem 1 (CartPole), TODO by TODO: 1.1.1, 1.2.1, 1.3.1, 1.3.2, 1.3.3.

Each TODO's section holds everything its points ride on: how its visible inputs are made (the
hidden ones come from the same makers with the instructor's seed, ``instructor/hidden_checks``),
its judges and tolerances, and last its behaviours (``TODO_1_2_1``: key, what is checked in words
(its points: the TODO table's ``checks``), the probe that runs in the sandbox, the maker and the
judge), with the line a failing visible check prints to rebuild its input (``REBUILT``). A probe's code is in
``hwtools/grade/in_sandbox/probes.py`` under the same name. The 1.3.x judges read only the
grader's own records of the episodes and evaluations it answered (``broker.py``, ``episodes.py``),
never what the student's process says about them. Standard library and numpy only.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hwtools import facts
from hwtools.grade.checks.behaviour import Behaviour
from hwtools.grade.checks.verdicts import (EXACTLY, Tolerance, Verdict, _close, _number_text, close_to, difference_words,
                                          exact, show)
from hwtools.grade.episodes import OWN_LOOP
from hwtools.grade.in_sandbox.probes import known_function, training_objective

REBUILT = {}  # probe: (what the rebuilding line unpacks, what to call then); see checks.rebuild_line


# --------------------------------------------------------------------------------------------
# 1.1.1 the linear policy, equation (1). Probe policy_choices: CartPoleLinearPolicy(params[i])(obs[i])
# for each row i, as a number, and whether env.step takes it as it is.
# --------------------------------------------------------------------------------------------


def _integer_rows(rng, want):
    """Rows (params, obs) of small whole numbers whose score params . obs is exactly each sign in
    ``want`` ({sign: count}): exact in any order of summation, so a score of 0 is a real tie."""
    rows, want = [], dict(want)
    while any(want.values()):
        params = rng.integers(-3, 4, size=4).astype(np.float64)
        obs = rng.integers(-3, 4, size=4).astype(np.float64)
        sign = int(np.sign(params @ obs))
        if want.get(sign):
            want[sign] -= 1
            rows.append((params, obs))
    return rows


ROUNDED = (2, 3, 4)  # decimals an observation rounded to takes a score near 0 to the other side on every input


def _near_boundary_rows(rng, count, low=1e-4, high=3e-3):
    """Rows of random parameters and states whose score params . obs is within ``low`` to ``high`` of 0,
    half on each side: far from any float rounding (1e-16; float32 observations move a score by 1e-6 at
    most here), near enough that an observation (or parameters) rounded, or any other change of the
    inputs, takes the other side."""
    rows = []
    for k in range(count):
        params, obs = rng.normal(size=4), rng.normal(size=4) * np.array([1.0, 1.0, 0.1, 1.0])
        score = float(rng.uniform(low, high)) * (1.0 if k % 2 else -1.0)
        obs = obs + (score - params @ obs) / (params @ params) * params
        rows.append((params, obs))
    return rows


def _rounding_shows(rng):
    """Near-boundary rows (4 within 3e-3 of 0, 4 within 2e-4) drawn until, for each number of decimals in
    ROUNDED, an observation rounded to it gives at least one of them the other action."""
    while True:
        rows = _near_boundary_rows(rng, 4) + _near_boundary_rows(rng, 4, 2e-5, 2e-4)
        params, obs = (np.array(part) for part in zip(*rows))
        right = np.einsum("ij,ij->i", params, obs) < 0
        if all(np.any((np.einsum("ij,ij->i", params, np.round(obs, d)) < 0) != right) for d in ROUNDED):
            return rows


def make_policy_states(rng, variant):
    """Random parameters and states (pole angles as small as the pole's), and at random places among
    them four scores of exactly 0 (the tie of equation (1): action 0), two just above and below, and
    eight random ones within 3e-3 of 0, four of them within 2e-4 (half on each side), on which an
    observation rounded to 2, 3 or 4 decimals takes the other side (``_rounding_shows``)."""
    count = 30
    params = rng.normal(size=(count, 4))
    obs = rng.normal(size=(count, 4)) * np.array([1.0, 1.0, 0.1, 1.0])
    rows = [(p, o) for p, o in zip(params, obs)] + _integer_rows(rng, {0: 4, 1: 2, -1: 2}) + _rounding_shows(rng)
    order = rng.permutation(len(rows))
    return {"params": np.array([rows[i][0] for i in order]), "obs": np.array([rows[i][1] for i in order])}


def _policy_row(args, index):
    (row,) = index
    params, obs = np.asarray(args["params"][row]), np.asarray(args["obs"][row])
    return f"row {row} (params . obs = {_number_text(params @ obs)}): params {show(params)}, obs {show(obs)}"


def _rounds_observation(args, actual, expected, tolerance, result=None):
    """"rounds_observation" (a known mistake) if the actions are equation (1) on the observation rounded to
    some number of decimals (0 to 8), else ""."""
    params, obs = np.asarray(args["params"], dtype=np.float64), np.asarray(args["obs"], dtype=np.float64)
    rounded = (np.einsum("ij,ij->i", params, np.round(obs, decimals)) < 0 for decimals in range(9))
    return "rounds_observation" if any(np.array_equal(actual, actions) for actions in rounded) else ""


ACTION_KINDS = {1: "a numpy bool", 2: "a float", 3: "an array", 4: "something else"}  # the worker's codes


def judge_env_actions(args, result, expected, services):
    """Right actions (as ``exact``), each of a type ``env.step`` takes."""
    verdict = exact("actions", EXACTLY, _policy_row)(args, result, expected, services)
    if not verdict.passed:
        return verdict
    accepted, kinds = result["values"]["accepted"], result["values"]["kinds"]
    if bool(np.all(accepted)):
        return verdict
    row = int(np.flatnonzero(~np.asarray(accepted, dtype=bool))[0])
    what = ACTION_KINDS.get(int(kinds[row]), "something else")
    refused = int(np.sum(~np.asarray(accepted, dtype=bool)))
    return Verdict(False, "the int 0 or 1, which env.step takes (a Python bool or a numpy integer works too)",
                   show(result["values"]["actions"]), f"the action of row {row} is {what}, which env.step refuses "
                   f"({refused} of {len(accepted)} rows); int(...) makes it the int 0 or 1",
                   summary=f"at row {row}: expected the int 0 or 1, actual {what}, which env.step refuses")


TODO_1_1_1 = (
    Behaviour("1.1.1", "equation-1", "equation (1): action 1 exactly where params . obs < 0 (a score of 0 gives 0)",
              "policy(obs) is 1 exactly where params . obs < 0, else 0 (equation (1)): on "
              "random parameters and states, and on scores of exactly 0 (the tie: action 0, the < is strict) and "
              "just above and below 0, mixed in among them", "policy_choices", make_policy_states,
              exact("actions", EXACTLY, _policy_row, rule=_rounds_observation), exact=True, value=True),
    Behaviour("1.1.1", "env-action", "each action one env.step takes: the int 0 or 1",
              "the right actions, each one env.step takes: the int 0 or 1 (a Python bool "
              "or a numpy integer works too; a float or a numpy bool does not)", "policy_choices", make_policy_states,
              judge_env_actions, visible_count=1, exact=True),
)
REBUILT["policy_choices"] = ("params, obs", "CartPoleLinearPolicy(params[i])(obs[i]) for the row i it names")


# --------------------------------------------------------------------------------------------
# 1.2.1 central differences, equation (3). Probe finite_diff: scalar_finite_diff(f, x, h), f a known
# function (probes.known_function).
# --------------------------------------------------------------------------------------------


def _signed(rng, size):
    return rng.uniform(0.5, 2.0, size=size) * rng.choice([-1.0, 1.0], size=size)


def _coupled(rng, size):
    """f(v) = sum_i a_i v_i^3 + sin(b . v) + v^T M v: a cubic part, on which a forward difference is
    off, and coordinates that interact, so that moving any other point than x shows."""
    return {"kind": "coupled", "a": _signed(rng, size), "b": rng.normal(size=size), "m": rng.normal(size=(size, size))}


def make_fd_uniform(rng, variant):
    if variant == 2:  # a single number x
        return {"f": _coupled(rng, 1), "x": float(rng.uniform(-2, 2)), "h": float(rng.uniform(0.1, 0.6)),
                "x_scalar": True, "h_scalar": True}
    size = int(rng.integers(3, 7))
    step = float(rng.uniform(0.1, 0.6))
    return {"f": _coupled(rng, size), "x": rng.uniform(-2, 2, size),
            "h": step if variant == 0 else np.full(size, step), "h_scalar": variant == 0}


def make_fd_steps(rng, variant):
    size = int(rng.integers(4, 8))
    return {"f": _coupled(rng, size), "x": rng.uniform(-1.5, 1.5, size), "h": rng.uniform(0.05, 0.8, size)}


def _coordinate(args, index):
    if not index:
        return ""
    (i,) = index
    h = np.broadcast_to(np.asarray(args["h"], dtype=np.float64), np.shape(args["x"]))
    return f"coordinate {i}: x[{i}] = {_number_text(args['x'][i])}, h[{i}] = {_number_text(h[i])}"


# A tolerance that tells formulas apart, not precisions. The right formula computed or stored in
# float32 (x, h or the answer as float32, even f's values rounded to float32) is off by at most
# 1.1e-5 * (|expected| + 1) on these inputs (2.5e-8 when only the answer is stored as float32); a
# wrong one (a forward difference, h for 2h, h/2 steps, another coordinate's step, every
# coordinate moved) by 5e-3 * (|expected| + 1) or more. 1.2.1 has no precision point: equation
# (3)'s own error (of order h^2, 1e-3 to 1e-1 here) is far above float32's rounding.
FD_TOLERANCE = Tolerance(1e-4, 1e-4, "the right formula in float32 is off by at most 1.1e-5 * (|expected| + 1) here, "
                                     "a wrong one by 5e-3 * (|expected| + 1) or more")


def _central(f, x, steps):
    """Equation (3) at ``x`` with step ``steps[i]`` in coordinate i (the grader's own, for the rules below)."""
    out = np.empty(len(x))
    for i, step in enumerate(steps):
        move = np.zeros(len(x))
        move[i] = step
        out[i] = (f(x + move) - f(x - move)) / (2.0 * step)
    return out


def _step_sizes(f, x, i, value):
    """The steps s > 0 (from 1e-8 to 1e3) with which equation (3) in coordinate i gives ``value``: the
    sign changes of a log-spaced scan, each narrowed by bisection."""
    def gap(s):
        return _central(f, x, [s if j == i else 1.0 for j in range(len(x))])[i] - value

    grid = np.geomspace(1e-8, 1e3, 300)
    gaps = np.array([gap(s) for s in grid])
    roots = []
    for k in np.flatnonzero(np.sign(gaps[:-1]) * np.sign(gaps[1:]) <= 0)[:8]:
        low, high = grid[k], grid[k + 1]
        for _ in range(60):
            middle = np.sqrt(low * high)
            low, high = (middle, high) if np.sign(gap(middle)) == np.sign(gaps[k]) else (low, middle)
        roots.append(float(np.sqrt(low * high)))
    return roots


def _finite_diff_rule(args, actual, expected, tolerance, result=None):
    """The known mistake a wrong gradient is, whatever its constant, or "": "moves_every_coordinate"
    (f(x + h) - f(x - h), or f(x + h_i) - f(x - h_i), over 2 h_i: every coordinate moved at once);
    "scaled_steps" (equation (3) with steps k h_i, one k != 1 for every coordinate: h_i / 2, 10 h_i);
    "one_step" (equation (3) with one step s for every coordinate where the h_i differ: h[0], 1e-3).
    Where every h_i is the same, a step of another size is both of the last two and neither is named."""
    f, x = known_function(args["f"]), np.atleast_1d(np.asarray(args["x"], dtype=np.float64))
    h = np.broadcast_to(np.asarray(args["h"], dtype=np.float64), x.shape).astype(np.float64)
    actual = actual.reshape(x.shape)
    for move in (lambda i: h, lambda i: np.full(len(x), h[i])):
        every = np.array([(f(x + move(i)) - f(x - move(i))) / (2.0 * h[i]) for i in range(len(x))])
        if close_to(actual, every, tolerance):
            return "moves_every_coordinate"
    if len(x) < 2 or np.allclose(h, h[0], rtol=1e-12, atol=0.0):
        return ""
    i = int(np.argmax(np.abs(actual - _central(f, x, h))))  # the coordinate that tells steps apart best
    roots = _step_sizes(f, x, i, actual[i])
    if any(close_to(actual, _central(f, x, np.full(len(x), s)), tolerance) for s in roots):
        return "one_step"  # first: steps so small that every size gives the derivative fit both
    if any(close_to(actual, _central(f, x, h * (s / h[i])), tolerance) for s in roots):
        return "scaled_steps"
    return ""


def _no_arithmetic(result):
    """What a gradient returned as a list or tuple breaks: 1.3.2's update (theta + learning_rate * gradient)."""
    form = int(result["values"]["form"])
    if not form:
        return ""
    return (f"returns a {('list', 'tuple')[form - 1]} where the training code does arithmetic on the gradient "
            "(learning_rate * gradient): return an array (np.array(...))")


TODO_1_2_1 = (
    Behaviour("1.2.1", "equation-3", "equation (3) with a step h_i per coordinate: only coordinate i moves, by +-h_i, over 2 h_i",
              "central differences, equation (3), with a different step h_i for each "
              "coordinate: only coordinate i moves, by +-h_i, and the difference is divided by 2 h_i; on functions "
              "where a forward difference, or a point other than x, is off (the answer: N numbers, shaped like x "
              "or in a list)", "finite_diff", make_fd_steps, exact("gradient", FD_TOLERANCE, _coordinate, _finite_diff_rule),
              exact=True, value=True, breaks_callers=_no_arithmetic),
    Behaviour("1.2.1", "one-step", "equation (3) with one step h for every coordinate, also for a single number x",
              "central differences with one step h for every coordinate (h a number or "
              "equal steps), also for a single number x (a number or one number in a list or array)",
              "finite_diff", make_fd_uniform, exact("gradient", FD_TOLERANCE, _coordinate, _finite_diff_rule), visible_count=3,
              exact=True),
)
REBUILT["finite_diff"] = ("f, x, h", "scalar_finite_diff(f, x, h)")


# --------------------------------------------------------------------------------------------
# 1.3.1 eval_params, judged by property on the grader's own records of the episodes it played. Probe
# eval_params: eval_params(params, num_rollouts, seed=seed), twice.
# --------------------------------------------------------------------------------------------
# Every episode is played on the trusted side, whatever door it comes through (``episodes.py``):
# run_policy (with a seed of the grader's choosing when the call gave none), run_policy in a
# gym.make environment, or the code's own reset/step loop in one (every reset and step answered
# and recorded). The probe calls eval_params twice with the same arguments. ``result["records"]``
# holds, in order, every episode (its parameters or the actions taken, seed, start state,
# reward): nothing the student's process says about them.

PLAYED = "through run_policy or a gym.make('CartPole-v1') environment"


def episode_lengths(params, seeds):
    """The steps of one episode of CartPoleLinearPolicy(params[k]) from ``reset(seed=seeds[k])`` for each k
    (``params`` one row per seed, or one vector for all), up to the
    episode cap (``facts.MAX_EPISODE_STEPS``): gymnasium's CartPole-v1 (its start states, constants and Euler
    step; the policy sees the float32 observation), in numpy. Only to choose inputs that reach a regime:
    the judges read the grader's records of the episodes played (``tests/grader/test_checks.py`` compares
    it with gymnasium)."""
    state = np.array([np.random.Generator(np.random.PCG64(np.random.SeedSequence(int(seed)))).uniform(-0.05, 0.05, 4)
                      for seed in seeds]).T
    x, x_dot, theta, theta_dot = state
    params = np.broadcast_to(np.asarray(params, dtype=np.float64), (len(seeds), 4))
    cap = facts.MAX_EPISODE_STEPS
    gravity, masspole, total_mass, length, force_mag, tau = 9.8, 0.1, 1.1, 0.5, 10.0, 0.02
    steps, going = np.zeros(len(seeds), dtype=np.int64), np.ones(len(seeds), dtype=bool)
    for _ in range(cap):
        obs = np.array([x, x_dot, theta, theta_dot], dtype=np.float32).astype(np.float64)
        force = np.where(np.einsum("kj,jk->k", params, obs) < 0, force_mag, -force_mag)
        costheta, sintheta = np.cos(theta), np.sin(theta)
        temp = (force + masspole * length * np.square(theta_dot) * sintheta) / total_mass
        thetaacc = (gravity * sintheta - costheta * temp) / (length * (4.0 / 3.0 - masspole * np.square(costheta) / total_mass))
        xacc = temp - masspole * length * thetaacc * costheta / total_mass
        x, x_dot, theta, theta_dot = x + tau * x_dot, x_dot + tau * xacc, theta + tau * theta_dot, theta_dot + tau * thetaacc
        steps += going
        going &= (np.abs(x) <= 2.4) & (np.abs(theta) <= 12 * 2 * np.pi / 360)
        if not going.any():
            break
    return steps


SHORT_EPISODE = 100  # steps: the other episodes of the case whose episode reaches the cap end sooner
# Parameters on the edge of balancing: from about half the start states an episode reaches the episode cap,
# from the others it ends within SHORT_EPISODE steps (found by bisection between parameters
# that always balance and ones that never do; tests/grader/test_checks.py keeps it true with gymnasium).
ON_THE_EDGE = ((0.2262, -1.1718, -1.1735, -0.8225), (0.0084, -1.2424, -1.1693, -0.8743),
               (-0.2396, -1.2359, -1.6123, -0.8697), (-0.0467, -1.3873, -1.3134, -0.9684),
               (-0.0642, -1.2619, -1.4058, -0.8906), (-0.2153, -1.0495, -1.6746, -0.745),
               (0.1042, -0.9974, -1.2005, -0.7006), (-0.0558, -1.1467, -1.182, -0.8006),
               (-0.1522, -0.9293, -1.6689, -0.6676), (0.2453, -1.1222, -1.5239, -0.805),
               (-0.0849, -1.0548, -1.0393, -0.7435), (0.0407, -1.0508, -1.2752, -0.7444))


def make_eval_case(rng, variant):
    """Random parameters (episodes of about 10 steps), or (variant 1) parameters ``ON_THE_EDGE`` (each
    entry moved by up to 1%) and a seed such that among the case's episodes (seed + k) one reaches the
    episode cap, neither the first nor the last (so that code stopping there plays fewer), and the
    others end within SHORT_EPISODE steps, in the same call (each step of an episode played in the
    code's own environment is a message: few steps keep such a run short)."""
    rollouts, span = int((3, 4, 1, 6)[variant % 4]), 32  # seeds played at once
    for _ in range(200 if variant == 1 else 0):
        params = np.array(ON_THE_EDGE[int(rng.integers(len(ON_THE_EDGE)))]) * rng.uniform(0.99, 1.01, 4)  # drawn too
        base = int(rng.integers(0, 5_000))
        lengths = episode_lengths(params, base + np.arange(span))
        capped, short = lengths == facts.MAX_EPISODE_STEPS, lengths < SHORT_EPISODE
        for first in range(span - rollouts + 1):
            window = slice(first, first + rollouts)
            if short[first] and capped[window].sum() == 1 and not capped[first + rollouts - 1] and \
                    np.all(capped[window] | short[window]):
                return {"params": params, "num_rollouts": rollouts, "seed": base + first}
    if variant == 1:  # an episode cap far from CartPole's (within SHORT_EPISODE steps): say so, never loop on
        raise ValueError(f"1.3.1's inputs: no episodes of parameters on the edge of balancing both reach the episode "
                         f"cap ({facts.MAX_EPISODE_STEPS}) and end within {SHORT_EPISODE} steps; see ON_THE_EDGE")
    return {"params": rng.uniform(-1.0, 1.0, 4) * np.array([0.3, 1.0, 1.0, 1.0]), "num_rollouts": rollouts,
            "seed": int(rng.integers(0, 5_000))}


def _eval_episodes(args, result):
    """The episodes of the case (those the code played itself, not inside a served eval_params) as
    {name: array}, or the Verdict's actual text when there are not num_rollouts of them for each
    of the two calls."""
    records, count = result["records"], args["num_rollouts"]
    direct = records["episode_direct"]
    episodes = {name: records[f"episode_{name}"][direct] for name in
                ("params", "seeds", "seeded", "determined", "rewards", "starts", "doors", "finished")}
    rows = np.flatnonzero(direct)
    episodes["actions_follow"] = np.array([_follows(records, row, args["params"]) for row in rows], dtype=bool)
    if len(rows) != 2 * count:
        return None, (f"{len(rows)} episode(s) played {PLAYED} in two calls of eval_params with "
                      f"num_rollouts={count}")
    return episodes, None


def _first_call(args, result, want):
    """The episodes of the case's first eval_params call, or the Verdict that ends the check."""
    if result["status"] != "ok":
        return None, Verdict(False, want, result["error"])
    episodes, problem = _eval_episodes(args, result)
    if problem:
        played = int(np.sum(result["records"]["episode_direct"]))
        return None, Verdict(False, want, f"{problem}, returned {show(result['values']['value'])}",
                             rule=_too_few_rule(args, result, played),
                             summary=f"expected {2 * args['num_rollouts']} episodes in two calls with num_rollouts="
                                     f"{args['num_rollouts']}, actual {played} (returned {show(result['values']['value'])})")
    return {name: part[:args["num_rollouts"]] for name, part in episodes.items()}, None


def _too_few_rule(args, result, played):
    """The known mistake of a call that played too few episodes, seen in the grader's records, or "":
    "stops_at_cap" (each call stops at the first episode that reaches the episode cap, after one or more
    that did not) or "one_episode" (one episode per call, where num_rollouts asks for more)."""
    count, half = args["num_rollouts"], played // 2
    rewards = result["records"]["episode_rewards"][result["records"]["episode_direct"]]
    if played % 2 or not 0 < half < count:
        return ""
    capped = rewards[:half] >= facts.MAX_EPISODE_STEPS
    if half > 1 and capped[-1] and not capped[:-1].any():
        return "stops_at_cap"
    return "one_episode" if half == 1 and not capped[0] else ""


def _follows(records, row, params):
    """True if episode ``row`` was played with CartPoleLinearPolicy(params): its parameters, or for
    an own loop every action it took (equation (1) on the observation the grader had shown)."""
    if records["episode_doors"][row] != OWN_LOOP:
        return bool(np.array_equal(records["episode_params"][row], np.asarray(params, dtype=np.float64)))
    mine = records["step_episode"] == row
    scores = records["step_obs"][mine] @ np.asarray(params, dtype=np.float64)
    wanted = (scores < 0).astype(np.int64)
    return bool(np.all((records["step_actions"][mine] == wanted) | (np.abs(scores) < 1e-12)))


def _shown_seeds(seeds, seeded):
    return "[" + ", ".join(str(int(s)) if flag else "unseeded" for s, flag in zip(seeds, seeded)) + "]"


def _distinct(starts):
    return len(np.unique(np.asarray(starts), axis=0)) == len(starts)


def judge_eval_mean(args, result, expected, services):
    count = args["num_rollouts"]
    want = f"the mean of {count} episode reward(s) of params {show(args['params'])}, each from its own start state"
    first, stop = _first_call(args, result, want)
    if stop:
        return stop
    if not np.all(first["actions_follow"]):
        wrong = int(np.flatnonzero(~first["actions_follow"])[0])
        played = f"params {show(first['params'][wrong])}" if first["doors"][wrong] != OWN_LOOP else \
            "actions that are not those of CartPoleLinearPolicy(params)"
        return Verdict(False, want, f"episode {wrong + 1} was played with {played}",
                       summary=f"episode {wrong + 1} was played with {played}, not CartPoleLinearPolicy(params)")
    if not np.all(first["finished"]):
        wrong = int(np.flatnonzero(~first["finished"])[0])
        return Verdict(False, want, f"episode {wrong + 1} stopped before it ended (no step answered terminated or "
                                    "truncated)", summary=f"episode {wrong + 1} stopped before it ended")
    if not _distinct(first["starts"]):
        seeds = _shown_seeds(first['seeds'], first['seeded'])
        return Verdict(False, want, f"episodes from the same start state: seeds {seeds}",
                       summary=f"expected {count} different start states, actual {len(np.unique(first['starts'], axis=0))} "
                               f"(seeds {seeds})")
    mean = float(np.mean(first["rewards"]))
    value = result["values"]["value"]
    return Verdict(_close(value, mean, 1e-9, 1e-9), f"{want}: {show(mean)} (rewards {show(first['rewards'])})",
                   show(value), summary=f"expected the mean {show(mean)} of the rewards {show(first['rewards'])}, "
                                        f"actual {show(value)}")


def judge_eval_distinct(args, result, expected, services):
    count = args["num_rollouts"]
    want = f"{count} episodes from {count} different start states"
    first, stop = _first_call(args, result, want)
    if stop:
        return stop
    seeds, seeded, starts = first["seeds"], first["seeded"], first["starts"]
    actual = f"{len(np.unique(starts, axis=0))} different start state(s), seeds {_shown_seeds(seeds, seeded)}"
    return Verdict(_distinct(starts), want, actual, summary=f"expected {count} different start states, actual {actual}")


def judge_eval_repeat(args, result, expected, services):
    """The same call twice: the same start states (in any order) and the same number. The records
    are split into the two calls' halves (a case with an odd number of episodes fails)."""
    if result["status"] != "ok":
        return Verdict(False, "the same number twice", result["error"])
    values, records = result["values"], result["records"]
    direct = records["episode_direct"]
    starts, determined = records["episode_starts"][direct], records["episode_determined"][direct]
    half = len(starts) // 2
    same_starts = len(starts) > 0 and len(starts) % 2 == 0 and \
        sorted(map(tuple, starts[:half])) == sorted(map(tuple, starts[half:]))
    same = _close(values["value_again"], values["value"], 0, 0)
    actual = f"{show(values['value'])}, then {show(values['value_again'])}"
    if not same_starts:
        actual += " (the second call's episodes started from other states" + \
            ("" if np.all(determined) else ": an episode without a seed starts from a random state") + ")"
    return Verdict(same_starts and same, "the same number twice, from the same start states", actual,
                   summary=f"expected the same number twice, actual {actual}")


TODO_1_3_1 = (
    Behaviour("1.3.1", "mean-reward", "the mean total reward of num_rollouts episodes of CartPoleLinearPolicy(params)",
              "eval_params returns the mean total reward of num_rollouts episodes of "
              "CartPoleLinearPolicy(params), each from its own start state, played with run_policy or in a "
              "gym.make('CartPole-v1') environment (every reset and step is answered and recorded on the "
              "grader's side)", "eval_params", make_eval_case, judge_eval_mean, visible_count=3, value=True),
    Behaviour("1.3.1", "different-starts", "the episodes of one evaluation start from different states",
              "the episodes of one evaluation start from different start states "
              "(counts only up to 30% of the TODO while the mean is wrong)", "eval_params", make_eval_case,
              judge_eval_distinct, judged_on="mean-reward"),
    Behaviour("1.3.1", "repeatable", "the same call gives the same number, from the same start states",
              "the same call gives the same number again, from the same start states "
              "(seeded from the seed argument; counts only up to 30% of the TODO while the mean is wrong)",
              "eval_params", make_eval_case, judge_eval_repeat, judged_on="mean-reward"),
)
REBUILT["eval_params"] = ("params, num_rollouts, seed", "eval_params(params, num_rollouts, seed=seed), twice")


# --------------------------------------------------------------------------------------------
# 1.3.2 the training loop: a known objective, and a real run, on the grader's records. Probes
# train_known and train_real: train_cartpole_policy(...) and what it returned.
# --------------------------------------------------------------------------------------------
# In ``train_known`` cases every eval_params call is answered by the grader with the case's known
# objective g (a quartic, so that central differences depend on the step) and recorded with its
# rollouts and seed; in ``train_real`` cases the reference server answers it and the grader
# records the same, with the reference's value. The judges read these records.


def make_known_training(rng, variant):
    """A known objective (``probes.training_objective``) and a short run on it. Variant 1 reaches the
    episode cap, as real rewards do: g is capped there, its first update takes g from below the cap to
    it (every evaluation of the first gradient below it), and the run goes on at the cap."""
    while True:
        basis = rng.normal(size=(4, 4))
        case = {"objective": {"A": basis @ basis.T / 8.0 + 0.5 * np.eye(4), "m": rng.normal(size=4),
                              "q": rng.uniform(0.01, 0.05, size=4), "c": float(rng.uniform(100, 400))},
                "iterations": int(2 + variant), "rollouts": int((2, 3)[variant % 2]),
                "learning_rate": float((0.07, 0.12, 0.2)[variant % 3]), "fd_step": float((0.5, 0.25, 0.4)[variant % 3]),
                "seed": int(rng.integers(0, 100)), "initial_params": rng.normal(size=4) * 0.5}
        if variant != 1:
            return case
        g, theta, step = training_objective(case["objective"]), case["initial_params"], case["fd_step"]
        around = max(g(theta + step * e) for e in np.vstack([np.eye(4), -np.eye(4)]))
        after = g(theta + case["learning_rate"] * central_difference(g, theta, step))
        if after > around + 1.0:  # the cap between them: the first update reaches it
            cap = float(facts.MAX_EPISODE_STEPS)
            case["objective"]["c"] += cap - float(rng.uniform(around, after - 0.5))
            case["objective"]["cap"] = cap
            return case


def central_difference(g, theta, step):
    eye = np.eye(len(theta))
    return np.array([(g(theta + step * e) - g(theta - step * e)) / (2 * step) for e in eye])


def _training_shape(args, values):
    iterations = args["iterations"]
    history, rewards = values["params_history"], values["rewards"]
    if history.shape != (iterations + 1, 4) or rewards.shape != (iterations + 1,):
        return f"params_history of shape {history.shape} and rewards of shape {rewards.shape}"
    return None


def _training_run(args, result, want, shape_want=None):
    """(values, None) of a training run that returned arrays of the right shapes, else (None, the
    Verdict that fails it: its error, or the shapes it returned against ``shape_want`` or ``want``)."""
    if result["status"] != "ok":
        return None, Verdict(False, want, result["error"])
    wrong_shape = _training_shape(args, result["values"])
    if wrong_shape:
        rewards = np.asarray(result["values"]["rewards"])
        early = rewards.ndim == 1 and 0 < len(rewards) < args["iterations"] + 1  # a loop left before its last update
        summary = f"expected {args['iterations']} updates, actual " + (f"{len(rewards) - 1} ({wrong_shape})" if early else wrong_shape)
        return None, Verdict(False, shape_want or want, wrong_shape, rule="stops_early" if early else "", summary=summary)
    return result["values"], None


def _rollouts_used(args, result, want):
    """None if every recorded evaluation asked for num_rollouts_per_eval episodes, else the Verdict
    that fails the run (the known mistake "other_rollouts" where one asked for another number)."""
    rollouts = result["records"]["evaluation_rollouts"]
    wrong = np.flatnonzero(rollouts != args["rollouts"])
    if len(rollouts) == 0:
        return Verdict(False, want, "eval_params was never called")
    if wrong.size:
        return Verdict(False, want, f"evaluation {int(wrong[0]) + 1} of {len(rollouts)} asked eval_params for "
                                    f"{int(rollouts[wrong[0]])} rollout(s); num_rollouts_per_eval is {args['rollouts']}",
                       rule="other_rollouts", summary=f"at evaluation {int(wrong[0]) + 1}: expected {args['rollouts']} "
                                                      f"rollouts (num_rollouts_per_eval), actual {int(rollouts[wrong[0]])}")
    return None


def _other_step(points, theta, step):
    """"other_step" (a known mistake) if the evaluations ``points`` around ``theta`` hold a central
    difference of another step than ``step`` (theta +- s e_i, s != step) and none of ``step``, else ""."""
    offsets = np.asarray(points, dtype=np.float64) - np.asarray(theta, dtype=np.float64)
    moved = ~np.isclose(offsets, 0.0, rtol=0.0, atol=1e-12)
    rows = np.flatnonzero(moved.sum(axis=1) == 1)  # evaluations that move one coordinate of theta
    axes = moved[rows].argmax(axis=1)
    sizes = offsets[rows, axes]
    steps = [size for axis, size in zip(axes, sizes)
             if size > 0 and np.any((axes == axis) & np.isclose(sizes, -size, rtol=1e-9, atol=0.0))]
    found = bool(steps) and not np.any(np.isclose(steps, step, rtol=1e-9, atol=0.0))
    return "other_step" if found else ""


def judge_known_steps(args, result, expected, services):
    want = (f"every iteration: g from eval_params with num_rollouts_per_eval = {args['rollouts']} rollouts, "
            "theta[t+1] = theta[t] + learning_rate * central-difference gradient of g at theta[t] with step "
            "fd_step, and rewards[t+1] = g(theta[t+1])")
    values, failed = _training_run(args, result, want, f"{args['iterations']} updates")
    if failed:
        return failed
    g = training_objective(args["objective"])
    history, rewards = values["params_history"], values["rewards"]
    if not _close(history[0], args["initial_params"], 0, 0):
        return Verdict(False, f"theta[0] = initial_params = {show(args['initial_params'])}", show(history[0]))
    wrong_rollouts = _rollouts_used(args, result, want)
    if wrong_rollouts:
        return wrong_rollouts
    for t in range(args["iterations"]):
        step = history[t] + args["learning_rate"] * central_difference(g, history[t], args["fd_step"])
        if not _close(history[t + 1], step, 1e-9, 1e-9):
            summary = difference_words(history[t + 1], step, UPDATE_TOLERANCE, args,
                                       lambda _, index: f"theta[{t + 1}][{index[0]}]")[2]
            return Verdict(False, f"theta[{t + 1}] = {show(step)} (step fd_step = {show(args['fd_step'])})",
                           f"theta[{t + 1}] = {show(history[t + 1])}",
                           rule=_other_step(result["records"]["evaluation_params"], history[t], args["fd_step"]),
                           summary=summary)
        if not _close(rewards[t + 1], g(history[t + 1]), 1e-9, 1e-9):
            return Verdict(False, f"rewards[{t + 1}] = g(theta[{t + 1}]) = {show(g(history[t + 1]))}, the reward "
                                  "after the update", f"rewards[{t + 1}] = {show(rewards[t + 1])}",
                           summary=f"at rewards[{t + 1}]: expected g(theta[{t + 1}]) = {show(g(history[t + 1]))}, "
                                   f"actual {show(rewards[t + 1])}")
    if not _close(values["final_params"], history[-1], 0, 0):
        return Verdict(False, f"the returned policy has theta[{args['iterations']}]", show(values["final_params"]))
    return Verdict(True)


def judge_known_rewards(args, result, expected, services):
    want = "rewards[t] = g(theta[t]) after every update"
    values, failed = _training_run(args, result, want)
    if failed:
        return failed
    g = training_objective(args["objective"])
    wanted = np.array([g(theta) for theta in values["params_history"]])
    passed, _, summary = difference_words(values["rewards"], wanted, UPDATE_TOLERANCE, args,
                                          lambda _, index: f"rewards[{index[0]}]")
    return Verdict(passed, show(wanted), show(values["rewards"]), summary=summary)


def make_real_training(rng, variant):
    # Rates that do not converge on the notebook's run: the inputs shown to students give no 1.3.3 answer away.
    # A step other than the settings' 0.5, so that a run that ignores fd_step shows.
    return {"iterations": 2, "rollouts": 3, "learning_rate": float((0.0003, 0.0002)[variant % 2]),
            "fd_step": 0.35, "seed": int(rng.integers(0, 1000)), "initial_params": rng.normal(size=4) * 0.05}


UPDATE_TOLERANCE = Tolerance(1e-9, 1e-9)  # an update equation (4) gives from the run's own evaluations
MAX_JUDGED_EVALUATIONS = 2_000  # recorded evaluations a real run's judge reads (an honest run of 2 iterations makes 18)


def _at(points, target):
    """The indices (ascending) of the rows of ``points`` equal to ``target`` within 1e-12 (one pass)."""
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    return np.flatnonzero(np.all(np.isclose(points, np.asarray(target, dtype=np.float64), rtol=1e-12, atol=1e-12),
                                 axis=1))


def _first_by_seed(indices, seeds, scores):
    """{seed: {score: the first index with it}} of the evaluations ``indices`` (ascending)."""
    found = {}
    for index in indices.tolist():
        found.setdefault(int(seeds[index]), {}).setdefault(float(scores[index]), index)
    return found


def judge_real_rewards(args, result, expected, services):
    want = (f"every update: theta[t] = theta[t-1] + learning_rate * (g(theta + h e_i) - g(theta - h e_i)) / 2h "
            f"with h = fd_step = {show(args['fd_step'])}, g from eval_params with {args['rollouts']} rollouts "
            "(both of one seed), and rewards[t] = eval_params of theta[t] after the update")
    values, failed = _training_run(args, result, want)
    if failed:
        return failed
    history, rewards, records = values["params_history"], values["rewards"], result["records"]
    if not _close(values["final_params"], history[-1], 0, 0):
        return Verdict(False, "the returned policy has the last parameters", show(values["final_params"]))
    wrong_rollouts = _rollouts_used(args, result, want)
    if wrong_rollouts:
        return wrong_rollouts
    points, seeds, scores = records["evaluation_params"], records["evaluation_seeds"], records["evaluation_values"]
    if len(points) > MAX_JUDGED_EVALUATIONS:
        return Verdict(False, want, f"{len(points)} evaluations of eval_params in {len(rewards) - 1} iteration(s), more "
                                    f"than the {MAX_JUDGED_EVALUATIONS} this check reads")
    h, rate = args["fd_step"], args["learning_rate"]
    for t in range(1, len(rewards)):
        latest = -1
        for i in range(4):
            offset = np.zeros(4)
            offset[i] = h
            # A pair (a at theta + h e_i, b at theta - h e_i, one seed) is good when its difference gives
            # theta[t][i]; the judge needs the good pair whose later evaluation comes first. Evaluations
            # of one seed with one score are the same for it: the first of each is enough (linear time).
            plus = _first_by_seed(_at(points, history[t - 1] + offset), seeds, scores)
            minus = _first_by_seed(_at(points, history[t - 1] - offset), seeds, scores)
            first_pair, best = None, None
            for seed, by_score in plus.items():
                if seed not in minus:
                    continue
                b_scores = np.array(list(minus[seed]), dtype=np.float64)
                b_first = np.array(list(minus[seed].values()), dtype=np.int64)
                for a_score, a in by_score.items():
                    if first_pair is None or (a, int(b_first.min())) < first_pair:
                        first_pair = (a, int(b_first.min()), a_score, float(b_scores[np.argmin(b_first)]))
                    moved = history[t - 1][i] + rate * ((a_score - b_scores) / (2.0 * h))
                    good = np.flatnonzero(np.abs(history[t][i] - moved) <= UPDATE_TOLERANCE.limits(moved, None))
                    if good.size:
                        later = int(np.min(np.maximum(a, b_first[good])))
                        best = later if best is None else min(best, later)
            if best is None:
                return dataclasses.replace(_update_off(args, history, t, i, first_pair),
                                           rule=_other_step(points, history[t - 1], h))
            latest = max(latest, best)
        after = [index for index in _at(points, history[t]).tolist() if index > latest and scores[index] == rewards[t]]
        if not after:
            return Verdict(False, want, f"rewards[{t}] = {show(rewards[t])} is no evaluation of theta[{t}] made after "
                                        "its update", summary=f"at rewards[{t}]: expected eval_params of theta[{t}] after "
                                                              f"update {t}, actual {show(rewards[t])}, no such evaluation")
    return Verdict(True)


def _update_off(args, history, t, i, pair):
    """The Verdict of a real run whose update t equation (4) does not give in coordinate i from the run's
    own evaluations: ``pair`` (a, b, g(theta + h e_i), g(theta - h e_i)) is the first pair of them at
    theta[t-1] +- h e_i with one seed, or None. Only the run's numbers: what it evaluated and returned."""
    h, rate, before, actual = args["fd_step"], args["learning_rate"], history[t - 1][i], history[t][i]
    where = f"theta[{t - 1}] + h e_{i} and theta[{t - 1}] - h e_{i} (h = fd_step = {show(h)})"
    if pair is None:
        return Verdict(False, f"theta[{t}][{i}] from equation (4) with eval_params at {where}, both with one seed",
                       f"theta[{t}][{i}] = {show(actual)}, and eval_params was not called at both with one seed",
                       summary=f"at theta[{t}][{i}]: expected an update from eval_params at theta[{t - 1}] +- h e_{i}, "
                               "actual: no such pair of evaluations with one seed")
    wanted = before + rate * (pair[2] - pair[3]) / (2.0 * h)
    expected = (f"theta[{t}][{i}] = theta[{t - 1}][{i}] + learning_rate * (g+ - g-) / (2 h) = {show(before)} + "
                f"{show(rate)} * ({show(pair[2])} - {show(pair[3])}) / {show(2.0 * h)} = {show(wanted)}, "
                f"with g+ and g- your eval_params at {where}")
    _, difference, summary = difference_words(actual, wanted, UPDATE_TOLERANCE, args,
                                              lambda *_: f"theta[{t}][{i}] in update {t}")
    return Verdict(False, expected, f"theta[{t}][{i}] = {show(actual)}", difference, UPDATE_TOLERANCE.words(),
                   summary=summary)


TODO_1_3_2 = (
    Behaviour("1.3.2", "equation-4", "theta += learning_rate * central-difference gradient of g with step fd_step, every iteration",
              "on a known smooth objective g standing in for eval_params (with a quartic "
              "term, so the step matters), every iteration evaluates g with num_rollouts_per_eval rollouts, takes "
              "the step of equation (4), theta <- theta + learning_rate * (central-difference gradient of g with "
              "step fd_step), and records g of the new parameters", "train_known", make_known_training,
              judge_known_steps, value=True),
    Behaviour("1.3.2", "records-reward", "rewards[t] is g of the parameters after update t",
              "on the same objective, rewards[t] is g of the parameters after update t",
              "train_known", make_known_training, judge_known_rewards, judged_on="equation-4", value=True),
    Behaviour("1.3.2", "real-run", "in a real run, every update is equation (4) from your own eval_params calls",
              "in a short real CartPole run, every update is equation (4) with central "
              "differences of step fd_step from eval_params calls with num_rollouts_per_eval episodes, and "
              "rewards[t] is eval_params of the parameters after update t (on the grader's records of every "
              "evaluation)", "train_real", make_real_training, judge_real_rewards, visible_count=1, value=True),
)
REBUILT["train_known"] = ("kwargs, g", "train_cartpole_policy(**kwargs) with g(p) as each eval_params(p, ...)")
REBUILT["train_real"] = ("kwargs", "train_cartpole_policy(**kwargs)")


# --------------------------------------------------------------------------------------------
# 1.3.3 the learning rate: the notebook's run, with the reference's training code. Probe
# settings_value: settings.LEARNING_RATE; the service train_notebook (run by the reference server).
# --------------------------------------------------------------------------------------------


def make_learning_rate(rng, variant):
    return {"name": "LEARNING_RATE"}


def _learning_rate_services(args, result):
    if result["status"] != "ok":
        return []
    value = float(result["values"]["value"])
    if not np.isfinite(value) or value <= 0:
        return []
    return [("train_notebook", {"learning_rate": value})]


def converged_at(rewards, max_reward):
    """The first t from which every reward is the maximum (t counts updates), or None."""
    below = np.flatnonzero(np.asarray(rewards) < max_reward)
    first = 0 if below.size == 0 else int(below[-1]) + 1
    return first if first < len(rewards) else None


def judge_learning_rate(args, result, expected, services):
    want = f"training converges within {facts.settings.CONVERGENCE_DEADLINE} iterations: reward {facts.MAX_EPISODE_STEPS} from then on"
    if result["status"] != "ok":
        return Verdict(False, want, result["error"])
    value = float(result["values"]["value"])
    if not np.isfinite(value) or value <= 0:
        return Verdict(False, want, f"LEARNING_RATE = {show(value)} is not a number > 0")
    if not services or services[0]["status"] != "ok":
        return Verdict(False, want, f"the training run with LEARNING_RATE = {show(value)} failed: "
                                    f"{services[0]['error'] if services else 'not run'}")
    run = services[0]["values"]
    deadline, top = int(run["deadline"]), float(run["max_reward"])
    want = f"training converges within {deadline} iterations: reward {show(top)} from then on"
    at = converged_at(run["rewards"], top)
    actual = f"LEARNING_RATE = {show(value)}: rewards {show(run['rewards'], 25)}; " + \
        (f"converged at iteration {at}" if at is not None else "never converged")
    passed = at is not None and at <= deadline
    summary = f"expected reward {show(top)} from iteration {deadline} on, actual " + \
        (f"from iteration {at}" if at is not None else f"never (best {show(np.max(run['rewards']))})") + \
        f" with LEARNING_RATE = {show(value)}"
    return Verdict(passed, want, actual, rule="" if passed else _learning_rate_rule(run["rewards"], top, at),
                   summary=summary)


def _learning_rate_rule(rewards, top, at):
    """The known mistake a run that does not converge in time shows: "overshoots" (a reward falls
    below half the best one before it: a step too far), "too_slow" (no such fall, and it ends
    higher than it started: still climbing, or converged too late), or none."""
    rewards = np.asarray(rewards, dtype=np.float64)
    if np.any(rewards < 0.5 * np.maximum.accumulate(rewards)):
        return "overshoots"
    return "too_slow" if at is not None or rewards[-1] > rewards[0] else ""


TODO_1_3_3 = (
    Behaviour("1.3.3", "converges", "the notebook's training run converges in time with your LEARNING_RATE",
              "with your LEARNING_RATE, the notebook's training run (settings.TRAINING_SEED, "
              f"from zeros; the note says whose training code it ran) reaches reward {facts.MAX_EPISODE_STEPS} within "
              f"{facts.settings.CONVERGENCE_DEADLINE} iterations and "
              "stays there", "settings_value", make_learning_rate, judge_learning_rate, visible_count=1,
              services=_learning_rate_services, value=True),
)
REBUILT["settings_value"] = None  # a setting: nothing to rebuild


BEHAVIOURS = TODO_1_1_1 + TODO_1_2_1 + TODO_1_3_1 + TODO_1_3_2 + TODO_1_3_3
