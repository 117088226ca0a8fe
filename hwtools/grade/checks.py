"""What the grader checks for each TODO, on which inputs, and how an answer is judged.

Each TODO's points ride on a few *behaviours* (``Behaviour``): one thing the handout asks,
described in words, worth some points, tested on visible inputs (made here, with a public seed;
students see them and the answer key holds their expected values) and on hidden inputs (made by
``instructor/hidden_checks`` with the instructor's own seed). A behaviour earns its points only
when every one of its inputs passes, visible and hidden, so an answer written for the visible
inputs earns nothing.

Two kinds of judging:

* **exact**, where the handout fixes the computation (eq. (1), eq. (3), the sigmoid, eq. (8), ...):
  the student's values must equal the reference solution's on the same input, within float
  tolerance;
* **by property**, where it does not (which start states ``eval_params`` plays, how the training
  loop is written): the property the handout asks for is checked, with the reference re-scoring
  what the student's code produced (``SERVICES``).

Checks that any code passes (the door checks, shapes made by given code) carry no points.
Standard library and numpy only; the worker module is imported for its pure helper functions.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hwtools.grade.probes import training_objective

PUBLIC_SEED = 20_240_131  # the visible inputs' seed: students may know it

# The other TODOs whose functions each TODO's check calls. No kit a student's code runs in holds
# their code: the worker's copies are proxies that the reference server answers (``served.py``).
NEEDS = {
    "1.1.1": (),
    "1.2.1": (),
    "1.3.1": ("1.1.1",),
    "1.3.2": ("1.1.1", "1.2.1", "1.3.1"),
    "1.3.3": (),  # only hwlib/settings.py is run with the student's block; the reference server trains
    "2.1.1": ("2.2.1",),
    "2.2.1": (),
    "2.2.2": ("2.2.1",),
    "2.2.3": ("2.1.1", "2.2.1"),
    "2.3.1": ("2.1.1", "2.2.1", "2.2.2", "2.2.3"),
}
SETTINGS_ONLY = {"1.3.3": ("hwlib/settings.py",)}  # TODOs whose kit holds only these files


@dataclass(frozen=True)
class Verdict:
    passed: bool
    expected: str = ""
    actual: str = ""


@dataclass(frozen=True)
class Behaviour:
    """One graded behaviour of a TODO."""

    todo: str
    key: str
    points: float
    description: str
    probe: str
    make: object  # make(rng, variant) -> the arguments of one case
    judge: object  # judge(args, result, expected_values, services) -> Verdict
    visible_count: int = 2
    services: object = None  # services(args, result) -> [(probe, args)]: reference runs the judge needs
    exact: bool = False  # judged against the reference's values on the same input
    judged_on: str = ""  # the key of another behaviour of the TODO whose cases this one judges (it has none of its own)

    @property
    def id(self):
        return f"{self.todo}/{self.key}"

    def visible_cases(self):
        rng = np.random.default_rng([PUBLIC_SEED, _number(self.id)])
        return [self.make(rng, variant) for variant in range(self.visible_count)]


def _number(text):
    return int.from_bytes(text.encode(), "little") % (2**63)


# --------------------------------------------------------------------------------------------
# Showing values
# --------------------------------------------------------------------------------------------


def show(value, limit=12):
    """A short text of ``value`` for feedback: at most ``limit`` numbers, 6 significant digits."""
    if isinstance(value, dict):
        return ", ".join(f"{key}={show(item, limit)}" for key, item in value.items())
    if isinstance(value, (list, tuple)) and not all(isinstance(item, (int, float, bool)) for item in value):
        return "[" + ", ".join(show(item, limit) for item in value) + "]"
    if isinstance(value, str):
        return value
    array = np.asarray(value)
    if array.dtype.kind not in "biuf":
        return f"<{type(value).__name__}>"
    if array.ndim == 0:
        return np.format_float_positional(array.item(), precision=6, unique=True, trim="-") \
            if array.dtype.kind == "f" else str(array.item())
    text = np.array2string(array.ravel()[:limit], precision=6, separator=", ", max_line_width=10_000)
    more = f" ... ({array.size} values)" if array.size > limit else ""
    shape = f" shape {array.shape}" if array.ndim > 1 else ""
    return text + more + shape


def _close(actual, expected, rtol, atol):
    actual, expected = np.asarray(actual, dtype=np.float64), np.asarray(expected, dtype=np.float64)
    return actual.shape == expected.shape and bool(np.all(np.isfinite(actual))) and \
        bool(np.allclose(actual, expected, rtol=rtol, atol=atol))


def exact(name, rtol=1e-9, atol=1e-12):
    """A judge: value ``name`` equals the reference's (same shape, within tolerance, finite)."""

    def judge(args, result, expected, services):
        if result["status"] != "ok":
            return Verdict(False, show(expected[name]), result["error"])
        actual = result["values"][name]
        return Verdict(_close(actual, expected[name], rtol, atol), show(expected[name]), show(actual))

    return judge


