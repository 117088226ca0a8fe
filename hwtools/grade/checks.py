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

from hwtools.grade.worker import quadratic_objective

PUBLIC_SEED = 20_240_131  # the visible inputs' seed: students may know it

# What each TODO's check runs besides the student's block: those blocks keep the reference
# solution in the kit the worker gets; every other block is a stub.
NEEDS = {
    "1.1.1": (),
    "1.2.1": (),
    "1.3.1": ("1.1.1",),
    "1.3.2": ("1.1.1", "1.2.1", "1.3.1"),
    "1.3.3": (),  # only hwlib/settings.py is run with the student's block; training uses the reference
    "2.1.1": ("2.2.1",),
    "2.2.1": (),
    "2.2.2": ("2.2.1",),
    "2.2.3": ("2.1.1", "2.2.1"),
    "2.3.1": ("2.1.1", "2.2.1", "2.2.2", "2.2.3"),
}
SETTINGS_ONLY = {"1.3.3": ("hwlib/settings.py",)}  # TODOs whose kit holds only these files


@dataclass(frozen=True)
class Verdict:
    """What one input gave: passed or not, the expected and the actual value in short, and for an
    answer of numbers, where they first differ (``difference``, from ``difference_words``) and what
    counts as equal (``tolerance``, ``Tolerance.words``)."""

    passed: bool
    expected: str = ""
    actual: str = ""
    difference: str = ""
    tolerance: str = ""


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

    @property
    def id(self):
        return f"{self.todo}/{self.key}"

    def visible_cases(self):
        rng = np.random.default_rng([PUBLIC_SEED, _number(self.id)])
        return [self.make(rng, variant) for variant in range(self.visible_count)]


def _number(text):
    return int.from_bytes(text.encode(), "little") % (2**63)


# --------------------------------------------------------------------------------------------
# Showing values, and the words of a difference
# --------------------------------------------------------------------------------------------


def _number_text(number, digits=6):
    number = float(number)
    if number == 0 or not np.isfinite(number):
        return "0" if number == 0 else str(number)
    return f"{number:.{digits}g}"


def show(value, limit=12):
    """A short text of ``value`` for feedback: at most ``limit`` numbers, 6 significant digits each
    (so that 2.4e-11 reads 2.4e-11, never 0)."""
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
        return _number_text(array.item()) if array.dtype.kind == "f" else str(array.item())
    items = array.ravel()[:limit]
    texts = [_number_text(item) for item in items] if array.dtype.kind == "f" else [str(item) for item in items.tolist()]
    text = "[" + ", ".join(texts) + (", ...]" if array.size > limit else "]")
    more = f" ({array.size} values)" if array.size > limit else ""
    shape = f" shape {array.shape}" if array.ndim > 1 else ""
    return text + more + shape


def tell_apart(expected, actual):
    """``expected`` and ``actual`` as texts with as many significant digits (6 at least, 17 at
    most) as it takes for the two to read differently."""
    expected, actual = float(expected), float(actual)
    if all(np.isfinite(v) and v.is_integer() and abs(v) < 1e15 for v in (expected, actual)):
        return str(int(expected)), str(int(actual))
    for digits in range(6, 18):
        texts = _number_text(expected, digits), _number_text(actual, digits)
        if texts[0] != texts[1]:
            break
    return texts


@dataclass(frozen=True)
class Tolerance:
    """When an actual number counts as the expected one: |actual - expected| <= rtol * |expected| + atol,
    with ``loose_atol`` in place of ``atol`` where ``loose(args)`` (booleans shaped like the answer)
    holds. ``why`` says why these limits fit the computation; ``words()`` says it all."""

    rtol: float
    atol: float
    why: str = ""
    loose_atol: float = 0.0
    loose: object = None  # loose(args) -> booleans shaped like the answer: where loose_atol applies
    loose_words: str = ""

    def limits(self, expected, args):
        expected = np.asarray(expected, dtype=np.float64)
        atol = np.full(expected.shape, self.atol)
        if self.loose is not None:
            atol = np.where(np.asarray(self.loose(args), dtype=bool).reshape(expected.shape), self.loose_atol, atol)
        return self.rtol * np.abs(expected) + atol

    def words(self):
        if self.rtol == 0 and self.atol == 0:
            text = "exactly equal"
        elif self.rtol == 0:
            text = f"|actual - expected| <= {self.atol:g}"
        else:
            text = f"|actual - expected| <= {self.rtol:g} * |expected|" + (f" + {self.atol:g}" if self.atol else "")
        if self.loose is not None:
            text += f"; + {self.loose_atol:g} in place of + {self.atol:g} {self.loose_words}"
        return text + (f"; {self.why}" if self.why else "")


