"""The reward landscape figure: one slice of g(θ) as a heatmap, θ and a training path on it.

The function returns a matplotlib Figure and never calls ``plt.show()``.
"""

from __future__ import annotations

import numpy as np

from hwlib.machinery.validation import check_path, check_positive_number
from hwlib.cartpole import MAX_EPISODE_REWARD, OBSERVATION_NAMES
from hwlib.plots._figure import LABEL_FONT_SIZE, figure_png, label_offsets, new_figure  # noqa: F401  (figure_png is re-exported)

AXIS_NAMES = ("θ₁", "θ₂", "θ₃", "θ₄")  # θ₁ is the weight on the cart position, ...
AXIS_LABELS = tuple(f"{symbol} · {name}" for symbol, name in zip(AXIS_NAMES, OBSERVATION_NAMES))

COLOUR_MAP = "viridis"
PATH_COLOUR = "tab:red"
MERGE_FRACTION = 0.025  # consecutive path points closer than this share of the plotted range (about one cell) share one label


def format_theta(theta):
    """θ as the landscape writes it: '(0.50, -1.25, 0.00, 2.00)'."""
    return "(" + ", ".join(f"{value + 0.0:.2f}" for value in theta) + ")"  # + 0.0: no "-0.00" for -0.0


def new_landscape_figure():
    """An empty figure of the size the landscape is drawn at."""
    return new_figure(6.4, 6.0, dpi=80)


def plot_reward_landscape(landscape, path=None, fd_step=None, figure=None):
    """The slice ``landscape`` (an ``hwlib.landscape.RewardSlice``) as a heatmap with a colour bar from 0 to the maximum reward.

    The slice's θ is marked with a star. ``path`` (shape (T + 1, 4), e.g. the parameters before
    training and after each update) is drawn projected onto the slice: one dot per iteration,
    numbered from 0; consecutive iterations that land on the same spot share one label ("9–20").
    ``fd_step`` (a number > 0) marks the points θ ± h along both axes, the finite-difference
    stencil. ``figure`` is cleared and reused if given.
    """
    if not all(hasattr(landscape, name) for name in ("theta", "axes", "values", "mean_rewards", "held_axes")):
        raise TypeError(f"landscape must be an hwlib.landscape.RewardSlice (from reward_slice), got {type(landscape).__name__}")
    path = None if path is None else check_path(path)
    fd_step = None if fd_step is None else check_positive_number(fd_step, "fd_step")
    figure = new_landscape_figure() if figure is None else figure
    figure.clear()
    ax = figure.add_subplot()

    horizontal, vertical = landscape.axes
    values = landscape.values
    half_cell = (values[1] - values[0]) / 2
    low, high = values[0] - half_cell, values[-1] + half_cell
    image = ax.imshow(
        landscape.mean_rewards, origin="lower", extent=(low, high, low, high), vmin=0, vmax=MAX_EPISODE_REWARD,
        cmap=COLOUR_MAP, interpolation="nearest",
    )
    colour_bar = figure.colorbar(image, ax=ax, shrink=0.85)
    colour_bar.set_label(f"mean reward of {landscape.num_episodes} episodes (the same starts in every cell)")
    ax.set_xlim(low, high)
    ax.set_ylim(low, high)
    ax.set_xlabel(AXIS_LABELS[horizontal])
    ax.set_ylabel(AXIS_LABELS[vertical])
    held = ", ".join(f"{AXIS_NAMES[index]} = {landscape.theta[index]:.2f}" for index in landscape.held_axes)
    ax.set_title(f"Reward landscape g(θ), held: {held}")

    theta_x, theta_y = landscape.theta[horizontal], landscape.theta[vertical]
    if fd_step is not None:
        stencil_x = theta_x + np.array([-fd_step, fd_step, 0, 0])
        stencil_y = theta_y + np.array([0, 0, -fd_step, fd_step])
        for x, y in zip(stencil_x, stencil_y):
            ax.plot([theta_x, x], [theta_y, y], color="white", lw=0.8, alpha=0.8)
        ax.plot(stencil_x, stencil_y, ls="none", marker="o", ms=5, mfc="white", mec="black", mew=0.8,
                label=f"θ ± h along each axis (h = {fd_step:g})")
    if path is not None:
        ax.plot(path[:, horizontal], path[:, vertical], color=PATH_COLOUR, lw=1.5, marker="o", ms=5, mec="white", mew=0.8,
                label=f"training path, iterations 0–{len(path) - 1} (projected onto the slice)")
    outside = not (low <= theta_x <= high and low <= theta_y <= high)
    ax.plot(theta_x, theta_y, ls="none", marker="*", ms=16, mfc="white", mec="black",
            label=f"θ = {format_theta(landscape.theta)}" + (" (outside the plotted range)" if outside else ""))
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=1, fontsize="small", frameon=False)
    if path is not None:
        figure.draw_without_rendering()  # the final layout: the labels' sides are chosen in its pixels
        _label_path(ax, path[:, horizontal], path[:, vertical], span=high - low)
    return figure


def _label_path(ax, xs, ys, span):
    """The training path's labels: each run of (nearly) coinciding consecutive points labelled once with
    its first and last iteration ("9–20"), beside it where neither the path nor another label is."""
    starts, labels, start = [], [], 0
    for index in range(1, len(xs) + 1):
        if index < len(xs) and np.hypot(xs[index] - xs[start], ys[index] - ys[start]) <= MERGE_FRACTION * span:
            continue
        starts.append(start)
        labels.append(str(start) if index - 1 == start else f"{start}–{index - 1}")
        start = index
    label_xs, label_ys = xs[starts], ys[starts]
    offsets = label_offsets(ax, label_xs, label_ys, labels, distance=12)
    for x, y, label, offset in zip(label_xs, label_ys, labels, offsets):  # a thin line from each label to its point
        ax.annotate(label, (x, y), xytext=offset, textcoords="offset points", ha="center", va="center",
                    fontsize=LABEL_FONT_SIZE, color="black", arrowprops={"arrowstyle": "-", "lw": 0.6, "color": "0.15"},
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85})
