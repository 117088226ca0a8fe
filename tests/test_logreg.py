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
    sigmoid,
    train_test_split,
)
from hwlib import logreg


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


# --- sigmoid -----------------------------------------------------------------------------


@pytest.mark.todo("2.2.1")
def test_sigmoid_matches_the_textbook_formula_where_that_is_safe():
    z = np.linspace(-30, 30, 121)
    np.testing.assert_allclose(sigmoid(z), 1.0 / (1.0 + np.exp(-z)), rtol=1e-13, atol=0)


@pytest.mark.todo("2.2.1")
def test_sigmoid_uses_the_standard_sign_convention():
    assert sigmoid(0.0) == 0.5
    assert sigmoid(2.0) > 0.5 > sigmoid(-2.0)


@pytest.mark.todo("2.2.1")
def test_sigmoid_is_symmetric():
    z = np.linspace(-40, 40, 81)
    np.testing.assert_allclose(sigmoid(-z), 1.0 - sigmoid(z), atol=1e-16)


@pytest.mark.todo("2.2.1")
def test_sigmoid_extremes_are_exact_and_silent():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with np.errstate(over="raise", invalid="raise", divide="raise"):
            values = sigmoid(np.array([-1000.0, -745.0, 745.0, 1000.0, -1e308, 1e308]))
    assert values[0] == 0.0 and values[3] == 1.0
    assert values[4] == 0.0 and values[5] == 1.0
    assert not np.any(np.isnan(values))


@pytest.mark.todo("2.2.1")
def test_sigmoid_keeps_shape():
    assert sigmoid(np.zeros((2, 3, 4))).shape == (2, 3, 4)
    assert np.ndim(sigmoid(1.0)) == 0
    assert sigmoid([0, 0]).dtype == np.float64  # integer input works too


@pytest.mark.parametrize("bad", [np.nan, [0.0, np.inf], [-np.inf]])
def test_sigmoid_rejects_non_finite_input(bad):
    with pytest.raises(ValueError, match="z must hold only finite numbers"):
        sigmoid(bad)


@pytest.mark.parametrize("bad", ["1.0", ["a", "b"], [object()]])
def test_sigmoid_rejects_non_numbers(bad):
    with pytest.raises(TypeError, match="z must be an array of real numbers"):
        sigmoid(bad)


# --- the two-class model -----------------------------------------------------------------


def test_add_bias_feature_appends_a_column_of_ones():
    augmented = add_bias_feature([[1.0, 2.0], [3.0, 4.0]])
    np.testing.assert_array_equal(augmented, [[1.0, 2.0, 1.0], [3.0, 4.0, 1.0]])


@pytest.mark.todo("2.2.2")
def test_predict_prob_uses_the_bias_as_the_last_weight():
    classifier = TwoClassLogisticRegressionClassifier(2)
    classifier.weights[:] = [1.0, -2.0, 0.5]
    X = np.array([[1.0, 1.0], [0.0, 0.0], [2.0, -1.0]])
    expected = 1.0 / (1.0 + np.exp(-(X @ [1.0, -2.0] + 0.5)))
    np.testing.assert_allclose(classifier.predict_prob(X), expected, rtol=1e-14)


@pytest.mark.todo("2.2.2")
def test_untrained_two_class_model_says_one_half():
    np.testing.assert_array_equal(TwoClassLogisticRegressionClassifier(3).predict_prob(np.ones((4, 3))), 0.5)


def test_predict_thresholds_the_probability_at_one_half():
    classifier = TwoClassLogisticRegressionClassifier(1)
    classifier.weights[:] = [1.0, -1.0]  # logit x - 1
    np.testing.assert_array_equal(classifier.predict(np.array([[0.0], [0.999], [1.001], [5.0]])), [0, 0, 1, 1])


@pytest.mark.todo("2.2.3")
@pytest.mark.hidden  # shows the gradient of 2.1.1: instructor-only
def test_first_fit_step_is_the_summed_gradient_of_equation_7():
    X, y = small_problem(seed=1)
    classifier = TwoClassLogisticRegressionClassifier(3)
    classifier.fit(X, y, learning_rate=0.05, n_iters=1)
    X_aug = np.hstack([X, np.ones((len(X), 1))])
    np.testing.assert_allclose(classifier.weights, 0.05 * X_aug.T @ (y - 0.5), rtol=1e-13)


@pytest.mark.todo("2.2.3")
def test_fit_climbs_the_log_likelihood():
    X, y = small_problem(seed=2)
    classifier = TwoClassLogisticRegressionClassifier(3)
    values = []
    for _ in range(20):
        classifier.fit(X, y, learning_rate=0.01, n_iters=1)
        values.append(log_likelihood(classifier.weights, X, y))
    assert np.all(np.diff(values) > 0)


@pytest.mark.todo("2.2.3")
def test_two_class_fit_returns_accuracy_before_and_after_each_step():
    X, y = separable_problem()
    binary = (y == 0).astype(int)
    classifier = TwoClassLogisticRegressionClassifier(2)
    accuracies = classifier.fit(X, binary, learning_rate=0.1, n_iters=5)
    assert accuracies.shape == (6,)
    assert accuracies[0] == pytest.approx(np.mean(binary == 0))  # zero weights predict 0 everywhere
    assert accuracies[-1] == accuracy(binary, classifier.predict(X)) == 1.0