EXACTLY = Tolerance(0.0, 0.0)


def same_numbers(actual, expected):
    """(``actual`` arranged as ``expected``, None), or (None, why not). Right: the same shape, or,
    where the answer is one number or one row of N numbers, any N numbers in a row (a list, an
    array of shape (N,); (1,) or a bare number for a single one)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    if actual.shape == expected.shape:
        return actual, None
    if actual.size == expected.size and actual.ndim <= 1 and expected.ndim <= 1:
        return actual.reshape(expected.shape), None
    if actual.ndim <= 1 and expected.ndim <= 1:
        return None, f"{actual.size} number(s), where {expected.size} are expected"
    return None, f"an array of shape {actual.shape}, where shape {expected.shape} is expected"


def difference_words(actual, expected, tolerance=EXACTLY, args=None, locate=None):
    """(passed, words): whether ``actual`` equals ``expected`` within ``tolerance`` (every entry
    finite), and if not, where they first differ, in words: the index (with what ``locate(args,
    index)`` says about that entry's input), expected and actual with enough digits to tell them
    apart, the difference, absolute and relative, and how many entries differ. This is the one
    wording of a difference; every report (the preview, the grade, the class's feedback,
    Gradescope) shows it as the failure's ``difference``."""
    arranged, wrong_shape = same_numbers(actual, expected)
    if wrong_shape:
        return False, f"the answer is {wrong_shape}"
    actual = np.asarray(arranged, dtype=np.float64)
    expected = np.asarray(expected, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        bad = ~np.isfinite(actual) | ~(np.abs(actual - expected) <= tolerance.limits(expected, args))
    if not bad.any():
        return True, ""
    index = tuple(int(i) for i in np.unravel_index(int(np.flatnonzero(bad.ravel())[0]), expected.shape))
    want, got = float(expected[index]), float(actual[index])
    context = locate(args, index) if locate is not None and args is not None else ""
    head = f"first difference at index [{', '.join(map(str, index))}]" if index else "the value differs"
    head += f" ({context})" if context else ""
    want_text, got_text = tell_apart(want, got) if np.isfinite(got) else (tell_apart(want, want)[0], str(got))
    words = f"{head}: expected {want_text}, actual {got_text}"
    if np.isfinite(got) and not (tolerance == EXACTLY and want.is_integer() and got.is_integer()):
        gap = abs(got - want)
        words += f"; difference {gap:.3g}, " + (f"relative difference {gap / abs(want):.3g}" if want != 0 else
                                                 "relative difference undefined (the expected value is 0)")
    if expected.size > 1:
        words += f"; {int(bad.sum())} of {expected.size} entries differ"
    return False, words


def _close(actual, expected, rtol, atol):
    actual, expected = np.asarray(actual, dtype=np.float64), np.asarray(expected, dtype=np.float64)
    return actual.shape == expected.shape and bool(np.all(np.isfinite(actual))) and \
        bool(np.allclose(actual, expected, rtol=rtol, atol=atol))


def exact(name, tolerance=EXACTLY, locate=None):
    """A judge: value ``name`` equals the reference's within ``tolerance`` (``difference_words``)."""

    def judge(args, result, expected, services):
        want = expected[name]
        if result["status"] != "ok":
            return Verdict(False, show(want), result["error"])
        actual = result["values"][name]
        passed, words = difference_words(actual, want, tolerance, args, locate)
        return Verdict(passed, show(want), show(actual), words, "" if passed else tolerance.words())

    return judge


# --------------------------------------------------------------------------------------------
# 1.1.1 the linear policy
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


def make_policy_states(rng, variant):
    """Random parameters and states (pole angles as small as the pole's), and at random places among
    them four scores of exactly 0 (the tie of equation (1): action 0) and two just above and below."""
    count = 30
    params = rng.normal(size=(count, 4))
    obs = rng.normal(size=(count, 4)) * np.array([1.0, 1.0, 0.1, 1.0])
    rows = [(p, o) for p, o in zip(params, obs)] + _integer_rows(rng, {0: 4, 1: 2, -1: 2})
    order = rng.permutation(len(rows))
    return {"params": np.array([rows[i][0] for i in order]), "obs": np.array([rows[i][1] for i in order])}


def _policy_row(args, index):
    (row,) = index
    params, obs = np.asarray(args["params"][row]), np.asarray(args["obs"][row])
    return f"row {row}: params {show(params)}, obs {show(obs)}, params . obs = {_number_text(params @ obs)}"


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
                   f"({refused} of {len(accepted)} rows); int(...) makes it the int 0 or 1")


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


def _coordinate(args, index):
    if not index:
        return ""
    (i,) = index
    h = np.broadcast_to(np.asarray(args["h"], dtype=np.float64), np.shape(args["x"]))
    return f"coordinate {i}: x[{i}] = {_number_text(args['x'][i])}, h[{i}] = {_number_text(h[i])}"


# Central differences of the same f at the same points, computed in another order ((f+ - f-) / (2h)
# or f+ / (2h) - f- / (2h), 0.5 * ... / h): rounding of values of f up to about 30 over steps
# down to 0.01 differs by at most about 1e-12; a wrong formula (h for 2h, h/2 steps, a forward
# difference) by 1e-3 or more.
FD_TOLERANCE = Tolerance(1e-9, 1e-10, "rounding of the same differences in another order stays below 1e-12")


# --------------------------------------------------------------------------------------------
# 1.3.1 eval_params, judged by property and re-scored by the reference
# --------------------------------------------------------------------------------------------


def make_eval_case(rng, variant):
    return {"params": rng.uniform(-1.0, 1.0, 4) * np.array([0.3, 1.0, 1.0, 1.0]),
            "num_rollouts": int((3, 4, 1, 6)[variant % 4]), "seed": int(rng.integers(0, 5_000))}


def _episodes_services(args, result):
    if result["status"] != "ok" or int(result["values"]["episodes"]) != args["num_rollouts"]:
        return []  # judged without the reference; and a run that played thousands of episodes costs it nothing
    values = result["values"]
    return [("episode_rewards", {"params": values["episode_params"], "seeds": values["episode_seeds"]})]


def judge_eval_mean(args, result, expected, services):
    want = f"the mean of {args['num_rollouts']} episode reward(s) of params {show(args['params'])}"
    if result["status"] != "ok":
        return Verdict(False, want, result["error"])
    values = result["values"]
    played = int(values["episodes"])
    if played != args["num_rollouts"]:
        return Verdict(False, want, f"{played} episode(s) played with run_policy, returned {show(values['value'])}")
    if not np.array_equal(values["episode_params"], np.repeat(np.asarray(args["params"])[None, :], played, axis=0)):
        return Verdict(False, want, f"episodes played with other parameters: {show(values['episode_params'])}")
    rescored = services[0]["values"]["rewards"] if services and services[0]["status"] == "ok" else None
    if rescored is None:
        return Verdict(False, want, "the reference could not re-score the episodes")
    mean = float(np.mean(rescored))
    return Verdict(_close(values["value"], mean, 1e-9, 1e-9), f"{want}: {show(mean)}", show(values["value"]))


def judge_eval_distinct(args, result, expected, services):
    want = f"{args['num_rollouts']} episodes from {args['num_rollouts']} different seeds"
    if result["status"] != "ok":
        return Verdict(False, want, result["error"])
    seeds = result["values"]["episode_seeds"]
    return Verdict(len(seeds) == args["num_rollouts"] and len(set(seeds.tolist())) == len(seeds), want,
                   f"{len(seeds)} episode(s), seeds {show(seeds)}")


def judge_eval_repeat(args, result, expected, services):
    if result["status"] != "ok":
        return Verdict(False, "the same number twice", result["error"])
    values = result["values"]
    seeded = bool(np.all(values["episode_seeded"])) and len(values["episode_seeded"]) > 0
    same = _close(values["value_again"], values["value"], 0, 0)
    actual = f"{show(values['value'])}, then {show(values['value_again'])}"
    if not seeded:
        actual += " (run_policy was called without a seed: a random start state each time)"
    return Verdict(seeded and same, "the same number twice", actual)


# --------------------------------------------------------------------------------------------
# 1.3.2 the training loop: a known objective, and a real run re-scored
# --------------------------------------------------------------------------------------------


def make_known_training(rng, variant):
    basis = rng.normal(size=(4, 4))
    return {"objective": {"A": basis @ basis.T / 8.0 + 0.5 * np.eye(4), "m": rng.normal(size=4),
                          "c": float(rng.uniform(100, 400))},
            "iterations": int(3 + variant), "rollouts": 2, "learning_rate": float((0.07, 0.12, 0.2)[variant % 3]),
            "fd_step": float((0.5, 0.25, 0.4)[variant % 3]), "seed": int(rng.integers(0, 100)),
            "initial_params": rng.normal(size=4) * 0.5}


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


def judge_known_steps(args, result, expected, services):
    want = "theta[t+1] = theta[t] + learning_rate * central-difference gradient of g at theta[t]"
    values, failed = _training_run(args, result, want, f"{args['iterations']} updates")
    if failed:
        return failed
    g = quadratic_objective(args["objective"])
    history = values["params_history"]
    if not _close(history[0], args["initial_params"], 0, 0):
        return Verdict(False, f"theta[0] = initial_params = {show(args['initial_params'])}", show(history[0]))
    for t in range(args["iterations"]):
        step = history[t] + args["learning_rate"] * central_difference(g, history[t], args["fd_step"])
        if not _close(history[t + 1], step, 1e-9, 1e-9):
            return Verdict(False, f"theta[{t + 1}] = {show(step)}", f"theta[{t + 1}] = {show(history[t + 1])}")
    if not _close(values["final_params"], history[-1], 0, 0):
        return Verdict(False, f"the returned policy has theta[{args['iterations']}]", show(values["final_params"]))
    return Verdict(True)


def judge_known_rewards(args, result, expected, services):
    want = "rewards[t] = g(theta[t]) after every update"
    values, failed = _training_run(args, result, want)
    if failed:
        return failed
    g = quadratic_objective(args["objective"])
    wanted = np.array([g(theta) for theta in values["params_history"]])
    return Verdict(_close(values["rewards"], wanted, 1e-9, 1e-9), show(wanted), show(values["rewards"]))


def make_real_training(rng, variant):
    # Rates that do not converge on the notebook's run: the inputs shown to students give no 1.3.3 answer away.
    return {"iterations": 2, "rollouts": 3, "learning_rate": float((0.0003, 0.0002)[variant % 2]),
            "fd_step": 0.5, "seed": int(rng.integers(0, 1000)), "initial_params": rng.normal(size=4) * 0.05}


def _recorded_reward_calls(args, values):
    """For every update t >= 1, the recorded eval_params call at theta[t] with num_rollouts_per_eval
    episodes whose value is rewards[t]; None where there is none."""
    history, rewards = values["params_history"], values["rewards"]
    found = []
    for t in range(1, len(rewards)):
        match = None
        for index in range(len(values["call_values"])):
            if values["call_rollouts"][index] == args["rollouts"] and np.array_equal(values["call_params"][index], history[t]) \
                    and values["call_values"][index] == rewards[t]:
                match = index
                break
        found.append(match)
    return found


def _real_services(args, result):
    if result["status"] != "ok" or _training_shape(args, result["values"]):
        return []
    values = result["values"]
    calls = [index for index in _recorded_reward_calls(args, values) if index is not None]
    if not calls:
        return []
    return [("eval_many", {"params": values["call_params"][calls], "rollouts": values["call_rollouts"][calls],
                           "seeds": values["call_seeds"][calls]})]


def judge_real_rewards(args, result, expected, services):
    want = f"rewards[t] = eval_params(theta[t], {args['rollouts']} rollouts) after every update"
    values, failed = _training_run(args, result, want)
    if failed:
        return failed
    if not _close(values["final_params"], values["params_history"][-1], 0, 0):
        return Verdict(False, "the returned policy has the last parameters", show(values["final_params"]))
    calls = _recorded_reward_calls(args, values)
    for t, index in enumerate(calls, start=1):
        if index is None:
            return Verdict(False, want, f"rewards[{t}] = {show(values['rewards'][t])} is no evaluation of theta[{t}] "
                                        f"with {args['rollouts']} rollouts")
    rescored = services[0]["values"]["values"] if services and services[0]["status"] == "ok" else None
    if rescored is None or not _close(rescored, values["rewards"][1:], 0, 1e-9):
        return Verdict(False, want, f"the reference's score of theta[1:] is {show(rescored)}, "
                                    f"the run recorded {show(values['rewards'][1:])}")
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


# The sigmoid: float64 resolves values near 1 to 1.1e-16 only, and a correct formula other than
# the reference's (1 / (1 + e^-z), 0.5 (1 + tanh(z / 2)), clipping at +-500) is off by up to
# 2.2e-16 there, and by as much in absolute terms near 0 (tanh); so: 1e-12 relative, plus 1e-15
# absolute (about nine float64 steps below 1). Far out (|z| > 20), where sigma is within 2.1e-9
# of 0 or 1, the values check accepts 1e-8 (a sigmoid clipped at +-20 is a shortcut, not a wrong
# formula); the precision check asks for float64 precision there too.
SIGMOID_PRECISION = Tolerance(1e-12, 1e-15, "float64 resolves values near 1 to 1.1e-16; correct formulas agree "
                                            "to 2.2e-16")
SIGMOID_TOLERANCE = Tolerance(1e-12, 1e-15, SIGMOID_PRECISION.why, loose_atol=1e-8,
                              loose=lambda args: np.abs(np.asarray(args["z"])) > 20,
                              loose_words="where |z| > 20 (sigma is within 2.1e-9 of 0 or 1 there)")
FAR_Z = np.array([-1000.0, -745.0, -709.5, -100.0, -40.0, -24.4, 24.4, 40.0, 100.0, 709.5, 745.0, 1000.0])


def _sigmoid_entry(args, index):
    z = np.asarray(args["z"], dtype=np.float64)
    return f"z{list(index) if index else ''} = {_number_text(z[index] if index else z)}"


def make_sigmoid_values(rng, variant):
    """Rows of numbers from -1000 to 1000: 0 and +-1, moderate values, and far tails (where
    e^z overflows for z > 709 and e^-z for z < -709)."""
    z = np.concatenate([rng.uniform(-20, 20, size=8), rng.uniform(20, 1000, size=4) * rng.choice([-1.0, 1.0], size=4)])
    if variant == 0:  # the landmarks among drawn values (so that no hidden input repeats or reads as a visible one)
        return {"z": rng.permutation(np.concatenate([[0.0, 1.0, -1.0, 3.0, -3.0, 10.0, -10.0, 19.9, -19.9], FAR_Z, z]))}
    return {"z": rng.permutation(z)}


def make_sigmoid_shapes(rng, variant):
    """A single number, and arrays of 2 and 3 axes holding moderate and far values."""
    if variant == 0:
        return {"z": np.asarray(float(rng.uniform(-8, 8)))}
    shape = ((3, 4), (2, 3, 2))[(variant - 1) % 2]
    z = rng.uniform(-35, 35, size=shape)
    z.flat[: 2] = rng.uniform(710, 1000, size=2) * np.array([1.0, -1.0])
    return {"z": z}


def make_sigmoid_precision(rng, variant):
    """20 < |z| <= 50, where sigma is within 2.1e-9 of 0 or 1: sigma(-24.4) = 2.5e-11, not 0."""
    z = rng.uniform(20, 50, size=10) * rng.choice([-1.0, 1.0], size=10)
    if variant == 0:  # the landmarks among drawn values
        return {"z": rng.permutation(np.concatenate([[-24.4, 24.4, -20.5, 20.5, -30.0, 30.0, -37.0, 37.0, -50.0, 50.0], z]))}
    return {"z": z}


def make_predict_prob(rng, variant, zero_bias=False):
    features = int(rng.integers(3, 6))
    X, _ = _two_class_data(rng, int(rng.integers(8, 15)), features)
    weights = rng.normal(size=features + 1)
    if zero_bias:
        weights[-1] = 0.0
    elif abs(weights[-1]) < 0.5:
        weights[-1] = 0.5 + weights[-1]
    if variant == 2 and not zero_bias:  # far scores (hundreds): probabilities 0 and 1, never NaN
        weights = weights * 150.0
    return {"n_features": features, "weights": weights, "X": X}


def _sample_row(args, index):
    return f"row {index[0]} of X, x~ = [{show(np.asarray(args['X'])[index[0]])[1:-1]}, 1]"


# Probabilities sigma(w~ . x~): the score summed in another order (a loop, X @ w + b) differs by
# about 1e-15 relative; sigma passes it on, no larger. A missing or misplaced bias shifts them by 0.01 or more.
PROBABILITY_TOLERANCE = Tolerance(1e-10, 1e-15, "the score summed in another order differs by rounding, "
                                               "about 1e-15")


def make_step(rng, variant, start="zero", steps=1):
    features = int(rng.integers(3, 6))
    X, y = _two_class_data(rng, int(rng.integers(15, 30)), features)
    weights = np.zeros(features + 1) if start == "zero" else rng.normal(size=features + 1) * 0.3
    if start != "zero" and variant == 2:  # far scores: y - sigma is 0 or +-1, never NaN
        weights = weights * 400.0
    return {"n_features": features, "weights": weights, "X": X, "y": y if variant % 2 == 0 else y.astype(np.float64),
            "learning_rate": float((0.05, 0.01, 0.02)[variant % 3]), "steps": steps}


def _step_weight(args, index):
    step, j = index
    bias = " (the bias)" if j == int(args["n_features"]) else ""
    return f"weight {j}{bias} after step {step + 1}"


def make_one_vs_rest(rng, variant, iterations=1, start="zero"):
    features, classes = int(rng.integers(3, 5)), int((3, 4)[variant % 2])
    X = rng.normal(size=(40, features))
    y = np.concatenate([np.arange(classes), rng.integers(0, classes, size=40 - classes)])
    case = {"n_features": features, "n_classes": classes, "X": X, "y": rng.permutation(y),
            "learning_rate": 0.05, "n_iters": iterations}
    if start != "zero":
        case["initial_weights"] = rng.normal(size=(classes, features + 1)) * 0.3
    return case


def make_iterations(rng, variant):
    """2 to 4 iterations, from zero weights and from weights a fit before left."""
    return make_one_vs_rest(rng, variant, iterations=(3, 2, 4)[variant % 3], start=("zero", "given")[variant % 2])


def _class_weight(args, index):
    c, j = index
    bias = " (the bias)" if j == int(args["n_features"]) else ""
    return f"classifier {c}, weight {j}{bias}"


def make_ll_gradient(rng, variant):
    features = int(rng.integers(2, 5))
    X, y = _two_class_data(rng, 25, features)
    weights = rng.normal(size=features + 1) * 0.5
    if variant == 1:  # far scores: sigma is 0 or 1 there, never NaN
        weights = weights * 300.0
    return {"weights": weights, "X": X, "y": y}


def _gradient_entry(args, index):
    (j,) = index
    bias = " (the bias)" if j == len(args["weights"]) - 1 else ""
    return f"entry {j}{bias}"


# Weights after steps of eq. (8): sums over up to 30 samples in another order (a loop, a matrix
# product) differ by about 1e-15; the mean for the sum, a sign or a missed step by 1e-3 or more.
STEP_TOLERANCE = Tolerance(1e-9, 1e-12, "sums over the samples in another order differ by rounding, about 1e-15")


# --------------------------------------------------------------------------------------------
# The table
# --------------------------------------------------------------------------------------------

BEHAVIOURS = (
    Behaviour("1.1.1", "equation-1", 1.5, "policy(obs) is 1 exactly where params . obs < 0, else 0 (equation (1)): on "
              "random parameters and states, and on scores of exactly 0 (the tie: action 0, the < is strict) and "
              "just above and below 0, mixed in among them", "policy_choices", make_policy_states,
              exact("actions", EXACTLY, _policy_row), exact=True),
    Behaviour("1.1.1", "env-action", 0.5, "the right actions, each one env.step takes: the int 0 or 1 (a Python bool "
              "or a numpy integer works too; a float or a numpy bool does not)", "policy_choices", make_policy_states,
              judge_env_actions, visible_count=1, exact=True),
    Behaviour("1.2.1", "equation-3", 7, "central differences, equation (3), with a different step h_i for each "
              "coordinate: only coordinate i moves, by +-h_i, and the difference is divided by 2 h_i; on functions "
              "where a forward difference, or a point other than x, is off (the answer: N numbers, shaped like x "
              "or in a list)", "finite_diff", make_fd_steps, exact("gradient", FD_TOLERANCE, _coordinate),
              exact=True),
    Behaviour("1.2.1", "one-step", 3, "central differences with one step h for every coordinate (h a number or "
              "equal steps), also for a single number x (a number or one number in a list or array)",
              "finite_diff", make_fd_uniform, exact("gradient", FD_TOLERANCE, _coordinate), visible_count=3,
              exact=True),
    Behaviour("1.3.1", "mean-reward", 3, "eval_params returns the mean total reward of num_rollouts episodes of "
              "CartPoleLinearPolicy(params) played with run_policy (each episode re-scored by the reference)",
              "eval_params", make_eval_case, judge_eval_mean, visible_count=3, services=_episodes_services),
    Behaviour("1.3.1", "different-starts", 1, "the episodes of one evaluation start from different start states "
              "(no seed used twice)", "eval_params", make_eval_case, judge_eval_distinct, visible_count=2),
    Behaviour("1.3.1", "repeatable", 1, "the same call gives the same number again: every episode is seeded from "
              "the seed argument", "eval_params", make_eval_case, judge_eval_repeat, visible_count=2),
    Behaviour("1.3.2", "equation-4", 3, "on a known smooth objective g standing in for eval_params, every iteration "
              "takes the step of equation (4): theta <- theta + learning_rate * (central-difference gradient of g)",
              "train_known", make_known_training, judge_known_steps),
    Behaviour("1.3.2", "records-reward", 1, "on the same objective, rewards[t] is g of the parameters after update t",
              "train_known", make_known_training, judge_known_rewards),
    Behaviour("1.3.2", "real-run", 1, "in a short real CartPole run, rewards[t] is eval_params of the parameters "
              "after update t with num_rollouts_per_eval episodes (re-scored by the reference)",
              "train_real", make_real_training, judge_real_rewards, visible_count=1, services=_real_services),
    Behaviour("1.3.3", "converges", 2, "with your LEARNING_RATE, the notebook's training run (the reference's "
              "training code, settings.TRAINING_SEED, from zeros) reaches reward 500 within 7 iterations and "
              "stays there", "settings_value", make_learning_rate, judge_learning_rate, visible_count=1,
              services=_learning_rate_services),
    Behaviour("2.1.1", "gradient", 0, "log_likelihood_gradient equals the summed gradient of equation (7), also "
              "where scores are in the hundreds (shown for the grader of the derivation; no automatic points)",
              "ll_gradient", make_ll_gradient, exact("gradient", STEP_TOLERANCE, _gradient_entry), exact=True),
    Behaviour("2.2.1", "values", 1.2, "sigma(z) = 1 / (1 + e^(-z)) for every entry of a row of numbers from -1000 to "
              "1000: 0, +-1, moderate values and far tails, where the values are 0 and 1 and never NaN (warnings are "
              "not failures)", "sigmoid", make_sigmoid_values, exact("values", SIGMOID_TOLERANCE, _sigmoid_entry),
              visible_count=3, exact=True),
    Behaviour("2.2.1", "any-shape", 0.3, "the same for a single number and for arrays of 2 and 3 axes: values shaped "
              "like z", "sigmoid", make_sigmoid_shapes, exact("values", SIGMOID_TOLERANCE, _sigmoid_entry),
              visible_count=3, exact=True),
    Behaviour("2.2.1", "precision", 0.5, "float64 precision where sigma is close to 0 or 1 (20 < |z| <= 50): "
              "sigma(-24.4) = 2.5e-11, not 0, and sigma(24.4) = 1 - 2.5e-11", "sigmoid", make_sigmoid_precision,
              exact("values", SIGMOID_PRECISION, _sigmoid_entry), exact=True),
    Behaviour("2.2.2", "with-bias", 2.5, "predict_prob gives sigma(w~ . [x, 1]) for each row: the constant 1 feature "
              "appended, the bias weight last; also for scores in the hundreds", "predict_prob", make_predict_prob,
              exact("probabilities", PROBABILITY_TOLERANCE, _sample_row), visible_count=3, exact=True),
    Behaviour("2.2.2", "zero-bias", 0.5, "with a zero bias weight, predict_prob gives sigma(w . x) for each row",
              "predict_prob", lambda rng, variant: make_predict_prob(rng, variant, zero_bias=True),
              exact("probabilities", PROBABILITY_TOLERANCE, _sample_row), exact=True),
    Behaviour("2.2.3", "from-zero", 1, "one step of equation (8) from zero weights: w~ += learning_rate * "
              "sum_i (y_i - sigma(w~ . x~_i)) x~_i, the summed gradient", "gradient_step", make_step,
              exact("weights", STEP_TOLERANCE, _step_weight), exact=True),
    Behaviour("2.2.3", "from-weights", 3, "one step of equation (8) from non-zero weights, also where scores are in "
              "the hundreds", "gradient_step", lambda rng, variant: make_step(rng, variant, start="random"),
              exact("weights", STEP_TOLERANCE, _step_weight), visible_count=3, exact=True),
    Behaviour("2.2.3", "two-steps", 1, "two steps in a row: the second starts from the weights the first left in "
              "self.weights", "gradient_step", lambda rng, variant: make_step(rng, variant, start="random", steps=2),
              exact("weights", STEP_TOLERANCE, _step_weight), visible_count=1, exact=True),
    Behaviour("2.3.1", "one-iteration", 1.5, "one iteration of fit from zero weights: classifier c takes one step of "
              "equation (8) on its one-vs-rest labels (1 for class c, 0 for every other class)", "one_vs_rest",
              make_one_vs_rest, exact("weights", STEP_TOLERANCE, _class_weight), exact=True),
    Behaviour("2.3.1", "iterations", 3.5, "2 to 4 iterations of fit, from zero weights and from the weights the "
              "classifiers already have: in every iteration each classifier takes exactly one step, on its own "
              "labels, from where the last one left it", "one_vs_rest", make_iterations,
              exact("weights", STEP_TOLERANCE, _class_weight), visible_count=2, exact=True),
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


def case_set(todo, hidden_module=None):
    cases = CaseSet(todo)
    for behaviour in BEHAVIOURS_BY_TODO[todo]:
        for number, args in enumerate(behaviour.visible_cases()):
            cases.visible.append((f"{behaviour.id}/v{number}", behaviour, args))
        if hidden_module is not None:
            for number, args in enumerate(hidden_module.hidden_cases(behaviour)):
                cases.hidden.append((f"{behaviour.id}/h{number}", behaviour, args))
    return cases