# --------------------------------------------------------------------------------------------
# 1.1.1 the linear policy
# --------------------------------------------------------------------------------------------


def make_policy_states(rng, variant):
    count = 30
    params = rng.normal(size=(count, 4))
    obs = rng.normal(size=(count, 4)) * np.array([1.0, 1.0, 0.1, 1.0])
    return {"params": params, "obs": obs}


def make_policy_ties(rng, variant):
    """Integer parameters and states, so that every score is exact: four ties at 0, two of each sign."""
    rows, want = [], {0: 4, 1: 2, -1: 2}
    while any(want.values()):
        params = rng.integers(-3, 4, size=4).astype(np.float64)
        obs = rng.integers(-3, 4, size=4).astype(np.float64)
        sign = int(np.sign(params @ obs))
        if want[sign]:
            want[sign] -= 1
            rows.append((params, obs))
    order = rng.permutation(len(rows))
    return {"params": np.array([rows[i][0] for i in order]), "obs": np.array([rows[i][1] for i in order])}


# --------------------------------------------------------------------------------------------
# 1.2.1 central differences
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


# --------------------------------------------------------------------------------------------
# 1.3.1 eval_params, judged by property on the grader's own records of the episodes it played
# --------------------------------------------------------------------------------------------
# The worker's run_policy forwards every episode to the trusted side, which plays it with the
# reference (with a seed of the grader's choosing when the call gave none) and records it; the
# probe calls eval_params twice with the same arguments. ``result["records"]`` holds, in order,
# every episode (params, seed, seeded, reward): nothing the student's process says about them.


def make_eval_case(rng, variant):
    return {"params": rng.uniform(-1.0, 1.0, 4) * np.array([0.3, 1.0, 1.0, 1.0]),
            "num_rollouts": int((3, 4, 1, 6)[variant % 4]), "seed": int(rng.integers(0, 5_000))}


def _eval_episodes(args, result):
    """(params, seeds, seeded, rewards) of the run_policy episodes of the case, or the Verdict's
    actual text when there are not num_rollouts of them for each of the two calls."""
    records, count = result["records"], args["num_rollouts"]
    direct = records["episode_direct"]
    params, seeds = records["episode_params"][direct], records["episode_seeds"][direct]
    seeded, rewards = records["episode_seeded"][direct], records["episode_rewards"][direct]
    if len(seeds) != 2 * count:
        return None, (f"{len(seeds)} episode(s) played with run_policy in two calls of eval_params with "
                      f"num_rollouts={count}")
    return (params, seeds, seeded, rewards), None


def _shown_seeds(seeds, seeded):
    return "[" + ", ".join(str(int(s)) if flag else "unseeded" for s, flag in zip(seeds, seeded)) + "]"


def judge_eval_mean(args, result, expected, services):
    count = args["num_rollouts"]
    want = f"the mean of {count} episode reward(s) of params {show(args['params'])}, each from its own start state"
    if result["status"] != "ok":
        return Verdict(False, want, result["error"])
    episodes, problem = _eval_episodes(args, result)
    if problem:
        return Verdict(False, want, f"{problem}, returned {show(result['values']['value'])}")
    params, seeds, seeded, rewards = (part[:count] for part in episodes)
    if not np.array_equal(params, np.repeat(np.asarray(args["params"], dtype=np.float64)[None, :], count, axis=0)):
        return Verdict(False, want, f"episodes played with other parameters: {show(params)}")
    if len(set(seeds.tolist())) != count:
        return Verdict(False, want, f"episodes from the same start state: seeds {_shown_seeds(seeds, seeded)}")
    mean = float(np.mean(rewards))
    value = result["values"]["value"]
    return Verdict(_close(value, mean, 1e-9, 1e-9), f"{want}: {show(mean)} (rewards {show(rewards)})", show(value))


