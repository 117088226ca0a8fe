"""Logistic regression by gradient ascent on the log-likelihood, two-class and one-vs-rest.

The model of the handout's equations (5)-(7), with the standard sign convention
``sigma(z) = 1 / (1 + exp(-z))`` and the bias folded in as a constant-1 feature:

| name              | shape                         | meaning                                            |
|-------------------|-------------------------------|----------------------------------------------------|
| ``X``             | (N, M) float                  | one sample per row, raw features (no bias column)  |
| ``X_aug``         | (N, M + 1)                    | ``X`` with a column of ones appended (equation 6)  |
| ``y`` (two-class) | (N,) 0/1                      | 1 marks the positive class                         |
| ``y`` (C classes) | (N,) int in 0..C-1            | the class of each sample                           |
| weights           | (M + 1,)                      | one two-class model: ``[w, b]``, bias last         |
| weights (C)       | (M + 1, C)                    | column c is the model of class c against the rest  |
| accuracies        | (n_iters + 1,)                | ``accuracies[t]``: training accuracy after t updates |

Training maximises equation (7) by gradient ascent, equation (8), with the *summed*
(not averaged) gradient of equation (7) (``log_likelihood_gradient``, derived in 2.1.1) and
starts from zero weights, as the course's skeleton does. One update of one model is ``_gradient_ascent_step``;
the one-vs-rest classifier either calls it once per class (the handout's loop) or once with
all C columns at a time (``vectorized=True``): the same code on a wider weight matrix.
"""

from __future__ import annotations

import numbers

import numpy as np

from hwlib._checks import check_count, check_positive_number, check_seed
from hwlib.finite_diff import scalar_finite_diff

_NUMERIC_KINDS = "biuf"  # bool, signed and unsigned int, float


def sigmoid(z):
    """The logistic function ``1 / (1 + exp(-z))``, elementwise, without overflow.

    Returns a float64 array shaped like ``z``. Exactly 0.0 and 1.0 far out in the tails
    (e.g. at -1000 and +1000) and never NaN for finite input.
    """
    z = _as_finite_float_array(z, "z")
    ### BEGIN SOLUTION 2.2.1
    ### HINT: 1 / (1 + exp(-z)) elementwise, without overflow or NaN for large |z| (e.g. z = -1000 or 1000)
    # exp(-|z|) lies in (0, 1], so it cannot overflow; for z < 0 the algebraically equal
    # form exp(z) / (1 + exp(z)) is used.
    with np.errstate(under="ignore"):
        decay = np.exp(-np.abs(z))
    return np.where(z >= 0, 1.0 / (1.0 + decay), decay / (1.0 + decay))
    ### END SOLUTION 2.2.1


def add_bias_feature(features):
    """``features`` (N, M) with a column of ones appended: the ``X_aug`` of equation (6)."""
    features = check_features(features, "X")
    return _with_bias(features)


def log_likelihood(weights, features, labels):
    """Equation (7): the log-likelihood of 0/1 ``labels`` under the two-class model ``weights``.

    ``weights`` has shape (M + 1,) with the bias last, ``features`` (N, M), ``labels`` (N,).
    Computed as ``sum(y * z - log(1 + exp(z)))`` with ``z = X_aug @ weights``, which is
    equation (7) rearranged so that no logarithm of 0 can occur.
    """
    features_aug, labels, weights = _check_two_class_problem(weights, features, labels)
    logits = features_aug @ weights
    return float(np.sum(labels * logits - np.logaddexp(0.0, logits)))


def log_likelihood_gradient(weights, features, labels):
    """The analytic gradient of equation (7) with respect to ``weights`` (derived in 2.1.1), shape (M + 1,)."""
    features_aug, labels, weights = _check_two_class_problem(weights, features, labels)
    ### BEGIN SOLUTION 2.1.1
    ### HINT: return the gradient of equation (7) you derived, summed over the samples, shape (M + 1,); features_aug has the bias column
    return features_aug.T @ (labels - sigmoid(features_aug @ weights))
    ### END SOLUTION 2.1.1


def gradient_check(weights, features, labels, step=1e-5):
    """Relative error between the analytic gradient and central finite differences.

    The finite differences come from problem 1's ``scalar_finite_diff`` applied to
    ``log_likelihood``; the error is ``|g_analytic - g_numeric| / (|g_analytic| + |g_numeric|)``
    (Euclidean norms), 0.0 when both are zero. Around 1e-10 for a correct gradient on a small
    problem; a wrong sign or a missing term gives something of order 1.
    """
    features_aug, labels, weights = _check_two_class_problem(weights, features, labels)
    step = check_positive_number(step, "step")
    features = features_aug[:, :-1]
    analytic = log_likelihood_gradient(weights, features, labels)
    numeric = scalar_finite_diff(lambda w: log_likelihood(w, features, labels), weights, step)
    scale = np.linalg.norm(analytic) + np.linalg.norm(numeric)
    return 0.0 if scale == 0.0 else float(np.linalg.norm(analytic - numeric) / scale)


