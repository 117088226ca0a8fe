"""The reward landscape: g(θ) on a 2-D slice of parameter space, and a widget to explore it.

A slice lets two coordinates of θ vary over a square grid while the other two stay at the
values of a given θ. Every cell of the grid is scored by the mean total reward of the same few
episodes (the same start states for every cell, drawn from one seed), so neighbouring cells
differ only because their policies act differently, never because their episodes started
elsewhere. Every cell plays your ``CartPoleLinearPolicy`` (TODO 1.1.1): the kit plays all cells in
one batch (the kit's NumPy port of CartPole's step) where your ``__call__`` gives the actions of equation
(1), and the others step by step with it (``hwlib/machinery/episodes.py``); ``batched=False`` plays
them all one by one, with the same rewards.

| setting           | default      | meaning                                           |
|-------------------|--------------|---------------------------------------------------|
| ``GRID_SIZE``     | 41           | grid points per axis (41 x 41 cells)              |
| ``VALUE_RANGE``   | (-2.0, 2.0)  | both varying coordinates run over this interval   |
| ``NUM_EPISODES``  | 5            | episodes per cell (the same start states in every cell) |
| ``SEED``          | 0            | master seed of those start states                 |
| ``DEFAULT_AXES``  | (2, 3)       | θ₃ and θ₄ (pole angle, pole angular velocity) vary |

Axes are 0-based indices into θ (0 is θ₁, the weight on the cart position).

``LandscapeExplorer`` is the notebook's widget: two dropdowns choose the axes, ``set_params``
moves the slice to another θ (the slider panel's button calls ``from_panel``), and a status line
says which θ it shows and where it came from. Its drawing is done by ``render_landscape``, a
plain function, so the widget logic is tested without a browser; its redraws run one at a time
and end on the latest request (``LatestOnly``).
"""

from __future__ import annotations

import html
import numbers
import threading
import time
from dataclasses import dataclass

import ipywidgets as widgets
import numpy as np

from hwlib import settings
from hwlib.cartpole import MAX_EPISODE_REWARD, NUM_OBSERVATIONS, episode_seeds
from hwlib.machinery.episodes import run_episodes
from hwlib.machinery.latest_only import LatestOnly
from hwlib.machinery.validation import as_float_array, check_count, check_params, check_path, check_positive_number, check_seed
from hwlib.plots.landscape import AXIS_LABELS, AXIS_NAMES, figure_png, format_theta, new_landscape_figure, plot_reward_landscape

GRID_SIZE = settings.LANDSCAPE_GRID_SIZE
VALUE_RANGE = settings.LANDSCAPE_VALUE_RANGE
NUM_EPISODES = settings.LANDSCAPE_NUM_EPISODES
SEED = settings.LANDSCAPE_SEED
DEFAULT_AXES = settings.LANDSCAPE_AXES

__all__ = ["AXIS_LABELS", "AXIS_NAMES", "LandscapeExplorer", "LandscapeFrame", "RewardSlice", "check_path",
           "format_theta", "landscape_caption", "render_landscape", "reward_slice", "slice_params"]


@dataclass(frozen=True)
class RewardSlice:
    """g(θ) on one slice: ``mean_rewards[j, i]`` is the mean reward with coordinate ``axes[0]``
    at ``values[i]`` (horizontal) and coordinate ``axes[1]`` at ``values[j]`` (vertical), the
    other two coordinates held at those of ``theta``; every cell played from ``seeds``."""

    theta: np.ndarray  # (4,) the point the slice passes through
    axes: tuple  # (horizontal, vertical) coordinate indices, 0-based
    values: np.ndarray  # (grid_size,) grid of both varying coordinates
    mean_rewards: np.ndarray  # (grid_size, grid_size)
    seeds: np.ndarray  # (num_episodes,) start-state seeds shared by every cell

    @property
    def held_axes(self):
        """The two coordinates held fixed, in increasing order."""
        return tuple(index for index in range(NUM_OBSERVATIONS) if index not in self.axes)

    @property
    def num_episodes(self):
        return len(self.seeds)

    def cell_params(self):
        """The parameters of every cell, shape (grid_size**2, 4), row by row (vertical value j, then horizontal i)."""
        return _slice_params(self.theta, self.axes, self.values)


