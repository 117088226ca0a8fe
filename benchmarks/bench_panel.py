"""Slider panel benchmark: how long one change of the panel takes in the kernel, and what a burst costs.

Run from the kit's root:  MPLBACKEND=Agg .venv/bin/python benchmarks/bench_panel.py  [--quick]

| line                    | what is timed                                                                 |
|-------------------------|-------------------------------------------------------------------------------|
| render_panel, reused    | the plain callback: play the episode and redraw the panel's one figure        |
| render_panel, new figure| the same with a new figure per change (what reusing the figure saves)         |
| slider callback         | one θ slider moved on a live ``SliderPanel``: episode, redraw, widget updates |
| time-step callback      | the time step moved: redraw only, no new episode                              |
| burst, two threads      | two threads make many changes at once: the draws it costs (coalesced)        |

The slider settings are seeded random weights in [-2, 2] on the sliders' grid, from seed 0's
start; most of them fail within a few dozen steps, as while hand-tuning. Target (issue 12 and
before): slider callback median < 150 ms. Timings are wall-clock on whatever the machine is
doing: run it on a quiet machine for numbers to quote.
"""

from __future__ import annotations

import argparse
import os
import threading
import time

os.environ.setdefault("MPLBACKEND", "Agg")

import numpy as np  # noqa: E402

from hwlib.cartpole import sample_random_params  # noqa: E402
from hwlib.plots.cartpole import EpisodeView  # noqa: E402
from hwlib.widgets import PRESETS, SliderPanel, render_panel, slider_grid_value  # noqa: E402

SETTINGS_SEED = 5


def slider_settings(num_moves):
    """``num_moves`` seeded weight vectors in [-2, 2], on the sliders' grid."""
    params = sample_random_params(num_moves, seed=SETTINGS_SEED, low=-2.0, high=2.0)
    return [tuple(slider_grid_value(float(value)) for value in row) for row in params]


def milliseconds(seconds):
    return f"median {np.median(seconds) * 1e3:.0f} ms, max {np.max(seconds) * 1e3:.0f} ms"


def timed(function, *args, **kwargs):
    start = time.perf_counter()
    function(*args, **kwargs)
    return time.perf_counter() - start


def bench_render_panel(settings):
    view = EpisodeView()
    render_panel(PRESETS["always right"], 0, view=view)  # warm-up
    reused = [timed(render_panel, params, 0, view=view) for params in settings]
    fresh = [timed(render_panel, params, 0) for params in settings]
    print(f"render_panel, reused figure ({len(settings)} settings): {milliseconds(reused)}")
    print(f"render_panel, new figure per change: {milliseconds(fresh)} ({np.median(fresh) / np.median(reused):.1f}x the reused)")
    return np.median(reused)


def bench_slider_callback(settings):
    panel = SliderPanel()
    seconds, steps = [], []
    for params in settings:
        panel.set_params((params[0], 0.0, *params[2:]))  # untimed: all but θ₂ ...
        if params[1] == 0.0:
            continue
        seconds.append(timed(setattr, panel.param_sliders[1], "value", params[1]))  # ... then one move of θ₂
        steps.append(panel.episode.num_steps)
    print(f"slider callback (one θ slider moved, {len(settings)} moves, episodes of median {np.median(steps):.0f} steps): "
          f"{milliseconds(seconds)} (target median < 150 ms)")
    return np.median(seconds)


def bench_time_step_callback(num_moves):
    panel = SliderPanel(PRESETS["always left"])
    panel.param_sliders[3].value = -0.2  # a 142-step episode to scrub through
    steps = np.random.default_rng(SETTINGS_SEED).integers(0, panel.episode.num_steps + 1, size=num_moves)
    seconds = [timed(setattr, panel.step_slider, "value", int(step)) for step in steps]
    print(f"time-step callback ({num_moves} moves through a {panel.episode.num_steps}-step episode): {milliseconds(seconds)}")
    return np.median(seconds)


def bench_burst(num_changes):
    panel = SliderPanel()
    draws = []
    show = panel.view.show
    panel.view.show = lambda episode, step=None: draws.append(step) or show(episode, step)
    settings = slider_settings(num_changes)
    start = threading.Barrier(2)

    def clicks():
        start.wait()
        for index in range(num_changes):
            panel.apply_preset(list(PRESETS)[index % 2])

    def moves():
        start.wait()
        for params in settings:
            panel.param_sliders[2].value = params[2]

    threads = [threading.Thread(target=work) for work in (clicks, moves)]
    began = time.perf_counter()
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    seconds = time.perf_counter() - began
    print(f"burst, two threads ({2 * num_changes} changes at once): {len(draws)} draws, {seconds:.2f} s in all "
          f"(one draw per change would be {2 * num_changes})")
    return len(draws)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller workloads, for a smoke test")
    args = parser.parse_args()
    num_moves = 5 if args.quick else 50
    settings = slider_settings(num_moves)
    bench_render_panel(settings)
    bench_slider_callback(settings)
    bench_time_step_callback(num_moves)
    bench_burst(10 if args.quick else 100)


if __name__ == "__main__":
    main()
