"""The checks of problem 2 (logistic regression), TODO by TODO: 2.1.1, 2.2.1, 2.2.2, 2.2.3, 2.3.1.

Each TODO's section holds everything its points ride on: how its visible inputs are made (the
hidden ones come from the same makers with the instructor's seed, ``instructor/hidden_checks``),
its tolerances, and last its behaviours (``TODO_2_2_1``: key, what is checked in words (its
points: the TODO table's ``checks``), the probe that runs in the sandbox, the maker and the
judge), with the line a failing visible check prints to rebuild its input (``REBUILT``). A probe's code is in
``hwtools/grade/in_sandbox/probes.py`` under the same name. Every problem-2 check is exact: the
student's values against the reference's on the same input (``verdicts.exact``). Standard library
and numpy only.
"""

from __future__ import annotations

import numpy as np

from hwtools.grade.checks.behaviour import Behaviour
from hwtools.grade.checks.verdicts import Tolerance, _number_text, close_to, exact, show

REBUILT = {}  # probe: (what the rebuilding line unpacks, what to call then); see checks.rebuild_line


def _two_class_data(rng, samples, features, scale=1.0):
    X = rng.normal(size=(samples, features)) * scale
    y = rng.integers(0, 2, size=samples)
    return X, y


# Probabilities sigma(w~ . x~), weights after steps of eq. (8), the gradient of eq. (7): the right
# formula computed or stored in float32 (or summed in another order) is off by at most 1e-6
# relative (plus about 1e-7 where sums cancel); a wrong one (no bias, the bias first, no sigmoid,
# the mean for the sum, a sign, a missed step, no learning rate) by 1e-2 or more.
FORMULA_TOLERANCE = Tolerance(1e-5, 1e-6, "the right formula in float32 is off by at most about 1e-6, a wrong one by "
                                          "1e-2 or more")


# --------------------------------------------------------------------------------------------
# 2.1.1 the log-likelihood gradient: shown for the grader of the derivation, no automatic points.
# Probe ll_gradient: log_likelihood_gradient(weights, X, y).
# --------------------------------------------------------------------------------------------


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


TODO_2_1_1 = (
    Behaviour("2.1.1", "gradient", "the summed gradient of equation (7)",
              "log_likelihood_gradient equals the summed gradient of equation (7), also "
              "where scores are in the hundreds (shown for the grader of the derivation; no automatic points)",
              "ll_gradient", make_ll_gradient, exact("gradient", FORMULA_TOLERANCE, _gradient_entry), exact=True),
)
REBUILT["ll_gradient"] = ("weights, X, y", "log_likelihood_gradient(weights, X, y)")


# --------------------------------------------------------------------------------------------
# 2.2.1 the sigmoid, equation (5). Probe sigmoid: sigmoid(z).
# --------------------------------------------------------------------------------------------

# The sigmoid. The values and shape checks tell formulas apart: sigma computed or stored in float32
# is off by up to 1.2e-6 relative for |z| <= 20 (z itself rounds to float32), a wrong formula (the
# sign of the exponent, a cut-off to 0 or 1 from |z| > 10) by 4.5e-5 relative or more (a cut-off
# to 0 by 100%); so 1e-5 relative. Far out (|z| > 20), where sigma is within 2.1e-9 of 0 or 1,
# they accept 1e-8 absolute (a sigmoid clipped at +-20 is a shortcut, not a wrong formula). The
# precision check is precision's own sub-point: float64 there (float64 resolves values near 1 to
# 1.1e-16, and correct float64 formulas, 1 / (1 + e^-z), 0.5 (1 + tanh(z / 2)), clipping at
# +-500, agree to 2.2e-16), so sigma(-24.4) = 2.5e-11, not 0.
SIGMOID_PRECISION = Tolerance(1e-12, 1e-15, "float64 resolves values near 1 to 1.1e-16; correct float64 formulas "
                                            "agree to 2.2e-16")
