"""Reward landscape benchmark: one 41 x 41 x 5 slice (8,405 episodes) batched, against the one-by-one loop.

Run from the kit's root:  .venv/bin/python benchmarks/bench_landscape.py  [--quick] [--loop-cells N]

Targets (issue 11): the slice <= 2 s on 2 cores and >= 10x faster than playing its episodes one
by one with ``run_policy(CartPoleLinearPolicy(params), seed=...)``. Both play the student's
``CartPoleLinearPolicy`` (issue 18): the batch only after checking its ``__call__`` against
equation (1) for every cell, which is included in its time. The loop plays every cell of
the slice (about 15 s per slice on 2 cores) and its rewards must equal the batched ones.
``--loop-cells N`` plays only a seeded random subset of N cells (every episode of each) and
extrapolates its time per cell to all cells (a random subset is as hard as the slice on
average); ``--quick`` does that on a smaller grid. The explorer's redraw (slice + figure + PNG,
what the kernel does when a dropdown changes) is timed too.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from hwlib.cartpole import MAX_EPISODE_REWARD, CartPoleLinearPolicy, make_env, run_policy
from hwlib.machinery.episodes import run_episodes
from hwlib.landscape import GRID_SIZE, NUM_EPISODES, render_landscape, reward_slice
from hwlib.plots.landscape import new_landscape_figure


def first_balancing_theta(seed=0, num_candidates=400):
    """A θ that balances on seeds 0-4, found by seeded random search (the kit ships none: that is 1.1.2)."""
    candidates = np.random.default_rng(seed).uniform(-1.0, 1.0, size=(num_candidates, 4))
    rewards = run_episodes(np.repeat(candidates, 5, axis=0), np.tile(np.arange(5), num_candidates)).reshape(-1, 5)
    return candidates[np.flatnonzero(np.all(rewards == MAX_EPISODE_REWARD, axis=1))[0]]


# Two slices of different cost: through a balancing θ (a large plateau of episodes that last to the cap) and
# through the origin (most episodes end within a few dozen steps).
THETAS = {
    "through a balancing θ (found by random search)": first_balancing_theta(),
    "through the origin": np.zeros(4),
}
SUBSET_SEED = 0


def timed(function, *args, **kwargs):
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return result, time.perf_counter() - start


def play_one_by_one(cell_params, seeds):
    """Mean reward of every cell, its episodes played one at a time with run_policy: the plain loop."""
    env = make_env()
    return np.array([
        np.mean([run_policy(CartPoleLinearPolicy(params), seed=int(seed), env=env) for seed in seeds])
        for params in cell_params
    ])


def bench_slice(name, theta, grid_size, repeats, loop_cells):
    reward_slice(theta, grid_size=3, num_episodes=1, progress=False)  # warm-up: imports, gymnasium's registry
    runs = [timed(reward_slice, theta, grid_size=grid_size, progress=False) for _ in range(repeats)]
    landscape = runs[0][0]
    seconds = sorted(run_time for _, run_time in runs)
    num_cells = grid_size**2
    num_episodes = num_cells * landscape.num_episodes
    at_max = np.mean(landscape.mean_rewards == MAX_EPISODE_REWARD)
    print(f"slice {name}: {grid_size} x {grid_size} x {landscape.num_episodes} = {num_episodes:,} episodes "
          f"({at_max:.0%} of the cells at {MAX_EPISODE_REWARD}): batched median {np.median(seconds):.2f} s, "
          f"best {seconds[0]:.2f} s, worst {seconds[-1]:.2f} s over {repeats} runs (target <= 2 s)")

    all_params = landscape.cell_params()
    if loop_cells >= num_cells:
        cells = np.arange(num_cells)
    else:
        cells = np.sort(np.random.default_rng(SUBSET_SEED).choice(num_cells, size=loop_cells, replace=False))
    looped, loop_seconds = timed(play_one_by_one, all_params[cells], landscape.seeds)
    same = np.array_equal(looped, landscape.mean_rewards.reshape(-1)[cells])
    loop_total = loop_seconds / len(cells) * num_cells
    how = "timed in full" if len(cells) == num_cells else (
        f"extrapolated from {len(cells)} random cells ({len(cells) * landscape.num_episodes:,} episodes) "
        f"played in {loop_seconds:.1f} s")
    print(f"  one-by-one loop: {loop_total:.1f} s for the whole slice ({how}); "
          f"speed-up {loop_total / np.median(seconds):.0f}x (target >= 10x); identical rewards: {same}")
    return np.median(seconds), loop_total / np.median(seconds), same


def bench_redraw(theta, repeats):
    figure = new_landscape_figure()
    render_landscape(theta, figure=figure)  # warm-up
    seconds = sorted(timed(render_landscape, theta, axes, figure=figure)[1]
                     for axes in [(0, 1), (2, 3), (1, 3), (0, 2)] * repeats)
    print(f"explorer redraw in the kernel (slice + figure + PNG, {len(seconds)} axis changes): "
          f"median {np.median(seconds):.2f} s, worst {seconds[-1]:.2f} s")
    return np.median(seconds)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a smaller grid and loop subset, for a smoke test")
    parser.add_argument("--loop-cells", type=int, default=None, help="time the loop on this many random cells and extrapolate")
    args = parser.parse_args()
    grid_size = 11 if args.quick else GRID_SIZE
    loop_cells = args.loop_cells or (20 if args.quick else grid_size**2)
    repeats = 2 if args.quick else 5
    load = ", ".join(f"{value:.1f}" for value in getattr(os, 'getloadavg', lambda: (float('nan'),) * 3)())
    print(f"{os.cpu_count()} cores, load average {load} (the machine may be shared: numbers are noisy); "
          f"{NUM_EPISODES} episodes per cell")
    for name, theta in THETAS.items():
        bench_slice(name, theta, grid_size, repeats, loop_cells)
    bench_redraw(next(iter(THETAS.values())), 1 if args.quick else 3)


if __name__ == "__main__":
    main()
