"""Figures of problem 1's episodes: the cart and pole, and an episode over time.

Every function returns a matplotlib Figure and never calls ``plt.show()``: a notebook shows
the figure it gets back, a script saves it.
"""

from __future__ import annotations

import io
import numbers

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_hex
from matplotlib.patches import Circle, Rectangle
from matplotlib.ticker import MaxNLocator
from PIL import Image

from hwlib.machinery.validation import as_float_array, check_finite, check_positive_number
from hwlib.cartpole import MAX_EPISODE_REWARD, THETA_THRESHOLD_RADIANS, X_THRESHOLD, Episode
from hwlib.plots._figure import figure_png, new_figure  # noqa: F401  (figure_png is re-exported)

CART_WIDTH, CART_HEIGHT = 0.5, 0.3
POLE_LENGTH = 1.0  # gymnasium's pole is 2 x 0.5 long
TRACK_LIMIT = X_THRESHOLD + 0.6
MIN_TIME_SPAN = 10  # the time axes show at least this many steps
STEP_LIMIT_GID = "step-limit"  # the id of the artists that mark the step limit (MAX_EPISODE_REWARD steps)
PNG_COMPRESS_LEVEL = 1  # zlib level of the panel's frames: 8 ms instead of 40 ms a frame, ~10% larger


class CartPoleDrawing:
    """The cart and pole drawn on an axes; ``show(state)`` moves them, cheaply, to a new state."""

    def __init__(self, ax):
        self.ax = ax
        ax.set_xlim(-TRACK_LIMIT, TRACK_LIMIT)
        ax.set_ylim(-0.4, 1.4)
        ax.set_aspect("equal")
        ax.set_yticks([])
        ax.set_xlabel("cart position [m]")
        ax.axhline(0, color="0.3", lw=1)
        for limit in (-X_THRESHOLD, X_THRESHOLD):
            ax.axvline(limit, color="tab:red", ls="--", lw=1)
        self.cart = ax.add_patch(Rectangle((0, 0), CART_WIDTH, CART_HEIGHT, color="0.25"))
        (self.pole,) = ax.plot([], [], color="tab:orange", lw=6, solid_capstyle="round")
        self.axle = ax.add_patch(Circle((0, 0), 0.04, color="tab:blue", zorder=3))
        self.caption = ax.set_title(f"step 0 of {MAX_EPISODE_REWARD}")  # a placeholder, so the layout leaves room for it

    @property
    def moving_artists(self):
        """What ``show`` changes: the cart, the pole, the axle and the caption."""
        return [self.cart, self.pole, self.axle, self.caption]

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
    state = check_finite(as_float_array(state, "state"), "state")
    if state.shape != (4,):
        raise ValueError(f"state must have shape (4,): cart position, cart velocity, pole angle, pole angular velocity; got shape {state.shape}")
    figure = new_figure(6.4, 2.4)
    CartPoleDrawing(figure.add_subplot()).show(state, caption)
    return figure