@pytest.mark.todo("2.2.3")
def test_fit_continues_from_the_current_weights():
    X, y = small_problem(seed=3)
    once = TwoClassLogisticRegressionClassifier(3)
    once.fit(X, y, 0.01, 4)
    twice = TwoClassLogisticRegressionClassifier(3)
    twice.fit(X, y, 0.01, 2)
    twice.fit(X, y, 0.01, 2)
    np.testing.assert_allclose(twice.weights, once.weights, rtol=1e-14)


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
def test_fit_rejects_bad_learning_rates(learning_rate):
    X, y = small_problem()
    for classifier in (TwoClassLogisticRegressionClassifier(3), MultiClassLogisticRegressionClassifier(3, 2)):
        with pytest.raises(ValueError, match="learning_rate"):
            classifier.fit(X, y, learning_rate, 5)


@pytest.mark.parametrize("n_iters", [0, -3, 2.5, "10", None])
def test_fit_rejects_bad_iteration_counts(n_iters):
    X, y = small_problem()
    for classifier in (TwoClassLogisticRegressionClassifier(3), MultiClassLogisticRegressionClassifier(3, 2)):
        with pytest.raises(ValueError, match="n_iters"):
            classifier.fit(X, y, 0.1, n_iters)


def test_fit_rejects_labels_out_of_range():
    X, _ = small_problem()
    with pytest.raises(ValueError, match=r"y must hold class indices 0\.\.1, found \[2\]"):
        TwoClassLogisticRegressionClassifier(3).fit(X, np.full(len(X), 2), 0.1, 1)
    with pytest.raises(ValueError, match=r"y must hold class indices 0\.\.2, found \[-1\]"):
        MultiClassLogisticRegressionClassifier(3, 3).fit(X, np.full(len(X), -1), 0.1, 1)


def test_fit_rejects_non_integer_labels():
    X, _ = small_problem()
    with pytest.raises(ValueError, match="y must hold whole-number class labels"):
        TwoClassLogisticRegressionClassifier(3).fit(X, np.full(len(X), 0.5), 0.1, 1)
    with pytest.raises(TypeError, match="y must be an array of integer class labels"):
        TwoClassLogisticRegressionClassifier(3).fit(X, ["a"] * len(X), 0.1, 1)


def test_fit_rejects_labels_of_the_wrong_length_or_shape():
    X, y = small_problem()
    with pytest.raises(ValueError, match="y must have 40 entries"):
        TwoClassLogisticRegressionClassifier(3).fit(X, y[:-1], 0.1, 1)
    with pytest.raises(ValueError, match="y must be a non-empty 1-d array"):
        MultiClassLogisticRegressionClassifier(3, 2).fit(X, y[:, None], 0.1, 1)


@pytest.mark.parametrize(
    "X, message",
    [
        (np.ones((5, 4)), "X must have 3 columns"),
        (np.ones(3), "X must be a 2-d array"),
        (np.ones((0, 3)), "X must have at least one row"),
        (np.array([[1.0, np.nan, 0.0]]), "X must hold only finite numbers, found 1 NaN"),
        (np.array([[1.0, np.inf, -np.inf]]), "found 2 NaN or infinite"),
    ],
)
def test_predictions_reject_bad_features(X, message):
    for classifier in (TwoClassLogisticRegressionClassifier(3), MultiClassLogisticRegressionClassifier(3, 2)):
        with pytest.raises(ValueError, match=message):
            classifier.predict(X)
        with pytest.raises(ValueError, match=message):
            classifier.predict_prob(X)


def test_predictions_reject_non_numeric_features():
    with pytest.raises(TypeError, match="X must be an array of real numbers"):
        TwoClassLogisticRegressionClassifier(1).predict([["a"]])


# --- log-likelihood, its gradient, and the gradient check --------------------------------


def test_log_likelihood_is_equation_7():
    X, y = small_problem(seed=4)
    weights = np.array([0.3, -0.2, 0.1, 0.05])
    p = 1.0 / (1.0 + np.exp(-(X @ weights[:3] + weights[3])))
    expected = np.sum(y * np.log(p) + (1 - y) * np.log(1 - p))
    assert log_likelihood(weights, X, y) == pytest.approx(expected, rel=1e-12)


def test_log_likelihood_stays_finite_for_confident_mistakes():
    value = log_likelihood(np.array([1000.0, 0.0]), np.array([[1.0]]), np.array([0]))
    assert value == pytest.approx(-1000.0)


@pytest.mark.todo("2.1.1")
@pytest.mark.hidden  # shows the gradient of 2.1.1: instructor-only
def test_gradient_matches_the_closed_form():
    X, y = small_problem(seed=5)
    weights = np.array([0.5, -1.0, 0.2, 0.3])
    X_aug = np.hstack([X, np.ones((len(X), 1))])
    expected = X_aug.T @ (y - 1.0 / (1.0 + np.exp(-X_aug @ weights)))
    np.testing.assert_allclose(log_likelihood_gradient(weights, X, y), expected, rtol=1e-12)


