"""Figures of problem 1's search: rewards of random policies, the training curve and the learning-rate sweep.

Every function returns a matplotlib Figure and never calls ``plt.show()``.
"""

from __future__ import annotations

import numpy as np

from hwlib.cartpole import MAX_EPISODE_REWARD
from hwlib.plots._figure import new_figure


def plot_reward_histogram(rewards):
    """Histogram of episode rewards, the maximum marked."""
    rewards = np.asarray(rewards, dtype=float)
    figure = new_figure()
    ax = figure.add_subplot()
    ax.hist(rewards, bins=np.linspace(0, MAX_EPISODE_REWARD, 51), color="tab:blue", edgecolor="white")
    ax.axvline(MAX_EPISODE_REWARD, color="tab:red", ls="--", label=f"max reward {MAX_EPISODE_REWARD}")
    ax.set_xlabel("episode reward")
    ax.set_ylabel("number of policies")
    ax.set_title(f"Rewards of {len(rewards)} random linear policies")
    ax.legend()
    return figure


def plot_training_curve(rewards, learning_rate=None):
    """Reward after each training iteration (iteration 0 is before any update), the maximum marked."""
    rewards = np.asarray(rewards, dtype=float)
    figure = new_figure()
    ax = figure.add_subplot()
    ax.plot(np.arange(len(rewards)), rewards, marker="o", label="mean reward")
    ax.axhline(MAX_EPISODE_REWARD, color="tab:red", ls="--", label=f"max reward {MAX_EPISODE_REWARD}")
    ax.set_xlabel("training iteration")
    ax.set_ylabel("reward")
    ax.set_ylim(0, MAX_EPISODE_REWARD * 1.08)
    title = "Training curve" if learning_rate is None else f"Training curve, learning rate {learning_rate:g}"
    ax.set_title(title)
    ax.legend(loc="lower right")
    return figure


def plot_learning_rate_sweep(sweep, chosen_learning_rate=None):
    """Fraction of seeds converging within the deadline, per learning rate (an ``hwlib.policy_search.SweepResult``),
    with ``chosen_learning_rate`` marked if given."""
    figure = new_figure()
    ax = figure.add_subplot()
    ax.semilogx(sweep.learning_rates, sweep.converged_fraction, marker="o")
    if chosen_learning_rate is not None:
        ax.axvline(chosen_learning_rate, color="tab:green", ls="--", label=f"chosen: {chosen_learning_rate:g}")
        ax.legend(loc="lower left")
    ax.set_ylim(-0.03, 1.03)
    ax.set_xlabel("learning rate")
    ax.set_ylabel(f"fraction of seeds converged by iteration {sweep.deadline}")
    ax.set_title(f"Learning-rate sweep, {len(sweep.seeds)} seeds per rate")
    ax.grid(True, which="both", alpha=0.3)
    return figure
