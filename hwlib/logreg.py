"""Logistic regression by gradient ascent on the log-likelihood: two-class, and one-vs-rest for C classes.

The model of the handout's equations (5)-(8), with the standard sign convention
``sigma(z) = 1 / (1 + exp(-z))`` and the bias folded in as a constant-1 feature (equation 6):

| name              | shape              | meaning                                                     |
|-------------------|--------------------|-------------------------------------------------------------|
| ``X``             | (N, M) float       | one sample per row, raw features (no constant-1 column)     |
| ``X_aug``         | (N, M + 1)         | ``X`` with a column of ones appended (equation 6)           |
| ``y`` (two-class) | (N,) 0/1           | 1 marks the positive class                                  |
| ``y`` (C classes) | (N,) int 0..C-1    | the class of each sample                                    |
| ``weights``       | (M + 1,)           | one two-class model ``[w, b]``, bias last; each model owns its own |
| stacked weights   | (M + 1, C)         | ``MultiClassLogisticRegressionClassifier.weights``: column c is a copy of ``classifiers[c].weights`` |
| accuracies        | (n_iters + 1,)     | ``accuracies[t]``: training accuracy after t iterations      |

The handout's TODOs in this file: ``sigmoid`` (2.2.1), ``TwoClassLogisticRegressionClassifier.predict_prob``
(2.2.2) and ``.gradient_ascent_step`` (2.2.3), the loop over classes in
``MultiClassLogisticRegressionClassifier.fit`` (2.3.1), and ``log_likelihood_gradient``, the code of
the derivation of 2.1.1. Every public function checks its arguments before its TODO runs, so the
code of a TODO can trust them. Training starts from zero weights and uses the *summed* (not
averaged) gradient of equation (7), as the course's skeleton does.
"""

from __future__ import annotations

import numbers

import numpy as np

from hwlib.finite_diff import scalar_finite_diff
from hwlib.machinery.todos import TodoNotDone  # noqa: F401 - the TODOs' starting code raises it until you write them
from hwlib.machinery.validation import (
    as_finite_float_array,
    check_count,
    check_features,
    check_label_vector,
    check_labels,
    check_positive_number,
    check_seed,
    check_two_class_problem,
    with_bias,
)


def sigmoid(z):
    """The logistic function ``sigma(z) = 1 / (1 + e^(-z))``, applied to every entry of ``z``.

    ``z``: a number or an array of any shape, finite. Returns float64 values in [0, 1], shaped like
    ``z``: ``sigmoid(0) = 0.5``, near 1 for large positive ``z``, near 0 for large negative ``z``
    (``sigmoid(-1000)`` is 0, not NaN).
    """
    z = as_finite_float_array(z, "z")
    ### BEGIN SOLUTION 2.2.1
    ### HINT: 1 / (1 + e^(-z)) for every entry of z (the standard sign; the notebook explains the slip in equation (5))
    # e^(-|z|) lies in (0, 1] and cannot overflow; for z < 0, sigma(z) = e^z / (1 + e^z) = e^(-|z|) / (1 + e^(-|z|)).
    with np.errstate(under="ignore"):
        decay = np.exp(-np.abs(z))
    values = np.where(z >= 0, 1.0 / (1.0 + decay), decay / (1.0 + decay))
    ### END SOLUTION 2.2.1
    return values


def add_bias_feature(features):
    """``features`` (N, M) with a column of ones appended: the ``X_aug`` of equation (6), shape (N, M + 1)."""
    return with_bias(check_features(features, "X"))


def log_likelihood(weights, features, labels):
    """Equation (7): the log-likelihood of 0/1 ``labels`` under the two-class model ``weights``.

    ``weights`` has shape (M + 1,) with the bias last, ``features`` (N, M), ``labels`` (N,).
    Computed as ``sum(y * z - log(1 + e^z))`` with ``z`` the score of each sample, which is
    equation (7) rearranged so that no logarithm of 0 can occur.
    """
    features_aug, labels, weights = check_two_class_problem(weights, features, labels)
    scores = features_aug @ weights
    return float(np.sum(labels * scores - np.logaddexp(0.0, scores)))


