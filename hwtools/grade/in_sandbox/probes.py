"""The probes: what the grader's worker calls in the kit for one check, and the values each one answers.

A probe takes one case's arguments (numbers, made by ``hwtools/grade/checks/``), calls the homework's
functions in the kit under test and returns its values: {name: number or array}. ``PROBES``
maps a probe's name to its function and ``RESULTS`` to the schema of its answer (every name,
its dtype kinds and number of dimensions), which the grader enforces on what comes back: an
answer with other names, other dtypes or more dimensions fails its case.

The probes run in the sandbox (this folder is copied into every kit). The trusted side imports
this module too, for ``RESULTS``, the known functions below and the input builders (``fd_inputs``,
...: ``hwtools.cases`` rebuilds a visible input with them), so it imports nothing beyond numpy at
the top: ``hwlib`` is imported inside the probes, from the kit under test only. They are grouped
by problem, in TODO order, under the names the checks' table gives (``checks/p1_cartpole.py``,
``checks/p2_logreg.py``).
"""

from __future__ import annotations

import importlib
import os

import numpy as np

KIT_DIR = "/kit"  # set by the runtime to the kit under test
PROBES, RESULTS = {}, {}
_FLOAT, _INT = "f", "iu"


def probe(**schema):
    """Register a probe: ``schema`` gives, per value it answers, (dtype kinds, allowed ndims)."""

    def register(function):
        name = function.__name__[len("probe_"):]
        PROBES[name], RESULTS[name] = function, schema
        return function

    return register


# --------------------------------------------------------------------------------------------
# Known functions (the grader computes the same ones on its side)
# --------------------------------------------------------------------------------------------


def known_function(spec):
    """The scalar function f of a finite-difference case: ``spec`` names its kind and coefficients.

    cubic:   f(v) = sum_i a_i v_i^3 + c                      (coordinates separate)
    coupled: f(v) = sum_i a_i v_i^3 + sin(b . v) + v^T M v   (coordinates interact)
    """
    kind = spec["kind"]
    a = np.asarray(spec["a"], dtype=np.float64)
    if kind == "cubic":
        c = float(spec.get("c", 0.0))

        def f(v):
            return float(np.sum(a * np.asarray(v, dtype=np.float64) ** 3) + c)
    elif kind == "coupled":
        b = np.asarray(spec["b"], dtype=np.float64)
        m = np.asarray(spec["m"], dtype=np.float64)

        def f(v):
            v = np.atleast_1d(np.asarray(v, dtype=np.float64))
            return float(np.sum(a * v**3) + np.sin(b @ v) + v @ m @ v)
    else:
        raise ValueError(f"unknown test function kind {kind!r}")
    return f


def training_objective(spec):
    """g(theta) = c - (theta - m)^T A (theta - m) - sum_i q_i (theta_i - m_i)^4, a smooth stand-in for
    the expected reward, at most ``spec["cap"]`` where it has one (as rewards stop at the episode cap).
    With q = 0 central differences are exact for any step; with q > 0 they depend on the step (for
    d^4: 4 d^3 + 4 d h^2), so a run that uses another step than fd_step shows."""
    a = np.asarray(spec["A"], dtype=np.float64)
    m = np.asarray(spec["m"], dtype=np.float64)
    q = np.asarray(spec.get("q", np.zeros_like(m)), dtype=np.float64)
    c, cap = float(spec["c"]), float(spec.get("cap", np.inf))

    def g(theta):
        d = np.asarray(theta, dtype=np.float64).reshape(-1) - m
        return float(min(cap, c - d @ a @ d - np.sum(q * d**4)))

    return g



# --------------------------------------------------------------------------------------------
# Turning what the student's code returned into numbers
# --------------------------------------------------------------------------------------------

_PLAIN = (np.ndarray, np.generic, int, float, bool, list, tuple)


def numbers(value, what):
    """``value`` as a plain float64 array, or a TypeError saying what came back instead."""
    if not isinstance(value, _PLAIN) or (isinstance(value, np.ndarray) and type(value) is not np.ndarray):
        raise TypeError(f"{what} returned a {type(value).__module__}.{type(value).__name__}, not numbers")
    try:
        return np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise TypeError(f"{what} returned something that is not an array of numbers ({error})") from None


IMPORT_FAILED = "raised while hwlib was imported"  # in a case's error where the kit's code raised at import (runtime.py)


def _import(name):
    module = importlib.import_module(name)
    kit = os.path.realpath(KIT_DIR)
    if not os.path.realpath(getattr(module, "__file__", "") or "").startswith(kit + os.sep):
        raise ImportError(f"{name} was not imported from the kit under test")
    return module


# --------------------------------------------------------------------------------------------
# Problem 1
# --------------------------------------------------------------------------------------------


