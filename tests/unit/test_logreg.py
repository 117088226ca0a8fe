import contextlib
import warnings

import numpy as np
import pytest

import hwlib
from hwlib import (
    MultiClassLogisticRegressionClassifier,
    TwoClassLogisticRegressionClassifier,
    accuracy,
    add_bias_feature,
    confusion_matrix,
    first_iteration_above,
    gradient_check,
    load_food_cutting,
    log_likelihood,
    log_likelihood_gradient,
    per_class_accuracy,
    settings,
    sigmoid,
    train_test_split,
)
from hwlib import logreg

# A correct sigmoid may warn: 1 / (1 + np.exp(-z)) at z = -1000 says "overflow encountered in exp"
# and still returns the right 0.0. These tests judge the values the student's code returns, not
# the warnings numpy prints on the way (pyproject.toml turns RuntimeWarnings into errors elsewhere).
# Tests of the kit's own numerics ask for silence explicitly (``silent()``).
pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")


@contextlib.contextmanager
def silent():
    """A context in which any warning is an error."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


def small_problem(seed=0, num_samples=40, num_features=3, num_classes=2):
    rng = np.random.default_rng(seed)
    features = rng.normal(size=(num_samples, num_features))
    labels = rng.integers(0, num_classes, size=num_samples)
    return features, labels


def separable_problem(seed=0, num_per_class=30):
    """Three well separated blobs in 2-d."""
    rng = np.random.default_rng(seed)
    centres = np.array([[4.0, 0.0], [-4.0, 4.0], [-4.0, -4.0]])
    labels = np.repeat(np.arange(3), num_per_class)
    features = centres[labels] + rng.normal(scale=0.5, size=(len(labels), 2))
    return features, labels


def numerical_gradient(weights, features, labels, step=1e-6):
    """Central differences of the log-likelihood (equation 7), one coordinate at a time."""
    gradient = np.zeros_like(weights)
    for i in range(len(weights)):
        offset = np.zeros_like(weights)
        offset[i] = step
        gradient[i] = (log_likelihood(weights + offset, features, labels) - log_likelihood(weights - offset, features, labels)) / (2 * step)
    return gradient


# --- 2.2.1 sigmoid ---------------------------------------------------------------------------


@pytest.mark.todo("2.2.1")
def test_sigmoid_matches_the_formula():
    z = np.linspace(-30, 30, 121)
    np.testing.assert_allclose(sigmoid(z), 1.0 / (1.0 + np.exp(-z)), rtol=1e-9, atol=1e-12)


@pytest.mark.todo("2.2.1")
def test_sigmoid_uses_the_standard_sign_convention():
    assert sigmoid(0.0) == 0.5
    assert sigmoid(2.0) > 0.5 > sigmoid(-2.0)


@pytest.mark.todo("2.2.1")
def test_sigmoid_is_symmetric():
    z = np.linspace(-40, 40, 81)
    np.testing.assert_allclose(sigmoid(-z), 1.0 - sigmoid(z), atol=1e-14)


@pytest.mark.todo("2.2.1")
def test_sigmoid_far_out_is_zero_or_one_not_nan():
    # Training on the food data drives scores into the thousands: there sigma must be 0 or 1.
    z = np.array([-1e308, -1000.0, -745.0, 745.0, 1000.0, 1e308])
    values = np.asarray(sigmoid(z))
    assert not np.any(np.isnan(values))
    np.testing.assert_allclose(values, [0.0, 0.0, 0.0, 1.0, 1.0, 1.0], rtol=0, atol=1e-12)


@pytest.mark.todo("2.2.1")
def test_sigmoid_keeps_shape():
    assert np.shape(sigmoid(np.zeros((2, 3, 4)))) == (2, 3, 4)
    assert np.ndim(sigmoid(1.0)) == 0
    assert np.asarray(sigmoid([0, 0])).dtype == np.float64  # integer input works too


@pytest.mark.parametrize("bad", [np.nan, [0.0, np.inf], [-np.inf]])
def test_sigmoid_rejects_non_finite_input(bad):
    with pytest.raises(ValueError, match="z must hold only finite numbers"):
        sigmoid(bad)


@pytest.mark.parametrize("bad", ["1.0", ["a", "b"], [object()]])
def test_sigmoid_rejects_non_numbers(bad):
    with pytest.raises(TypeError, match="z must be an array of real numbers"):
        sigmoid(bad)


# --- 2.2.2 predict_prob ----------------------------------------------------------------------


def test_add_bias_feature_appends_a_column_of_ones():
    augmented = add_bias_feature([[1.0, 2.0], [3.0, 4.0]])
    np.testing.assert_array_equal(augmented, [[1.0, 2.0, 1.0], [3.0, 4.0, 1.0]])


@pytest.mark.todo("2.2.2")
def test_predict_prob_uses_the_bias_as_the_last_weight():
    classifier = TwoClassLogisticRegressionClassifier(2)
    classifier.weights = np.array([1.0, -2.0, 0.5])
    X = np.array([[1.0, 1.0], [0.0, 0.0], [2.0, -1.0]])
    expected = 1.0 / (1.0 + np.exp(-(X @ [1.0, -2.0] + 0.5)))
    np.testing.assert_allclose(classifier.predict_prob(X), expected, rtol=1e-9)


@pytest.mark.todo("2.2.2")
def test_untrained_two_class_model_says_one_half():
    np.testing.assert_array_equal(TwoClassLogisticRegressionClassifier(3).predict_prob(np.ones((4, 3))), 0.5)


@pytest.mark.todo("2.2.2")
def test_predict_prob_of_one_sample_and_of_integer_features():
    classifier = TwoClassLogisticRegressionClassifier(2)
    classifier.weights = np.array([0.0, 0.0, -3.0])  # only the bias: P = sigma(-3) for every sample
    np.testing.assert_allclose(classifier.predict_prob(np.array([[5, 7]])), [1.0 / (1.0 + np.exp(3.0))], rtol=1e-9)
    assert np.shape(classifier.predict_prob(np.zeros((6, 2), dtype=int))) == (6,)


@pytest.mark.todo("2.2.2")
def test_predict_thresholds_the_probability_at_one_half():
    classifier = TwoClassLogisticRegressionClassifier(1)
    classifier.weights = np.array([1.0, -1.0])  # score x - 1
    np.testing.assert_array_equal(classifier.predict(np.array([[0.0], [0.999], [1.001], [5.0]])), [0, 0, 1, 1])


# --- 2.2.3 gradient_ascent_step --------------------------------------------------------------


@pytest.mark.todo("2.2.3")
def test_step_follows_equation_8_with_the_gradient_of_equation_7():
    X, y = small_problem(seed=1)
    start = np.random.default_rng(1).normal(scale=0.3, size=4)
    classifier = TwoClassLogisticRegressionClassifier(3)
    classifier.weights = start.copy()
    classifier.gradient_ascent_step(X, y, learning_rate=0.05)
    np.testing.assert_allclose(classifier.weights, start + 0.05 * numerical_gradient(start, X, y), rtol=1e-6, atol=1e-8)


@pytest.mark.todo("2.2.3")
def test_steps_climb_the_log_likelihood():
    X, y = small_problem(seed=2)
    classifier = TwoClassLogisticRegressionClassifier(3)
    values = [log_likelihood(classifier.weights, X, y)]
    for _ in range(20):
        classifier.gradient_ascent_step(X, y, learning_rate=0.01)
        values.append(log_likelihood(classifier.weights, X, y))
    assert np.all(np.diff(values) > 0)


@pytest.mark.todo("2.2.3")
def test_step_changes_only_this_classifiers_weights_and_not_its_inputs():
    X, y = small_problem(seed=3)
    X_before, y_before = X.copy(), y.copy()
    stepped, other = TwoClassLogisticRegressionClassifier(3), TwoClassLogisticRegressionClassifier(3)
    stepped.gradient_ascent_step(X, y, learning_rate=0.1)
    assert np.shape(stepped.weights) == (4,) and np.all(np.isfinite(stepped.weights))
    assert np.any(stepped.weights != 0.0)
    np.testing.assert_array_equal(other.weights, np.zeros(4))
    np.testing.assert_array_equal(X, X_before)
    np.testing.assert_array_equal(y, y_before)


@pytest.mark.todo("2.2.3")
def test_step_treats_bool_int_and_float_labels_alike():
    X, y = small_problem(seed=4)
    results = []
    for labels in (y.astype(bool), y, y.astype(float)):
        classifier = TwoClassLogisticRegressionClassifier(3)
        classifier.gradient_ascent_step(X, labels, learning_rate=0.1)
        results.append(classifier.weights)
    np.testing.assert_allclose(results[1], results[0], rtol=1e-12)
    np.testing.assert_allclose(results[2], results[0], rtol=1e-12)


@pytest.mark.todo("2.2.3")
def test_two_class_fit_returns_accuracy_before_and_after_each_step():
    X, y = separable_problem()
    binary = (y == 0).astype(int)
    classifier = TwoClassLogisticRegressionClassifier(2)
    accuracies = classifier.fit(X, binary, learning_rate=0.1, n_iters=5)
    assert accuracies.shape == (6,)
    assert accuracies[0] == pytest.approx(np.mean(binary == 0))  # zero weights: every score is 0, predicted 0
    assert accuracies[-1] == 1.0


@pytest.mark.todo("2.2.3")
def test_fit_continues_from_the_current_weights():
    X, y = small_problem(seed=3)
    once = TwoClassLogisticRegressionClassifier(3)
    once.fit(X, y, 0.01, 4)
    twice = TwoClassLogisticRegressionClassifier(3)
    twice.fit(X, y, 0.01, 2)
    twice.fit(X, y, 0.01, 2)
    np.testing.assert_allclose(twice.weights, once.weights, rtol=1e-12)


# --- every argument is checked before a TODO's code runs -------------------------------------


@pytest.mark.parametrize("n_features", [0, -1, 2.5, True, "3", None])
def test_constructors_reject_bad_n_features(n_features):
    with pytest.raises(ValueError, match="n_features"):
        TwoClassLogisticRegressionClassifier(n_features)
    with pytest.raises(ValueError, match="n_features"):
        MultiClassLogisticRegressionClassifier(n_features, 3)


@pytest.mark.parametrize("n_classes", [0, 1, -2, 2.0, None])
def test_multi_class_rejects_bad_n_classes(n_classes):
    with pytest.raises(ValueError, match="n_classes"):
        MultiClassLogisticRegressionClassifier(2, n_classes)


@pytest.mark.parametrize("learning_rate", [0.0, -0.1, np.nan, np.inf, "0.1", None, True])
def test_training_rejects_bad_learning_rates(learning_rate):
    X, y = small_problem()
    with pytest.raises(ValueError, match="learning_rate"):
        TwoClassLogisticRegressionClassifier(3).gradient_ascent_step(X, y, learning_rate)
    for classifier in (TwoClassLogisticRegressionClassifier(3), MultiClassLogisticRegressionClassifier(3, 2)):
        with pytest.raises(ValueError, match="learning_rate"):
            classifier.fit(X, y, learning_rate, 5)


@pytest.mark.parametrize("n_iters", [0, -3, 2.5, "10", None])
def test_fit_rejects_bad_iteration_counts(n_iters):
    X, y = small_problem()
    for classifier in (TwoClassLogisticRegressionClassifier(3), MultiClassLogisticRegressionClassifier(3, 2)):
        with pytest.raises(ValueError, match="n_iters"):
            classifier.fit(X, y, 0.1, n_iters)


def test_training_rejects_labels_out_of_range():
    X, y = small_problem(num_classes=3)
    # The mistake of training a two-class model on the class labels 0..C-1 is stopped by the argument checks.
    with pytest.raises(ValueError, match=r"y must hold class indices 0\.\.1, found \[2\]"):
        TwoClassLogisticRegressionClassifier(3).gradient_ascent_step(X, y, 0.1)
    with pytest.raises(ValueError, match=r"y must hold class indices 0\.\.1, found \[2\]"):
        TwoClassLogisticRegressionClassifier(3).fit(X, np.full(len(X), 2), 0.1, 1)
    with pytest.raises(ValueError, match=r"y must hold class indices 0\.\.2, found \[-1\]"):
        MultiClassLogisticRegressionClassifier(3, 3).fit(X, np.full(len(X), -1), 0.1, 1)


def test_training_rejects_non_integer_labels():
    X, _ = small_problem()
    with pytest.raises(ValueError, match="y must hold whole-number class labels"):
        TwoClassLogisticRegressionClassifier(3).fit(X, np.full(len(X), 0.5), 0.1, 1)
    with pytest.raises(ValueError, match="y must hold whole-number class labels"):
        TwoClassLogisticRegressionClassifier(3).gradient_ascent_step(X, np.full(len(X), 0.5), 0.1)
    with pytest.raises(TypeError, match="y must be an array of integer class labels"):
        TwoClassLogisticRegressionClassifier(3).fit(X, ["a"] * len(X), 0.1, 1)


def test_training_rejects_labels_of_the_wrong_length_or_shape():
    X, y = small_problem()
    with pytest.raises(ValueError, match="y must have 40 entries"):
        TwoClassLogisticRegressionClassifier(3).fit(X, y[:-1], 0.1, 1)
    with pytest.raises(ValueError, match="y must have 40 entries"):
        TwoClassLogisticRegressionClassifier(3).gradient_ascent_step(X, y[:-1], 0.1)
    with pytest.raises(ValueError, match="y must be a non-empty 1-d array"):
        MultiClassLogisticRegressionClassifier(3, 2).fit(X, y[:, None], 0.1, 1)


BAD_FEATURES = [
    (np.ones((5, 4)), "X must have 3 columns"),
    (np.ones(3), "X must be a 2-d array"),
    (np.ones((0, 3)), "X must have at least one row"),
    (np.array([[1.0, np.nan, 0.0]]), "X must hold only finite numbers, found 1 NaN"),
    (np.array([[1.0, np.inf, -np.inf]]), "found 2 NaN or infinite"),
]


@pytest.mark.parametrize("X, message", BAD_FEATURES)
def test_predictions_reject_bad_features(X, message):
    for classifier in (TwoClassLogisticRegressionClassifier(3), MultiClassLogisticRegressionClassifier(3, 2)):
        with pytest.raises(ValueError, match=message):
            classifier.predict(X)
        with pytest.raises(ValueError, match=message):
            classifier.predict_prob(X)


@pytest.mark.parametrize("X, message", BAD_FEATURES)
def test_training_rejects_bad_features(X, message):
    y = np.zeros(len(X), dtype=int)
    with pytest.raises(ValueError, match=message):
        TwoClassLogisticRegressionClassifier(3).gradient_ascent_step(X, y, 0.1)
    with pytest.raises(ValueError, match=message):
        MultiClassLogisticRegressionClassifier(3, 2).fit(X, y, 0.1, 1)


def test_predictions_reject_non_numeric_features():
    with pytest.raises(TypeError, match="X must be an array of real numbers"):
        TwoClassLogisticRegressionClassifier(1).predict([["a"]])


# --- 2.1.1 the gradient, and the gradient check ---------------------------------------------


def test_log_likelihood_is_equation_7():
    X, y = small_problem(seed=4)
    weights = np.array([0.3, -0.2, 0.1, 0.05])
    p = 1.0 / (1.0 + np.exp(-(X @ weights[:3] + weights[3])))
    expected = np.sum(y * np.log(p) + (1 - y) * np.log(1 - p))
    assert log_likelihood(weights, X, y) == pytest.approx(expected, rel=1e-12)


def test_log_likelihood_stays_finite_and_silent_for_confident_mistakes():
    with silent():
        value = log_likelihood(np.array([1000.0, 0.0]), np.array([[1.0]]), np.array([0]))
    assert value == pytest.approx(-1000.0)


@pytest.mark.todo("2.1.1")
def test_gradient_is_shaped_like_the_weights_and_matches_finite_differences():
    X, y = small_problem(seed=5, num_samples=30)
    weights = np.array([0.5, -1.0, 0.2, 0.3])
    gradient = np.asarray(log_likelihood_gradient(weights, X, y))
    assert gradient.shape == (4,)
    np.testing.assert_allclose(gradient, numerical_gradient(weights, X, y), rtol=1e-6, atol=1e-6)


@pytest.mark.todo("2.1.1")
def test_gradient_check_passes_for_the_analytic_gradient():
    X, y = small_problem(seed=6, num_samples=25, num_features=4)
    weights = np.random.default_rng(6).normal(size=5)
    assert gradient_check(weights, X, y) < 1e-7


@pytest.mark.todo("2.1.1")
def test_gradient_check_is_the_relative_error_the_notebook_prints():
    X, y = small_problem(seed=0, num_samples=20, num_features=5)
    weights = np.random.default_rng(0).normal(size=6)
    analytic = log_likelihood_gradient(weights, X, y)
    numeric = numerical_gradient(weights, X, y, step=1e-5)
    error = np.linalg.norm(analytic - numeric) / (np.linalg.norm(analytic) + np.linalg.norm(numeric))
    assert error < 1e-6
    assert gradient_check(weights, X, y) == pytest.approx(error, rel=1e-3, abs=1e-9)
    flipped = np.linalg.norm(-analytic - numeric) / (np.linalg.norm(analytic) + np.linalg.norm(numeric))
    assert flipped > 0.5


@pytest.mark.todo("2.1.1")
def test_gradient_check_catches_a_wrong_sign(monkeypatch):
    # The handout's equation (5) read literally gives sigma(-z): the gradient flips sign.
    monkeypatch.setattr(logreg, "log_likelihood_gradient", lambda w, X, y: -log_likelihood_gradient(w, X, y))
    X, y = small_problem(seed=6, num_samples=25, num_features=4)
    weights = np.random.default_rng(6).normal(size=5)
    assert logreg.gradient_check(weights, X, y) > 0.9


def test_gradient_functions_reject_mismatched_weights():
    X, y = small_problem()
    with pytest.raises(ValueError, match=r"weights must have shape \(4,\)"):
        log_likelihood_gradient(np.zeros(3), X, y)
    with pytest.raises(ValueError, match="weights must hold only finite numbers"):
        log_likelihood(np.array([0.0, np.nan, 0.0, 0.0]), X, y)
    with pytest.raises(ValueError, match="step must be a finite number > 0"):
        gradient_check(np.zeros(4), X, y, step=0.0)
    with pytest.raises(ValueError, match=r"labels must hold class indices 0\.\.1"):
        gradient_check(np.zeros(4), X, y + 1)


# --- 2.3.1 one-vs-rest ----------------------------------------------------------------------


@pytest.mark.todo("2.3.1")
def test_each_class_model_takes_exactly_one_two_class_step_per_iteration():
    X, y = small_problem(seed=7, num_classes=4)
    multi = MultiClassLogisticRegressionClassifier(3, 4)
    multi.fit(X, y, learning_rate=0.1, n_iters=1)
    for c in range(4):
        single = TwoClassLogisticRegressionClassifier(3)
        single.gradient_ascent_step(X, (y == c).astype(int), learning_rate=0.1)
        np.testing.assert_allclose(multi.classifiers[c].weights, single.weights, rtol=1e-12)


@pytest.mark.todo("2.3.1")
def test_class_models_own_their_weights_and_the_stack_follows_them():
    X, y = separable_problem()
    multi = MultiClassLogisticRegressionClassifier(2, 3)
    multi.fit(X, y, 0.1, 3)
    stacked = multi.weights
    assert stacked.shape == (3, 3)
    for c, classifier in enumerate(multi.classifiers):
        np.testing.assert_array_equal(stacked[:, c], classifier.weights)
        for other in multi.classifiers[c + 1:]:
            assert not np.shares_memory(classifier.weights, other.weights)
    with pytest.raises(ValueError, match="read-only"):
        stacked[0, 0] = 1.0  # a copy: writing to it would change nothing, so it refuses


@pytest.mark.todo("2.3.1")
def test_multi_class_learns_separable_blobs():
    X, y = separable_problem()
    multi = MultiClassLogisticRegressionClassifier(2, 3)
    accuracies = multi.fit(X, y, 0.01, 20)
    assert accuracies.shape == (21,)
    assert accuracies[0] == pytest.approx(1 / 3)  # all scores 0: the tie goes to class 0
    assert accuracies[-1] == 1.0
    np.testing.assert_array_equal(multi.predict(X), y)
    probabilities = multi.predict_prob(X)
    assert probabilities.shape == (90, 3)
    np.testing.assert_array_equal(np.argmax(probabilities, axis=1), y)


@pytest.mark.todo("2.3.1")
def test_multi_class_fit_continues_and_leaves_its_inputs_alone():
    X, y = small_problem(seed=8, num_classes=3)
    X_before, y_before = X.copy(), y.copy()
    once = MultiClassLogisticRegressionClassifier(3, 3)
    once.fit(X, y, 0.05, 4)
    twice = MultiClassLogisticRegressionClassifier(3, 3)
    twice.fit(X, y, 0.05, 2)
    twice.fit(X, y, 0.05, 2)
    np.testing.assert_allclose(twice.weights, once.weights, rtol=1e-12)
    np.testing.assert_array_equal(X, X_before)
    np.testing.assert_array_equal(y, y_before)


@pytest.mark.todo("2.3.1")
def test_one_step_on_the_food_data_stays_finite():
    data = load_food_cutting()
    multi = MultiClassLogisticRegressionClassifier(data.features.shape[1], len(data.names))
    accuracies = multi.fit(data.features, data.labels, settings.P2_LEARNING_RATE, 2)
    assert np.all(np.isfinite(multi.weights))
    assert accuracies[-1] > accuracies[0]


def test_predict_has_no_ties_where_probabilities_round_to_one():
    multi = MultiClassLogisticRegressionClassifier(1, 3)
    for classifier, weights in zip(multi.classifiers, ([100.0, 0.0], [200.0, 0.0], [-5.0, 0.0])):
        classifier.weights = np.array(weights)
    # Scores 1000, 2000, -50: the first two probabilities are both 1.0 in float64; the scores are not.
    assert multi.predict(np.array([[10.0]]))[0] == 1
    np.testing.assert_array_equal(multi.decision_function(np.array([[10.0]])), [[1000.0, 2000.0, -50.0]])


# --- metrics and the split ------------------------------------------------------------------


def test_accuracy_counts_matches():
    assert accuracy([0, 1, 2, 2], [0, 1, 1, 2]) == 0.75
    assert accuracy(np.array([3]), np.array([3])) == 1.0


@pytest.mark.parametrize(
    "y_true, y_pred, error, message",
    [
        ([0, 1], [0], ValueError, "y_pred must have 2 entries"),
        ([], [], ValueError, "y_true must be a non-empty 1-d array"),
        ([[0, 1]], [[0, 1]], ValueError, "y_true must be a non-empty 1-d array"),
        (["a"], ["a"], TypeError, "y_true must be an array of integer class labels"),
        ([0.5], [0], ValueError, "y_true must hold whole-number class labels"),
    ],
)
def test_accuracy_rejects_bad_labels(y_true, y_pred, error, message):
    with pytest.raises(error, match=message):
        accuracy(y_true, y_pred)


def test_confusion_matrix_rows_are_true_columns_are_predicted():
    counts = confusion_matrix([0, 0, 1, 2, 2, 2], [0, 1, 1, 2, 0, 2], 3)
    np.testing.assert_array_equal(counts, [[1, 1, 0], [0, 1, 0], [1, 0, 2]])
    assert counts.dtype == np.int64


def test_confusion_matrix_rejects_labels_out_of_range():
    with pytest.raises(ValueError, match=r"y_pred must hold class indices 0\.\.2, found \[3\]"):
        confusion_matrix([0, 1], [0, 3], 3)
    with pytest.raises(ValueError, match="n_classes"):
        confusion_matrix([0], [0], 0)


def test_per_class_accuracy_is_the_recall_of_each_class():
    result = per_class_accuracy([0, 0, 1, 1, 1, 2], [0, 1, 1, 1, 0, 2], 4)
    np.testing.assert_allclose(result[:3], [0.5, 2 / 3, 1.0])
    assert np.isnan(result[3])  # class 3 has no samples


def test_train_test_split_is_a_seeded_partition():
    features = np.arange(20.0).reshape(10, 2)
    labels = np.arange(10) % 3
    X_train, X_test, y_train, y_test = train_test_split(features, labels, test_fraction=0.3, seed=4)
    assert X_test.shape == (3, 2) and X_train.shape == (7, 2)
    rows = np.concatenate([X_train[:, 0], X_test[:, 0]]) / 2
    np.testing.assert_array_equal(np.sort(rows), np.arange(10))
    np.testing.assert_array_equal(y_train, (X_train[:, 0] / 2).astype(int) % 3)  # rows and labels stay paired
    again = train_test_split(features, labels, test_fraction=0.3, seed=4)
    np.testing.assert_array_equal(again[1], X_test)
    other = train_test_split(features, labels, test_fraction=0.3, seed=5)
    assert not np.array_equal(other[1], X_test)


def test_train_test_split_uses_no_global_random_state():
    features, labels = np.arange(40.0).reshape(20, 2), np.zeros(20, dtype=int)
    np.random.seed(1)
    first = train_test_split(features, labels, seed=0)[1]
    np.random.seed(2)
    np.testing.assert_array_equal(train_test_split(features, labels, seed=0)[1], first)


@pytest.mark.parametrize("test_fraction", [0.0, 1.0, -0.1, 1.5, np.nan, True, "0.3"])
def test_train_test_split_rejects_bad_fractions(test_fraction):
    with pytest.raises(ValueError, match="test_fraction"):
        train_test_split(np.ones((10, 2)), np.zeros(10, dtype=int), test_fraction=test_fraction)


def test_train_test_split_rejects_an_empty_part_bad_seed_and_mismatched_labels():
    with pytest.raises(ValueError, match="leaves an empty train or test set"):
        train_test_split(np.ones((2, 2)), np.zeros(2, dtype=int), test_fraction=0.1)
    with pytest.raises(ValueError, match="seed"):
        train_test_split(np.ones((10, 2)), np.zeros(10, dtype=int), seed=-1)
    with pytest.raises(ValueError, match="labels must have 10 entries"):
        train_test_split(np.ones((10, 2)), np.zeros(9, dtype=int))


def test_first_iteration_above():
    assert first_iteration_above([0.1, 0.5, 0.991, 0.98, 0.995]) == 2
    assert first_iteration_above([0.1, 0.99]) is None  # strictly above
    assert first_iteration_above([0.1, 0.6], threshold=0.5) == 1
    with pytest.raises(ValueError, match="accuracies must be a non-empty 1-d array"):
        first_iteration_above([])
    with pytest.raises(ValueError, match="threshold"):
        first_iteration_above([0.5], threshold=2)


def test_public_names_are_importable_from_the_top_level():
    for name in ("MultiClassLogisticRegressionClassifier", "sigmoid", "load_food_cutting", "gradient_check"):
        assert hasattr(hwlib, name)