def log_likelihood_gradient(weights, features, labels):
    """The gradient of the log-likelihood of equation (7) with respect to ``weights`` (your derivation of 2.1.1).

    ``weights`` (M + 1,), bias last; ``features`` (N, M); ``labels`` (N,) 0/1. Given to your code:
    ``features_aug`` (N, M + 1), the features with the constant 1 of equation (6) appended, and
    ``labels`` as floats. Returns a float64 array shaped like ``weights``: the sum over the N
    samples, not the mean.
    """
    features_aug, labels, weights = check_two_class_problem(weights, features, labels)
    gradient = np.zeros_like(weights)
    ### BEGIN SOLUTION 2.1.1
    ### HINT: the gradient of equation (7) that you derived in 2.1.1, evaluated at weights and summed over the N samples
    gradient = features_aug.T @ (labels - sigmoid(features_aug @ weights))
    ### END SOLUTION 2.1.1
    return gradient


def gradient_check(weights, features, labels, step=1e-5):
    """Relative error between ``log_likelihood_gradient`` and central finite differences of ``log_likelihood``.

    The finite differences come from problem 1's ``scalar_finite_diff``; the error is
    ``|g_analytic - g_numeric| / (|g_analytic| + |g_numeric|)`` (Euclidean norms), 0.0 when both
    are zero. Around 1e-10 for a correct gradient on a small problem; a wrong sign or a missing
    term gives something of order 1.
    """
    features_aug, labels, weights = check_two_class_problem(weights, features, labels)
    step = check_positive_number(step, "step")
    features = features_aug[:, :-1]
    analytic = log_likelihood_gradient(weights, features, labels)
    numeric = scalar_finite_diff(lambda w: log_likelihood(w, features, labels), weights, step)
    scale = np.linalg.norm(analytic) + np.linalg.norm(numeric)
    return 0.0 if scale == 0.0 else float(np.linalg.norm(analytic - numeric) / scale)


class TwoClassLogisticRegressionClassifier:
    """Logistic regression for labels 0/1, trained by gradient ascent from zero weights.

    ``weights`` (shape (n_features + 1,), bias last) is the ``w~`` of equation (6). The
    classifier owns it: ``self.weights = ...`` and ``self.weights += ...`` both update it.
    """

    def __init__(self, n_features):
        self.n_features = check_count(n_features, "n_features")
        self.weights = np.zeros(self.n_features + 1)

    def predict_prob(self, X):
        """P(y = 1 | x) for each row x of ``X``: equation (5) with the standard sign (see ``sigmoid``).

        ``X``: (N, n_features), one sample per row, without the constant 1 feature. Returns shape (N,).
        """
        X = check_features(X, "X", self.n_features)
        ### BEGIN SOLUTION 2.2.2
        ### HINT: append the constant 1 feature to each sample (equation (6)), then the sigmoid of each sample's score w~^T x~
        X_aug = np.hstack([X, np.ones((X.shape[0], 1))])
        probabilities = sigmoid(X_aug @ self.weights)
        ### END SOLUTION 2.2.2
        return probabilities

    def predict(self, X):
        """Labels 0/1, shape (N,): 1 where ``predict_prob`` exceeds 0.5."""
        return (self.predict_prob(X) > 0.5).astype(np.int64)

    def gradient_ascent_step(self, X, y, learning_rate):
        """One step of gradient ascent on the log-likelihood, equation (8), applied to ``self.weights``.

        ``X`` (N, n_features) samples, ``y`` (N,) labels 0/1, ``learning_rate`` > 0. The gradient
        is the one you derived in 2.1.1, summed over the N samples. Given to your code: ``X_aug``
        (N, n_features + 1), the samples with the constant 1 of equation (6) appended, and ``y``
        as floats. Returns nothing: the step updates ``self.weights``.
        """
        X_aug = with_bias(check_features(X, "X", self.n_features))  # X with the constant 1 of equation (6) appended
        y = check_labels(y, "y", 2, len(X_aug)).astype(np.float64)  # 0.0 and 1.0
        learning_rate = check_positive_number(learning_rate, "learning_rate")
        ### BEGIN SOLUTION 2.2.3
        ### HINT: the gradient of equation (7) at self.weights (your 2.1.1 result), then the update of equation (8) on self.weights
        probabilities = sigmoid(X_aug @ self.weights)
        gradient = X_aug.T @ (y - probabilities)
        self.weights = self.weights + learning_rate * gradient
        ### END SOLUTION 2.2.3

    def fit(self, X, y, learning_rate, n_iters):
        """``n_iters`` gradient-ascent steps on equation (7), continuing from the current weights.

        Returns the training accuracy before the first step and after each step, shape (n_iters + 1,).
        """
        X = check_features(X, "X", self.n_features)
        y = check_labels(y, "y", 2, len(X))
        learning_rate = check_positive_number(learning_rate, "learning_rate")
        n_iters = check_count(n_iters, "n_iters")
        X_aug = with_bias(X)
        accuracies = [self._accuracy(X_aug, y)]
        for _ in range(n_iters):
            self.gradient_ascent_step(X, y, learning_rate)
            accuracies.append(self._accuracy(X_aug, y))
        return np.array(accuracies)

    def _accuracy(self, X_aug, y):
        # A positive score is a probability above 0.5: the same labels as predict, without predict_prob.
        return np.mean((X_aug @ self.weights > 0) == y)