def check_axes(axes, name="axes"):
    """Two different coordinate indices in 0..3, returned as a tuple of ints."""
    try:
        pair = tuple(axes)
    except TypeError:
        pair = None
    if (
        pair is None
        or len(pair) != 2
        or any(isinstance(a, bool) or not isinstance(a, numbers.Integral) or not 0 <= a < NUM_OBSERVATIONS for a in pair)
        or pair[0] == pair[1]
    ):
        raise ValueError(
            f"{name} must be two different coordinate indices in 0..3 (0 is θ₁ ... 3 is θ₄), "
            f"horizontal then vertical, got {axes!r}"
        )
    return int(pair[0]), int(pair[1])


def check_value_range(value_range, name="value_range"):
    """Two finite numbers (low, high) with low < high, returned as floats."""
    array = as_float_array(value_range, name)
    if array.shape != (2,) or not np.all(np.isfinite(array)) or not array[0] < array[1]:
        raise ValueError(f"{name} must be two finite numbers (low, high) with low < high, got {value_range!r}")
    return float(array[0]), float(array[1])


def check_grid_size(grid_size, name="grid_size"):
    """An integer >= 2 (a grid needs both ends)."""
    if isinstance(grid_size, bool) or not isinstance(grid_size, numbers.Integral) or grid_size < 2:
        raise ValueError(f"{name} must be an integer >= 2 (grid points per axis), got {grid_size!r}")
    return int(grid_size)


def slice_params(theta, axes, values):
    """Parameters of every cell of a slice, shape (len(values)**2, 4), row by row: row ``j * n + i``
    is ``theta`` with coordinate ``axes[0]`` set to ``values[i]`` and ``axes[1]`` to ``values[j]``."""
    return _slice_params(check_params(theta, "theta"), check_axes(axes), np.asarray(values, dtype=np.float64))


def _slice_params(theta, axes, values):
    horizontal, vertical = axes
    grid_x, grid_y = np.meshgrid(values, values)  # grid_x[j, i] = values[i], grid_y[j, i] = values[j]
    params = np.tile(theta, (values.size**2, 1))
    params[:, horizontal] = grid_x.ravel()
    params[:, vertical] = grid_y.ravel()
    return params


def reward_slice(
    theta,
    axes=DEFAULT_AXES,
    grid_size=GRID_SIZE,
    value_range=VALUE_RANGE,
    num_episodes=NUM_EPISODES,
    seed=SEED,
    batched=True,
    progress=True,
):
    """The slice of g(θ) through ``theta`` in which coordinates ``axes`` (horizontal, vertical) vary.

    Both vary over ``grid_size`` evenly spaced values in ``value_range``; the other two stay at
    ``theta``'s. Each cell is the mean total reward of ``num_episodes`` episodes of your
    ``CartPoleLinearPolicy`` from the start states of ``hwlib.cartpole.episode_seeds(num_episodes,
    seed)``, the same for every cell. Deterministic: the same arguments give the same slice.
    ``progress``: show a progress bar in the notebook. Returns a ``RewardSlice``.
    """
    theta = check_params(theta, "theta").copy()  # the slice keeps its own θ
    axes = check_axes(axes)
    grid_size = check_grid_size(grid_size)
    low, high = check_value_range(value_range)
    seeds = episode_seeds(num_episodes, seed)
    if not isinstance(batched, bool):
        raise TypeError(f"batched must be True or False, got {batched!r}")

    values = np.linspace(low, high, grid_size)
    params = _slice_params(theta, axes, values)
    title = f"reward landscape ({grid_size} × {grid_size} cells × {num_episodes} episodes)" if progress else None
    rewards = run_episodes(np.repeat(params, len(seeds), axis=0), np.tile(seeds, len(params)), batched, title)
    mean_rewards = rewards.reshape(grid_size, grid_size, len(seeds)).mean(axis=2)
    return RewardSlice(theta, axes, values, mean_rewards, seeds)


