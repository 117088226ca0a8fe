"""Gradients by central finite differences, equation (3) of the handout (TODO 1.2.1).

For f: R^N -> R, a point x and step sizes h (one per coordinate),

    df/dx_i (x) ~ (f(x + h_i v_i) - f(x - h_i v_i)) / (2 h_i)

where v_i is the i-th unit vector: 2N evaluations of f for one gradient. Policy search uses it
on the expected reward g(theta) (``hwlib/policy_search.py``), problem 2 to check the gradient
derived in 2.1.1.
"""

from __future__ import annotations

import numpy as np

from hwlib._checks import as_float_array
from hwlib._todo import TodoNotDone  # noqa: F401 - the TODO's starting code raises it until you write it


def scalar_finite_diff(f, x, h):
    """The gradient of the scalar function ``f`` at ``x`` by central differences, equation (3).

    ``x`` holds N numbers (a 1-d array; a single number counts as N = 1); ``h`` the positive step
    sizes, one per coordinate of ``x`` (a single number is used for every coordinate). ``f(x)``
    must return one finite number. Returns the N partial derivatives, shaped like ``x``.
    """
    x_shape, x, h, f = _check_arguments(f, x, h)  # x, h: float64 of shape (N,); f returns a float
    gradient = np.zeros_like(x)
    ### BEGIN SOLUTION 1.2.1
    ### HINT: for each coordinate i, perturb a copy of x by +h[i] and -h[i] in coordinate i only, and fill gradient[i] with equation (3)
    for i in range(len(x)):
        step = np.zeros_like(x)
        step[i] = h[i]
        gradient[i] = (f(x + step) - f(x - step)) / (2.0 * h[i])
    ### END SOLUTION 1.2.1
    return gradient.reshape(x_shape)


def _check_arguments(f, x, h):
    """The argument checks of ``scalar_finite_diff``: x and h as float64 arrays of shape (N,), and an ``f``
    that takes such an array (reshaped as the caller's x) and returns a checked float."""
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
