"""The reward landscape: the slice of g(θ), its figure and the explorer widget (no browser)."""

import threading

import numpy as np
import pytest
from matplotlib.figure import Figure

from hwlib import CartPoleLinearPolicy, run_policy
from hwlib import landscape as landscape_module
from hwlib.cartpole import MAX_EPISODE_REWARD, episode_seeds, make_env
from hwlib.machinery.episodes import run_episodes
from hwlib.landscape import (
    AXIS_LABELS,
    LandscapeExplorer,
    RewardSlice,
    landscape_caption,
    render_landscape,
    reward_slice,
    slice_params,
)
from hwlib.plots import plot_reward_landscape

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
THETA = np.array([0.3, -0.6, -1.1, -0.7])
SMALL = {"grid_size": 5, "num_episodes": 2}  # a quick slice for the widget tests


@pytest.fixture(scope="module")
def default_slice():
    return reward_slice(THETA)


# --- the slice -------------------------------------------------------------------------------


def test_default_slice_is_41_by_41_over_minus_2_to_2_with_5_shared_episodes(default_slice):
    assert default_slice.axes == (2, 3) and default_slice.held_axes == (0, 1)
    np.testing.assert_array_equal(default_slice.values, np.linspace(-2, 2, 41))
    assert default_slice.mean_rewards.shape == (41, 41)
    np.testing.assert_array_equal(default_slice.seeds, episode_seeds(5, 0))
    assert default_slice.num_episodes == 5
    assert np.all((default_slice.mean_rewards >= 1) & (default_slice.mean_rewards <= MAX_EPISODE_REWARD))
    # A landscape worth looking at: plateaus at the maximum and cells that fail fast.
    assert np.any(default_slice.mean_rewards == MAX_EPISODE_REWARD) and np.any(default_slice.mean_rewards < 20)


def test_cells_hold_the_other_coordinates_and_vary_the_chosen_ones(default_slice):
    params = default_slice.cell_params()
    n = len(default_slice.values)
    assert params.shape == (n * n, 4)
    np.testing.assert_array_equal(params[:, [0, 1]], np.tile(THETA[[0, 1]], (n * n, 1)))
    grid = params.reshape(n, n, 4)  # [vertical j, horizontal i]
    np.testing.assert_array_equal(grid[3, :, 2], default_slice.values)  # across: θ₃
    np.testing.assert_array_equal(grid[:, 3, 3], default_slice.values)  # up: θ₄


def test_each_cell_is_the_mean_of_its_episodes_from_the_shared_starts(default_slice):
    values, seeds = default_slice.values, default_slice.seeds
    for j, i in [(0, 0), (12, 30), (40, 7), (20, 20)]:
        params = THETA.copy()
        params[2], params[3] = values[i], values[j]
        rewards = run_episodes(np.tile(params, (len(seeds), 1)), seeds)
        assert default_slice.mean_rewards[j, i] == rewards.mean()


def test_scaling_theta_by_two_scales_the_slice_and_nothing_else_changes():
    """The policy sees only the direction of θ. Doubling θ and the range doubles every cell's
    parameters exactly (a power of two), so every cell must score exactly the same."""
    axes = (1, 3)
    base = reward_slice(THETA, axes, grid_size=21, value_range=(-1.0, 1.0), num_episodes=3, seed=7)
    doubled = reward_slice(2 * THETA, axes, grid_size=21, value_range=(-2.0, 2.0), num_episodes=3, seed=7)
    np.testing.assert_array_equal(doubled.cell_params(), 2 * base.cell_params())
    np.testing.assert_array_equal(doubled.mean_rewards, base.mean_rewards)
    assert len(np.unique(base.mean_rewards)) > 3, "a flat slice would prove nothing"


