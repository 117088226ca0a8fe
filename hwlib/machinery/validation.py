"""Input validation: the checks every public function of ``hwlib`` makes at its door.

A public function checks its arguments once, when it is called, with these functions; the code
behind the door (a TODO's code among it) trusts them and checks nothing again. Every check names
the argument it rejects and says what was expected, so a student never has to read a numpy
traceback to find out what went wrong.
"""

from __future__ import annotations

import numbers

import numpy as np

NUM_PARAMS = 4


def as_float_array(value, name):
    """``value`` as a float64 array, or a TypeError naming ``name``."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise TypeError(f"{name} must be an array of numbers, got {type(value).__name__}: {error}") from None
    return array


def check_finite(array, name):
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must hold only finite numbers, got {array!r}")
    return array


def check_params(params, name="params"):
    """One policy parameter vector: 4 finite numbers, returned as a float64 array of shape (4,)."""
    array = as_float_array(params, name)
    if array.shape != (NUM_PARAMS,):
        raise ValueError(f"{name} must have shape (4,), one weight per observation component, got shape {array.shape}")
    return check_finite(array, name)


def check_params_batch(params, name="params"):
    """A batch of policy parameters: shape (K, 4) with K >= 1, all finite."""
    array = as_float_array(params, name)
    if array.ndim != 2 or array.shape[1] != NUM_PARAMS or array.shape[0] == 0:
        raise ValueError(f"{name} must have shape (K, 4) with K >= 1, one row per policy, got shape {array.shape}")
    return check_finite(array, name)


def check_policy(policy, name="policy"):
    """A policy: anything callable as ``policy(obs) -> action``."""
    if not callable(policy):
        raise TypeError(f"{name} must be callable as {name}(obs) -> action, got {type(policy).__name__}")
    return policy


def check_seed(seed, name="seed"):
    """A seed: a non-negative integer."""
    if type(seed) is int and seed >= 0:  # the common case, without the slower checks below
        return seed
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {seed!r}")
    return int(seed)


def check_seeds(seeds, name="seeds"):
    """A 1-d sequence of non-negative integer seeds, at least one."""
    array = np.asarray(seeds)
    if array.ndim != 1 or array.size == 0 or not np.issubdtype(array.dtype, np.integer) or np.any(array < 0):
        raise ValueError(f"{name} must be a non-empty 1-d sequence of non-negative integers, got {seeds!r}")
    return array.astype(np.int64)


def check_count(value, name):
    """A positive integer count."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def check_positive_number(value, name):
    """A finite number > 0."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def check_path(path, name="path"):
    """A training path: shape (T + 1, 4), finite; returned as a float64 array."""
    array = as_float_array(path, name)
    if array.ndim != 2 or array.shape[1] != NUM_PARAMS or array.shape[0] == 0:
        raise ValueError(
            f"{name} must have shape (T + 1, 4): the parameters before training and after each update, "
            f"got shape {array.shape}"
        )
    return check_finite(array, name)


def check_finite_diff_arguments(f, x, h):
    """The door of ``scalar_finite_diff``: ``(x's shape, x, h, f)`` with x and h float64 arrays of shape (N,),
    and ``f`` wrapped so that it takes such an array (reshaped as the caller's x) and returns a checked float."""
    if not callable(f):
        raise TypeError(f"f must be callable as f(x) -> number, got {type(f).__name__}")
    x = as_float_array(x, "x")
    if x.ndim > 1 or x.size == 0:
        raise ValueError(f"x must be a number or a non-empty 1-d array, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"x must hold only finite numbers, got {x!r}")
    x_shape, point = x.shape, np.atleast_1d(x).copy()
    steps = as_float_array(h, "h")
    if steps.ndim == 0:
        steps = np.full(point.shape, float(steps))
    if steps.shape != point.shape:
        raise ValueError(f"h must be a number or have the same shape as x, {point.shape}, got shape {steps.shape}")
    if not np.all(np.isfinite(steps)) or np.any(steps <= 0):
        raise ValueError(f"h must hold finite step sizes > 0, got {steps!r}")

    def checked_f(perturbed):
        value = f(np.asarray(perturbed, dtype=np.float64).reshape(x_shape))
        return _scalar_value(value)

    return x_shape, point, steps, checked_f


def _scalar_value(value):
    array = np.asarray(value)
    if array.size != 1 or not np.issubdtype(array.dtype, np.number):
        raise ValueError(f"f must return a single number, got {value!r}")
    number = float(array.reshape(()))
    if not np.isfinite(number):
        raise ValueError(f"f must return a finite number, got {number}")
    return number


# --- problem 2: samples, labels and weights -----------------------------------------------------

_NUMERIC_KINDS = "biuf"  # bool, signed and unsigned int, float


def as_finite_float_array(value, name, require_2d=False):
    """``value`` as a float64 array of real numbers, all finite (2-d if ``require_2d``)."""
    array = np.asarray(value)
    if array.dtype.kind not in _NUMERIC_KINDS:
        raise TypeError(f"{name} must be an array of real numbers, got dtype {array.dtype}")
    if require_2d and array.ndim != 2:
        raise ValueError(f"{name} must be a 2-d array (samples x features), got shape {array.shape}")
    array = array.astype(np.float64, copy=False)
    num_bad = array.size - np.count_nonzero(np.isfinite(array))
    if num_bad:
        raise ValueError(f"{name} must hold only finite numbers, found {num_bad} NaN or infinite entries")
    return array


def check_features(features, name, n_features=None):
    """Samples: a finite 2-d float64 array with at least one row (and ``n_features`` columns if given)."""
    array = as_finite_float_array(features, name, require_2d=True)
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise ValueError(f"{name} must have at least one row and one column, got shape {array.shape}")
    if n_features is not None and array.shape[1] != n_features:
        raise ValueError(f"{name} must have {n_features} columns (one per feature), got shape {array.shape}")
    return array


def with_bias(features):
    """Checked samples (N, M) with a column of ones appended: the ``X_aug`` of equation (6), (N, M + 1)."""
    return np.hstack([features, np.ones((features.shape[0], 1))])


def checked_with_bias(features, name, n_features=None):
    """``features`` checked (``check_features``), with the constant-1 column appended."""
    return with_bias(check_features(features, name, n_features))


def check_label_vector(labels, name, length=None):
    """A non-empty 1-d array of whole numbers (of ``length`` entries if given), as int64."""
    array = np.asarray(labels)
    if array.dtype.kind not in _NUMERIC_KINDS:
        raise TypeError(f"{name} must be an array of integer class labels, got dtype {array.dtype}")
    if array.ndim != 1 or array.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-d array, got shape {array.shape}")
    if length is not None and array.size != length:
        raise ValueError(f"{name} must have {length} entries, one per sample, got {array.size}")
    if array.dtype.kind == "f":
        if not np.all(np.isfinite(array)) or np.any(array != np.round(array)):
            raise ValueError(f"{name} must hold whole-number class labels, found non-integer or non-finite values")
    return array.astype(np.int64)


def check_labels(labels, name, n_classes, length=None):
    """A 1-d int64 array of class indices in 0..n_classes-1 (of ``length`` entries if given)."""
    labels = check_label_vector(labels, name, length)
    if labels.min() < 0 or labels.max() >= n_classes:
        bad = labels[(labels < 0) | (labels >= n_classes)]
        raise ValueError(f"{name} must hold class indices 0..{n_classes - 1}, found {np.unique(bad)[:5].tolist()}")
    return labels


def check_two_class_problem(weights, features, labels):
    """``(features_aug, labels as 0.0/1.0, weights)`` of one two-class model on its samples, checked."""
    features_aug = checked_with_bias(features, "features")
    weights = as_finite_float_array(weights, "weights")
    if weights.shape != (features_aug.shape[1],):
        raise ValueError(
            f"weights must have shape ({features_aug.shape[1]},), one per feature plus the bias, got shape {weights.shape}"
        )
    labels = check_labels(labels, "labels", 2, len(features_aug)).astype(np.float64)
    return features_aug, labels, weights