# --- the explorer widget ------------------------------------------------------------------------


@dataclass(frozen=True)
class LandscapeFrame:
    """What the explorer shows for one request: the slice, its picture and the line under it."""

    landscape: RewardSlice
    png: bytes
    caption: str


def landscape_caption(landscape):
    """The explorer's line under the picture: its two axes, the θ it goes through, its cells and episodes per
    cell, and the share of cells that score the maximum reward (the episode cap) on every episode."""
    horizontal, vertical = landscape.axes
    n = len(landscape.values)
    share = np.mean(landscape.mean_rewards == MAX_EPISODE_REWARD)
    return (
        f"{AXIS_NAMES[horizontal]} across, {AXIS_NAMES[vertical]} up; through θ = {format_theta(landscape.theta)}; "
        f"{n} × {n} cells × {landscape.num_episodes} episodes each; "
        f"{share:.0%} of the cells score {MAX_EPISODE_REWARD} on every episode"
    )


def render_landscape(
    theta,
    axes=DEFAULT_AXES,
    path=None,
    fd_step=None,
    figure=None,
    grid_size=GRID_SIZE,
    value_range=VALUE_RANGE,
    num_episodes=NUM_EPISODES,
    seed=SEED,
):
    """The explorer's callback: compute the slice through ``theta`` and draw it.

    ``path`` (shape (T + 1, 4)) is drawn projected onto the slice, ``fd_step`` marks the
    finite-difference stencil around θ (see ``plot_reward_landscape``); ``figure`` is the figure
    to redraw (a new one if None); the rest goes to ``reward_slice``. Returns a ``LandscapeFrame``.
    """
    landscape = reward_slice(theta, axes, grid_size, value_range, num_episodes, seed, progress=False)
    figure = plot_reward_landscape(landscape, path=path, fd_step=fd_step, figure=figure)
    return LandscapeFrame(landscape, figure_png(figure), landscape_caption(landscape))


def status_line(theta, source, received, clock=None):
    """The explorer's status line: the θ on show and where it came from, e.g. 'θ = (0.10, ...) received
    from the slider panel at 14:03:05 (θ number 3 received)'; before any, the θ it started with."""
    if received == 0:
        return f"Slice through θ = {format_theta(theta)}. The slider panel's button sends its θ here."
    origin = f" from {source}" if source else ""
    when = f" at {clock}" if clock else ""
    return f"<b>Received θ = {format_theta(theta)}{origin}{when}</b> (θ number {received} received)."