def test_through_the_origin_the_slice_is_constant_along_rays():
    """Held coordinates at zero: cell (x, y) and cell (2x, 2y) are the same policy."""
    one_side = reward_slice(np.zeros(4), (2, 3), grid_size=9, value_range=(-2.0, 2.0), num_episodes=5, seed=3)
    values = one_side.values  # -2, -1.5, ..., 2: exact in binary
    position = {float(v): k for k, v in enumerate(values)}
    pairs = 0
    for j, y in enumerate(values):
        for i, x in enumerate(values):
            if (x, y) != (0, 0) and float(2 * x) in position and float(2 * y) in position:
                assert one_side.mean_rewards[position[float(2 * y)], position[float(2 * x)]] == one_side.mean_rewards[j, i], (x, y)
                pairs += 1
    assert pairs == 24
    assert len(np.unique(one_side.mean_rewards)) > 3


@pytest.mark.todo("1.1.1")
def test_batched_slice_equals_the_same_cells_played_one_by_one():
    batched = reward_slice(THETA, (0, 2), grid_size=4, value_range=(-1.5, 1.5), num_episodes=2, seed=11)
    env = make_env()
    one_by_one = np.array([
        np.mean([run_policy(CartPoleLinearPolicy(params), seed=int(seed), env=env) for seed in batched.seeds])
        for params in batched.cell_params()
    ]).reshape(4, 4)
    np.testing.assert_array_equal(batched.mean_rewards, one_by_one)
    looped = reward_slice(THETA, (0, 2), grid_size=4, value_range=(-1.5, 1.5), num_episodes=2, seed=11, batched=False)
    np.testing.assert_array_equal(looped.mean_rewards, batched.mean_rewards)


def test_the_same_arguments_give_the_same_slice_and_the_seed_picks_the_starts():
    first = reward_slice(THETA, (0, 3), grid_size=7, num_episodes=3, seed=5)
    again = reward_slice(THETA, (0, 3), grid_size=7, num_episodes=3, seed=5)
    other = reward_slice(THETA, (0, 3), grid_size=7, num_episodes=3, seed=6)
    np.testing.assert_array_equal(first.mean_rewards, again.mean_rewards)
    np.testing.assert_array_equal(first.seeds, episode_seeds(3, 5))
    assert not np.array_equal(first.seeds, other.seeds)


def test_slice_params_lays_cells_out_row_by_row():
    params = slice_params([1.0, 2.0, 3.0, 4.0], (3, 0), [10.0, 20.0])  # θ₄ across, θ₁ up
    np.testing.assert_array_equal(params, [[10, 2, 3, 10], [10, 2, 3, 20], [20, 2, 3, 10], [20, 2, 3, 20]])


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"theta": [1, 2, 3]}, ValueError, r"theta must have shape \(4,\)"),
        ({"theta": [0, np.nan, 0, 0]}, ValueError, "theta must hold only finite numbers"),
        ({"theta": "abcd"}, TypeError, "theta must be an array of numbers"),
        ({"axes": (2, 2)}, ValueError, "axes must be two different coordinate indices in 0..3"),
        ({"axes": (0, 4)}, ValueError, "axes must be two different"),
        ({"axes": (-1, 2)}, ValueError, "axes must be two different"),
        ({"axes": (1,)}, ValueError, "axes must be two different"),
        ({"axes": (1, 2, 3)}, ValueError, "axes must be two different"),
        ({"axes": (True, 2)}, ValueError, "axes must be two different"),
        ({"axes": (1.0, 2)}, ValueError, "axes must be two different"),
        ({"axes": 3}, ValueError, "axes must be two different"),
        ({"grid_size": 1}, ValueError, "grid_size must be an integer >= 2"),
        ({"grid_size": 10.0}, ValueError, "grid_size must be an integer >= 2"),
        ({"grid_size": True}, ValueError, "grid_size must be an integer >= 2"),
        ({"value_range": (1.0, 1.0)}, ValueError, r"value_range must be two finite numbers \(low, high\) with low < high"),
        ({"value_range": (2.0, -2.0)}, ValueError, "value_range must be two finite numbers"),
        ({"value_range": (0.0, np.inf)}, ValueError, "value_range must be two finite numbers"),
        ({"value_range": (0.0, 1.0, 2.0)}, ValueError, "value_range must be two finite numbers"),
        ({"value_range": 2.0}, ValueError, "value_range must be two finite numbers"),
        ({"num_episodes": 0}, ValueError, "num_episodes must be a positive integer"),
        ({"seed": -1}, ValueError, "seed must be a non-negative integer"),
        ({"seed": 1.5}, ValueError, "seed must be a non-negative integer"),
        ({"batched": "yes"}, TypeError, "batched must be True or False"),
    ],
)
def test_bad_arguments_are_rejected_naming_the_argument(kwargs, error, message):
    arguments = {"theta": THETA, **kwargs}
    with pytest.raises(error, match=message):
        reward_slice(**arguments)