SIGMOID_TOLERANCE = Tolerance(1e-5, 1e-15, "sigma in float32 is off by up to 1.2e-6 relative, a wrong formula by "
                                           "4.5e-5 or more", loose_atol=1e-8,
                              loose=lambda args: np.abs(np.asarray(args["z"])) > 20,
                              loose_words="where |z| > 20 (sigma is within 2.1e-9 of 0 or 1 there)")
FAR_Z = np.array([-1000.0, -745.0, -709.5, -100.0, -40.0, -24.4, 24.4, 40.0, 100.0, 709.5, 745.0, 1000.0])


def _sigmoid_entry(args, index):
    z = np.asarray(args["z"], dtype=np.float64)
    return f"z{list(index) if index else ''} = {_number_text(z[index] if index else z)}"


def _cuts_off(args, actual, expected, tolerance, result=None):
    """"cuts_off" (a known mistake) if the values are exactly 0 and 1 from some |z| = c on (c below 36, where
    sigma itself is not yet 1 in float64) and sigma below it, whatever c is, else ""."""
    z = np.asarray(args["z"], dtype=np.float64).reshape(actual.shape)
    off = ~(np.abs(actual - expected) <= tolerance.limits(expected, args))
    saturated = np.where(z > 0, actual == 1.0, actual == 0.0)
    if not off.any() or not np.all(saturated[off]):
        return ""
    cut = float(np.min(np.abs(z[off])))
    beyond = np.abs(z) >= cut
    return "cuts_off" if cut < 36 and np.all(saturated[beyond]) and not np.any(off[~beyond]) else ""


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


TODO_2_2_1 = (
    Behaviour("2.2.1", "values", "sigma(z) = 1 / (1 + e^(-z)) from z = -1000 to 1000, never NaN",
              "sigma(z) = 1 / (1 + e^(-z)) for every entry of a row of numbers from -1000 to "
              "1000: 0, +-1, moderate values and far tails, where the values are 0 and 1 and never NaN (warnings are "
              "not failures)", "sigmoid", make_sigmoid_values, exact("values", SIGMOID_TOLERANCE, _sigmoid_entry, _cuts_off),
              visible_count=3, exact=True, value=True),
    Behaviour("2.2.1", "any-shape", "sigma of a single number and of 2- and 3-axis arrays, shaped like z",
              "the same for a single number and for arrays of 2 and 3 axes: values shaped "
              "like z", "sigmoid", make_sigmoid_shapes, exact("values", SIGMOID_TOLERANCE, _sigmoid_entry, _cuts_off),
              visible_count=3, exact=True),
    Behaviour("2.2.1", "precision", "float64 precision near 0 and 1: sigma(-24.4) = 2.5e-11, not 0",
              "float64 precision where sigma is close to 0 or 1 (20 < |z| <= 50): "
              "sigma(-24.4) = 2.5e-11, not 0, and sigma(24.4) = 1 - 2.5e-11", "sigmoid", make_sigmoid_precision,
              exact("values", SIGMOID_PRECISION, _sigmoid_entry, _cuts_off), exact=True),
)
REBUILT["sigmoid"] = ("z", "sigmoid(z)")


# --------------------------------------------------------------------------------------------
# 2.2.2 predict_prob: the constant 1 feature, the bias weight last. Probe predict_prob:
# TwoClassLogisticRegressionClassifier with the case's weights, predict_prob(X).
# --------------------------------------------------------------------------------------------


def _past_overflow(rng, X, weights):
    """``X`` with its first two rows replaced by points whose scores are drawn past +709 and past
    -709 (750 to 1,000: where e^s overflows, so a sigmoid computed as e^s / (1 + e^s) gives NaN and
    one as 1 / (1 + e^-s) a warning): each a multiple of the weights (without the bias)."""
    X, w, bias = X.copy(), np.asarray(weights[:-1], dtype=np.float64), float(weights[-1])
    for row, sign in ((0, 1.0), (1, -1.0)):
        X[row] = (sign * float(rng.uniform(750, 1000)) - bias) * w / (w @ w)
    return X


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
        X = _past_overflow(rng, X, weights)
    return {"n_features": features, "weights": weights, "X": X}


