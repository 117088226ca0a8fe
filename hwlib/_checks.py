"""Input validation shared by the kit's public functions.

Every check names the argument it rejects and says what was expected, so a student never
has to read a numpy traceback to find out what went wrong.
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


def check_observation(obs, name="obs"):
    """One CartPole observation: 4 finite numbers, returned as a float64 array of shape (4,)."""
    array = as_float_array(obs, name)
    if array.shape != (NUM_PARAMS,):
        raise ValueError(f"{name} must have shape (4,): cart position, cart velocity, pole angle, "
                         f"pole angular velocity; got shape {array.shape}")
    return check_finite(array, name)


def check_params_batch(params, name="params"):
    """A batch of policy parameters: shape (K, 4) with K >= 1, all finite."""
    array = as_float_array(params, name)
    if array.ndim != 2 or array.shape[1] != NUM_PARAMS or array.shape[0] == 0:
        raise ValueError(f"{name} must have shape (K, 4) with K >= 1, one row per policy, got shape {array.shape}")
    return check_finite(array, name)


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
