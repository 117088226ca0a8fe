import numpy as np
import pytest
from matplotlib.figure import Figure

from hwlib import CartPoleLinearPolicy, play_episode
from hwlib.cartpole import BALANCING_PARAMS
from hwlib.plots import draw_cartpole, plot_episode, plot_learning_rate_sweep, plot_reward_histogram, plot_training_curve
from hwlib.policy_search import SweepResult


def _line_ydata(ax):
    return [tuple(np.round(line.get_ydata(), 6)) for line in ax.get_lines()]


def test_training_curve_draws_rewards_and_the_500_line():
    figure = plot_training_curve([10, 200, 500, 500], learning_rate=0.002)
    ax = figure.axes[0]
    assert isinstance(figure, Figure)
    assert (10.0, 200.0, 500.0, 500.0) in _line_ydata(ax)
    assert (500.0, 500.0) in _line_ydata(ax)
    assert ax.get_xlabel() == "training iteration" and ax.get_ylabel() == "reward"
    assert "0.002" in ax.get_title()


def test_histogram_counts_every_policy():
    rewards = np.array([9, 10, 500, 500, 250])
    ax = plot_reward_histogram(rewards).axes[0]
    assert sum(patch.get_height() for patch in ax.patches) == len(rewards)


@pytest.mark.todo("1.1.1")
def test_episode_figure_draws_the_thresholds_and_the_cart_where_it_is():
    episode = play_episode(CartPoleLinearPolicy(BALANCING_PARAMS), seed=2)
    figure = plot_episode(episode, step=10)
    position_ax, angle_ax, drawing_ax = figure.axes
    assert (2.4, 2.4) in _line_ydata(position_ax) and (-2.4, -2.4) in _line_ydata(position_ax)
    assert (12.0, 12.0) in _line_ydata(angle_ax)
    cart = drawing_ax.patches[0]
    assert cart.get_x() + cart.get_width() / 2 == np.float64(episode.states[10, 0])
    assert drawing_ax.get_title() == "step 10 of 500"


def test_drawing_tilts_the_pole_with_the_angle():
    ax = draw_cartpole([0.5, 0.0, 0.2, 0.0]).axes[0]
    pole = ax.get_lines()[-1]
    x_data, y_data = pole.get_xdata(), pole.get_ydata()
    assert x_data[1] > x_data[0]  # a positive angle leans right
    np.testing.assert_allclose(np.hypot(x_data[1] - x_data[0], y_data[1] - y_data[0]), 1.0)


def test_sweep_figure_plots_the_fraction_per_rate():
    rewards = np.full((2, 3, 9), 500.0)
    rewards[0, :, :] = 10.0
    sweep = SweepResult(np.array([1e-4, 1e-3]), np.arange(3), rewards, 7)
    ax = plot_learning_rate_sweep(sweep, chosen_learning_rate=5e-4).axes[0]
    np.testing.assert_array_equal(ax.get_lines()[0].get_ydata(), [0.0, 1.0])
    np.testing.assert_array_equal(ax.get_lines()[1].get_xdata(), [5e-4, 5e-4])