def _gradient_ascent_step(weights, features_aug, targets, learning_rate):
    """One step of equation (8), in place: ``weights += learning_rate *`` the gradient of equation (7) for ``targets``.

    Either one model (weights (M + 1,), targets (N,)) or C models side by side
    (weights (M + 1, C), targets (N, C)); the same two lines serve both.
    """
    ### BEGIN SOLUTION 2.2.3
    ### HINT: weights += learning_rate * the summed gradient you derived in 2.1.1, in place; with matrix products it serves targets (N,) and (N, C) alike
    residuals = targets - sigmoid(features_aug @ weights)
    weights += learning_rate * (features_aug.T @ residuals)
    ### END SOLUTION 2.2.3


class TwoClassLogisticRegressionClassifier:
    """Logistic regression for labels 0/1, trained by gradient ascent from zero weights.

    ``weights`` (shape (n_features + 1,), bias last) is the learned ``w~`` of equation (6).
    """

    def __init__(self, n_features):
        self.n_features = check_count(n_features, "n_features")
        self.weights = np.zeros(self.n_features + 1)

    @classmethod
    def _sharing(cls, weights_column):
        """A classifier whose weights are a view into a wider weight matrix."""
        classifier = cls(len(weights_column) - 1)
        classifier.weights = weights_column
        return classifier

    def decision_function(self, X):
        """The logits ``X_aug @ weights``, shape (N,): positive means class 1 is more likely."""
        return self._logits(_with_bias(check_features(X, "X", self.n_features)))

    def predict_prob(self, X):
        """P(y = 1 | x) for each row of ``X`` (N, n_features), equation (5) with the standard sign."""
        X = check_features(X, "X", self.n_features)
        ### BEGIN SOLUTION 2.2.2
        ### HINT: sigmoid of the logit for each row of X, shape (N,); append the constant 1 feature first (equation (6)), the bias is the last weight
        X_aug = _with_bias(X)
        return sigmoid(X_aug @ self.weights)
        ### END SOLUTION 2.2.2

    def predict(self, X):
        """Labels 0/1, shape (N,): 1 where P(y = 1 | x) > 0.5, i.e. where the logit is positive."""
        return (self.decision_function(X) > 0).astype(np.int64)

    def fit(self, X, y, learning_rate, n_iters):
        """``n_iters`` gradient-ascent steps on equation (7), continuing from the current weights.

        Returns the training accuracy before the first step and after each step, shape (n_iters + 1,).
        """
        X_aug = _with_bias(check_features(X, "X", self.n_features))
        targets = check_labels(y, "y", 2, len(X_aug)).astype(np.float64)
        learning_rate = check_learning_rate(learning_rate)
        n_iters = check_count(n_iters, "n_iters")
        accuracies = np.empty(n_iters + 1)
        for iteration in range(n_iters):
            accuracies[iteration] = np.mean((self._logits(X_aug) > 0) == targets)
            _gradient_ascent_step(self.weights, X_aug, targets, learning_rate)
        accuracies[-1] = np.mean((self._logits(X_aug) > 0) == targets)
        return accuracies

    def _logits(self, X_aug):
        return X_aug @ self.weights