class MultiClassLogisticRegressionClassifier:
    """One-vs-rest logistic regression: one two-class classifier per class.

    ``classifiers[c]`` separates class c (label 1) from all other classes (label 0) and owns its
    weights. ``weights`` stacks them side by side, shape (n_features + 1, n_classes), and
    ``predict`` picks, for each sample, the class whose classifier gives the highest score.
    """

    def __init__(self, n_features, n_classes):
        self.n_features = check_count(n_features, "n_features")
        self.n_classes = check_count(n_classes, "n_classes")
        if self.n_classes < 2:
            raise ValueError(f"n_classes must be at least 2, got {n_classes!r}")
        self.classifiers = [TwoClassLogisticRegressionClassifier(self.n_features) for _ in range(self.n_classes)]

    @property
    def weights(self):
        """The classifiers' weights side by side, shape (n_features + 1, n_classes); a read-only copy.

        To change the model, change ``classifiers[c].weights``.
        """
        stacked = np.column_stack([classifier.weights for classifier in self.classifiers])
        stacked.flags.writeable = False
        return stacked

    def decision_function(self, X):
        """The score of every class's classifier for every sample, shape (N, n_classes)."""
        return with_bias(check_features(X, "X", self.n_features)) @ self.weights

    def predict_prob(self, X):
        """P(class c | x) of each one-vs-rest classifier, shape (N, n_classes); rows need not sum to 1."""
        X = check_features(X, "X", self.n_features)
        return np.column_stack([classifier.predict_prob(X) for classifier in self.classifiers])

    def predict(self, X):
        """The most probable class of each row, shape (N,).

        Taken as the highest score: sigma is increasing, so this is the class of highest
        probability, and unlike probabilities that have rounded to exactly 1.0 it has no ties.
        """
        return np.argmax(self.decision_function(X), axis=1)

    def fit(self, X, y, learning_rate, n_iters):
        """``n_iters`` outer iterations of one-vs-rest training, from the current weights.

        ``X`` (N, n_features), ``y`` (N,) class labels 0..n_classes-1, ``learning_rate`` > 0. In each
        iteration every class's classifier takes one gradient-ascent step, on its own two-class
        labels. Returns the training accuracy before the first iteration and after each, shape (n_iters + 1,).
        """
        X = check_features(X, "X", self.n_features)
        y = check_labels(y, "y", self.n_classes, len(X))  # int class labels 0..n_classes-1
        learning_rate = check_positive_number(learning_rate, "learning_rate")
        n_iters = check_count(n_iters, "n_iters")
        X_aug = with_bias(X)
        accuracies = [self._accuracy(X_aug, y)]
        for _ in range(n_iters):
            for c in range(self.n_classes):
                ### BEGIN SOLUTION 2.3.1
                ### HINT: new two-class labels for classifier c (1 for the samples of class c, 0 for all the others), then train classifier c on them for one step
                labels_c = (y == c).astype(np.int64)
                self.classifiers[c].gradient_ascent_step(X, labels_c, learning_rate)
                ### END SOLUTION 2.3.1
            accuracies.append(self._accuracy(X_aug, y))
        return np.array(accuracies)

    def _accuracy(self, X_aug, y):
        return np.mean(np.argmax(X_aug @ self.weights, axis=1) == y)