@pytest.mark.todo("2.1.1")
def test_gradient_check_passes_for_the_analytic_gradient():
    X, y = small_problem(seed=6, num_samples=25, num_features=4)
    weights = np.random.default_rng(6).normal(size=5)
    assert gradient_check(weights, X, y) < 1e-7


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


# --- one-vs-rest ----------------------------------------------------------------------------


@pytest.mark.todo("2.3.1")
def test_each_class_model_takes_exactly_one_two_class_step_per_iteration():
    X, y = small_problem(seed=7, num_classes=4)
    multi = MultiClassLogisticRegressionClassifier(3, 4)
    multi.fit(X, y, learning_rate=0.1, n_iters=1)
    for c in range(4):
        single = TwoClassLogisticRegressionClassifier(3)
        single.fit(X, (y == c).astype(int), learning_rate=0.1, n_iters=1)
        np.testing.assert_allclose(multi.classifiers[c].weights, single.weights, rtol=1e-13)


@pytest.mark.todo("2.3.1")
def test_class_models_share_the_weight_matrix():
    X, y = separable_problem()
    multi = MultiClassLogisticRegressionClassifier(2, 3)
    multi.fit(X, y, 0.1, 3)
    for c, classifier in enumerate(multi.classifiers):
        np.testing.assert_array_equal(classifier.weights, multi.weights[:, c])
        np.testing.assert_allclose(classifier.predict_prob(X), multi.predict_prob(X)[:, c], rtol=1e-12)


@pytest.mark.todo("2.3.1")
def test_multi_class_learns_separable_blobs():
    X, y = separable_problem()
    multi = MultiClassLogisticRegressionClassifier(2, 3)
    accuracies = multi.fit(X, y, 0.01, 20)
    assert accuracies.shape == (21,)
    assert accuracies[0] == pytest.approx(1 / 3)  # all logits 0: the tie goes to class 0
    assert accuracies[-1] == 1.0
    np.testing.assert_array_equal(multi.predict(X), y)
    assert multi.predict_prob(X).shape == (90, 3)


@pytest.mark.todo("2.3.1")
def test_vectorized_fit_gives_the_same_numbers_as_the_per_class_loop():
    data = load_food_cutting()
    X_train, _, y_train, _ = train_test_split(data.features, data.labels, 0.3, seed=0)
    loop = MultiClassLogisticRegressionClassifier(X_train.shape[1], 7)
    vectorized = MultiClassLogisticRegressionClassifier(X_train.shape[1], 7)
    loop_accuracies = loop.fit(X_train, y_train, 0.1, 30)
    vectorized_accuracies = vectorized.fit(X_train, y_train, 0.1, 30, vectorized=True)
    np.testing.assert_array_equal(vectorized_accuracies, loop_accuracies)
    np.testing.assert_allclose(vectorized.weights, loop.weights, rtol=1e-9, atol=1e-9 * np.abs(loop.weights).max())


@pytest.mark.todo("2.2.1")
def test_predict_has_no_ties_when_probabilities_round_to_one():
    multi = MultiClassLogisticRegressionClassifier(1, 3)
    multi.weights[:] = [[100.0, 200.0, -5.0], [0.0, 0.0, 0.0]]
    X = np.array([[10.0]])  # logits 1000, 2000, -50: probabilities 1.0, 1.0, ~0
    assert multi.predict_prob(X)[0, 0] == multi.predict_prob(X)[0, 1] == 1.0
    assert multi.predict(X)[0] == 1


@pytest.mark.todo("2.3.1")
def test_one_step_on_the_food_data_stays_finite():
    data = load_food_cutting()
    multi = MultiClassLogisticRegressionClassifier(data.features.shape[1], len(data.names))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        multi.fit(data.features, data.labels, 0.1, 2)
    assert np.all(np.isfinite(multi.weights))


@pytest.mark.todo("2.3.1")
def test_training_exceeds_99_percent_within_70_iterations_on_this_machines_data():
    data = load_food_cutting()  # the course's file when data/data.npz exists, else the stand-in
    X_train, X_test, y_train, y_test = train_test_split(data.features, data.labels, test_fraction=0.3, seed=0)
    multi = MultiClassLogisticRegressionClassifier(X_train.shape[1], len(data.names))
    accuracies = multi.fit(X_train, y_train, learning_rate=0.1, n_iters=70)
    first = first_iteration_above(accuracies, 0.99)
    assert first is not None and first <= 70, f"{data.source}: train accuracy {accuracies[-1]:.4f} after 70 iterations"
    assert accuracy(y_test, multi.predict(X_test)) > 0.95


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


def test_fit_rejects_a_non_boolean_vectorized_flag():
    X, y = small_problem()
    with pytest.raises(TypeError, match="vectorized must be True or False"):
        MultiClassLogisticRegressionClassifier(3, 2).fit(X, y, 0.1, 1, vectorized="yes")