class EpisodeView:
    """One figure for an episode: cart position and pole angle over time with the failure
    thresholds, and the cart and pole at one chosen step. ``show`` updates it in place, which
    keeps the slider panel quick.

    The time axes span the episode (at least ``MIN_TIME_SPAN`` steps), so an 8-step failure fills
    the plot as a run to the step limit does; that limit is marked only when the episode reaches it.
    The pole angle is in radians, the unit of the observation (and of the slider panel's θ₃
    label), with degrees on the right-hand axis. The figure is opaque white, so a PNG of it is
    never transparent (whatever the notebook's backend).

    ``frame_png(episode, step)`` is the slider panel's picture: what depends only on the episode
    (the curves, the axes, the limits) is drawn once per episode and kept; each step then redraws
    only the time cursors and the cart (about 10 ms instead of 50, so ▶ Play keeps up).
    """

    def __init__(self, dpi=80, width=9.0, height=4.4):
        dpi, width, height = (check_positive_number(value, name) for value, name in ((dpi, "dpi"), (width, "width"), (height, "height")))
        self.figure = new_figure(width, height, dpi=dpi)
        self.canvas = FigureCanvasAgg(self.figure)
        self.figure.set_facecolor("white")
        grid = self.figure.add_gridspec(2, 2, height_ratios=(1, 1))
        self.position_ax = self.figure.add_subplot(grid[0, 0])
        self.angle_ax = self.figure.add_subplot(grid[0, 1], sharex=self.position_ax)
        self.drawing = CartPoleDrawing(self.figure.add_subplot(grid[1, :]))
        self.position_line = self._time_panel(self.position_ax, "cart position [m]", X_THRESHOLD)
        self.angle_line = self._time_panel(self.angle_ax, "pole angle [rad]", THETA_THRESHOLD_RADIANS)
        degrees = self.angle_ax.secondary_yaxis("right", functions=(np.degrees, np.radians))
        degrees.set_ylabel("[°]")
        self.cursors = [ax.axvline(0, color="0.5", lw=1) for ax in (self.position_ax, self.angle_ax)]
        self.limit_marks = []
        for ax in (self.position_ax, self.angle_ax):
            self.limit_marks.append(ax.axvline(MAX_EPISODE_REWARD, color="tab:green", ls=":", lw=2, gid=STEP_LIMIT_GID))
            self.limit_marks.append(ax.text(
                MAX_EPISODE_REWARD, 0.97, f"{MAX_EPISODE_REWARD}-step limit ", transform=ax.get_xaxis_transform(),
                ha="right", va="top", color="tab:green", fontsize="small", gid=STEP_LIMIT_GID,
            ))
        self.position_ax.xaxis.set_major_locator(MaxNLocator(integer=True, steps=[1, 2, 2.5, 5, 10]))
        # The layout (room for labels and titles) does not depend on the episode: lay the figure out
        # once and keep it, which makes redraws ~35% faster. Only the x tick labels change, below the axes.
        self.figure.draw_without_rendering()
        self.figure.set_layout_engine("none")
        self._background = None  # (episode, pixels) of the last frame_png's episode-only drawing

    @staticmethod
    def _time_panel(ax, label, threshold):
        ax.set_xlim(0, MAX_EPISODE_REWARD)
        ax.set_ylim(-1.25 * threshold, 1.25 * threshold)
        ax.set_xlabel("time step")
        ax.set_ylabel(label)
        for limit in (-threshold, threshold):
            ax.axhline(limit, color="tab:red", ls="--", lw=1)
        (line,) = ax.plot([], [], color="tab:blue")
        return line

    @property
    def moving_artists(self):
        """The artists that change with the step alone: the time cursors and the cart drawing."""
        return [*self.cursors, *self.drawing.moving_artists]

    def show(self, episode, step=None):
        """Draw ``episode`` (an ``hwlib.cartpole.Episode``) with the cart at ``step`` (default: the end).

        ``step`` is None or a whole number from 0 to ``episode.num_steps``.
        """
        if not isinstance(episode, Episode):
            raise TypeError(f"episode must be an hwlib.cartpole.Episode, got {type(episode).__name__}")
        step = check_step(step, episode.num_steps)
        if self._background is None or self._background[0] is not episode:
            self._show_episode(episode)
        for cursor in self.cursors:
            cursor.set_xdata([step, step])
        caption = f"step {step} of {episode.num_steps}"
        if step == episode.num_steps:
            caption += f": {how_it_ended(episode)}"
        self.drawing.show(episode.states[step], caption)
        return self.figure

    def _show_episode(self, episode):
        self._background = None
        steps = np.arange(episode.num_steps + 1)
        self.position_line.set_data(steps, episode.states[:, 0])
        self.angle_line.set_data(steps, episode.states[:, 2])
        self.position_ax.set_xlim(0, time_axis_end(episode.num_steps))  # shared with the angle axes
        reached_limit = episode.num_steps >= MAX_EPISODE_REWARD
        for mark in self.limit_marks:
            mark.set_visible(reached_limit)

    def frame_png(self, episode, step=None):
        """PNG bytes of the figure showing ``episode`` at ``step``, as ``show`` draws it.

        The episode-only part is drawn once and kept (the moving artists are left out of it and
        drawn over it for each step), so every frame of one episode costs only the moving parts
        and the PNG encoding. The pixels do not depend on which frames were drawn before.
        """
        self.show(episode, step)
        moving = self.moving_artists
        if self._background is None:
            for artist in moving:
                artist.set_animated(True)  # left out of canvas.draw(), drawn below over the kept part
            self.canvas.draw()
            self._background = (episode, self.canvas.copy_from_bbox(self.figure.bbox))
        else:
            self.canvas.restore_region(self._background[1])
        renderer = self.canvas.get_renderer()
        for artist in moving:
            artist.draw(renderer)
        pixels = np.asarray(self.canvas.buffer_rgba())
        buffer = io.BytesIO()
        Image.fromarray(pixels, "RGBA").save(buffer, format="png", compress_level=PNG_COMPRESS_LEVEL)
        return buffer.getvalue()

    def overlay(self, episode):
        """Where ``frame_png`` draws the moving parts at every step of ``episode``, in pixels from the
        picture's top-left corner, with their colours and widths: what the slider panel's browser part
        needs to play the episode over ``background_png`` without asking the kernel for each frame."""
        self.show(episode, None)
        height = self.figure.bbox.height
        points_per_pixel = self.figure.dpi / 72
        steps = np.arange(episode.num_steps + 1)
        cursors = []
        for ax in (self.position_ax, self.angle_ax):
            x, _ = _pixels(ax, np.column_stack([steps, np.zeros(len(steps))]), height)
            cursors.append({"x": _rounded(x), "top": round(float(height - ax.bbox.y1), 2), "bottom": round(float(height - ax.bbox.y0), 2)})
        ax = self.drawing.ax
        cart_x, pole_angle = episode.states[:, 0], episode.states[:, 2]
        left, top = _pixels(ax, np.column_stack([cart_x - CART_WIDTH / 2, np.full(len(cart_x), CART_HEIGHT)]), height)
        right, bottom = _pixels(ax, [[CART_WIDTH / 2, 0.0]], height)
        zero_x, _ = _pixels(ax, [[0.0, 0.0]], height)
        axle_x, axle_y = _pixels(ax, np.column_stack([cart_x, np.full(len(cart_x), CART_HEIGHT)]), height)
        tip_x, tip_y = _pixels(ax, np.column_stack([cart_x + POLE_LENGTH * np.sin(pole_angle),
                                                    CART_HEIGHT + POLE_LENGTH * np.cos(pole_angle)]), height)
        scale = float(right[0] - zero_x[0]) / (CART_WIDTH / 2)  # pixels per metre (equal aspect)
        caption_x, caption_y = self.drawing.caption.get_transform().transform(self.drawing.caption.get_position())
        return {
            "num_steps": int(episode.num_steps),
            "ending": how_it_ended(episode),
            "cursors": cursors,
            "cursor": {"color": to_hex(self.cursors[0].get_color()), "width": self.cursors[0].get_linewidth() * points_per_pixel},
            "clip": {"left": round(float(ax.bbox.x0), 2), "top": round(float(height - ax.bbox.y1), 2),
                     "width": round(float(ax.bbox.width), 2), "height": round(float(ax.bbox.height), 2)},
            "cart": {"left": _rounded(left), "top": round(float(top[0]), 2), "width": round(CART_WIDTH * scale, 2),
                     "height": round(float(bottom[0] - top[0]), 2), "color": to_hex(self.drawing.cart.get_facecolor())},
            "pole": {"x0": _rounded(axle_x), "y0": round(float(axle_y[0]), 2), "x1": _rounded(tip_x), "y1": _rounded(tip_y),
                     "width": self.drawing.pole.get_linewidth() * points_per_pixel, "color": to_hex(self.drawing.pole.get_color())},
            "axle": {"radius": round(self.drawing.axle.get_radius() * scale, 2), "color": to_hex(self.drawing.axle.get_facecolor())},
            "caption": {"x": round(float(caption_x), 2), "y": round(float(height - caption_y), 2),
                        "size": self.drawing.caption.get_fontsize() * points_per_pixel, "color": to_hex(self.drawing.caption.get_color())},
        }

    def background_png(self, episode):
        """PNG bytes of what ``frame_png`` keeps for ``episode``: the figure without the moving parts."""
        if self._background is None or self._background[0] is not episode:
            self.frame_png(episode, None)
        self.canvas.restore_region(self._background[1])
        pixels = np.asarray(self.canvas.buffer_rgba())
        buffer = io.BytesIO()
        Image.fromarray(pixels, "RGBA").save(buffer, format="png", compress_level=PNG_COMPRESS_LEVEL)
        return buffer.getvalue()