def _sample_row(args, index):
    return f"row {index[0]} of X: x~ = [{show(np.asarray(args['X'])[index[0]])[1:-1]}, 1]"


TODO_2_2_2 = (
    Behaviour("2.2.2", "with-bias", "sigma(w~ . [x, 1]) for each row: the 1 appended, the bias weight last",
              "predict_prob gives sigma(w~ . [x, 1]) for each row: the constant 1 feature "
              "appended, the bias weight last; also for scores in the hundreds", "predict_prob", make_predict_prob,
              exact("probabilities", FORMULA_TOLERANCE, _sample_row), visible_count=3, exact=True, value=True),
    Behaviour("2.2.2", "zero-bias", "with a zero bias weight, sigma(w . x) for each row",
              "with a zero bias weight, predict_prob gives sigma(w . x) for each row",
              "predict_prob", lambda rng, variant: make_predict_prob(rng, variant, zero_bias=True),
              exact("probabilities", FORMULA_TOLERANCE, _sample_row), exact=True, value=True),
)
REBUILT["predict_prob"] = ("model, X", "model.predict_prob(X)")


# --------------------------------------------------------------------------------------------
# 2.2.3 one gradient ascent step, equation (8). Probe gradient_step: gradient_ascent_step(X, y,
# learning_rate), steps times, and self.weights after each.
# --------------------------------------------------------------------------------------------


def make_step(rng, variant, start="zero", steps=1):
    """Random samples and labels; in variant 1 every label is 1 (a single class: y - sigma is never negative)."""
    features = int(rng.integers(3, 6))
    X, y = _two_class_data(rng, int(rng.integers(15, 30)), features)
    y = np.ones_like(y) if variant == 1 else y
    weights = np.zeros(features + 1) if start == "zero" else rng.normal(size=features + 1) * 0.3
    if start != "zero" and variant == 2:  # far scores: y - sigma is 0 or +-1, never NaN
        weights = weights * 400.0
        X = _past_overflow(rng, X, weights)
    return {"n_features": features, "weights": weights, "X": X, "y": y if variant % 2 == 0 else y.astype(np.float64),
            "learning_rate": float((0.05, 0.01, 0.02)[variant % 3]), "steps": steps}


def _other_rate(args, actual, expected, tolerance, result):
    """"other_rate" (a known mistake) if the first step is equation (8) with one rate r > 0 of another size
    than learning_rate (none: r = 1; a number of one's own), whatever r is, else "". The gradient is the
    reference's own, read from its answer (its first step over learning_rate). The mean gradient (r =
    learning_rate / N) and a step down (r < 0) are mistakes of their own."""
    rate, weights = float(args["learning_rate"]), np.asarray(args["weights"], dtype=np.float64)
    gradient = (expected[0] - weights) / rate
    if not np.all(np.isfinite(gradient)) or gradient @ gradient == 0:
        return ""
    r = float((actual[0] - weights) @ gradient / (gradient @ gradient))
    if not r > 0 or any(np.isclose(r, other, rtol=1e-4) for other in (rate, rate / len(args["X"]))):
        return ""
    return "other_rate" if close_to(actual[0], weights + r * gradient, tolerance) else ""


def _weight(args, j):
    return f"weight {j}" + (" (the bias)" if j == int(args["n_features"]) else "")


def _step_weight(args, index):
    return f"{_weight(args, index[1])} after step {index[0] + 1}"


TODO_2_2_3 = (
    Behaviour("2.2.3", "from-zero", "one step of equation (8) from zero weights, with the summed gradient",
              "one step of equation (8) from zero weights: w~ += learning_rate * "
              "sum_i (y_i - sigma(w~ . x~_i)) x~_i, the summed gradient", "gradient_step", make_step,
              exact("weights", FORMULA_TOLERANCE, _step_weight, _other_rate), exact=True, value=True),
    Behaviour("2.2.3", "from-weights", "one step of equation (8) from non-zero weights",
              "one step of equation (8) from non-zero weights, also where scores are in "
              "the hundreds", "gradient_step", lambda rng, variant: make_step(rng, variant, start="random"),
              exact("weights", FORMULA_TOLERANCE, _step_weight, _other_rate), visible_count=3, exact=True, value=True),
    Behaviour("2.2.3", "two-steps", "two steps in a row, the second from where the first left self.weights",
              "two steps in a row: the second starts from the weights the first left in "
              "self.weights", "gradient_step", lambda rng, variant: make_step(rng, variant, start="random", steps=2),
              exact("weights", FORMULA_TOLERANCE, _step_weight, _other_rate), visible_count=1, exact=True, value=True),
)
REBUILT["gradient_step"] = ("model, X, y, learning_rate, steps", "model.gradient_ascent_step(X, y, learning_rate), steps times")


