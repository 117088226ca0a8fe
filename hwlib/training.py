"""Running your training code: one training run, and the learning-rate sweep (handout 1.3.3).

``run_training(...)`` is your ``train_cartpole_policy(...)`` with the same arguments and result,
and ``learning_rate_sweep(...)`` trains it from zeros with every learning rate of a grid and
several seeds. Both show a progress bar with a time estimate in the notebook, stop within a
second on Kernel → Interrupt, and play the episodes your code asks for many at a time
(``hwlib/machinery/batch.py``): every episode is still played from its own start state with your policy,
so the numbers are those your code gives one episode at a time (``batched=False`` does that).

| what                    | how the kit plays it                                               |
|-------------------------|--------------------------------------------------------------------|
| ``eval_params`` calls   | a call runs twice: once to learn which episodes it asks for (any seeds: ``seed + k``, a generator, none), then for real, after they were played in one batch; once a run's calls have shown that their seeds follow from their arguments, only the real pass runs |
| ``scalar_finite_diff``  | the same, so the 8 evaluations of one gradient are played in one batch |
| the sweep's runs        | side by side, one at a time in a fixed order; what they all wait for is played together |
| episodes without a seed | start where the next ``reset()`` of the run's own environment, seeded once with the run's seed, starts them, so a run gives the same numbers every time, batched or not |
| ``eval_params`` with its own ``gym.make("CartPole-v1")`` | the environment is the kit's: ``reset`` as gymnasium's, the first ``step`` ends the episode with its whole reward, played in the batches; a call with a longer episode than any checked so far runs again on gymnasium's environment; if the numbers differ, or the code uses the environment otherwise, the kit plays on gymnasium's from then on (slow: the time limit says why) |
| a policy that is not equation (1) | played step by step with your ``__call__``: slow; if that would take more than ``max_minutes``, the kit says so, with its estimate, before it starts |
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from hwlib import policy_search, settings
from hwlib.cartpole import CartPoleLinearPolicy, make_env, play_episode
from hwlib.machinery import batch, episodes
from hwlib.machinery.progress import Progress, format_seconds
from hwlib.machinery.validation import as_float_array, check_count, check_seed
from hwlib.policy_search import check_learning_rate, converged_within
from hwlib.machinery import reuse  # last: it notes the code loaded so far (the sweep's)

# With a policy that follows equation (1), the sweep's episodes last this many steps on average
# (measured with benchmarks/bench_cartpole.py); a policy played step by step costs about as much.
MEAN_EPISODE_STEPS = 370


@dataclass(frozen=True)
class SweepResult:
    """Learning-rate sweep: ``rewards[r, s]`` is the curve of rate r with seed s."""

    learning_rates: np.ndarray  # (num_rates,)
    seeds: np.ndarray  # (num_seeds,)
    rewards: np.ndarray  # (num_rates, num_seeds, num_training_iterations + 1)
    deadline: int
    reused: bool = False  # read back from an earlier sweep of the same code and settings (``reuse_stored=True``)

    @property
    def converged(self):
        """(num_rates, num_seeds) booleans: converged within the deadline."""
        return np.array([[converged_within(curve, self.deadline) for curve in row] for row in self.rewards])

    @property
    def converged_fraction(self):
        """Fraction of seeds that converged within the deadline, one per learning rate."""
        return self.converged.mean(axis=1)

    def advice(self):
        """What the sweep says about choosing ``LEARNING_RATE`` (TODO 1.3.3), in a sentence or two."""
        fractions = self.converged_fraction
        if not fractions.any():
            return ("No run converged with any of these learning rates. Before tuning the rate, check the direction "
                    "of your steps: the gradient of equation (3), (f(x + h) - f(x - h)) / 2h (TODO 1.2.1), and the "
                    "update of equation (4), which climbs it: theta + learning_rate * gradient (TODO 1.3.2).")
        full = self.learning_rates[fractions == 1.0]
        if full.size:
            return (f"Every seed converged within {self.deadline} iterations with the learning rate "
                    f"{_listed(full)}: set LEARNING_RATE in hwlib/settings.py to one of them (TODO 1.3.3).")
        best = int(np.argmax(fractions))
        return (f"No rate made every seed converge; {self.learning_rates[best]:g} did best ({fractions[best]:.0%}). "
                "Try rates near it with learning_rate_sweep, then set LEARNING_RATE in hwlib/settings.py (TODO 1.3.3).")


def _listed(rates):
    shown = [f"{rate:g}" for rate in rates]
    return shown[0] if len(shown) == 1 else ", ".join(shown[:-1]) + " or " + shown[-1]


def run_training(
    num_training_iterations=settings.NUM_TRAINING_ITERATIONS,
    num_rollouts_per_eval=settings.NUM_ROLLOUTS,
    learning_rate=None,
    fd_step=settings.FD_STEP,
    seed=settings.TRAINING_SEED,
    initial_params=None,
    *,
    batched=True,
    progress=True,
    max_minutes=settings.MAX_MINUTES,
):
    """Your ``train_cartpole_policy`` with these arguments (it checks them): returns its ``TrainingRun``.

    ``batched=False`` plays every episode on its own (slow; the same numbers). ``progress``: show
    a progress bar in the notebook. ``max_minutes``: if the run would take longer, stop with an
    estimate (None: never).
    """
    def task():
        return policy_search.train_cartpole_policy(num_training_iterations, num_rollouts_per_eval, learning_rate,
                                                   fd_step, seed, initial_params)

    iterations = num_training_iterations if _is_count(num_training_iterations) else None
    rollouts = num_rollouts_per_eval if _is_count(num_rollouts_per_eval) else None
    [run] = _run([task], [seed], iterations, rollouts, batched, "training run" if progress else None,
                 "This training run", max_minutes)
    return run


def learning_rate_sweep(
    learning_rates=settings.SWEEP_LEARNING_RATES,
    num_seeds=settings.SWEEP_NUM_SEEDS,
    first_seed=0,
    num_training_iterations=settings.NUM_TRAINING_ITERATIONS,
    num_rollouts_per_eval=settings.NUM_ROLLOUTS,
    fd_step=settings.FD_STEP,
    deadline=settings.CONVERGENCE_DEADLINE,
    batched=True,
    *,
    progress=True,
    max_minutes=settings.MAX_MINUTES,
    reuse_stored=False,
):
    """Train from zeros with every learning rate and ``num_seeds`` seeds (your ``train_cartpole_policy``).

    The run with rate r and seed s is ``run_training(learning_rate=r, seed=s, ...)``: the runs
    train side by side and their episodes are played together; ``batched=False`` trains them one
    after another, every episode on its own (the same numbers, for comparisons). ``progress`` and
    ``max_minutes`` as in ``run_training``. ``reuse_stored``: read the rewards back from an earlier
    sweep of the same code and settings, if one was stored (checked on its first run, trained again),
    and store them after training (``hwlib/machinery/reuse.py``). Returns a ``SweepResult``.
    """
    rates = np.atleast_1d(as_float_array(learning_rates, "learning_rates"))
    if rates.ndim != 1 or rates.size == 0:
        raise ValueError(f"learning_rates must be a non-empty 1-d array, got shape {rates.shape}")
    for rate in rates:
        check_learning_rate(float(rate), "learning_rates")
    num_seeds = check_count(num_seeds, "num_seeds")
    first_seed = check_seed(first_seed, "first_seed")
    deadline = check_count(deadline, "deadline")
    for name, flag in (("batched", batched), ("reuse_stored", reuse_stored)):
        if not isinstance(flag, bool):
            raise TypeError(f"{name} must be True or False, got {flag!r}")
    seeds = np.arange(first_seed, first_seed + num_seeds)
    # train_cartpole_policy checks these itself, at the first run's start.
    options = {"num_training_iterations": num_training_iterations, "num_rollouts_per_eval": num_rollouts_per_eval,
               "fd_step": fd_step}
    tasks, task_seeds = [], []
    for rate in rates:
        for seed in seeds:
            tasks.append(lambda rate=float(rate), seed=int(seed):
                         policy_search.train_cartpole_policy(learning_rate=rate, seed=seed, **options).rewards)
            task_seeds.append(int(seed))
    iterations = num_training_iterations if _is_count(num_training_iterations) else None
    rollouts = num_rollouts_per_eval if _is_count(num_rollouts_per_eval) else None
    title = f"learning-rate sweep ({len(tasks)} training runs side by side)" if progress else None
    describe = "This learning-rate sweep"
    key = None
    if reuse_stored and iterations is not None:
        key = reuse.sweep_key({"learning_rates": [rate.hex() for rate in rates.tolist()], "first_seed": first_seed,
                               "num_seeds": num_seeds, "batched": batched, **{name: repr(value) for name, value in options.items()}},
                              settings)
        stored = reuse.load(key, (len(rates), num_seeds, iterations + 1), float(settings.MAX_EPISODE_STEPS))
        # The same code gives the same numbers: its first run, trained again, must give the stored ones.
        if stored is not None and np.array_equal(_run(tasks[:1], task_seeds[:1], iterations, rollouts, batched, None, describe,
                                                      max_minutes)[0], stored[0, 0]):
            with Progress(title, 1, None) as bar:
                bar.note = "the stored result of the same code and settings (its first run trained again: the same)"
                bar.set(1)
            return SweepResult(rates, seeds, stored, deadline, reused=True)
    curves = _run(tasks, task_seeds, iterations, rollouts, batched, title, describe, max_minutes)
    rewards = np.array(curves, dtype=np.float64).reshape(len(rates), num_seeds, -1)
    reuse.store(key, rewards)
    return SweepResult(rates, seeds, rewards, deadline)


class TooSlow(RuntimeError):
    """The work would take much longer than ``max_minutes``; the two lines say how long and why."""

    def __init__(self, first, second):
        super().__init__(f"{first}\n{second}")
        self.first, self.second = first, second

    def _render_traceback_(self):
        return [f"\x1b[1;31m{self.first}\x1b[0m", self.second]


def _run(tasks, env_seeds, iterations, rollouts, batched, title, describe, max_minutes):
    max_seconds = None if max_minutes is None else 60.0 * float(max_minutes)
    if batched and len(tasks) > 1 and max_seconds is not None and iterations is not None and rollouts is not None:
        # Only many runs can take hours; one run played step by step takes seconds to minutes.
        _refuse_hours_of_step_by_step(len(tasks), iterations, rollouts, describe, max_seconds)
    with Progress(title, 1000, None) as bar:
        watch = _Watch(iterations, bar if title else None, max_seconds, describe)
        session = batch.Session(batched, on_round=watch)
        with session.replaying(policy_search, ("eval_params", "scalar_finite_diff"), counted="eval_params"):
            return session.run(tasks, env_seeds)


class _Watch:
    """After every batch: the progress bar, and the time limit (``TooSlow`` once the projected
    time exceeds ``max_seconds``). Progress counts evaluations: 1 + 9 per iteration for each run."""

    def __init__(self, iterations, progress, max_seconds, describe):
        self.iterations, self.progress, self.max_seconds, self.describe = iterations, progress, max_seconds, describe
        self.expected = None if iterations is None else 1 + batch.EVALUATIONS_PER_ITERATION * iterations

    def __call__(self, session):
        fraction = self.fraction_done(session)
        if self.progress is not None:
            self.progress.set(round(fraction * self.progress.total), self.detail(session))
        elapsed = time.perf_counter() - session.started
        if self.max_seconds is not None and elapsed > 3.0 and fraction > 0.01 and elapsed / fraction > self.max_seconds:
            raise TooSlow(f"{self.describe} would take about {format_seconds(elapsed / fraction)} on this machine, "
                          f"so the kit stopped it after {format_seconds(elapsed)}.", self.why_slow(session))

    def fraction_done(self, session):
        if not self.expected or not session.runs:
            return 0.0
        done = sum(min(run.evaluations, self.expected) for run in session.runs)
        return done / (self.expected * len(session.runs))

    def detail(self, session):
        """'iteration 5 of 20': how far the slowest run still going has come."""
        if self.iterations is None:
            return ""
        going = [run.evaluations for run in session.runs if run.state != "done"]
        evaluations = min(going) if going else self.expected
        iteration = min(max(evaluations - 1, 0) // batch.EVALUATIONS_PER_ITERATION, self.iterations)
        return f"iteration {iteration} of {self.iterations}"

    @staticmethod
    def why_slow(session):
        """What made the work slow, in a sentence, from what was played so far."""
        if session.step_by_step > 0.5 * max(session.episodes_played, 1):
            return ("Most episodes were played step by step with your CartPoleLinearPolicy.__call__, because it does "
                    "not give the actions of equation (1) (TODO 1.1.1); fix it, or pass max_minutes=None to wait.")
        evaluations = sum(run.evaluations for run in session.runs) / max(len(session.runs), 1)
        if session.not_replayed is not None or not session.episodes_played:
            why = f" ({session.not_replayed})" if session.not_replayed else ""
            return (f"Your eval_params plays its episodes in an environment of its own in a way the kit cannot replay{why}, "
                    "so every step runs in Python; play each with run_policy(policy, seed=seed + k), or pass "
                    "max_minutes=None to wait.")
        if session.rounds > 3 * max(evaluations, 1):
            return ("Your code asks for its episodes one at a time in a way the kit cannot foresee (eval_params draws "
                    "different seeds each time it runs?); pass max_minutes=None to wait.")
        return "Pass max_minutes=None to wait for it."


def _refuse_hours_of_step_by_step(num_runs, iterations, rollouts, describe, max_seconds):
    """Before starting: if your ``__call__`` is not equation (1), every episode would be played step
    by step; say so, with the estimate, when that would take longer than ``max_seconds``."""
    disagreement = episodes.first_disagreement(CartPoleLinearPolicy)  # raises TodoNotDone for the stub
    if disagreement is None:
        return
    num_episodes = num_runs * (1 + batch.EVALUATIONS_PER_ITERATION * iterations) * rollouts
    seconds = num_episodes * MEAN_EPISODE_STEPS * _seconds_per_step()
    if seconds <= max_seconds:
        return
    params, obs, action, expected = disagreement
    shown = ", ".join(f"{value:.3g}" for value in obs)
    got = f"raises {action!r}" if isinstance(action, BaseException) else f"returns {action!r}"
    raise TooSlow(
        f"{describe} would take about {format_seconds(seconds)}, so the kit did not start it: your "
        f"CartPoleLinearPolicy.__call__ (TODO 1.1.1) does not follow equation (1), so each of its {num_episodes:,} "
        "episodes would be played step by step with it.",
        f"For example CartPoleLinearPolicy({np.round(params, 3).tolist()})([{shown}]) {got}; equation (1) gives "
        f"{expected}. Fix 1.1.1, or pass max_minutes=None to run it anyway.")


def _seconds_per_step():
    """What one step of your policy played step by step costs here (its __call__ and env.step)."""
    env, steps, start = make_env(), 0, time.perf_counter()
    generator = np.random.default_rng(0)
    while steps < 300:
        try:
            steps += play_episode(CartPoleLinearPolicy(generator.uniform(-1, 1, 4)), int(generator.integers(1000)), env).num_steps
        except Exception:  # noqa: BLE001 - a policy that fails at once costs little; count its try as a step
            steps += 1
    env.close()
    return (time.perf_counter() - start) / steps


def _is_count(value):
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value > 0