def how_it_ended(episode):
    """Why ``episode`` stopped, in a few words: the pole fell, the cart left the track, or the step limit."""
    cart_x, _, pole_angle, _ = episode.states[-1]
    reasons = []
    if abs(pole_angle) > THETA_THRESHOLD_RADIANS:
        reasons.append(f"the pole fell past ±{THETA_THRESHOLD_RADIANS:.2f} rad = ±{np.degrees(THETA_THRESHOLD_RADIANS):.0f}°")
    if abs(cart_x) > X_THRESHOLD:
        reasons.append(f"the cart ran off the track past ±{X_THRESHOLD} m")
    if not reasons and episode.num_steps >= MAX_EPISODE_REWARD:
        reasons.append(f"reached the {MAX_EPISODE_REWARD}-step limit")
    return " and ".join(reasons) if reasons else "stopped"


def time_axis_end(num_steps):
    """Where the time axes end for an episode of ``num_steps`` steps: just past its last step."""
    return max(num_steps, MIN_TIME_SPAN) * 1.03


def check_step(step, num_steps):
    """``step`` as an int in [0, num_steps]; None means the last step."""
    if step is None:
        return num_steps
    if isinstance(step, bool) or not isinstance(step, numbers.Integral) or not 0 <= step <= num_steps:
        raise ValueError(f"step must be None or a whole number from 0 to {num_steps} (the episode's steps), got {step!r}")
    return int(step)