def judge_eval_distinct(args, result, expected, services):
    count = args["num_rollouts"]
    want = f"{count} episodes from {count} different seeds"
    if result["status"] != "ok":
        return Verdict(False, want, result["error"])
    episodes, problem = _eval_episodes(args, result)
    if problem:
        return Verdict(False, want, problem)
    seeds, seeded = episodes[1][:count], episodes[2][:count]
    return Verdict(len(set(seeds.tolist())) == count, want, f"seeds {_shown_seeds(seeds, seeded)}")


def judge_eval_repeat(args, result, expected, services):
    if result["status"] != "ok":
        return Verdict(False, "the same number twice", result["error"])
    values, records = result["values"], result["records"]
    flags = records["episode_seeded"][records["episode_direct"]]
    seeded = len(flags) > 0 and bool(np.all(flags))
    same = _close(values["value_again"], values["value"], 0, 0)
    actual = f"{show(values['value'])}, then {show(values['value_again'])}"
    if not seeded:
        actual += " (run_policy was called without a seed: a random start state each time)"
    return Verdict(seeded and same, "the same number twice", actual)


# --------------------------------------------------------------------------------------------
# 1.3.2 the training loop: a known objective, and a real run, on the grader's records
# --------------------------------------------------------------------------------------------
# In ``train_known`` cases every eval_params call is answered by the grader with the case's known
# objective g (a quartic, so that central differences depend on the step) and recorded with its
# rollouts and seed; in ``train_real`` cases the reference server answers it and the grader
# records the same, with the reference's value. The judges read these records.


def make_known_training(rng, variant):
    basis = rng.normal(size=(4, 4))
    return {"objective": {"A": basis @ basis.T / 8.0 + 0.5 * np.eye(4), "m": rng.normal(size=4),
                          "q": rng.uniform(0.01, 0.05, size=4), "c": float(rng.uniform(100, 400))},
            "iterations": int(2 + variant), "rollouts": int((2, 3)[variant % 2]),
            "learning_rate": float((0.07, 0.12, 0.2)[variant % 3]), "fd_step": float((0.5, 0.25, 0.4)[variant % 3]),
            "seed": int(rng.integers(0, 100)), "initial_params": rng.normal(size=4) * 0.5}


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
        return None, Verdict(False, shape_want or want, wrong_shape)
    return result["values"], None


def _rollouts_used(args, result):
    """None if every recorded evaluation asked for num_rollouts_per_eval episodes, else the Verdict's actual."""
    rollouts = result["records"]["evaluation_rollouts"]
    wrong = np.flatnonzero(rollouts != args["rollouts"])
    if len(rollouts) == 0:
        return "eval_params was never called"
    if wrong.size:
        return (f"evaluation {int(wrong[0]) + 1} of {len(rollouts)} asked eval_params for {int(rollouts[wrong[0]])} "
                f"rollout(s); num_rollouts_per_eval is {args['rollouts']}")
    return None


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
    wrong_rollouts = _rollouts_used(args, result)
    if wrong_rollouts:
        return Verdict(False, want, wrong_rollouts)
    for t in range(args["iterations"]):
        step = history[t] + args["learning_rate"] * central_difference(g, history[t], args["fd_step"])
        if not _close(history[t + 1], step, 1e-9, 1e-9):
            return Verdict(False, f"theta[{t + 1}] = {show(step)} (step fd_step = {show(args['fd_step'])})",
                           f"theta[{t + 1}] = {show(history[t + 1])}")
        if not _close(rewards[t + 1], g(history[t + 1]), 1e-9, 1e-9):
            return Verdict(False, f"rewards[{t + 1}] = g(theta[{t + 1}]) = {show(g(history[t + 1]))}, the reward "
                                  "after the update", f"rewards[{t + 1}] = {show(rewards[t + 1])}")
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
    return Verdict(_close(values["rewards"], wanted, 1e-9, 1e-9), show(wanted), show(values["rewards"]))


