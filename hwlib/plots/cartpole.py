"""Figures of problem 1's episodes: the cart and pole, and an episode over time.

Every function returns a matplotlib Figure and never calls ``plt.show()``: a notebook shows
the figure it gets back, a script saves it.
"""

from __future__ import annotations

import numpy as np
from matplotlib.patches import Circle, Rectangle

from hwlib.cartpole import MAX_EPISODE_REWARD, THETA_THRESHOLD_RADIANS, X_THRESHOLD
from hwlib.plots._figure import figure_png, new_figure  # noqa: F401  (figure_png is re-exported)

CART_WIDTH, CART_HEIGHT = 0.5, 0.3
POLE_LENGTH = 1.0  # gymnasium's pole is 2 x 0.5 long
TRACK_LIMIT = X_THRESHOLD + 0.6

class CartPoleDrawing:
    """The cart and pole drawn on an axes; ``show(state)`` moves them, cheaply, to a new state."""

    def __init__(self, ax):
        self.ax = ax
        ax.set_xlim(-TRACK_LIMIT, TRACK_LIMIT)
        ax.set_ylim(-0.4, 1.4)
        ax.set_aspect("equal")
        ax.set_yticks([])
        ax.set_xlabel("cart position")
        ax.axhline(0, color="0.3", lw=1)
        for limit in (-X_THRESHOLD, X_THRESHOLD):
            ax.axvline(limit, color="tab:red", ls="--", lw=1)
        self.cart = ax.add_patch(Rectangle((0, 0), CART_WIDTH, CART_HEIGHT, color="0.25"))
        (self.pole,) = ax.plot([], [], color="tab:orange", lw=6, solid_capstyle="round")
        self.axle = ax.add_patch(Circle((0, 0), 0.04, color="tab:blue", zorder=3))
        self.caption = ax.set_title("step 0 of 500")  # a placeholder, so the layout leaves room for it

    def show(self, state, caption=""):
        cart_x, _, pole_angle, _ = np.asarray(state, dtype=float)
        axle = (cart_x, CART_HEIGHT)
        self.cart.set_xy((cart_x - CART_WIDTH / 2, 0))
        self.axle.center = axle
        self.pole.set_data(
            [axle[0], axle[0] + POLE_LENGTH * np.sin(pole_angle)],
            [axle[1], axle[1] + POLE_LENGTH * np.cos(pole_angle)],
        )
        self.caption.set_text(caption)


def draw_cartpole(state, caption=""):
    """A still picture of the cart and pole in ``state`` (cart x, cart speed, angle, angular speed)."""
    figure = new_figure(6.4, 2.4)
    CartPoleDrawing(figure.add_subplot()).show(state, caption)
    return figure


class EpisodeView:
    """One figure for an episode: cart position and pole angle over time with the failure
    thresholds, and the cart and pole at one chosen step. ``show`` updates it in place, which
    keeps the slider panel quick."""

    def __init__(self, dpi=80):
        self.figure = new_figure(9.0, 5.0, dpi=dpi)
        grid = self.figure.add_gridspec(2, 2, height_ratios=(1, 1))
        self.position_ax = self.figure.add_subplot(grid[0, 0])
        self.angle_ax = self.figure.add_subplot(grid[0, 1], sharex=self.position_ax)
        self.drawing = CartPoleDrawing(self.figure.add_subplot(grid[1, :]))
        self.position_line = self._time_panel(self.position_ax, "cart position", X_THRESHOLD)
        self.angle_line = self._time_panel(self.angle_ax, "pole angle (degrees)", np.degrees(THETA_THRESHOLD_RADIANS))
        self.cursors = [ax.axvline(0, color="0.5", lw=1) for ax in (self.position_ax, self.angle_ax)]
        # The axes limits never change, so lay the figure out once and keep it: redraws get ~35% faster.
        self.figure.draw_without_rendering()
        self.figure.set_layout_engine("none")

    @staticmethod
    def _time_panel(ax, label, threshold):
        ax.set_xlim(0, MAX_EPISODE_REWARD)
        ax.set_ylim(-1.25 * threshold, 1.25 * threshold)
        ax.set_xlabel("step")
        ax.set_ylabel(label)
        for limit in (-threshold, threshold):
            ax.axhline(limit, color="tab:red", ls="--", lw=1)
        (line,) = ax.plot([], [], color="tab:blue")
        return line

    def show(self, episode, step=None):
        """Draw ``episode`` (an ``hwlib.cartpole.Episode``) with the cart at ``step`` (default: the end)."""
        step = episode.num_steps if step is None else int(np.clip(step, 0, episode.num_steps))
        steps = np.arange(episode.num_steps + 1)
        self.position_line.set_data(steps, episode.states[:, 0])
        self.angle_line.set_data(steps, np.degrees(episode.states[:, 2]))
        for cursor in self.cursors:
            cursor.set_xdata([step, step])
        self.drawing.show(episode.states[step], f"step {step} of {episode.num_steps}")
        return self.figure


def plot_episode(episode, step=None):
    """A figure of ``episode``: position and angle over time, and the cart at ``step``."""
    return EpisodeView(dpi=100).show(episode, step)
