"""Every figure the notebooks show, one module per problem."""

from hwlib.plots.cartpole import (
    EpisodeView,
    draw_cartpole,
    figure_png,
    plot_episode,
    plot_learning_rate_sweep,
    plot_reward_histogram,
    plot_training_curve,
)
