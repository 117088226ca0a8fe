"""Figures of problem 1's search: rewards of random policies, the training curve and the learning-rate sweep.

Every function returns a matplotlib Figure and never calls ``plt.show()``. The figures are
``PRINT_WIDTH`` inches wide, the text width of the report's A4 page, so they print at their
own font size; legends sit outside the axes, below them, where they cannot hide data.
"""

from __future__ import annotations

import numpy as np
from matplotlib.ticker import MaxNLocator, MultipleLocator, PercentFormatter

from hwlib import settings
from hwlib.cartpole import MAX_EPISODE_REWARD
from hwlib.plots._figure import LABEL_FONT_SIZE, label_offsets, new_figure
from hwlib.policy_search import iterations_to_converge

PRINT_WIDTH = 7.0  # inches: A4 (210 mm) less two 16 mm margins is 178 mm


def _check_rewards(rewards, name):
    rewards = np.asarray(rewards)
    if rewards.dtype.kind not in "iuf" or rewards.ndim != 1 or rewards.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-d array of numbers, got shape {rewards.shape}")
    rewards = rewards.astype(np.float64)
    if not np.all(np.isfinite(rewards)) or np.any((rewards < 0) | (rewards > MAX_EPISODE_REWARD)):
        raise ValueError(f"{name} must hold episode rewards in [0, {MAX_EPISODE_REWARD}]")
    return rewards


def _legend_below(figure, ax, columns):
    """The axes' legend under the figure (constrained layout makes room for it)."""
    handles, labels = ax.get_legend_handles_labels()
    figure.legend(handles, labels, loc="outside lower center", ncols=min(columns, len(labels)), frameon=False)


def plot_reward_histogram(rewards):
    """Histogram of episode rewards; the episodes that reached the maximum get their own bar, labelled
    with their count and share."""
    rewards = _check_rewards(rewards, "rewards")
    at_max = int(np.sum(rewards >= MAX_EPISODE_REWARD))
    bin_width = MAX_EPISODE_REWARD / 50
    figure = new_figure(PRINT_WIDTH, 3.0)
    ax = figure.add_subplot()
    ax.hist(rewards[rewards < MAX_EPISODE_REWARD], bins=np.linspace(0, MAX_EPISODE_REWARD, 51), color="tab:blue",
            edgecolor="white")
    ax.bar(MAX_EPISODE_REWARD, at_max, width=bin_width, align="edge", color="tab:orange", edgecolor="white")
    ax.set_xlim(0, MAX_EPISODE_REWARD + 2 * bin_width)
    top = ax.get_ylim()[1]
    ax.annotate(
        f"reward {MAX_EPISODE_REWARD}: {at_max} of {len(rewards)} ({at_max / len(rewards):.1%})",
        xy=(MAX_EPISODE_REWARD + bin_width / 2, at_max), xytext=(MAX_EPISODE_REWARD - 2 * bin_width, max(at_max, 0.45 * top)),
        ha="right", va="center", color="tab:orange", fontweight="bold",
        arrowprops={"arrowstyle": "->", "color": "tab:orange"},
    )
    ax.set_xlabel("episode reward")
    ax.set_ylabel("number of policies")
    ax.set_title(f"Rewards of {len(rewards)} random linear policies, one episode each")
    ax.grid(axis="y", alpha=0.3)
    return figure


def plot_training_curve(rewards, learning_rate=None, deadline=settings.CONVERGENCE_DEADLINE):
    """Reward after each training iteration (iteration 0 is before any update), with the maximum, the
    convergence deadline and the iteration the run converged at (the maximum reward from then on) marked."""
    rewards = _check_rewards(rewards, "rewards")
    iterations = np.arange(len(rewards))
    converged_at = iterations_to_converge(rewards)
    figure = new_figure(PRINT_WIDTH, 3.4)
    ax = figure.add_subplot()
    ax.plot(iterations, rewards, marker="o", color="tab:blue", label="mean reward")
    ax.axhline(MAX_EPISODE_REWARD, color="tab:red", ls="--", lw=1, label=f"max reward {MAX_EPISODE_REWARD}")
    ax.axvline(deadline, color="0.35", ls=":", lw=1.5, label=f"deadline: iteration {deadline}")
    if converged_at is None:
        ax.plot([], [], " ", label=f"not converged within {len(rewards) - 1} iterations")
    else:
        ax.plot(converged_at, rewards[converged_at], marker="o", ms=14, mfc="none", mec="tab:green", mew=2.5, ls="none",
                label=f"converged at iteration {converged_at}")
    ax.set_xlim(-0.5, len(rewards) - 0.5)
    ax.xaxis.set_major_locator(MultipleLocator(1) if len(rewards) <= 31 else MaxNLocator(integer=True))
    ax.set_ylim(0, MAX_EPISODE_REWARD * 1.08)
    ax.set_xlabel("training iteration")
    ax.set_ylabel("reward")
    ax.grid(alpha=0.3)
    title = "Training curve" if learning_rate is None else f"Training curve, learning rate {learning_rate:g}"
    ax.set_title(title)
    _legend_below(figure, ax, 2)
    return figure




def plot_learning_rate_sweep(sweep, chosen_learning_rate=None):
    """Share of seeds converging within the deadline, per learning rate, with ``chosen_learning_rate`` marked.

    ``sweep`` is an ``hwlib.training.SweepResult`` or anything with the same ``learning_rates``,
    ``converged_fraction``, ``seeds`` and ``deadline``. Each point's share is written beside it, on
    the side where neither the line nor another label is (``label_offsets``).
    """
    rates = np.asarray(sweep.learning_rates, dtype=np.float64)
    fractions = np.asarray(sweep.converged_fraction, dtype=np.float64)
    if rates.ndim != 1 or rates.size == 0 or fractions.shape != rates.shape:
        raise ValueError(f"the sweep needs one converged fraction per learning rate, got shapes {rates.shape} and {fractions.shape}")
    figure = new_figure(PRINT_WIDTH, 3.0)
    ax = figure.add_subplot()
    ax.semilogx(rates, fractions, marker="o", color="tab:blue", label=f"share of {len(sweep.seeds)} seeds")
    ax.set_ylim(-0.14, 1.24)  # room for a label above 100% and below 0%
    ax.set_yticks(np.linspace(0, 1, 6))
    ax.yaxis.set_major_formatter(PercentFormatter(xmax=1))
    ax.set_xlabel("learning rate")
    ax.set_ylabel(f"converged by iteration {sweep.deadline}")
    ax.set_title(f"Learning-rate sweep: share of {len(sweep.seeds)} seeds converged within {sweep.deadline} iterations")
    ax.grid(True, which="both", alpha=0.3)
    if chosen_learning_rate is not None:
        ax.axvline(chosen_learning_rate, color="tab:green", ls="--", label=f"chosen learning rate {chosen_learning_rate:g}")
    _legend_below(figure, ax, 2)
    figure.draw_without_rendering()  # the final layout: the labels' sides are chosen in its pixels
    labels = [f"{fraction:.0%}" for fraction in fractions]
    for rate, fraction, label, offset in zip(rates, fractions, labels, label_offsets(ax, rates, fractions, labels)):
        ax.annotate(label, (rate, fraction), xytext=offset, textcoords="offset points", ha="center", va="center",
                    fontsize=LABEL_FONT_SIZE, bbox={"boxstyle": "round,pad=0.1", "facecolor": "white", "edgecolor": "none", "alpha": 0.85})
    return figure