def plot_episode(episode, step=None):
    """A figure of ``episode``: position and angle over time, and the cart at ``step``."""
    return EpisodeView(dpi=100).show(episode, step)


def message_png(lines, size_inches, dpi):
    """PNG bytes of a white picture of ``size_inches`` (width, height) at ``dpi`` that shows ``lines``
    of text: what the slider panel shows in place of an episode it could not play."""
    if isinstance(lines, str) or not all(isinstance(line, str) for line in lines):
        raise TypeError("lines must be a list of strings")
    width, height = (check_positive_number(value, name) for value, name in zip(size_inches, ("width", "height")))
    figure = new_figure(width, height, dpi=check_positive_number(dpi, "dpi"))
    figure.set_layout_engine("none")
    figure.set_facecolor("white")
    figure.text(0.5, 0.5, "\n".join(lines), ha="center", va="center", wrap=True, fontsize="large", color="0.2")
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    buffer = io.BytesIO()
    Image.fromarray(np.asarray(canvas.buffer_rgba()), "RGBA").save(buffer, format="png", compress_level=PNG_COMPRESS_LEVEL)
    return buffer.getvalue()


def _pixels(ax, points, height):
    """Display coordinates of data ``points`` (N x 2) on ``ax``, from the picture's top-left corner."""
    xy = ax.transData.transform(np.asarray(points, dtype=float))
    return xy[:, 0], height - xy[:, 1]


def _rounded(values):
    return [round(float(value), 2) for value in np.atleast_1d(values)]