# --- the figure ------------------------------------------------------------------------------

# Iterations 5-6 and 9-12 stay put on the (θ₃, θ₄) slice (they move only in θ₁, θ₂).
PATH = np.array([
    [0.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, -0.3, -0.2],
    [0.0, 0.1, -0.6, -0.4],
    [0.0, 0.2, -0.8, -0.6],
    [0.1, 0.3, -0.9, -0.8],
    [0.1, 0.4, -1.0, -1.0],
    [0.2, 0.5, -1.0, -1.0],
    [0.2, 0.5, -1.2, -1.0],
    [0.2, 0.5, -1.2, -1.4],
    [0.2, 0.5, -1.4, -1.5],
    [0.3, 0.6, -1.4, -1.5],
    [0.3, 0.7, -1.4, -1.5],
    [0.3, 0.8, -1.4, -1.5],
])


def _labels(ax):
    return [text.get_text() for text in ax.texts]


def test_figure_shows_the_slice_with_a_fixed_colour_bar_named_axes_and_the_held_values(default_slice):
    figure = plot_reward_landscape(default_slice)
    assert isinstance(figure, Figure)
    ax, colour_bar_ax = figure.axes
    (image,) = ax.get_images()
    assert image.get_clim() == (0, MAX_EPISODE_REWARD)
    np.testing.assert_array_equal(image.get_array(), default_slice.mean_rewards)
    assert ax.get_xlabel() == "θ₃ · pole angle" == AXIS_LABELS[2]
    assert ax.get_ylabel() == "θ₄ · pole angular velocity"
    assert "θ₁ = 0.30" in ax.get_title() and "θ₂ = -0.60" in ax.get_title()
    assert colour_bar_ax.get_ylim() == (0, MAX_EPISODE_REWARD)
    (theta_marker,) = ax.get_lines()
    assert (theta_marker.get_xdata()[0], theta_marker.get_ydata()[0]) == (-1.1, -0.7)
    assert _labels(ax) == []


def test_figure_projects_the_training_path_with_one_numbered_dot_per_iteration(default_slice):
    ax = plot_reward_landscape(default_slice, path=PATH).axes[0]
    path_line = next(line for line in ax.get_lines() if "training path" in line.get_label())
    np.testing.assert_array_equal(path_line.get_xdata(), PATH[:, 2])
    np.testing.assert_array_equal(path_line.get_ydata(), PATH[:, 3])
    assert path_line.get_marker() == "o" and "iterations 0–12" in path_line.get_label()
    assert _labels(ax) == ["0", "1", "2", "3", "4", "5–6", "7", "8", "9–12"]
    for label in _labels(ax):
        assert all(part.isdigit() for part in label.split("–")), "iteration labels are whole numbers"


def test_figure_marks_the_finite_difference_stencil(default_slice):
    ax = plot_reward_landscape(default_slice, fd_step=0.5).axes[0]
    stencil = next(line for line in ax.get_lines() if "h = 0.5" in line.get_label())
    np.testing.assert_allclose(stencil.get_xdata(), [-1.6, -0.6, -1.1, -1.1])
    np.testing.assert_allclose(stencil.get_ydata(), [-0.7, -0.7, -1.2, -0.2])
    from matplotlib.colors import to_rgb

    assert to_rgb(stencil.get_markeredgecolor()) != to_rgb("white"), "its legend marker must show on the white legend"


