"""Figures of problem 2: the training curve, the confusion matrix and the per-class accuracy.

Every function returns a matplotlib Figure and never calls ``plt.show()``: a notebook shows
the figure it gets back, a script saves it.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from hwlib.logreg import first_iteration_above

TARGET_ACCURACY = 0.99  # the handout's goal for the training accuracy


def _new_figure(width, height):
    return Figure(figsize=(width, height), dpi=100, layout="constrained")


def plot_training_accuracy(accuracies, target=TARGET_ACCURACY, zoom_from=0.95):
    """Training accuracy against iteration (``accuracies[t]`` after t updates), with the target line.

    Left: the whole range, as the handout's plot. Right: the same curve from ``zoom_from`` up,
    where the slow last percent happens.
    """
    accuracies = _check_curve(accuracies)
    iterations = np.arange(len(accuracies))
    first = first_iteration_above(accuracies, target)
    figure = _new_figure(11.0, 4.2)
    full_ax, zoom_ax = figure.subplots(1, 2)
    for ax, bottom in ((full_ax, 0.0), (zoom_ax, zoom_from)):
        ax.plot(iterations, accuracies, color="tab:blue", lw=1.8, label="training accuracy")
        ax.axhline(target, color="tab:red", ls="--", lw=1, label=f"{target:.0%}")
        if first is not None:
            ax.axvline(first, color="0.4", ls=":", lw=1.2, label=f"first above {target:.0%}: iteration {first}")
        ax.set_xlim(0, max(len(accuracies) - 1, 1))
        ax.set_ylim(bottom, 1.0 + (1.0 - bottom) * 0.02)
        ax.set_xlabel("training iteration")
        ax.grid(alpha=0.3)
    full_ax.set_ylabel("training accuracy")
    full_ax.set_title("Accuracy on the training set during training")
    zoom_ax.set_title(f"The same, from {zoom_from:.0%} up")
    zoom_ax.legend(loc="lower right")
    return figure


def plot_confusion_matrix(counts, class_names, title="Confusion matrix of the test set"):
    """Counts (rows: true class, columns: predicted class) as a heat map, each cell labelled."""
    counts = np.asarray(counts)
    class_names = _check_names(class_names)
    if counts.shape != (len(class_names), len(class_names)) or counts.dtype.kind not in "iu" or np.any(counts < 0):
        raise ValueError(
            f"counts must be a ({len(class_names)}, {len(class_names)}) array of non-negative integers, one row and "
            f"column per class name, got dtype {counts.dtype} and shape {counts.shape}"
        )
    figure = _new_figure(7.0, 6.0)
    ax = figure.add_subplot()
    # Colour by the share of each true class so small classes are as readable as big ones.
    support = counts.sum(axis=1, keepdims=True)
    shares = np.divide(counts, support, out=np.zeros(counts.shape), where=support > 0)
    image = ax.imshow(shares, cmap="Blues", vmin=0, vmax=1)
    for (row, col), count in np.ndenumerate(counts):
        ax.text(col, row, str(count), ha="center", va="center", color="white" if shares[row, col] > 0.6 else "black")
    ticks = np.arange(len(class_names))
    ax.set_xticks(ticks, class_names, rotation=45, ha="right")
    ax.set_yticks(ticks, class_names)
    ax.set_xlabel("predicted food")
    ax.set_ylabel("true food")
    ax.set_title(title)
    figure.colorbar(image, ax=ax, label="share of the true class")
    return figure


def plot_per_class_accuracy(per_class, class_names, title="Test accuracy per food"):
    """One bar per class: the fraction of its samples classified correctly."""
    per_class = np.asarray(per_class, dtype=np.float64)
    class_names = _check_names(class_names)
    if per_class.shape != (len(class_names),):
        raise ValueError(f"per_class must have one value per class name, shape ({len(class_names)},), got {per_class.shape}")
    finite = per_class[np.isfinite(per_class)]
    if np.any((finite < 0) | (finite > 1)):
        raise ValueError("per_class must hold fractions in [0, 1] (NaN for a class without samples)")
    figure = _new_figure(8.0, 4.0)
    ax = figure.add_subplot()
    bottom = float(np.clip(np.floor(20 * np.nanmin(per_class)) / 20 - 0.05, 0.0, 0.9)) if finite.size else 0.0
    bars = ax.bar(class_names, np.nan_to_num(per_class), color="tab:green")
    for bar, value in zip(bars, per_class):
        label = "no samples" if np.isnan(value) else f"{value:.3f}"
        inside = not np.isnan(value) and value - bottom > 0.1 * (1 - bottom)
        ax.text(
            bar.get_x() + bar.get_width() / 2,
            value - 0.01 * (1 - bottom) if inside else bottom + 0.01 * (1 - bottom),
            label,
            ha="center",
            va="top" if inside else "bottom",
            color="white" if inside else "black",
            fontsize=9,
        )
    ax.set_ylim(bottom, 1.0)
    ax.set_ylabel("accuracy" if bottom == 0 else f"accuracy (axis starts at {bottom:.2f})")
    ax.set_title(title)
    ax.tick_params(axis="x", rotation=30)
    ax.grid(axis="y", alpha=0.3)
    return figure


def _check_curve(accuracies):
    accuracies = np.asarray(accuracies)
    if accuracies.dtype.kind not in "iuf" or accuracies.ndim != 1 or accuracies.size == 0:
        raise ValueError(f"accuracies must be a non-empty 1-d array of numbers, got shape {accuracies.shape}")
    accuracies = accuracies.astype(np.float64)
    if not np.all(np.isfinite(accuracies)) or np.any((accuracies < 0) | (accuracies > 1)):
        raise ValueError("accuracies must hold fractions in [0, 1]")
    return accuracies


def _check_names(class_names):
    if isinstance(class_names, str) or not all(isinstance(name, str) for name in class_names):
        raise TypeError("class_names must be a sequence of strings, one per class")
    return list(class_names)