class LandscapeExplorer:
    """The ipywidgets view of the landscape. Display ``explorer.widget`` in a notebook.

    Two dropdowns choose the horizontal and vertical coordinates (choosing the one the other
    dropdown shows swaps them); ``set_params(theta)`` moves the slice to another θ (the slider
    panel's button calls ``from_panel``, which says so in the status line). Redraws never overlap: while one runs, a new request only
    replaces the one waiting, and the running redraw picks up the newest when it finishes, so
    the last request is always the one left on show. ``path``, ``fd_step`` and the slice
    options are those of ``render_landscape``.
    """

    def __init__(
        self,
        theta,
        axes=DEFAULT_AXES,
        path=None,
        fd_step=None,
        grid_size=GRID_SIZE,
        value_range=VALUE_RANGE,
        num_episodes=NUM_EPISODES,
        seed=SEED,
    ):
        # Everything is checked here, before the first drawing, so that nothing fails later inside a widget callback.
        self._theta = check_params(theta, "theta").copy()
        axes = check_axes(axes)
        self.path = None if path is None else check_path(path)
        self.fd_step = None if fd_step is None else check_positive_number(fd_step, "fd_step")
        self.slice_options = {
            "grid_size": check_grid_size(grid_size),
            "value_range": check_value_range(value_range),
            "num_episodes": check_count(num_episodes, "num_episodes"),
            "seed": check_seed(seed, "seed"),
        }
        self.figure = new_landscape_figure()
        self.frame = None  # the LandscapeFrame on show

        self._lock = threading.Lock()  # guards _theta and received
        self._redraws = LatestOnly(self._draw)

        options = [(label, index) for index, label in enumerate(AXIS_LABELS)]
        self.horizontal = widgets.Dropdown(options=options, value=axes[0], description="across")
        self.vertical = widgets.Dropdown(options=options, value=axes[1], description="up")
        self.image = widgets.Image(format="png", layout=widgets.Layout(align_self="flex-start"))  # its own size, not stretched
        self.image.add_class("hwlib-landscape")
        self.caption = widgets.HTML()
        self.caption.add_class("hwlib-landscape-caption")
        self.status = widgets.HTML()  # which θ is on show and where it came from
        self.status.add_class("hwlib-landscape-status")
        self.received = 0  # θs received from set_params / from_panel
        self.horizontal.observe(self._on_axis_change, names="value")
        self.vertical.observe(self._on_axis_change, names="value")
        self.widget = widgets.VBox([widgets.HBox([self.horizontal, self.vertical]), self.status, self.image, self.caption])
        self.status.value = status_line(self._theta, None, 0)
        self.redraw()

    @property
    def theta(self):
        """The θ the slice passes through (a copy)."""
        return self._theta.copy()

    @property
    def axes(self):
        """The (horizontal, vertical) coordinates the dropdowns show."""
        return self.horizontal.value, self.vertical.value

    def set_params(self, theta, source=None):
        """Move the slice to ``theta`` (4 finite numbers) and redraw; the status line names ``source``
        (e.g. "the slider panel") and the time it arrived."""
        theta = check_params(theta, "theta").copy()  # the caller may change its array later
        with self._lock:
            self._theta = theta
            self.received += 1
            received = self.received
        self.status.value = status_line(theta, source, received, time.strftime("%H:%M:%S"))
        self.redraw()

    def from_panel(self, theta):
        """The slider panel's button: ``set_params(theta, source="the slider panel")``."""
        self.set_params(theta, source="the slider panel")

    def set_axes(self, axes):
        """Choose the (horizontal, vertical) coordinates and redraw once."""
        self._set_dropdowns(*check_axes(axes))
        self.redraw()

    def redraw(self):
        """Draw the slice for the current θ and axes; if a redraw is already running, it draws this
        request next (``LatestOnly``) and this call returns at once."""
        self._redraws.request()

    def _draw(self):
        with self._lock:
            theta = self._theta
        if self.frame is not None:
            self.caption.value = "drawing the slice…"
        try:
            frame = render_landscape(theta, self.axes, self.path, self.fd_step, self.figure, **self.slice_options)
        except Exception as error:
            self.caption.value = "could not draw the slice: " + "<br>".join(html.escape(line) for line in str(error).splitlines())
            raise
        if not self._redraws.pending:  # else the newer request's picture follows right away
            self.frame = frame
            self.image.value = frame.png
            self.caption.value = frame.caption

    def _set_dropdowns(self, horizontal, vertical):
        for dropdown in (self.horizontal, self.vertical):
            dropdown.unobserve(self._on_axis_change, names="value")
        try:
            self.horizontal.value, self.vertical.value = horizontal, vertical
        finally:
            for dropdown in (self.horizontal, self.vertical):
                dropdown.observe(self._on_axis_change, names="value")

    def _on_axis_change(self, change):
        horizontal, vertical = self.axes
        if horizontal == vertical:  # the other dropdown showed this coordinate: swap the two
            if change["owner"] is self.horizontal:
                vertical = change["old"]
            else:
                horizontal = change["old"]
            self._set_dropdowns(horizontal, vertical)
        self.redraw()