def test_the_path_labels_stay_inside_the_axes_and_clear_of_each_other():
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    path = np.zeros((21, 4))  # the notebook's path: a climb, then a pile of iterations near one spot
    path[:, 2] = [0, -0.02, -0.3, -0.56, -0.77, -0.9, -0.95, -0.98, -1.02, -1.03] + [-1.04] * 11
    path[:, 3] = [0, -0.12, -0.24, -0.45, -0.64, -0.66, -0.63, -0.63, -0.62, -0.62] + [-0.92] * 11
    figure = plot_reward_landscape(reward_slice(path[-1], axes=(2, 3), grid_size=5, num_episodes=1), path=path, fd_step=0.5)
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    ax = figure.axes[0]
    boxes = [text.get_bbox_patch().get_window_extent(canvas.get_renderer()) for text in ax.texts]
    assert [text.get_text() for text in ax.texts] == _labels(ax) and "10–20" in _labels(ax)
    for index, box in enumerate(boxes):
        assert ax.bbox.x0 <= box.x0 and box.x1 <= ax.bbox.x1 and ax.bbox.y0 <= box.y0 and box.y1 <= ax.bbox.y1, _labels(ax)[index]
        assert not any(box.overlaps(other) for other in boxes[index + 1:]), _labels(ax)[index]


def test_figure_names_theta_and_says_when_it_lies_outside_the_plotted_range():
    inside = plot_reward_landscape(reward_slice([-0.0, 0.5, 1.0, -1.5], grid_size=3, num_episodes=1)).axes[0]
    assert inside.get_lines()[-1].get_label() == "θ = (0.00, 0.50, 1.00, -1.50)"
    outside = plot_reward_landscape(reward_slice([0.0, 0.5, 5.0, -1.5], grid_size=3, num_episodes=1)).axes[0]
    assert outside.get_lines()[-1].get_label() == "θ = (0.00, 0.50, 5.00, -1.50) (outside the plotted range)"


def test_figure_is_redrawn_in_place(default_slice):
    figure = plot_reward_landscape(default_slice, path=PATH)
    again = plot_reward_landscape(default_slice, figure=figure)
    assert again is figure and len(figure.axes) == 2 and _labels(figure.axes[0]) == []


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"path": np.zeros((5, 3))}, r"path must have shape \(T \+ 1, 4\)"),
        ({"path": np.zeros(4)}, r"path must have shape \(T \+ 1, 4\)"),
        ({"path": [[0, 0, np.inf, 0]]}, "path must hold only finite numbers"),
        ({"fd_step": 0}, "fd_step must be a finite number > 0"),
    ],
)
def test_figure_rejects_bad_arguments(default_slice, kwargs, message):
    with pytest.raises(ValueError, match=message):
        plot_reward_landscape(default_slice, **kwargs)


def test_figure_wants_a_slice():
    with pytest.raises(TypeError, match="landscape must be an hwlib.landscape.RewardSlice"):
        plot_reward_landscape(np.zeros((41, 41)))


# --- the explorer ----------------------------------------------------------------------------


def test_render_landscape_computes_and_draws_the_slice():
    frame = render_landscape(THETA, (1, 2), path=PATH, fd_step=0.5, **SMALL)
    assert isinstance(frame.landscape, RewardSlice) and frame.landscape.axes == (1, 2)
    np.testing.assert_array_equal(frame.landscape.mean_rewards, reward_slice(THETA, (1, 2), **SMALL).mean_rewards)
    assert frame.png.startswith(PNG_SIGNATURE)
    assert frame.caption == landscape_caption(frame.landscape)
    assert frame.caption.startswith("θ₂ across, θ₃ up; through θ = (0.30, -0.60, -1.10, -0.70); 5 × 5 cells × 2 episodes each; ")


def test_explorer_shows_the_slice_through_its_theta():
    explorer = LandscapeExplorer(THETA, path=PATH, **SMALL)
    assert explorer.axes == (2, 3)
    assert explorer.image.value == explorer.frame.png and bytes(explorer.image.value).startswith(PNG_SIGNATURE)
    assert explorer.caption.value == explorer.frame.caption
    np.testing.assert_array_equal(explorer.frame.landscape.theta, THETA)
    assert [label for label, _ in explorer.horizontal.options] == list(AXIS_LABELS)


