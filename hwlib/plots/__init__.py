"""Every figure the notebooks show: one module per subject."""

from hwlib.plots._figure import figure_png, new_figure
from hwlib.plots.cartpole import EpisodeView, draw_cartpole, plot_episode
from hwlib.plots.landscape import plot_reward_landscape
from hwlib.plots.training import plot_learning_rate_sweep, plot_reward_histogram, plot_training_curve
