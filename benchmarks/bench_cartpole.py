"""Problem 1 benchmarks: batched episodes against the one-episode-at-a-time loop, side by side.

Run from the kit's root:  .venv/bin/python benchmarks/bench_cartpole.py  [--quick]

Every comparison does the same work both ways and checks that both give the same numbers
before it prints the speed-up. Targets (from the issue): random policies >= 8x, the whole
learning-rate sweep < 60 s and >= 5x, slider callback median < 150 ms, convergence within
7 iterations for >= 95% of 100 seeds with the notebook's defaults.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from hwlib import random_policy_rewards
from hwlib.cartpole import BALANCING_PARAMS, sample_random_params
from hwlib.plots.cartpole import EpisodeView
from hwlib.policy_search import (
    CONVERGENCE_DEADLINE,
    DEFAULT_LEARNING_RATE,
    converged_within,
    learning_rate_sweep,
    train_cartpole_policies,
)
from hwlib.widgets import render_panel

SWEEP_LEARNING_RATES = np.geomspace(1e-4, 1e-2, 8)


def timed(function, *args, **kwargs):
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return result, time.perf_counter() - start


def bench_random_policies(num_policies):
    (_, looped), loop_seconds = timed(random_policy_rewards, num_policies, seed=0, batched=False)
    (_, batched), batch_seconds = timed(random_policy_rewards, num_policies, seed=0, batched=True)
    same = np.array_equal(looped, batched)
    print(f"random policies ({num_policies}): loop {loop_seconds:.2f} s, batched {batch_seconds:.3f} s, "
          f"speed-up {loop_seconds / batch_seconds:.1f}x (target >= 8x), identical rewards: {same}")
    return loop_seconds / batch_seconds, same


def bench_sweep(num_seeds, loop_rates):
    sweep, sweep_seconds = timed(learning_rate_sweep, SWEEP_LEARNING_RATES, num_seeds=num_seeds)
    num_runs = len(SWEEP_LEARNING_RATES) * num_seeds
    print(f"learning-rate sweep ({len(SWEEP_LEARNING_RATES)} rates x {num_seeds} seeds x 20 iterations, batched): "
          f"{sweep_seconds:.1f} s (target < 60 s)")
    # The loop plays ~90 episodes per run and iteration one by one; timing it on the whole sweep
    # would take many minutes, so both ways train the same subset of runs here.
    subset_rates = np.asarray(loop_rates)
    subset_seeds = np.arange(len(subset_rates))
    starts = np.zeros((len(subset_rates), 4))
    (_, looped), loop_seconds = timed(train_cartpole_policies, starts, subset_rates, subset_seeds, batched=False)
    (_, batched), batch_seconds = timed(train_cartpole_policies, starts, subset_rates, subset_seeds, batched=True)
    same = np.array_equal(looped, batched)
    print(f"  same {len(subset_rates)} runs both ways: loop {loop_seconds:.1f} s, batched {batch_seconds:.2f} s, "
          f"speed-up {loop_seconds / batch_seconds:.1f}x (target >= 5x), identical rewards: {same}")
    print(f"  loop extrapolated to the whole sweep: ~{loop_seconds / len(subset_rates) * num_runs:.0f} s")
    print("  converged fraction per rate: "
          + ", ".join(f"{rate:.2g}: {fraction:.2f}" for rate, fraction in zip(sweep.learning_rates, sweep.converged_fraction)))
    return sweep_seconds, loop_seconds / batch_seconds, same


def bench_slider_callback(num_moves):
    settings = sample_random_params(num_moves, seed=5) * 2  # slider range [-2, 2]
    view = EpisodeView()
    render_panel(BALANCING_PARAMS, 0, view=view)  # warm-up
    reused = [timed(render_panel, params, 0, view=view)[1] for params in settings]
    fresh = [timed(render_panel, params, 0)[1] for params in settings]
    print(f"slider callback (episode + redraw, {num_moves} moves): median {np.median(reused) * 1e3:.0f} ms, "
          f"max {np.max(reused) * 1e3:.0f} ms (target median < 150 ms); "
          f"a new figure per move instead: median {np.median(fresh) * 1e3:.0f} ms, "
          f"{np.median(fresh) / np.median(reused):.1f}x slower")
    return np.median(reused)


def bench_convergence(num_seeds):
    starts = np.zeros((num_seeds, 4))
    rates = np.full(num_seeds, DEFAULT_LEARNING_RATE)
    (_, rewards), seconds = timed(train_cartpole_policies, starts, rates, np.arange(num_seeds))
    converged = np.array([converged_within(curve, CONVERGENCE_DEADLINE) for curve in rewards])
    print(f"convergence with the defaults (learning rate {DEFAULT_LEARNING_RATE:g}): "
          f"{converged.sum()} of {num_seeds} seeds within {CONVERGENCE_DEADLINE} iterations "
          f"({converged.mean():.0%}, target >= 95%), {seconds:.1f} s")
    return converged.mean()


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller workloads, for a smoke test")
    args = parser.parse_args()
    scale = 0.1 if args.quick else 1.0
    bench_random_policies(int(1000 * scale))
    bench_sweep(num_seeds=max(2, int(20 * scale)), loop_rates=SWEEP_LEARNING_RATES[3:4] if args.quick else SWEEP_LEARNING_RATES[::2])
    bench_slider_callback(int(30 * scale) or 3)
    bench_convergence(int(100 * scale))


if __name__ == "__main__":
    main()
