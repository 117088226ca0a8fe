"""Gradients by central finite differences, equation (3) of the handout (TODO 1.2.1).

For f: R^N -> R, a point x and step sizes h (one per coordinate),

    df/dx_i (x) ~ (f(x + h_i v_i) - f(x - h_i v_i)) / (2 h_i)

where v_i is the i-th unit vector: 2N evaluations of f for one gradient. Policy search uses it
on the expected reward g(theta) (``hwlib/policy_search.py``), problem 2 to check the gradient
derived in 2.1.1.
"""

from __future__ import annotations

import numpy as np

from hwlib.machinery.todos import TodoNotDone  # noqa: F401 - the TODO's starting code raises it until you write it
from hwlib.machinery.validation import check_finite_diff_arguments


def scalar_finite_diff(f, x, h):
    """The gradient of the scalar function ``f`` at ``x`` by central differences, equation (3).

    ``x`` holds N numbers (a 1-d array; a single number counts as N = 1); ``h`` the positive step
    sizes, one per coordinate of ``x`` (a single number is used for every coordinate). ``f(x)``
    must return one finite number. Returns the N partial derivatives, shaped like ``x``.
    """
    x_shape, x, h, f = check_finite_diff_arguments(f, x, h)  # x, h: float64 of shape (N,); f returns a float
    gradient = np.zeros_like(x)
    ### BEGIN SOLUTION 1.2.1
    ### HINT: for each coordinate i, perturb a copy of x by +h[i] and -h[i] in coordinate i only, and fill gradient[i] with equation (3)
    for i in range(len(x)):
        step = np.zeros_like(x)
        step[i] = h[i]
        gradient[i] = (f(x + step) - f(x - step)) / (2.0 * h[i])
    ### END SOLUTION 1.2.1
    return gradient.reshape(x_shape)