def _action_kind(value):
    """0: a type ``env.step`` takes (gymnasium's own test: an int, bools included, a numpy integer,
    a 0-d integer array); else what it is: 1 a numpy bool, 2 a float, 3 an array, 4 anything else."""
    import gymnasium  # noqa: PLC0415 - the kit's own dependency, there in the sandbox

    if gymnasium.spaces.Discrete(2).contains(value):
        return 0
    if isinstance(value, np.bool_):
        return 1
    if isinstance(value, (float, np.floating)):
        return 2
    return 3 if isinstance(value, np.ndarray) else 4


def policy_inputs(args):
    """(params, obs): row i of each is one call, CartPoleLinearPolicy(params[i])(obs[i])."""
    return np.asarray(args["params"], dtype=np.float64), np.asarray(args["obs"], dtype=np.float64)


@probe(actions=(_FLOAT, (1,)), accepted=("b", (1,)), kinds=(_INT, (1,)))
def probe_policy_choices(args):
    """The policy's action on each (params, obs) row as a number (whatever numeric type it came
    in), and whether env.step takes it as it is (``accepted``, with its ``kinds``)."""
    cartpole = _import("hwlib.cartpole")
    params, observations = np.asarray(args["params"]), np.asarray(args["obs"])
    actions, kinds = [], []
    for p, o in zip(params, observations):
        value = cartpole.CartPoleLinearPolicy(p.copy())(o.copy())
        if not isinstance(value, _PLAIN) or np.asarray(value).dtype.kind not in "biuf" or np.asarray(value).size != 1:
            raise TypeError(f"the policy returned {type(value).__module__}.{type(value).__name__}, not the number 0 or 1")
        kinds.append(_action_kind(value))
        actions.append(float(np.asarray(value, dtype=np.float64).reshape(())))
    return {"actions": np.array(actions, dtype=np.float64), "accepted": np.array(kinds, dtype=np.int64) == 0,
            "kinds": np.array(kinds, dtype=np.int64)}


def fd_inputs(args):
    """(f, x, h) of a finite-difference case, as scalar_finite_diff gets them."""
    f = known_function(args["f"])
    x = float(args["x"]) if args.get("x_scalar") else np.array(args["x"], dtype=np.float64)
    h = float(args["h"]) if args.get("h_scalar") else np.array(args["h"], dtype=np.float64)
    return f, x, h


@probe(gradient=(_FLOAT, (0, 1, 2)), form=(_INT, (0,)))
def probe_finite_diff(args):
    """The gradient, and its ``form``: 0 an array (or a number for a single number x), 1 a list, 2 a
    tuple, on which the training code's arithmetic (learning_rate * gradient) fails."""
    finite_diff = _import("hwlib.finite_diff")
    gradient = finite_diff.scalar_finite_diff(*fd_inputs(args))
    form = 1 if isinstance(gradient, list) else 2 if isinstance(gradient, tuple) else 0
    return {"gradient": numbers(gradient, "scalar_finite_diff"), "form": np.int64(form)}


FORMS = ("form",)  # values that tell an answer's form, not its numbers: no known mistake is told by them


def eval_inputs(args):
    """(params, num_rollouts, seed) of an eval_params case."""
    return np.array(args["params"], dtype=np.float64), int(args["num_rollouts"]), int(args["seed"])


@probe(value=(_FLOAT, (0, 1)), value_again=(_FLOAT, (0, 1)))
def probe_eval_params(args):
    """Two calls of eval_params with the same arguments. The episodes they play are recorded by
    the grader (run_policy is answered on its side), never here."""
    policy_search = _import("hwlib.policy_search")
    params, num_rollouts, seed = eval_inputs(args)
    first = numbers(policy_search.eval_params(params.copy(), num_rollouts, seed=seed), "eval_params")
    again = numbers(policy_search.eval_params(params.copy(), num_rollouts, seed=seed), "eval_params")
    return {"value": first, "value_again": again}


def train_inputs(args):
    """The keyword arguments of train_cartpole_policy in a training case."""
    return {"num_training_iterations": int(args["iterations"]), "num_rollouts_per_eval": int(args["rollouts"]),
            "learning_rate": float(args["learning_rate"]), "fd_step": float(args["fd_step"]), "seed": int(args["seed"]),
            "initial_params": np.array(args["initial_params"], dtype=np.float64)}


@probe(rewards=(_FLOAT, (1,)), params_history=(_FLOAT, (2,)), final_params=(_FLOAT, (1,)))
def probe_train_known(args):
    """A training run. In ``train_known`` cases every eval_params call is answered by the grader with
    the known objective ``args["objective"]``; in ``train_real`` cases (the same probe under another
    name) by the reference server, every episode played there. The grader records each call."""
    policy_search = _import("hwlib.policy_search")
    run = policy_search.train_cartpole_policy(**train_inputs(args))
    return {"rewards": numbers(getattr(run, "rewards", None), "train_cartpole_policy's rewards"),
            "params_history": numbers(getattr(run, "params_history", None), "train_cartpole_policy's params_history"),
            "final_params": numbers(getattr(getattr(run, "policy", None), "params", None), "the trained policy's params")}