def make_real_training(rng, variant):
    # Rates that do not converge on the notebook's run: the inputs shown to students give no 1.3.3 answer away.
    # A step other than the settings' 0.5, so that a run that ignores fd_step shows.
    return {"iterations": 2, "rollouts": 3, "learning_rate": float((0.0003, 0.0002)[variant % 2]),
            "fd_step": 0.35, "seed": int(rng.integers(0, 1000)), "initial_params": rng.normal(size=4) * 0.05}


def _at(points, target):
    return [index for index, point in enumerate(points) if np.allclose(point, target, rtol=1e-12, atol=1e-12)]


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
    wrong_rollouts = _rollouts_used(args, result)
    if wrong_rollouts:
        return Verdict(False, want, wrong_rollouts)
    points, seeds, scores = records["evaluation_params"], records["evaluation_seeds"], records["evaluation_values"]
    h, rate = args["fd_step"], args["learning_rate"]
    for t in range(1, len(rewards)):
        latest = -1
        for i in range(4):
            offset = np.zeros(4)
            offset[i] = h
            pairs = [(a, b) for a in _at(points, history[t - 1] + offset) for b in _at(points, history[t - 1] - offset)
                     if seeds[a] == seeds[b]]
            good = [(a, b) for a, b in pairs
                    if _close(history[t][i], history[t - 1][i] + rate * ((scores[a] - scores[b]) / (2.0 * h)), 1e-9, 1e-9)]
            if not good:
                found = "no evaluations at theta[t-1] +- h e_i" if not pairs else \
                    f"evaluations there give theta[{t}][{i}] = {show(history[t - 1][i] + rate * (scores[pairs[0][0]] - scores[pairs[0][1]]) / (2.0 * h))}"
                return Verdict(False, want, f"theta[{t}][{i}] = {show(history[t][i])}: {found}")
            latest = max(latest, min(max(pair) for pair in good))
        after = [index for index in _at(points, history[t]) if index > latest and scores[index] == rewards[t]]
        if not after:
            return Verdict(False, want, f"rewards[{t}] = {show(rewards[t])} is no evaluation of theta[{t}] made after "
                                        "its update")
    return Verdict(True)


# --------------------------------------------------------------------------------------------
# 1.3.3 the learning rate: the notebook's run, with the reference's training code
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
    want = "training converges within 7 iterations: reward 500 from then on"
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
    return Verdict(at is not None and at <= deadline, want, actual)


# --------------------------------------------------------------------------------------------
# Problem 2
# --------------------------------------------------------------------------------------------


def _two_class_data(rng, samples, features, scale=1.0):
    X = rng.normal(size=(samples, features)) * scale
    y = rng.integers(0, 2, size=samples)
    return X, y


def make_sigmoid_moderate(rng, variant):
    shape = ((9,), (3, 4), (2, 3, 2), ())[variant % 4]
    z = rng.uniform(-35, 35, size=shape)
    if variant == 0:
        z = np.concatenate([[0.0, 1.0, -1.0], z[3:]])
    return {"z": np.asarray(z)}


def make_sigmoid_tails(rng, variant):
    if variant == 0:
        return {"z": np.array([-1000.0, -745.0, -709.5, -100.0, -40.0, 40.0, 100.0, 709.5, 745.0, 1000.0])}
    return {"z": rng.uniform(50, 1000, size=(2, 5)) * rng.choice([-1.0, 1.0], size=(2, 5))}


def make_predict_prob(rng, variant, zero_bias=False):
    features = int(rng.integers(3, 6))
    X, _ = _two_class_data(rng, int(rng.integers(8, 15)), features)
    weights = rng.normal(size=features + 1)
    if zero_bias:
        weights[-1] = 0.0
    elif abs(weights[-1]) < 0.5:
        weights[-1] = 0.5 + weights[-1]
    return {"n_features": features, "weights": weights, "X": X}


def make_step(rng, variant, start="zero", steps=1):
    features = int(rng.integers(3, 6))
    X, y = _two_class_data(rng, int(rng.integers(15, 30)), features)
    weights = np.zeros(features + 1) if start == "zero" else rng.normal(size=features + 1) * 0.3
    return {"n_features": features, "weights": weights, "X": X, "y": y if variant % 2 == 0 else y.astype(np.float64),
            "learning_rate": float((0.05, 0.01)[variant % 2]), "steps": steps}