def test_set_params_moves_the_slice_and_redraws():
    explorer = LandscapeExplorer(THETA, **SMALL)
    before = explorer.image.value
    explorer.set_params([0.0, 0.0, 1.0, 1.0])
    np.testing.assert_array_equal(explorer.frame.landscape.theta, [0.0, 0.0, 1.0, 1.0])
    np.testing.assert_array_equal(explorer.theta, [0.0, 0.0, 1.0, 1.0])
    assert explorer.image.value == explorer.frame.png != before


def test_the_status_line_shows_the_theta_the_slider_panel_sent():
    explorer = LandscapeExplorer(THETA, **SMALL)
    assert explorer.status.value.startswith("Slice through θ = (0.30, -0.60, -1.10, -0.70).")
    assert explorer.status in explorer.widget.children and "hwlib-landscape-status" in explorer.status._dom_classes
    explorer.from_panel([0.1, -0.5, 1.0, -0.5])
    assert "Received θ = (0.10, -0.50, 1.00, -0.50) from the slider panel at " in explorer.status.value
    assert "(θ number 1 received)" in explorer.status.value
    explorer.from_panel([0.1, -0.5, 1.0, -0.5])  # the same θ again still shows that it arrived
    assert "(θ number 2 received)" in explorer.status.value
    explorer.set_params(np.zeros(4))
    assert "Received θ = (0.00, 0.00, 0.00, 0.00) at " in explorer.status.value and "(θ number 3 received)" in explorer.status.value


def test_the_slice_plays_the_students_policy(monkeypatch):
    def mirrored(self, obs):
        return int(np.dot(self.params, obs) > 0)

    kit = reward_slice(THETA, **SMALL, progress=False)
    monkeypatch.setattr(CartPoleLinearPolicy, "__call__", mirrored)
    student = reward_slice(THETA, **SMALL, progress=False)
    looped = reward_slice(THETA, **SMALL, batched=False, progress=False)
    np.testing.assert_array_equal(student.mean_rewards, looped.mean_rewards)
    assert not np.array_equal(student.mean_rewards, kit.mean_rewards)


def test_choosing_an_axis_redraws_once_and_choosing_the_other_ones_swaps_them(monkeypatch):
    explorer = LandscapeExplorer(THETA, **SMALL)
    drawn = []
    real_render = landscape_module.render_landscape
    monkeypatch.setattr(landscape_module, "render_landscape", lambda theta, axes, *a, **k: drawn.append(axes) or real_render(theta, axes, *a, **k))
    explorer.horizontal.value = 0
    assert explorer.axes == (0, 3) and explorer.frame.landscape.axes == (0, 3)
    explorer.vertical.value = 0  # the coordinate shown across: the two swap
    assert explorer.axes == (3, 0) and explorer.frame.landscape.axes == (3, 0)
    explorer.set_axes((1, 2))
    assert explorer.axes == (1, 2)
    assert drawn == [(0, 3), (3, 0), (1, 2)]


def test_explorer_rejects_bad_arguments_at_the_door_and_keeps_its_picture():
    explorer = LandscapeExplorer(THETA, **SMALL)
    shown = explorer.image.value
    with pytest.raises(ValueError, match=r"theta must have shape \(4,\)"):
        explorer.set_params([1.0, 2.0])
    with pytest.raises(ValueError, match="axes must be two different"):
        explorer.set_axes((1, 1))
    assert explorer.image.value == shown and explorer.axes == (2, 3)
    for kwargs, message in [
        ({"axes": (0, 0)}, "axes must be"),
        ({"path": np.zeros((3, 2))}, "path must have shape"),
        ({"fd_step": -1.0}, "fd_step must be"),
        ({"grid_size": 1}, "grid_size must be"),
        ({"value_range": (1, 0)}, "value_range must be"),
        ({"num_episodes": 0}, "num_episodes must be"),
        ({"seed": -2}, "seed must be"),
    ]:
        with pytest.raises(ValueError, match=message):
            LandscapeExplorer(THETA, **kwargs)