class MultiClassLogisticRegressionClassifier:
    """One-vs-rest logistic regression: one two-class model per class, C models in all.

    ``classifiers[c]`` separates class c from the rest; its weights are column c of
    ``weights`` (shape (n_features + 1, n_classes)), so both views always agree.
    """

    def __init__(self, n_features, n_classes):
        self.n_features = check_count(n_features, "n_features")
        self.n_classes = check_count(n_classes, "n_classes")
        if self.n_classes < 2:
            raise ValueError(f"n_classes must be at least 2, got {n_classes!r}")
        self.weights = np.zeros((self.n_features + 1, self.n_classes))
        self.classifiers = [TwoClassLogisticRegressionClassifier._sharing(self.weights[:, c]) for c in range(self.n_classes)]

    def decision_function(self, X):
        """The logits of every class's model, shape (N, n_classes)."""
        return _with_bias(check_features(X, "X", self.n_features)) @ self.weights

    def predict_prob(self, X):
        """P(class c | x) of each one-vs-rest model, shape (N, n_classes); rows need not sum to 1."""
        return sigmoid(self.decision_function(X))

    def predict(self, X):
        """The most probable class of each row, shape (N,).

        Taken as the largest logit: sigma is increasing, so this is the class of highest
        probability, and unlike probabilities that have rounded to exactly 1.0 it has no ties.
        """
        return np.argmax(self.decision_function(X), axis=1)

    def fit(self, X, y, learning_rate, n_iters, vectorized=False):
        """``n_iters`` outer iterations; in each, every class's model takes one step on its own 0/1 labels.

        ``vectorized=False`` follows the handout: a loop over the classes. ``vectorized=True``
        steps all columns of ``weights`` at once with the same update code and gives the same
        numbers up to float rounding. Returns the training accuracy before the first iteration
        and after each, shape (n_iters + 1,).
        """
        X_aug = _with_bias(check_features(X, "X", self.n_features))
        labels = check_labels(y, "y", self.n_classes, len(X_aug))
        learning_rate = check_learning_rate(learning_rate)
        n_iters = check_count(n_iters, "n_iters")
        if not isinstance(vectorized, bool):
            raise TypeError(f"vectorized must be True or False, got {vectorized!r}")
        accuracies = np.empty(n_iters + 1)
        for iteration in range(n_iters):
            accuracies[iteration] = self._accuracy(X_aug, labels)
            self._one_vs_rest_step(X_aug, labels, learning_rate, vectorized)
        accuracies[-1] = self._accuracy(X_aug, labels)
        return accuracies

    def _one_vs_rest_step(self, X_aug, labels, learning_rate, vectorized):
        """One outer iteration: every class's model takes one gradient-ascent step on its own 0/1 labels."""
        ### BEGIN SOLUTION 2.3.1
        ### HINT: for each class c: its two-class labels (1 where the label is c, 0 elsewhere), then one _gradient_ascent_step on classifiers[c].weights (vectorized: all C columns of self.weights at once)
        if vectorized:
            all_targets = (labels[:, None] == np.arange(self.n_classes)).astype(np.float64)  # column c: class c
            _gradient_ascent_step(self.weights, X_aug, all_targets, learning_rate)
            return
        for class_index, classifier in enumerate(self.classifiers):
            class_targets = (labels == class_index).astype(np.float64)
            _gradient_ascent_step(classifier.weights, X_aug, class_targets, learning_rate)
        ### END SOLUTION 2.3.1

    def _accuracy(self, X_aug, labels):
        return np.mean(np.argmax(X_aug @ self.weights, axis=1) == labels)


def first_iteration_above(accuracies, threshold=0.99):
    """The first t with ``accuracies[t] > threshold`` (t counts updates), or None if never."""
    accuracies = _as_finite_float_array(accuracies, "accuracies")
    if accuracies.ndim != 1 or accuracies.size == 0:
        raise ValueError(f"accuracies must be a non-empty 1-d array, got shape {accuracies.shape}")
    if isinstance(threshold, bool) or not isinstance(threshold, numbers.Real) or not 0 <= threshold <= 1:
        raise ValueError(f"threshold must be a number in [0, 1], got {threshold!r}")
    above = np.flatnonzero(accuracies > threshold)
    return int(above[0]) if above.size else None


def accuracy(y_true, y_pred):
    """The fraction of positions where ``y_pred`` equals ``y_true`` (two 1-d integer label arrays of equal length)."""
    y_true = _check_label_vector(y_true, "y_true")
    y_pred = _check_label_vector(y_pred, "y_pred", len(y_true))
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
    labels = _check_label_vector(labels, "labels", len(features))
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


# --- input checks ---------------------------------------------------------------------------


def check_learning_rate(learning_rate):
    return check_positive_number(learning_rate, "learning_rate")


def check_features(features, name, n_features=None):
    """A finite 2-d float64 array with at least one row (and ``n_features`` columns if given)."""
    array = _as_finite_float_array(features, name, require_2d=True)
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise ValueError(f"{name} must have at least one row and one column, got shape {array.shape}")
    if n_features is not None and array.shape[1] != n_features:
        raise ValueError(f"{name} must have {n_features} columns (one per feature), got shape {array.shape}")
    return array


def check_labels(labels, name, n_classes, length=None):
    """A 1-d int64 array of class indices in 0..n_classes-1 (of ``length`` entries if given)."""
    labels = _check_label_vector(labels, name, length)
    if labels.size and (labels.min() < 0 or labels.max() >= n_classes):
        bad = labels[(labels < 0) | (labels >= n_classes)]
        raise ValueError(f"{name} must hold class indices 0..{n_classes - 1}, found {np.unique(bad)[:5].tolist()}")
    return labels


def _check_label_vector(labels, name, length=None):
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


def _check_two_class_problem(weights, features, labels):
    features = check_features(features, "features")
    weights = _as_finite_float_array(weights, "weights")
    if weights.shape != (features.shape[1] + 1,):
        raise ValueError(
            f"weights must have shape ({features.shape[1] + 1},), one per feature plus the bias, got shape {weights.shape}"
        )
    labels = check_labels(labels, "labels", 2, len(features)).astype(np.float64)
    return _with_bias(features), labels, weights


def _as_finite_float_array(value, name, require_2d=False):
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


def _with_bias(features):
    return np.hstack([features, np.ones((features.shape[0], 1))])
