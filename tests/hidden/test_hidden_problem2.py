"""Hidden tests of problem 2: instructor-only, left out of the student edition.

Other data, other shapes, other starting weights than the visible tests; some state the
gradient of 2.1.1 outright, which is why students must not see them.
"""

import numpy as np
import pytest

from hwlib.logreg import (
    MultiClassLogisticRegressionClassifier,
    TwoClassLogisticRegressionClassifier,
    log_likelihood,
    log_likelihood_gradient,
    sigmoid,
)

pytestmark = pytest.mark.hidden


def _problem(seed, num_samples=60, num_features=5, num_classes=2):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(num_samples, num_features)), rng.integers(0, num_classes, size=num_samples)


def _augmented(X):
    return np.hstack([X, np.ones((len(X), 1))])


@pytest.mark.todo("2.2.1")
def test_sigmoid_on_random_values_and_shapes():
    z = np.random.default_rng(3).normal(scale=20.0, size=(4, 25))
    expected = np.exp(-np.logaddexp(0.0, -z))  # 1 / (1 + e^-z), computed another way
    result = sigmoid(z)
    assert result.shape == (4, 25) and result.dtype == np.float64
    np.testing.assert_allclose(result, expected, rtol=1e-12, atol=1e-300)


@pytest.mark.todo("2.2.2")
def test_predict_prob_on_random_weights():
    X, _ = _problem(4, num_features=6)
    classifier = TwoClassLogisticRegressionClassifier(6)
    classifier.weights[:] = np.random.default_rng(4).normal(size=7)
    expected = 1.0 / (1.0 + np.exp(-(X @ classifier.weights[:6] + classifier.weights[6])))
    np.testing.assert_allclose(classifier.predict_prob(X), expected, rtol=1e-12)


@pytest.mark.todo("2.2.3")
def test_two_steps_from_non_zero_weights_follow_equation_eight():
    X, y = _problem(5)
    classifier = TwoClassLogisticRegressionClassifier(5)
    start = np.random.default_rng(5).normal(scale=0.1, size=6)
    classifier.weights[:] = start
    classifier.fit(X, y, learning_rate=0.02, n_iters=2)
    X_aug, weights = _augmented(X), start.copy()
    for _ in range(2):
        weights = weights + 0.02 * X_aug.T @ (y - 1.0 / (1.0 + np.exp(-X_aug @ weights)))
    np.testing.assert_allclose(classifier.weights, weights, rtol=1e-12)


@pytest.mark.todo("2.1.1")
def test_gradient_equals_numerical_derivative_of_the_log_likelihood():
    X, y = _problem(6, num_samples=30, num_features=3)
    weights = np.array([0.4, -0.3, 0.2, -0.1])
    step = 1e-6
    numeric = [
        (log_likelihood(weights + step * e, X, y) - log_likelihood(weights - step * e, X, y)) / (2 * step) for e in np.eye(4)
    ]
    np.testing.assert_allclose(log_likelihood_gradient(weights, X, y), numeric, rtol=1e-6, atol=1e-6)


@pytest.mark.todo("2.3.1")
def test_three_one_vs_rest_iterations_on_four_classes():
    X, y = _problem(7, num_samples=80, num_features=4, num_classes=4)
    multi = MultiClassLogisticRegressionClassifier(4, 4)
    multi.fit(X, y, learning_rate=0.05, n_iters=3)
    X_aug, weights = _augmented(X), np.zeros((5, 4))
    for _ in range(3):
        for c in range(4):
            targets = (y == c).astype(float)
            weights[:, c] += 0.05 * X_aug.T @ (targets - 1.0 / (1.0 + np.exp(-X_aug @ weights[:, c])))
    np.testing.assert_allclose(multi.weights, weights, rtol=1e-12, atol=1e-12)