# --------------------------------------------------------------------------------------------
# 2.3.1 one-vs-rest fit. Probe one_vs_rest: MultiClassLogisticRegressionClassifier(...).fit(X, y,
# learning_rate, n_iters), and each classifier's weights after it.
# --------------------------------------------------------------------------------------------


def make_one_vs_rest(rng, variant, iterations=1, start="zero", absent=False):
    """40 samples of 3 or 4 classes, each class present, or with ``absent`` the last class absent (its
    classifier steps on labels that are all 0)."""
    features, classes = int(rng.integers(3, 5)), int((3, 4)[variant % 2])
    X = rng.normal(size=(40, features))
    present = classes - 1 if absent else classes
    y = np.concatenate([np.arange(present), rng.integers(0, present, size=40 - present)])
    case = {"n_features": features, "n_classes": classes, "X": X, "y": rng.permutation(y),
            "learning_rate": 0.05, "n_iters": iterations}
    if start != "zero":
        case["initial_weights"] = rng.normal(size=(classes, features + 1)) * 0.3
    return case


def make_iterations(rng, variant):
    """2 to 4 iterations, from zero weights and from weights a fit before left; in variant 1 a class has no sample."""
    return make_one_vs_rest(rng, variant, iterations=(3, 2, 4)[variant % 3], start=("zero", "given")[variant % 2],
                            absent=variant == 1)


def _steps_per_class(args, actual, expected, tolerance, result):
    """"other_steps" (a known mistake) if the code asked the grader for k steps (gradient_ascent_step,
    answered by the reference and recorded) per classifier and iteration, one k of 2 or more, whatever k
    is, else "". (k = n_iters is the two-class fit for n_iters steps inside the loop, a mistake of its own.)"""
    calls = int(np.sum(result["records"].get("served", np.zeros(0, dtype=str)) == "gradient_ascent_step"))
    once = int(args["n_classes"]) * int(args["n_iters"])
    return "other_steps" if calls >= 2 * once and calls % once == 0 and calls // once != int(args["n_iters"]) else ""


def _class_weight(args, index):
    return f"classifier {index[0]}, {_weight(args, index[1])}"


TODO_2_3_1 = (
    Behaviour("2.3.1", "one-iteration", "one iteration from zero weights: one step per classifier on labels (y == c)",
              "one iteration of fit from zero weights: classifier c takes one step of "
              "equation (8) on its one-vs-rest labels (1 for class c, 0 for every other class)", "one_vs_rest",
              make_one_vs_rest, exact("weights", FORMULA_TOLERANCE, _class_weight, _steps_per_class), exact=True, value=True),
    Behaviour("2.3.1", "iterations", "2 to 4 iterations: exactly one step per classifier in each, from where it was",
              "2 to 4 iterations of fit, from zero weights and from the weights the "
              "classifiers already have: in every iteration each classifier takes exactly one step, on its own "
              "labels, from where the last one left it", "one_vs_rest", make_iterations,
              exact("weights", FORMULA_TOLERANCE, _class_weight, _steps_per_class), visible_count=2, exact=True, value=True),
)
REBUILT["one_vs_rest"] = ("model, X, y, learning_rate, n_iters", "model.fit(X, y, learning_rate, n_iters)")


BEHAVIOURS = TODO_2_1_1 + TODO_2_2_1 + TODO_2_2_2 + TODO_2_2_3 + TODO_2_3_1