PROBES["train_real"], RESULTS["train_real"] = PROBES["train_known"], RESULTS["train_known"]


@probe(value=(_FLOAT, (0,)))
def probe_settings_value(args):
    settings = _import("hwlib.settings")
    name = args["name"]
    value = getattr(settings, name, None)
    if value is None:
        raise ValueError(f"{name} is None: it is not set yet")
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} is a {type(value).__name__}, not a number")
    return {"value": np.float64(value)}


# --------------------------------------------------------------------------------------------
# Problem 2
# --------------------------------------------------------------------------------------------


def sigmoid_inputs(args):
    return (np.array(args["z"], dtype=np.float64),)


@probe(values=(_FLOAT, (0, 1, 2, 3)))
def probe_sigmoid(args):
    logreg = _import("hwlib.logreg")
    (z,) = sigmoid_inputs(args)
    return {"values": numbers(logreg.sigmoid(z.copy()), "sigmoid")}


def classifier_inputs(args, logreg):
    """(model, X) of a predict_prob case, or (model, X, y, learning_rate, steps) of a step case: the
    two-class classifier of ``logreg`` (the kit's module) with the case's weights."""
    model = logreg.TwoClassLogisticRegressionClassifier(int(args["n_features"]))
    model.weights = np.array(args["weights"], dtype=np.float64)
    X = np.array(args["X"], dtype=np.float64)
    if "y" not in args:
        return model, X
    return model, X, np.array(args["y"]), float(args["learning_rate"]), int(args["steps"])


@probe(probabilities=(_FLOAT, (0, 1, 2)))
def probe_predict_prob(args):
    model, X = classifier_inputs(args, _import("hwlib.logreg"))
    return {"probabilities": numbers(model.predict_prob(X), "predict_prob")}


@probe(weights=(_FLOAT, (1, 2, 3)))
def probe_gradient_step(args):
    classifier, X, y, learning_rate, steps = classifier_inputs(args, _import("hwlib.logreg"))
    after = []
    for _ in range(steps):
        classifier.gradient_ascent_step(X.copy(), y.copy(), learning_rate)
        after.append(numbers(classifier.weights, "self.weights after gradient_ascent_step").copy())
    return {"weights": np.array(after)}


def one_vs_rest_inputs(args, logreg):
    """(model, X, y, learning_rate, n_iters) of a one-vs-rest case: the multi-class classifier of
    ``logreg`` with the weights its fit starts from."""
    model = logreg.MultiClassLogisticRegressionClassifier(int(args["n_features"]), int(args["n_classes"]))
    for c, start in enumerate(np.array(args.get("initial_weights", ()), dtype=np.float64)):  # where fit starts
        model.classifiers[c].weights = start.copy()
    return (model, np.array(args["X"], dtype=np.float64), np.array(args["y"]), float(args["learning_rate"]),
            int(args["n_iters"]))


@probe(weights=(_FLOAT, (1, 2, 3)), accuracies=(_FLOAT, (0, 1)))
def probe_one_vs_rest(args):
    model, X, y, learning_rate, n_iters = one_vs_rest_inputs(args, _import("hwlib.logreg"))
    accuracies = model.fit(X, y, learning_rate, n_iters)
    weights = np.array([numbers(c.weights, "classifiers[c].weights") for c in model.classifiers])
    return {"weights": weights, "accuracies": numbers(accuracies, "fit")}


def ll_gradient_inputs(args):
    return np.array(args["weights"], dtype=np.float64), np.array(args["X"], dtype=np.float64), np.array(args["y"])


@probe(gradient=(_FLOAT, (0, 1, 2)))
def probe_ll_gradient(args):
    logreg = _import("hwlib.logreg")
    return {"gradient": numbers(logreg.log_likelihood_gradient(*ll_gradient_inputs(args)), "log_likelihood_gradient")}


# --------------------------------------------------------------------------------------------
# Services: run by the reference server only, to judge what a student's run produced
# --------------------------------------------------------------------------------------------


@probe(rewards=(_FLOAT, (1,)), deadline=(_INT, (0,)), max_reward=(_FLOAT, (0,)), iterations=(_INT, (0,)),
       seed=(_INT, (0,)))
def probe_train_notebook(args):
    training = _import("hwlib.training")  # the notebook's training cell: train_cartpole_policy, batched
    settings = _import("hwlib.settings")
    cartpole = _import("hwlib.cartpole")
    run = training.run_training(learning_rate=float(args["learning_rate"]), progress=False, max_minutes=None)
    return {"rewards": np.array(run.rewards, dtype=np.float64),
            "deadline": np.int64(settings.CONVERGENCE_DEADLINE),
            "max_reward": np.float64(cartpole.MAX_EPISODE_REWARD),
            "iterations": np.int64(settings.NUM_TRAINING_ITERATIONS),
            "seed": np.int64(settings.TRAINING_SEED)}
