"""The figures of problem 1's search (hwlib/plots/training.py) and what the report's problem 2 figures must say
(hwlib/plots/food.py): what each marks, whole-number iteration ticks, legends off the data."""

from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from hwlib import settings
from hwlib.food_data import COURSE_FILE, FOOD_NAMES, SYNTHETIC
from hwlib.plots import plot_learning_rate_sweep, plot_reward_histogram, plot_training_curve
from hwlib.plots.food import plot_confusion_matrix, plot_per_class_accuracy, plot_training_accuracy
from hwlib.plots.training import PRINT_WIDTH
from hwlib.training import SweepResult

TOP = float(settings.MAX_EPISODE_STEPS)  # the best reward


def _line_ydata(ax):
    return [tuple(np.round(line.get_ydata(), 6)) for line in ax.get_lines()]


def _drawn(figure):
    """The figure laid out and drawn (off screen), as a reader sees it; returns its renderer."""
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    return canvas.get_renderer()


def _texts(figure):
    """Every piece of text the figure shows: titles, labels, annotations, legend entries, tick labels."""
    _drawn(figure)
    return [text.get_text() for text in figure.findobj(lambda artist: hasattr(artist, "get_text")) if text.get_text()]


def _legend_clear_of_axes(figure):
    """The figure's legends, each checked to lie outside every axes (so it hides no data)."""
    renderer = _drawn(figure)
    assert all(ax.get_legend() is None for ax in figure.axes), "a legend inside the axes"
    assert figure.legends, "no legend"
    for legend in figure.legends:
        box = legend.get_window_extent(renderer)
        for ax in figure.axes:
            assert not box.overlaps(ax.get_window_extent(renderer)), "the legend overlaps an axes"
    return figure.legends


def _integer_ticks(ax):
    ticks = [tick for tick in ax.get_xticks() if ax.get_xlim()[0] <= tick <= ax.get_xlim()[1]]
    return ticks and all(float(tick).is_integer() for tick in ticks)


def _sweep():
    rewards = np.full((2, 3, 9), TOP)
    rewards[0, :, :] = 10.0
    return SweepResult(np.array([1e-4, 1e-3]), np.arange(3), rewards, 7)


# --- the random-policy histogram ---------------------------------------------------------------


def test_histogram_counts_every_policy():
    rewards = np.array([9, 10, TOP, TOP, TOP / 2])
    ax = plot_reward_histogram(rewards).axes[0]
    assert sum(patch.get_height() for patch in ax.patches) == len(rewards)


def test_histogram_marks_the_share_that_reached_the_maximum():
    rewards = np.concatenate([np.full(977, 12.0), np.full(23, TOP)])
    figure = plot_reward_histogram(rewards)
    assert f"reward {TOP:g}: 23 of 1000 (2.3%)" in _texts(figure)
    ax = figure.axes[0]
    bar_at_top = [patch for patch in ax.patches if patch.get_x() == TOP]
    assert len(bar_at_top) == 1 and bar_at_top[0].get_height() == 23
    assert figure.get_figwidth() == PRINT_WIDTH


def test_histogram_rejects_rewards_that_are_not_episode_rewards():
    for bad in ([], [[1.0]], [10.0, np.nan], [TOP + 100], [-1.0]):
        with pytest.raises(ValueError, match="rewards"):
            plot_reward_histogram(bad)


# --- the training curve ------------------------------------------------------------------------


def test_training_curve_draws_rewards_and_the_maximum_line():
    figure = plot_training_curve([10, 100, TOP, TOP], learning_rate=0.002)
    ax = figure.axes[0]
    assert isinstance(figure, Figure)
    assert (10.0, 100.0, TOP, TOP) in _line_ydata(ax)
    assert (TOP, TOP) in _line_ydata(ax)
    assert ax.get_xlabel() == "training iteration" and ax.get_ylabel() == "reward"
    assert "0.002" in ax.get_title()


def test_training_curve_marks_the_deadline_and_the_convergence_iteration_on_whole_number_ticks():
    rewards = [9, 13, 40, 41, 47] + [TOP] * 7
    figure = plot_training_curve(rewards, learning_rate=0.0007)
    ax = figure.axes[0]
    texts = _texts(figure)
    assert f"deadline: iteration {settings.CONVERGENCE_DEADLINE}" in texts
    assert "converged at iteration 5" in texts
    deadline = [line for line in ax.get_lines() if line.get_label().startswith("deadline")][0]
    np.testing.assert_array_equal(deadline.get_xdata(), [settings.CONVERGENCE_DEADLINE] * 2)
    marker = [line for line in ax.get_lines() if line.get_label() == "converged at iteration 5"][0]
    assert (marker.get_xdata()[0], marker.get_ydata()[0]) == (5, TOP)
    assert _integer_ticks(ax)
    _legend_clear_of_axes(figure)


