"""Which functions of the kit a TODO's run may call on the trusted side, and what such a call may carry.

The worker that runs a student's code for TODO T holds no reference solution. When that code
calls a function of ANOTHER TODO (``sigmoid`` inside 2.2.3, ``eval_params`` inside 1.3.2, ...)
or ``run_policy``, the worker's copy of the function is a *proxy*: it sends the call's
arguments (numbers only) to the grader, which has the reference server answer it and sends
the answer back (``runtime.py`` is the process side, ``broker.py`` the grader's). ``SERVED``
lists those functions. A function is served to T's run only if it is not T's own and does not
compute T's result (``uses``: the TODOs whose result it computes, directly or through what it
calls), so that no served function is an oracle for T; any other TODO function stays a stub
that says why. A function of the kit itself (``todo`` None) that would compute T's result
simply runs in the worker with T's code (``run_policy`` in 1.1.1's run).

Methods carry the state of their object (``init``: the constructor's arguments, ``state``: the
attributes set after it; ``updates``: what the call changes, set back on the student's object).
Arguments named in ``callables`` may be functions: they stay in the worker and are called back.

Plain data and checks on decoded messages; imported by the grader and copied into every kit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAX_NUMBERS = 1_000_000  # numbers in the arguments of one call
MAX_CALLABLES = 4  # functions passed in one call
MAX_INT = 2**62


@dataclass(frozen=True)
class Served:
    name: str  # the name calls use on the channel
    module: str  # where the function lives in the kit
    owner: str | None  # the class of a method, else None
    attribute: str
    todo: str | None  # the TODO whose code this is (None: the kit's own code)
    uses: frozenset  # TODOs whose result it computes (itself included), directly or through what it calls
    params: tuple  # the argument names the proxy sends (every one, defaults applied)
    init: tuple = ()  # a method's object: the constructor's arguments, from the object's attributes
    state: tuple = ()  # a method's object: attributes set after construction ("a.b": attribute b of each item of list a)
    updates: tuple = ()  # attributes the call changes, sent back and set on the caller's object
    callables: tuple = ()  # arguments that may be functions, called back in the worker
    limits: tuple = ()  # (argument, largest integer value served)

    @property
    def where(self):
        return f"{self.owner}.{self.attribute}" if self.owner else self.attribute

    def available_to(self, todo):
        """True if a run checking ``todo`` may have this function answered by the reference."""
        return self.todo != todo and todo not in self.uses


_P1 = frozenset({"1.1.1"})
SERVED = (
    Served("policy_action", "hwlib.cartpole", "CartPoleLinearPolicy", "__call__", "1.1.1", _P1, ("obs",),
           init=("params",)),
    Served("run_policy", "hwlib.cartpole", None, "run_policy", None, _P1, ("params", "seed", "env")),
    Served("scalar_finite_diff", "hwlib.finite_diff", None, "scalar_finite_diff", "1.2.1", frozenset({"1.2.1"}),
           ("f", "x", "h"), callables=("f",)),
    Served("eval_params", "hwlib.policy_search", None, "eval_params", "1.3.1", frozenset({"1.3.1", "1.1.1"}),
           ("params", "num_rollouts", "seed"), limits=(("num_rollouts", 1_000),)),
    Served("sigmoid", "hwlib.logreg", None, "sigmoid", "2.2.1", frozenset({"2.2.1"}), ("z",)),
    Served("log_likelihood_gradient", "hwlib.logreg", None, "log_likelihood_gradient", "2.1.1",
           frozenset({"2.1.1", "2.2.2", "2.2.1"}), ("weights", "features", "labels")),
    Served("predict_prob", "hwlib.logreg", "TwoClassLogisticRegressionClassifier", "predict_prob", "2.2.2",
           frozenset({"2.2.2", "2.2.1"}), ("X",), init=("n_features",), state=("weights",)),
    Served("gradient_ascent_step", "hwlib.logreg", "TwoClassLogisticRegressionClassifier", "gradient_ascent_step",
           "2.2.3", frozenset({"2.2.3", "2.1.1", "2.2.2", "2.2.1"}), ("X", "y", "learning_rate"),
           init=("n_features",), state=("weights",), updates=("weights",)),
    Served("one_vs_rest_fit", "hwlib.logreg", "MultiClassLogisticRegressionClassifier", "fit", "2.3.1",
           frozenset({"2.3.1", "2.2.3", "2.1.1", "2.2.2", "2.2.1"}), ("X", "y", "learning_rate", "n_iters"),
           init=("n_features", "n_classes"), state=("classifiers.weights",), updates=("classifiers.weights",),
           limits=(("n_iters", 1_000), ("n_classes", 100))),
)
SERVED_BY_NAME = {served.name: served for served in SERVED}


def plan(todo):
    """For a run checking ``todo``: ({name: Served} answered by the reference, {name: why not} for
    the other TODOs' functions, which stay stubs). Kit functions that compute ``todo``'s result
    are in neither: they run in the worker."""
    served, refused = {}, {}
    for entry in SERVED:
        if entry.available_to(todo):
            served[entry.name] = entry
        elif entry.todo is not None and entry.todo != todo:
            refused[entry.name] = (f"{entry.where} (TODO {entry.todo}) is not available while TODO {todo} is "
                                   f"checked: it computes what TODO {todo} computes, so it is not part of this check")
    return served, refused


# --------------------------------------------------------------------------------------------
# What a call may carry (checked by the grader on the decoded message)
# --------------------------------------------------------------------------------------------


def _numbers(value, depth=0):
    """How many numbers ``value`` holds if it is numbers only (None, bools, ints, floats, numeric
    arrays and scalars, lists of those), else None."""
    if depth > 6:
        return None
    if value is None or isinstance(value, (bool, float)):
        return 1
    if isinstance(value, int):
        return 1 if abs(value) <= MAX_INT else None
    if isinstance(value, (np.ndarray, np.generic)):
        return int(np.size(value)) if np.asarray(value).dtype.kind in "biuf" else None
    if isinstance(value, list):
        total = 0
        for item in value:
            count = _numbers(item, depth + 1)
            if count is None:
                return None
            total += count
        return total
    return None


def is_callable_mark(value):
    return isinstance(value, dict) and set(value) == {"__callable__"} and isinstance(value["__callable__"], int) \
        and not isinstance(value["__callable__"], bool)


def check_call(entry, args, state, limit=MAX_NUMBERS):
    """None if ``args`` and ``state`` are what a call of ``entry`` may carry (numbers only, at most
    ``limit`` of them), else why not (words of the grader, naming the argument). Returns (problem,
    callable ids)."""
    if not isinstance(args, dict) or set(args) != set(entry.params):
        return f"{entry.where} takes the arguments {', '.join(entry.params)}", ()
    wanted = set(entry.init) | set(entry.state)
    if not isinstance(state, dict) or set(state) != wanted:
        return f"{entry.where} needs its object's {', '.join(sorted(wanted)) or 'nothing'}", ()
    total, marks = 0, []
    for name, value in list(args.items()) + list(state.items()):
        if name in entry.callables and is_callable_mark(value):
            marks.append(value["__callable__"])
            continue
        count = _numbers(value)
        if count is None:
            return f"the grader passes only numbers to {entry.where}: {name} is not numbers", ()
        total += count
    if total > min(limit, MAX_NUMBERS) or len(marks) > MAX_CALLABLES:
        return f"the arguments of {entry.where} are larger than the grader serves in this check", ()
    for name, largest in entry.limits:
        value = args.get(name, state.get(name))
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and int(value) > largest:
            return f"the grader serves {entry.where} with {name} up to {largest}", ()
    return None, tuple(marks)


def check_value(value, limit=MAX_NUMBERS):
    """True if ``value`` (what a call-back returned) is numbers only, at most ``limit`` of them."""
    count = _numbers(value)
    return count is not None and count <= limit
