import numpy as np
import pytest

from hwlib import scalar_finite_diff


@pytest.mark.todo("1.2.1")
def test_linear_function_gradient_is_its_coefficients():
    coefficients = np.array([3.0, -2.0, 0.5, 7.0])
    gradient = scalar_finite_diff(lambda x: coefficients @ x + 4.0, np.array([1.0, 2.0, -3.0, 0.1]), np.full(4, 1e-3))
    np.testing.assert_allclose(gradient, coefficients, rtol=1e-9)


@pytest.mark.todo("1.2.1")
def test_trigonometric_gradient():
    x = np.array([0.0, 0.7, 2.0])
    gradient = scalar_finite_diff(lambda v: np.sin(v[0]) + np.cos(v[1]) * v[2], x, np.full(3, 1e-5))
    expected = [np.cos(0.0), -np.sin(0.7) * 2.0, np.cos(0.7)]
    np.testing.assert_allclose(gradient, expected, atol=1e-8)


@pytest.mark.todo("1.2.1")
def test_quadratic_form_gradient_is_exact_for_central_differences():
    rng = np.random.default_rng(3)
    matrix = rng.normal(size=(5, 5))
    x = rng.normal(size=5)
    gradient = scalar_finite_diff(lambda v: v @ matrix @ v, x, np.full(5, 0.5))
    np.testing.assert_allclose(gradient, (matrix + matrix.T) @ x, rtol=1e-9)


@pytest.mark.todo("1.2.1")
def test_non_uniform_steps_use_each_coordinates_own_step():
    # For a cubic, the central difference has error h_i^2 * f'''/6 in coordinate i, so each
    # coordinate's result reveals the step it used.
    steps = np.array([0.1, 0.5, 1.0])
    gradient = scalar_finite_diff(lambda v: np.sum(v**3), np.zeros(3), steps)
    np.testing.assert_allclose(gradient, steps**2, rtol=1e-9)


@pytest.mark.todo("1.2.1")
def test_uses_central_not_forward_differences():
    # A forward difference of x^2 at 0 with step 1 gives 1; the central one gives the exact 0.
    assert scalar_finite_diff(lambda v: float(v[0] ** 2), np.array([0.0]), np.array([1.0]))[0] == pytest.approx(0.0)


@pytest.mark.todo("1.2.1")
def test_scalar_step_is_broadcast_and_scalar_x_accepted():
    np.testing.assert_allclose(scalar_finite_diff(lambda v: np.sum(v**2), np.array([1.0, -2.0]), 1e-3), [2.0, -4.0])
    assert scalar_finite_diff(lambda v: v**2, 3.0, 1e-3) == pytest.approx(6.0)


@pytest.mark.todo("1.2.1")
def test_f_sees_points_shaped_like_x_and_x_is_not_changed():
    x = np.array([1.0, 2.0])
    seen = []

    def f(v):
        seen.append(np.array(v))
        return float(v @ v)

    scalar_finite_diff(f, x, 0.25)
    np.testing.assert_array_equal(x, [1.0, 2.0])
    assert all(point.shape == (2,) for point in seen) and len(seen) == 4


@pytest.mark.parametrize("h", [0.0, -1e-3, np.array([1e-3, 0.0]), np.array([1e-3, np.nan]), np.inf])
def test_rejects_non_positive_or_non_finite_steps(h):
    with pytest.raises(ValueError, match="h must hold finite step sizes > 0"):
        scalar_finite_diff(lambda v: float(np.sum(v)), np.zeros(2), h)


def test_rejects_step_of_the_wrong_shape():
    with pytest.raises(ValueError, match=r"h must be a number or have the same shape as x, \(3,\)"):
        scalar_finite_diff(lambda v: float(np.sum(v)), np.zeros(3), np.full(2, 1e-3))


@pytest.mark.parametrize("x", [np.zeros((2, 2)), np.array([])])
def test_rejects_x_that_is_not_a_vector(x):
    with pytest.raises(ValueError, match="x must be a number or a non-empty 1-d array"):
        scalar_finite_diff(lambda v: 0.0, x, 1e-3)


def test_rejects_non_numeric_x():
    with pytest.raises(TypeError, match="x must be an array of numbers"):
        scalar_finite_diff(lambda v: 0.0, ["a", "b"], 1e-3)


@pytest.mark.parametrize(
    ("f", "message"),
    [
        (lambda v: v, "f must return a single number"),
        (lambda v: "3", "f must return a single number"),
        (lambda v: np.nan, "f must return a finite number"),
        (lambda v: np.inf, "f must return a finite number"),
    ],
)
@pytest.mark.todo("1.2.1")
def test_rejects_f_that_does_not_return_a_finite_scalar(f, message):
    with pytest.raises(ValueError, match=message):
        scalar_finite_diff(f, np.zeros(2), 1e-3)


def test_rejects_f_that_is_not_callable():
    with pytest.raises(TypeError, match="f must be callable"):
        scalar_finite_diff(3.0, np.zeros(2), 1e-3)