def first_iteration_above(accuracies, threshold=0.99):
    """The first t with ``accuracies[t] > threshold`` (t counts updates), or None if never."""
    accuracies = as_finite_float_array(accuracies, "accuracies")
    if accuracies.ndim != 1 or accuracies.size == 0:
        raise ValueError(f"accuracies must be a non-empty 1-d array, got shape {accuracies.shape}")
    if isinstance(threshold, bool) or not isinstance(threshold, numbers.Real) or not 0 <= threshold <= 1:
        raise ValueError(f"threshold must be a number in [0, 1], got {threshold!r}")
    above = np.flatnonzero(accuracies > threshold)
    return int(above[0]) if above.size else None


def accuracy(y_true, y_pred):
    """The fraction of positions where ``y_pred`` equals ``y_true`` (two 1-d integer label arrays of equal length)."""
    y_true = check_label_vector(y_true, "y_true")
    y_pred = check_label_vector(y_pred, "y_pred", len(y_true))
    return float(np.mean(y_true == y_pred))


def confusion_matrix(y_true, y_pred, n_classes):
    """Counts, shape (n_classes, n_classes): entry [i, j] is the number of samples of class i predicted as j."""
    n_classes = check_count(n_classes, "n_classes")
    y_true = check_labels(y_true, "y_true", n_classes)
    y_pred = check_labels(y_pred, "y_pred", n_classes, len(y_true))
    counts = np.zeros((n_classes, n_classes), dtype=np.int64)
    np.add.at(counts, (y_true, y_pred), 1)
    return counts


def per_class_accuracy(y_true, y_pred, n_classes):
    """For each class, the fraction of its samples predicted correctly (its recall), shape (n_classes,).

    NaN for a class with no samples in ``y_true``.
    """
    counts = confusion_matrix(y_true, y_pred, n_classes)
    support = counts.sum(axis=1)
    correct = np.diag(counts).astype(np.float64)
    return np.divide(correct, support, out=np.full(n_classes, np.nan), where=support > 0)


def train_test_split(features, labels, test_fraction=0.3, seed=0):
    """Shuffle the samples with ``seed`` and cut off ``test_fraction`` of them as the test set.

    ``features`` (N, M), ``labels`` (N,). The test set has ``round(test_fraction * N)`` samples
    and both parts at least one. Returns ``(X_train, X_test, y_train, y_test)``.
    """
    features = check_features(features, "features")
    labels = check_label_vector(labels, "labels", len(features))
    if isinstance(test_fraction, bool) or not isinstance(test_fraction, numbers.Real) or not 0 < test_fraction < 1:
        raise ValueError(f"test_fraction must be a number strictly between 0 and 1, got {test_fraction!r}")
    seed = check_seed(seed, "seed")
    num_test = int(round(test_fraction * len(features)))
    if not 0 < num_test < len(features):
        raise ValueError(
            f"test_fraction={test_fraction} of {len(features)} samples leaves an empty train or test set"
        )
    order = np.random.default_rng(seed).permutation(len(features))
    test_rows, train_rows = order[:num_test], order[num_test:]
    return features[train_rows], features[test_rows], labels[train_rows], labels[test_rows]
