"""Problem 1 benchmarks: the student's own sequential code, batched by the kit vs played one by one.

Run from the kit's root:  .venv/bin/python benchmarks/bench_cartpole.py  [--quick]

Everything here runs the homework's functions as written in ``hwlib`` (in the student edition:
the student's). "Loop" plays every episode on its own through ``env.step`` (``_batch.disabled``);
"batched" is what the notebook does. Both are timed in the same run on the same work, and each
comparison checks that both give identical numbers before it prints the ratio.

Targets (issue "The student edition is the handout's homework"): the learning-rate sweep
(8 rates x 20 seeds x 20 iterations) <= 20 s on 2 cores and >= 20x the one-by-one loop;
convergence with the defaults for >= 99% of 100 seeds within 7 iterations; Run All of the
problem 1 notebook <= 30 s.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hwlib import _batch, settings, train_cartpole_policy
from hwlib.cartpole import random_policy_rewards
from hwlib.policy_search import learning_rate_sweep

KIT = Path(__file__).resolve().parents[1]
P1_NOTEBOOK = KIT / "notebooks" / "p1_cartpole_finite_difference.ipynb"


def timed(function, *args, **kwargs):
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return result, time.perf_counter() - start


def bench_random_policies():
    (_, rewards), seconds = timed(random_policy_rewards, settings.NUM_RANDOM_POLICIES, seed=settings.RANDOM_POLICY_SEED)
    print(f"1000 random policies, one by one with CartPoleLinearPolicy.__call__: {seconds:.2f} s "
          f"({np.mean(rewards == 500):.1%} at 500)")


def bench_training_run():
    run, batch_seconds = timed(train_cartpole_policy, seed=settings.TRAINING_SEED)
    with _batch.disabled():
        looped, loop_seconds = timed(train_cartpole_policy, seed=settings.TRAINING_SEED)
    same = np.array_equal(run.rewards, looped.rewards) and np.array_equal(run.params_history, looped.params_history)
    print(f"one training run ({settings.NUM_TRAINING_ITERATIONS} iterations): loop {loop_seconds:.1f} s, "
          f"batched {batch_seconds:.2f} s, {loop_seconds / batch_seconds:.1f}x, identical: {same}")
    return same


def bench_sweep(num_loop_runs):
    sweep, sweep_seconds = timed(learning_rate_sweep, settings.SWEEP_LEARNING_RATES, num_seeds=settings.SWEEP_NUM_SEEDS)
    num_runs = len(sweep.learning_rates) * len(sweep.seeds)
    # The loop would take the better part of an hour on the whole sweep: time it on a few of the
    # same runs (one rate from each end and the middle) and scale by the runs' episode counts.
    picks = np.linspace(0, len(sweep.learning_rates) - 1, num_loop_runs).round().astype(int)
    loop_seconds, same = 0.0, True
    for rate_index in picks:
        rate = float(sweep.learning_rates[rate_index])
        with _batch.disabled():
            looped, seconds = timed(train_cartpole_policy, learning_rate=rate, seed=int(sweep.seeds[0]))
        loop_seconds += seconds
        same &= np.array_equal(looped.rewards, sweep.rewards[rate_index, 0])
    loop_per_run = loop_seconds / len(picks)
    loop_estimate = loop_per_run * num_runs
    ratio = loop_estimate / sweep_seconds
    print(f"learning-rate sweep ({len(sweep.learning_rates)} rates x {len(sweep.seeds)} seeds x "
          f"{settings.NUM_TRAINING_ITERATIONS} iterations, the student's train_cartpole_policy in {num_runs} threads): "
          f"{sweep_seconds:.1f} s (target <= 20 s)")
    print(f"  the loop: {loop_per_run:.1f} s per run measured on {len(picks)} of the same runs -> "
          f"about {loop_estimate / 60:.0f} min for the sweep; batched is {ratio:.0f}x faster (target >= 20x), "
          f"identical rewards: {bool(same)}")
    return sweep_seconds, ratio, bool(same)


def bench_convergence(num_seeds):
    sweep, seconds = timed(learning_rate_sweep, [settings.LEARNING_RATE], num_seeds=num_seeds, first_seed=0)
    fraction = float(sweep.converged_fraction[0])
    print(f"convergence with the defaults (learning rate {settings.LEARNING_RATE:g}, step {settings.FD_STEP}, "
          f"{settings.NUM_ROLLOUTS} rollouts): {fraction:.0%} of {num_seeds} seeds within "
          f"{settings.CONVERGENCE_DEADLINE} iterations (target >= 99%), {seconds:.1f} s")
    return fraction


def bench_notebook():
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "p1.ipynb"
        command = [sys.executable, "-m", "jupyter", "nbconvert", "--to", "notebook", "--execute",
                   "--output", str(out), str(P1_NOTEBOOK)]
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True, cwd=KIT / "notebooks")
        seconds = time.perf_counter() - start
    print(f"Run All of the problem 1 notebook (nbconvert --execute, kernel start included): {seconds:.1f} s (target <= 30 s)")
    return seconds


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer loop runs and seeds (a smoke test)")
    args = parser.parse_args(argv)
    bench_random_policies()
    ok = bench_training_run()
    _, _, same = bench_sweep(num_loop_runs=1 if args.quick else 3)
    bench_convergence(20 if args.quick else 100)
    if not args.quick:
        bench_notebook()
    return 0 if ok and same else 1


if __name__ == "__main__":
    sys.exit(main())
