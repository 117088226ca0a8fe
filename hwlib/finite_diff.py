"""Gradients by central finite differences, equation (3) of the handout.

For f: R^N -> R, a point x and step sizes h (one per coordinate),

    df/dx_i (x) ~ (f(x + h_i e_i) - f(x - h_i e_i)) / (2 h_i)

``scalar_finite_diff`` is the handout's function: it calls ``f`` once per perturbed point.
``batched_finite_diff`` does the same for M points at once and hands ``f`` every perturbed
point of all of them in a single call, which lets policy search evaluate them all in one
batch of episodes. Both share the same two steps, so they give the same numbers.
"""

from __future__ import annotations

import numpy as np

from hwlib._checks import as_float_array, check_finite


def batched_finite_diff(f_batch, points, h):
    """Central-difference gradients at each row of ``points`` (shape (M, N)).

    ``f_batch`` takes an array of shape (M, 2N, N), perturbed copies of every point (first the
    N points x + h_i e_i, then the N points x - h_i e_i), and returns their M x 2N values.
    ``h`` is positive, shaped (N,) or a scalar applied to every coordinate.
    Returns the gradients, shape (M, N).
    """
    points = as_float_array(points, "points")
    if points.ndim != 2 or points.shape[0] == 0 or points.shape[1] == 0:
        raise ValueError(f"points must have shape (M, N) with M, N >= 1, got shape {points.shape}")
    check_finite(points, "points")
    steps = _check_steps(h, points.shape[1])
    if not callable(f_batch):
        raise TypeError(f"f must be callable, got {type(f_batch).__name__}")
    ### BEGIN SOLUTION 1.2.1
    ### HINT: stack the perturbed points (M, 2N, N): x + h_i e_i for each i, then x - h_i e_i; get their values with _check_values(f_batch(perturbed), (M, 2N)); return eq. (3), shape (M, N)
    offsets = np.diag(steps)  # row i is h_i e_i
    perturbed = points[:, None, :] + np.concatenate([offsets, -offsets])[None, :, :]
    values = _check_values(f_batch(perturbed), perturbed.shape[:2])
    num_dims = points.shape[1]
    return (values[:, :num_dims] - values[:, num_dims:]) / (2.0 * steps)
    ### END SOLUTION 1.2.1


def scalar_finite_diff(f, x, h):
    """Gradient of the scalar function ``f`` at ``x`` by central differences.

    ``x`` is a 1-d array of N numbers (a Python scalar counts as N = 1), ``h`` the positive
    perturbation sizes, shaped like ``x`` or a scalar used for every coordinate. ``f(x)`` must
    return one finite number. Returns an array shaped like ``x``.
    """
    x = as_float_array(x, "x")
    if x.ndim > 1 or x.size == 0:
        raise ValueError(f"x must be a scalar or a non-empty 1-d array, got shape {x.shape}")
    if not callable(f):
        raise TypeError(f"f must be callable, got {type(f).__name__}")
    point = np.atleast_1d(x)

    def f_each(perturbed):
        return np.array([[_scalar_value(f(p.reshape(x.shape))) for p in row] for row in perturbed])

    return batched_finite_diff(f_each, point[None, :], h)[0].reshape(x.shape)


def _check_steps(h, num_dims):
    steps = as_float_array(h, "h")
    if steps.ndim == 0:
        steps = np.full(num_dims, float(steps))
    if steps.shape != (num_dims,):
        raise ValueError(f"h must be a scalar or have the same shape as x, ({num_dims},), got shape {steps.shape}")
    if not np.all(np.isfinite(steps)) or np.any(steps <= 0):
        raise ValueError(f"h must hold finite step sizes > 0, got {steps!r}")
    return steps


def _scalar_value(value):
    array = np.asarray(value)
    if array.size != 1 or not np.issubdtype(array.dtype, np.number):
        raise ValueError(f"f must return a single number, got {value!r}")
    number = float(array.reshape(()))
    if not np.isfinite(number):
        raise ValueError(f"f must return a finite number, got {number}")
    return number


def _check_values(values, expected_shape):
    values = np.asarray(values, dtype=np.float64)
    if values.shape != expected_shape:
        raise ValueError(f"f must return one value per perturbed point, shape {expected_shape}, got shape {values.shape}")
    return check_finite(values, "values returned by f")