def make_one_vs_rest(rng, variant, iterations=1):
    features, classes = int(rng.integers(3, 5)), int((3, 4)[variant % 2])
    X = rng.normal(size=(40, features))
    y = np.concatenate([np.arange(classes), rng.integers(0, classes, size=40 - classes)])
    return {"n_features": features, "n_classes": classes, "X": X, "y": rng.permutation(y),
            "learning_rate": 0.05, "n_iters": iterations}


def make_ll_gradient(rng, variant):
    features = int(rng.integers(2, 5))
    X, y = _two_class_data(rng, 25, features)
    return {"weights": rng.normal(size=features + 1) * 0.5, "X": X, "y": y}


# --------------------------------------------------------------------------------------------
# The table
# --------------------------------------------------------------------------------------------

BEHAVIOURS = (
    Behaviour("1.1.1", "equation-1", 1.5, "policy(obs) is 1 exactly where params . obs < 0, else 0 (equation (1)), "
              "on random parameters and states", "policy_actions", make_policy_states, exact("actions", 0, 0),
              exact=True),
    Behaviour("1.1.1", "tie-at-zero", 0.5, "a score params . obs of exactly 0 gives action 0 (the < of equation (1)); "
              "scores just above and below 0 give 0 and 1", "policy_actions", make_policy_ties, exact("actions", 0, 0),
              visible_count=1, exact=True),
    Behaviour("1.2.1", "one-step", 5, "central differences, equation (3), with one step h for every coordinate (also "
              "for a single number x), on functions where a forward difference, or a point other than x, is off",
              "finite_diff", make_fd_uniform, exact("gradient", 1e-7, 1e-9), visible_count=3, exact=True),
    Behaviour("1.2.1", "step-per-coordinate", 5, "central differences with a different step h_i for each coordinate: "
              "only coordinate i moves, by +-h_i", "finite_diff", make_fd_steps, exact("gradient", 1e-7, 1e-9),
              exact=True),
    Behaviour("1.3.1", "mean-reward", 3, "eval_params returns the mean total reward of num_rollouts episodes of "
              "CartPoleLinearPolicy(params), each from its own start state, played with run_policy (every episode "
              "is played and recorded on the grader's side)", "eval_params", make_eval_case, judge_eval_mean,
              visible_count=3),
    Behaviour("1.3.1", "different-starts", 1, "the episodes of one evaluation start from different start states "
              "(no seed used twice)", "eval_params", make_eval_case, judge_eval_distinct, judged_on="mean-reward"),
    Behaviour("1.3.1", "repeatable", 1, "the same call gives the same number again: every episode is seeded from "
              "the seed argument", "eval_params", make_eval_case, judge_eval_repeat, judged_on="mean-reward"),
    Behaviour("1.3.2", "equation-4", 3, "on a known smooth objective g standing in for eval_params (with a quartic "
              "term, so the step matters), every iteration evaluates g with num_rollouts_per_eval rollouts, takes "
              "the step of equation (4), theta <- theta + learning_rate * (central-difference gradient of g with "
              "step fd_step), and records g of the new parameters", "train_known", make_known_training,
              judge_known_steps),
    Behaviour("1.3.2", "records-reward", 1, "on the same objective, rewards[t] is g of the parameters after update t",
              "train_known", make_known_training, judge_known_rewards, judged_on="equation-4"),
    Behaviour("1.3.2", "real-run", 1, "in a short real CartPole run, every update is equation (4) with central "
              "differences of step fd_step from eval_params calls with num_rollouts_per_eval episodes, and "
              "rewards[t] is eval_params of the parameters after update t (on the grader's records of every "
              "evaluation)", "train_real", make_real_training, judge_real_rewards, visible_count=1),
    Behaviour("1.3.3", "converges", 2, "with your LEARNING_RATE, the notebook's training run (the reference's "
              "training code, settings.TRAINING_SEED, from zeros) reaches reward 500 within 7 iterations and "
              "stays there", "settings_value", make_learning_rate, judge_learning_rate, visible_count=1,
              services=_learning_rate_services),
    Behaviour("2.1.1", "gradient", 0, "log_likelihood_gradient equals the summed gradient of equation (7) (shown "
              "for the grader of the derivation; no automatic points)", "ll_gradient", make_ll_gradient,
              exact("gradient", 1e-9, 1e-9), exact=True),
    Behaviour("2.2.1", "values", 1.5, "sigma(z) = 1 / (1 + e^(-z)) for every entry, within float tolerance, for "
              "|z| <= 35 and arrays of any shape", "sigmoid", make_sigmoid_moderate, exact("values", 1e-9, 1e-12),
              visible_count=4, exact=True),
    Behaviour("2.2.1", "tails", 0.5, "far out (|z| up to 1000) the values are 0 and 1 within tolerance, never NaN "
              "(warnings are not failures)", "sigmoid", make_sigmoid_tails, exact("values", 1e-9, 1e-12), exact=True),
    Behaviour("2.2.2", "with-bias", 2, "predict_prob gives sigma(w~ . [x, 1]) for each row: the constant 1 feature "
              "appended, the bias weight last", "predict_prob", make_predict_prob, exact("probabilities", 1e-9, 1e-12),
              exact=True),
    Behaviour("2.2.2", "zero-bias", 1, "with a zero bias weight, predict_prob gives sigma(w . x) for each row",
              "predict_prob", lambda rng, variant: make_predict_prob(rng, variant, zero_bias=True),
              exact("probabilities", 1e-9, 1e-12), exact=True),
    Behaviour("2.2.3", "from-zero", 1, "one step of equation (8) from zero weights: w~ += learning_rate * "
              "sum_i (y_i - sigma(w~ . x~_i)) x~_i, the summed gradient", "gradient_step", make_step,
              exact("weights", 1e-9, 1e-12), exact=True),
    Behaviour("2.2.3", "from-weights", 3, "one step of equation (8) from non-zero weights", "gradient_step",
              lambda rng, variant: make_step(rng, variant, start="random"), exact("weights", 1e-9, 1e-12), exact=True),
    Behaviour("2.2.3", "two-steps", 1, "two steps in a row: the second starts from the weights the first left in "
              "self.weights", "gradient_step", lambda rng, variant: make_step(rng, variant, start="random", steps=2),
              exact("weights", 1e-9, 1e-12), visible_count=1, exact=True),
    Behaviour("2.3.1", "one-vs-rest", 3, "one iteration of fit: classifier c takes one step of equation (8) on its "
              "one-vs-rest labels (1 for class c, 0 for every other class)", "one_vs_rest", make_one_vs_rest,
              exact("weights", 1e-9, 1e-12), exact=True),
    Behaviour("2.3.1", "every-iteration", 2, "several iterations: one step per class in every iteration",
              "one_vs_rest", lambda rng, variant: make_one_vs_rest(rng, variant, iterations=3),
              exact("weights", 1e-9, 1e-12), visible_count=1, exact=True),
)
BEHAVIOURS_BY_TODO = {}
for _behaviour in BEHAVIOURS:
    BEHAVIOURS_BY_TODO.setdefault(_behaviour.todo, []).append(_behaviour)
