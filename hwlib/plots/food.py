"""Figures of problem 2: the training curve, the confusion matrix and the per-class accuracy.

Every function returns a matplotlib Figure and never calls ``plt.show()``: a notebook shows
the figure it gets back, a script saves it. Pass ``data_source=data.source`` and the figure says
which data it came from (the course's file or the kit's synthetic stand-in), so that a figure
read on its own is never taken for the real data's. Like problem 1's, the figures are
``PRINT_WIDTH`` wide, so they print at their own font size.
"""

from __future__ import annotations

import numpy as np
from matplotlib.ticker import MaxNLocator

from hwlib import settings
from hwlib.food_data import SYNTHETIC
from hwlib.logreg import first_iteration_above
from hwlib.plots._figure import new_figure
from hwlib.plots.training import PRINT_WIDTH


def _say_data_source(figure, data_source):
    """The data's source above the figure; the stand-in's in red, as it is not the real data."""
    if data_source is None:
        return
    if not isinstance(data_source, str) or not data_source:
        raise TypeError(f"data_source must be a non-empty string such as data.source, got {data_source!r}")
    synthetic = data_source == SYNTHETIC
    text = f"data: {data_source}" + (" (not the course's data)" if synthetic else "")
    figure.suptitle(text, x=0.01, ha="left", fontsize="medium", color="tab:red" if synthetic else "0.25")


def plot_training_accuracy(accuracies, target=settings.TARGET_ACCURACY, zoom_from=0.95, *,
                           deadline=settings.TARGET_ITERATIONS, data_source=None):
    """Training accuracy against iteration (``accuracies[t]`` after t updates), with the target line, the
    handout's deadline (iteration ``deadline``) and the first iteration above the target marked.

    Left: the whole range, as the handout's plot. Right: the same curve from ``zoom_from`` up,
    where the slow last percent happens.
    """
    accuracies = _check_curve(accuracies)
    iterations = np.arange(len(accuracies))
    first = first_iteration_above(accuracies, target)
    figure = new_figure(PRINT_WIDTH, 3.2)
    full_ax, zoom_ax = figure.subplots(1, 2)
    for ax, bottom in ((full_ax, 0.0), (zoom_ax, zoom_from)):
        ax.plot(iterations, accuracies, color="tab:blue", lw=1.8, label="training accuracy")
        ax.axhline(target, color="tab:red", ls="--", lw=1, label=f"{target:.0%}")
        if deadline is not None and deadline < len(accuracies):
            ax.axvline(deadline, color="0.35", ls="-.", lw=1, label=f"deadline: iteration {deadline}")
        if first is not None:
            ax.axvline(first, color="tab:green", ls=":", lw=1.8, label=f"first above {target:.0%}: iteration {first}")
        ax.set_xlim(0, max(len(accuracies) - 1, 1))
        ax.set_ylim(bottom, 1.0 + (1.0 - bottom) * 0.02)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("training iteration")
        ax.grid(alpha=0.3)
    full_ax.set_ylabel("training accuracy")
    full_ax.set_title("Training accuracy")
    zoom_ax.set_title(f"The same, from {zoom_from:.0%} up")
    handles, labels = zoom_ax.get_legend_handles_labels()
    if first is None:
        handles, labels = handles + full_ax.plot([], [], " "), labels + [f"never above {target:.0%}"]
    figure.legend(handles, labels, loc="outside lower center", ncols=2, frameon=False)
    _say_data_source(figure, data_source)
    return figure


def plot_confusion_matrix(counts, class_names, title="Confusion matrix of the test set", *, data_source=None):
    """Counts (rows: true class, columns: predicted class) as a heat map, each cell labelled."""
    counts = np.asarray(counts)
    class_names = _check_names(class_names)
    if counts.shape != (len(class_names), len(class_names)) or counts.dtype.kind not in "iu" or np.any(counts < 0):
        raise ValueError(
            f"counts must be a ({len(class_names)}, {len(class_names)}) array of non-negative integers, one row and "
            f"column per class name, got dtype {counts.dtype} and shape {counts.shape}"
        )
    figure = new_figure(PRINT_WIDTH, 5.6)  # tall enough for seven rows of readable cells beside the colour bar
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
    _say_data_source(figure, data_source)
    return figure


def plot_per_class_accuracy(per_class, class_names, title="Test accuracy per food", *, data_source=None):
    """One bar per class: the fraction of its samples classified correctly."""
    per_class = np.asarray(per_class, dtype=np.float64)
    class_names = _check_names(class_names)
    if per_class.shape != (len(class_names),):
        raise ValueError(f"per_class must have one value per class name, shape ({len(class_names)},), got {per_class.shape}")
    finite = per_class[np.isfinite(per_class)]
    if np.any((finite < 0) | (finite > 1)):
        raise ValueError("per_class must hold fractions in [0, 1] (NaN for a class without samples)")
    figure = new_figure(PRINT_WIDTH, 3.5)
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
    _say_data_source(figure, data_source)
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
