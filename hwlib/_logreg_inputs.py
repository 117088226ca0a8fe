"""The input checks of problem 2 (``hwlib/logreg.py``), and the samples a training loop prepares once.

Every public function of ``logreg.py`` checks its arguments before its TODO runs, with these
functions, so the code of a TODO can trust them. A check names the argument and says what was
expected.

Training calls the two-class step C x n_iters times on the same samples (700 times in the
notebook). Copying the samples with their constant-1 column at every step costs several times
more than the step itself, so ``prepare_training_features`` checks the samples once and builds
a read-only ``X_aug`` once, and hands the step the read-only view ``X_aug[:, :-1]``; the checks
recognise that view and reuse its check and its ``X_aug``. Any other array is checked and copied
as usual.
"""

from __future__ import annotations

import weakref

import numpy as np

from hwlib._checks import check_positive_number

_NUMERIC_KINDS = "biuf"  # bool, signed and unsigned int, float


def check_learning_rate(learning_rate):
    return check_positive_number(learning_rate, "learning_rate")


def check_features(features, name, n_features=None):
    """A finite 2-d float64 array with at least one row (and ``n_features`` columns if given)."""
    if _prepared_augmentation(features) is not None:
        array = features  # already checked when a training loop prepared it
    else:
        array = as_finite_float_array(features, name, require_2d=True)
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise ValueError(f"{name} must have at least one row and one column, got shape {array.shape}")
    if n_features is not None and array.shape[1] != n_features:
        raise ValueError(f"{name} must have {n_features} columns (one per feature), got shape {array.shape}")
    return array


def check_labels(labels, name, n_classes, length=None):
    """A 1-d int64 array of class indices in 0..n_classes-1 (of ``length`` entries if given)."""
    labels = check_label_vector(labels, name, length)
    if labels.size and (labels.min() < 0 or labels.max() >= n_classes):
        bad = labels[(labels < 0) | (labels >= n_classes)]
        raise ValueError(f"{name} must hold class indices 0..{n_classes - 1}, found {np.unique(bad)[:5].tolist()}")
    return labels


def check_label_vector(labels, name, length=None):
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


def check_two_class_problem(weights, features, labels):
    features_aug = checked_with_bias(features, "features")
    features = features_aug[:, :-1]
    weights = as_finite_float_array(weights, "weights")
    if weights.shape != (features.shape[1] + 1,):
        raise ValueError(
            f"weights must have shape ({features.shape[1] + 1},), one per feature plus the bias, got shape {weights.shape}"
        )
    labels = check_labels(labels, "labels", 2, len(features)).astype(np.float64)
    return features_aug, labels, weights


def as_finite_float_array(value, name, require_2d=False):
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


def with_bias(features):
    return np.hstack([features, np.ones((features.shape[0], 1))])


def checked_with_bias(features, name, n_features=None):
    """``features`` checked (``check_features``), with the constant-1 column appended."""
    features = check_features(features, name, n_features)
    augmented = _prepared_augmentation(features)
    return with_bias(features) if augmented is None else augmented


_PREPARED = weakref.WeakValueDictionary()  # id(X_aug) -> X_aug, for X_aug built by a training loop


def prepare_training_features(features, n_features):
    """``(X, X_aug)`` for a training loop: ``features`` checked once, ``X_aug`` built once, both read-only."""
    features = check_features(features, "X", n_features)
    augmented = _prepared_augmentation(features)
    if augmented is None:
        augmented = with_bias(features)
        augmented.flags.writeable = False
        _PREPARED[id(augmented)] = augmented
    return augmented[:, :-1], augmented


def _prepared_augmentation(features):
    """The read-only X_aug of which ``features`` is the feature part (a view), or None."""
    base = getattr(features, "base", None)
    if base is None or _PREPARED.get(id(base)) is not base or base.flags.writeable:
        return None
    is_feature_part = (
        features.shape == (base.shape[0], base.shape[1] - 1)
        and features.strides == base.strides
        and features.ctypes.data == base.ctypes.data
        and features.dtype == base.dtype
    )
    return base if is_feature_part else None