GRADED_TODOS = tuple(BEHAVIOURS_BY_TODO)


@dataclass
class CaseSet:
    """The cases of one TODO: ``visible`` and ``hidden`` lists of (case id, behaviour, args)."""

    todo: str
    visible: list = field(default_factory=list)
    hidden: list = field(default_factory=list)

    def requests(self):
        """The worker requests: visible cases first, the hidden ones only once those are answered."""
        phases = [self.visible] + ([self.hidden] if self.hidden else [])
        return [{"cases": [{"id": case_id, "probe": behaviour.probe, "args": args} for case_id, behaviour, args in phase]}
                for phase in phases]


def cases_of(behaviour):
    """The behaviour whose cases ``behaviour`` is judged on (itself, or the one it names)."""
    if not behaviour.judged_on:
        return behaviour
    return next(other for other in BEHAVIOURS_BY_TODO[behaviour.todo] if other.key == behaviour.judged_on)


def case_set(todo, hidden_module=None):
    cases = CaseSet(todo)
    for behaviour in BEHAVIOURS_BY_TODO[todo]:
        if behaviour.judged_on:
            continue  # judged on the cases of another behaviour
        for number, args in enumerate(behaviour.visible_cases()):
            cases.visible.append((f"{behaviour.id}/v{number}", behaviour, args))
        if hidden_module is not None:
            for number, args in enumerate(hidden_module.hidden_cases(behaviour)):
                cases.hidden.append((f"{behaviour.id}/h{number}", behaviour, args))
    return cases