def test_training_curve_says_when_the_run_did_not_converge():
    texts = _texts(plot_training_curve([9, 50, TOP, TOP - 80], deadline=3))
    assert "not converged within 3 iterations" in texts and "deadline: iteration 3" in texts


# --- the learning-rate sweep -------------------------------------------------------------------


def test_sweep_figure_plots_the_fraction_per_rate():
    ax = plot_learning_rate_sweep(_sweep(), chosen_learning_rate=5e-4).axes[0]
    np.testing.assert_array_equal(ax.get_lines()[0].get_ydata(), [0.0, 1.0])
    np.testing.assert_array_equal(ax.get_lines()[1].get_xdata(), [5e-4, 5e-4])


def test_sweep_figure_labels_each_rate_and_keeps_its_legend_off_the_data():
    figure = plot_learning_rate_sweep(_sweep(), chosen_learning_rate=5e-4)
    texts = _texts(figure)
    assert "0%" in texts and "100%" in texts
    assert "chosen learning rate 0.0005" in texts
    assert "converged within 7 iterations" in figure.axes[0].get_title()
    _legend_clear_of_axes(figure)


def label_boxes_clear(figure, texts):
    """The window boxes of the annotations whose text is in ``texts``, checked: inside the axes, clear
    of each other and of every point of the axes' lines."""
    renderer = _drawn(figure)
    ax = figure.axes[0]
    boxes = [annotation.get_bbox_patch().get_window_extent(renderer) for annotation in ax.texts if annotation.get_text() in texts]
    assert boxes
    for index, box in enumerate(boxes):
        assert ax.bbox.x0 <= box.x0 and box.x1 <= ax.bbox.x1 and ax.bbox.y0 <= box.y0 and box.y1 <= ax.bbox.y1, "a label leaves the axes"
        assert not any(box.overlaps(other) for other in boxes[index + 1:]), "two labels overlap"
        for line in ax.get_lines():
            points = ax.transData.transform(np.column_stack([line.get_xdata(), line.get_ydata()]))
            assert not any(box.contains(x, y) for x, y in points), "a label sits on a point"
    return boxes


def test_sweep_labels_sit_beside_their_points_not_on_them_or_each_other():
    rates = [1e-4, 3e-4, 3.5e-4, 4e-4, 6e-4, 8e-4, 1e-3, 1.2e-3, 2e-3, 5e-3, 1e-2]
    shares = [0.0, 0.2, 0.95, 1.0, 1.0, 1.0, 1.0, 0.95, 0.85, 0.7, 0.45]  # the notebook's sweep
    summary = SimpleNamespace(learning_rates=rates, converged_fraction=shares, seeds=range(20), deadline=7)
    figure = plot_learning_rate_sweep(summary, chosen_learning_rate=6.5e-4)
    assert len(label_boxes_clear(figure, {f"{share:.0%}" for share in shares})) == len(rates)


def test_sweep_figure_takes_any_record_with_the_sweep_fields():
    summary = SimpleNamespace(learning_rates=[1e-3, 1e-2], converged_fraction=[0.5, 1.0], seeds=range(4), deadline=7)
    assert "share of 4 seeds" in _texts(plot_learning_rate_sweep(summary))
    summary.converged_fraction = [0.5]
    with pytest.raises(ValueError, match="one converged fraction per learning rate"):
        plot_learning_rate_sweep(summary)


# --- problem 2: the figures say which data they came from --------------------------------------


@pytest.mark.parametrize("source", [SYNTHETIC, COURSE_FILE])
def test_problem_2_figures_name_their_data(source):
    counts = np.eye(7, dtype=np.int64) * 10
    figures = [
        plot_training_accuracy(np.linspace(0.2, 1.0, 80), data_source=source),
        plot_confusion_matrix(counts, FOOD_NAMES, data_source=source),
        plot_per_class_accuracy(np.full(7, 0.9), FOOD_NAMES, data_source=source),
    ]
    for figure in figures:
        label = figure.get_suptitle()
        assert label.startswith(f"data: {source}")
        assert ("not the course's data" in label) == (source == SYNTHETIC)


def test_problem_2_figures_reject_a_data_source_that_is_not_text():
    with pytest.raises(TypeError, match="data_source"):
        plot_training_accuracy([0.5, 0.9], data_source=3)


def test_training_accuracy_marks_the_deadline_with_whole_number_ticks_and_an_outside_legend():
    curve = np.concatenate([np.linspace(0.2, 0.985, 60), np.linspace(0.986, 0.999, 41)])
    figure = plot_training_accuracy(curve, data_source=SYNTHETIC)
    texts = _texts(figure)
    assert f"deadline: iteration {settings.TARGET_ITERATIONS}" in texts
    first = int(np.flatnonzero(curve > settings.TARGET_ACCURACY)[0])
    assert f"first above 99%: iteration {first}" in texts
    assert all(_integer_ticks(ax) for ax in figure.axes)
    _legend_clear_of_axes(figure)
    assert "never above 99%" in _texts(plot_training_accuracy(np.full(5, 0.5)))
