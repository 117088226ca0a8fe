"""The progress bar of the kit's long cells (hwlib/machinery/progress.py): a time estimate, and text nbval can compare."""

import numpy as np
import pytest

from hwlib.machinery import progress as _progress
from hwlib.cartpole import random_policy_rewards
from hwlib.landscape import reward_slice
from hwlib.training import learning_rate_sweep, run_training


@pytest.fixture
def shown(monkeypatch):
    """Pretend to be a notebook: every bar the kit displays is collected here."""
    import IPython.display

    bars = []
    monkeypatch.setattr(_progress, "in_notebook", lambda: True)
    monkeypatch.setattr(IPython.display, "display", bars.append)
    return bars


def test_outside_a_notebook_nothing_is_shown():
    with _progress.Progress("work", 10, "steps") as bar:
        bar.advance(3)
        assert bar.done == 3
    assert bar.widget is None and bar.status == "done"


def test_the_line_gives_the_time_left_and_how_it_ended(monkeypatch):
    now = [100.0]
    monkeypatch.setattr(_progress.time, "perf_counter", lambda: now[0])
    bar = _progress.Progress("sweep", 100, "runs", show=True)
    bar.__enter__()  # started at 100 s
    now[0], bar.done = 102.0, 25
    assert bar.text() == "sweep: 25 of 100 runs · 2.0 s so far · about 6.0 s left"  # 2 s for a quarter: 6 s more
    now[0] = 104.0
    bar.__exit__(None, None, None)
    assert bar.text() == "sweep: 100 runs · done in 4.0 s"
    stopped = _progress.Progress("sweep", 10, None, show=True)
    stopped.status = "stopped by Kernel → Interrupt"
    assert "stopped by Kernel → Interrupt after" in stopped.text() and " of " not in stopped.text()


@pytest.mark.parametrize(("kind", "status"), [(KeyboardInterrupt, "stopped by Kernel → Interrupt"),
                                              (ValueError, "stopped: bad\nsecond line")])
def test_an_interrupt_or_an_error_shows_on_the_bar(kind, status):
    with pytest.raises(kind), _progress.Progress("work", 10, None, show=True) as bar:
        raise kind("bad\nsecond line")
    assert bar.status == status.splitlines()[0]
    assert bar.widget.children[0].bar_style == "danger"


def test_a_todo_not_done_before_any_work_shows_no_bar_only_its_message(shown):
    from hwlib.machinery.todos import TodoNotDone

    with pytest.raises(TodoNotDone), _progress.Progress("work", 10, None, show=True):
        raise TodoNotDone("1.1.1")
    assert shown == []
    with pytest.raises(TodoNotDone), _progress.Progress("work", 10, None, show=True) as bar:
        bar.advance(1)  # once the work has begun, the bar says where it stopped
        raise TodoNotDone("1.3.2")
    assert len(shown) == 1 and "stopped: TODO 1.3.2" in bar.widget.children[1].value


def test_the_text_nbval_compares_is_fixed_by_title_and_size():
    bar = _progress.Progress("random policies", 1000, "episodes", show=True)
    before = repr(bar.widget)
    with bar:
        bar.advance(400)
    assert repr(bar.widget) == before == "[progress bar: random policies, 1000 episodes]"
    assert bar.widget._repr_mimebundle_()["text/plain"] == before


def test_the_long_cells_show_one_bar_each_and_finish_it(shown):
    run_training(2, learning_rate=0.001)
    learning_rate_sweep([0.001, 0.002], num_seeds=2, num_training_iterations=2)
    random_policy_rewards(20, seed=0)  # the plain loop of 1.1.3, about a second for 1000: no bar
    reward_slice(np.zeros(4), grid_size=5, num_episodes=2)
    assert [repr(bar) for bar in shown] == [
        "[progress bar: training run]",
        "[progress bar: learning-rate sweep (4 training runs side by side)]",
        "[progress bar: reward landscape (5 × 5 cells × 2 episodes), 50 episodes]",
    ]
    for bar in shown:
        assert bar.children[0].value == 1.0 and "done in" in bar.children[1].value


def test_a_training_run_shows_its_iteration(monkeypatch):
    seen = []
    original = _progress.Progress.set

    def spy(self, done, detail=None):
        seen.append(detail)
        original(self, done, detail)

    monkeypatch.setattr(_progress.Progress, "set", spy)
    monkeypatch.setattr(_progress, "in_notebook", lambda: True)
    monkeypatch.setattr("IPython.display.display", lambda widget: None)
    run_training(3, learning_rate=0.001)
    assert "iteration 1 of 3" in seen and seen[-1] == "iteration 3 of 3"


def test_the_explorer_draws_without_a_bar(shown):
    from hwlib.landscape import LandscapeExplorer

    LandscapeExplorer(np.zeros(4), grid_size=3, num_episodes=1)
    assert shown == []