def test_redraws_never_overlap_and_the_last_request_wins(monkeypatch):
    """While one redraw runs, later requests only replace the waiting one: the running redraw
    then draws the newest and shows it, and the picture of the request overtaken is never shown."""
    real_render = landscape_module.render_landscape
    drawn, running, most_running = [], [0], [0]
    release = threading.Event()

    def slow_render(theta, axes, *args, **kwargs):
        running[0] += 1
        most_running[0] = max(most_running[0], running[0])
        drawn.append((tuple(theta), axes))
        try:
            if len(drawn) == 2:  # the first redraw after the explorer's own first picture waits
                assert release.wait(30)
            return real_render(theta, axes, *args, **kwargs)
        finally:
            running[0] -= 1

    monkeypatch.setattr(landscape_module, "render_landscape", slow_render)
    explorer = LandscapeExplorer(np.zeros(4), **SMALL)
    shown = []
    explorer.image.observe(lambda change: shown.append(change["new"]), names="value")

    first = threading.Thread(target=explorer.set_params, args=([1.0, 0.0, 0.0, 0.0],))
    first.start()
    while len(drawn) < 2:
        threading.Event().wait(0.01)
    explorer.set_params([2.0, 0.0, 0.0, 0.0])  # each returns at once: a redraw is running
    explorer.set_axes((0, 1))
    explorer.set_params([3.0, 0.0, 0.0, 0.0])
    assert len(drawn) == 2
    release.set()
    first.join(30)
    assert not first.is_alive()

    assert drawn[1:] == [((1.0, 0.0, 0.0, 0.0), (2, 3)), ((3.0, 0.0, 0.0, 0.0), (0, 1))]
    assert most_running[0] == 1
    assert shown == [explorer.frame.png]  # the overtaken request's picture was never shown
    np.testing.assert_array_equal(explorer.frame.landscape.theta, [3.0, 0.0, 0.0, 0.0])
    assert explorer.frame.landscape.axes == (0, 1)


def test_requests_from_many_threads_never_overlap_and_the_last_one_is_shown(monkeypatch):
    real_render = landscape_module.render_landscape
    running, most_running = [0], [0]
    counter_lock = threading.Lock()

    def counting_render(*args, **kwargs):
        with counter_lock:
            running[0] += 1
            most_running[0] = max(most_running[0], running[0])
        try:
            return real_render(*args, **kwargs)
        finally:
            with counter_lock:
                running[0] -= 1

    monkeypatch.setattr(landscape_module, "render_landscape", counting_render)
    explorer = LandscapeExplorer(np.zeros(4), grid_size=2, num_episodes=1)
    rng = np.random.default_rng(0)
    requests = rng.uniform(-2, 2, size=(4, 10, 4))

    def send(thetas):
        for theta in thetas:
            explorer.set_params(theta)

    threads = [threading.Thread(target=send, args=(thetas,)) for thetas in requests]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    assert most_running[0] == 1
    np.testing.assert_array_equal(explorer.frame.landscape.theta, explorer.theta)
    assert explorer.image.value == explorer.frame.png


def test_a_failed_redraw_says_so_and_the_next_one_works(monkeypatch):
    explorer = LandscapeExplorer(THETA, **SMALL)
    real_render = landscape_module.render_landscape

    def broken(*args, **kwargs):
        raise RuntimeError("no figure today")

    monkeypatch.setattr(landscape_module, "render_landscape", broken)
    with pytest.raises(RuntimeError, match="no figure today"):
        explorer.set_params(np.zeros(4))
    assert explorer.caption.value == "could not draw the slice: no figure today"
    monkeypatch.setattr(landscape_module, "render_landscape", real_render)
    explorer.set_params(np.ones(4))
    np.testing.assert_array_equal(explorer.frame.landscape.theta, np.ones(4))
