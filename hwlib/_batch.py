"""How the kit plays the episodes of your training runs together. Students need not read this.

Your code is plain and sequential: ``eval_params`` loops over its rollouts and calls
``run_policy`` once per episode, training loops over iterations, the learning-rate sweep trains
run after run. Played one by one, the sweep's 640,000 episodes would take the better part of an
hour. ``Session.run(tasks)`` (used by ``hwlib/training.py``) makes the same code fast:

1. **Record, then replay.** The functions named in ``Session.replaying`` (``eval_params`` and
   ``scalar_finite_diff`` as your training calls them) run twice per call. The first time every
   episode not yet played gets a placeholder reward (0) and is only written down, so the kit
   learns exactly which episodes the call asks for, whatever seeds it uses; then all of them are
   played in one batch, and the call runs again for real with the true rewards. The random state
   (the run's generator, numpy's and ``random``'s global ones) is put back before the second run,
   so it asks for the same episodes. Nothing is played that the code does not ask for. (Saving the
   global generators is slow, so they are saved only while the run's first calls show that its
   code draws from them.)
2. **Runs side by side.** Several tasks (the sweep's 160 training runs) run in threads, one at a
   time in a fixed order, each until it waits for episodes; then the main thread plays what all
   of them wait for in one batch (``hwlib/_engine.py``). The order never depends on timing, so a
   sweep gives the same numbers every time.
3. **Episodes without a seed** (``run_policy(policy)``) start from a seed drawn from the run's own
   generator (``np.random.default_rng(seed)`` of the training run), so they too are the same in
   the batched run and in the plain loop (``batched=False``), and from one run to the next.
4. **Checked, not trusted**: a parameter vector's episodes are played with the kit's copy of
   equation (1) only after ``_engine.agrees_with_equation_one``; others are played step by step
   with the policy's own ``__call__``. Results are kept by (policy class, parameters, seed), and
   an episode is a pure function of those, so the rewards are those of the plain loop.
5. **Stopping**: Kernel → Interrupt (KeyboardInterrupt in the main thread) or an error in one run
   stops every run within a second; no thread is left behind. Work that would take longer than
   ``max_seconds`` is stopped early with an estimate (``TooSlow``).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import random
import threading
import time

import numpy as np

from hwlib import _engine
from hwlib._progress import format_seconds
from hwlib.cartpole import SEED_BOUND, CartPoleLinearPolicy, _play, make_env

EVALUATIONS_PER_ITERATION = 2 * _engine.NUM_OBSERVATIONS + 1  # eq. (3) on 4 coordinates, then g(new params)
PLACEHOLDER_REWARD = 0.0  # what an episode not yet played gives while a call is being recorded
_KEEP_ROUNDS = 4  # results are kept for this many batches after they were played
_MAX_RECORDED = 100_000  # a recording pass that asks for more than this is given up
_JOIN_SECONDS = 1.0  # how long a stopped run's thread may take to end
_WATCH_CALLS = 3  # recorded calls during which a run is watched for draws from the global random generators
class _Current(threading.local):
    run = None  # the _Run this thread works for


_current = _Current()
_FLOAT64, _SHAPE = np.dtype(np.float64), (_engine.NUM_OBSERVATIONS,)


class Cancelled(BaseException):
    """Raised inside a run the kit stopped (Kernel → Interrupt, or another run failed)."""


class _GiveUpRecording(BaseException):
    pass


class TooSlow(RuntimeError):
    """The work would take much longer than the kit allows (``max_minutes``); it says why."""

    def __init__(self, first, second):
        super().__init__(f"{first}\n{second}")
        self.first, self.second = first, second

    def _render_traceback_(self):
        return [f"\x1b[1;31m{self.first}\x1b[0m", self.second]


def current_run():
    """The run this thread works for, or None."""
    return _current.run


class _Run:
    """One task of a session, and what it is doing."""

    def __init__(self, session, index, task, seed_of_generator):
        self.session, self.index, self.task = session, index, task
        self._seed_of_generator, self._generator = seed_of_generator, None
        self._watch, self._globals_used = _WATCH_CALLS, False
        self.recording = False
        self.replaying = 0  # depth of replayed calls running for real
        self.recorded = {}  # key -> (policy, params), in the order asked for
        self.evaluations = 0  # real (second) passes of the first replayed function
        self.state = "ready"  # ready | running | waiting | done
        self.go = threading.Event()  # set when this run's thread may go on
        self.result = self.error = None

    @property
    def generator(self):
        if self._generator is None:  # created when first needed: the training code has checked its seed by then
            self._generator = np.random.default_rng(self._seed_of_generator)
        return self._generator

    def draw_seed(self):
        return int(self.generator.integers(0, SEED_BOUND))

    def random_state(self):
        """The run's generator's state, and numpy's and Python's global ones while they are watched."""
        watching = self._globals_used or self._watch > 0
        return (self.generator.bit_generator.state, np.random.get_state() if watching else None,
                random.getstate() if watching else None)

    def set_random_state(self, state):
        """Put the random state back. The global generators are slow to save; they are watched for the
        first few calls, and from then on only if the run's code drew from them."""
        generator_state, numpy_state, python_state = state
        self.generator.bit_generator.state = generator_state
        if numpy_state is None:
            return
        now = np.random.get_state()
        if numpy_state[2] != now[2] or not np.array_equal(numpy_state[1], now[1]) or python_state != random.getstate():
            self._globals_used = True
            np.random.set_state(numpy_state)
            random.setstate(python_state)
        elif not self._globals_used:
            self._watch -= 1


class Session:
    """Runs tasks with their episodes played together. ``batched=False``: every episode on its own
    (the plain loop, for comparisons), the runs one after another.

    ``iterations``: training iterations per task (each of 1 + 9 per iteration evaluations, counted
    by ``replaying(..., counted=...)``), for the progress and the time estimate; ``progress``: an
    ``hwlib._progress.Progress`` (or None) kept up to date; ``max_seconds``: stop with ``TooSlow``
    once the projected time exceeds it (None: never); ``describe``: the work's name in that
    message ("This learning-rate sweep").
    """

    def __init__(self, batched=True, iterations=None, progress=None, max_seconds=None, describe="This run"):
        self.batched, self.progress, self.max_seconds, self.describe = batched, progress, max_seconds, describe
        self.iterations = iterations
        self.expected_evaluations = None if iterations is None else 1 + EVALUATIONS_PER_ITERATION * iterations
        self._too_slow = None
        self._results = {}  # key -> (round, reward or exception)
        self._pending = {}  # key -> (policy, params): to be played in the next round
        self._trusted = {}  # (policy class, params bytes) -> True, False or the TodoNotDone its probe raised
        self._back = threading.Event()  # set when the thread that had its turn waits or ends
        self._threaded = False
        self.cancelled = False
        self.runs = []
        self.rounds = self.episodes_played = self.step_by_step = self.asked = 0
        self._env = None
        self._started = None

    # --- running the tasks --------------------------------------------------------------------

    def run(self, tasks, generator_seeds=None):
        """Run the callables ``tasks``; returns their results in order. The first error any of them
        raises is raised here (the others are stopped first). ``generator_seeds[i]`` seeds the
        generator of task i's unseeded episodes (default: i)."""
        seeds = list(range(len(tasks))) if generator_seeds is None else list(generator_seeds)
        self.runs = [_Run(self, index, task, seed) for index, (task, seed) in enumerate(zip(tasks, seeds))]
        self._started = time.perf_counter()
        try:
            if len(self.runs) > 1 and self.batched:
                self._run_threads()
            else:
                for run in self.runs:
                    self._run_inline(run)
        except Cancelled:
            if self._too_slow is not None:
                raise self._too_slow from None
            raise
        finally:
            if self._env is not None:
                self._env.close()
                self._env = None
        return [run.result for run in self.runs]

    def _run_inline(self, run):
        previous_run, previous_route = current_run(), _engine.set_route(self._route)
        _current.run = run
        try:
            run.state = "running"
            run.result = run.task()
        finally:
            run.state = "done"
            _current.run = previous_run
            _engine.set_route(previous_route)

    def _run_threads(self):
        self._threaded = True
        threads = [threading.Thread(target=self._work, args=(run,), daemon=True, name=f"hwlib-run-{run.index}")
                   for run in self.runs]
        for thread in threads:
            thread.start()
        try:
            while True:
                for run in self.runs:
                    if run.state == "ready":
                        self._hand_over(run)
                        if run.error is not None and not isinstance(run.error, Cancelled):
                            raise run.error
                if not any(run.state == "waiting" for run in self.runs):
                    break
                self.play_round()
                for run in self.runs:
                    if run.state == "waiting":
                        run.state = "ready"
                self._after_round()
        except BaseException:
            self._stop(threads)
            raise
        for thread in threads:
            thread.join()

    def _hand_over(self, run):
        """Let ``run``'s thread go on until it waits for episodes or ends."""
        run.state = "running"
        self._back.clear()
        run.go.set()
        while not self._back.wait(0.05):  # a timeout, so that Kernel → Interrupt is seen at once
            pass

    def _work(self, run):
        _current.run = run
        _engine.set_route(self._route)
        run.go.wait()
        try:
            if not self.cancelled:
                run.result = run.task()
        except BaseException as error:  # noqa: BLE001 - handed to the main thread
            run.error = error
        finally:
            run.state = "done"
            _engine.set_route(None)
            _current.run = None
            self._back.set()

    def _wait_for_round(self, run):
        """In a run's thread: let the others ask for their episodes, then the main thread play them all."""
        if not self._threaded:
            self.play_round()
            return
        run.state = "waiting"
        run.go.clear()
        self._back.set()
        run.go.wait()
        if self.cancelled:
            raise Cancelled()

    def _stop(self, threads):
        """Stop every run and wait (a moment) for its thread to end."""
        self.cancelled = True
        for run in self.runs:
            run.go.set()
        deadline = time.monotonic() + _JOIN_SECONDS
        for thread in threads:
            thread.join(max(0.0, min(0.3, deadline - time.monotonic())))
        for thread in threads:
            if thread.is_alive():  # busy in its own code, far from any episode: interrupt it there
                ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread.ident), ctypes.py_object(Cancelled))
        for thread in threads:
            thread.join(max(0.0, deadline - time.monotonic()))

    # --- episodes -----------------------------------------------------------------------------

    def _route(self, policy, seed):
        """``run_policy(policy, seed)`` inside a run (its arguments checked). Called for every
        episode the training asks for, so it is written for speed."""
        if self.cancelled:
            raise Cancelled()
        run = _current.run
        if seed is None:
            seed = run.draw_seed()
        if not self.batched:
            self.episodes_played += 1
            return _play(policy, seed, None).total_reward
        params = policy.params if isinstance(policy, CartPoleLinearPolicy) else None
        if type(params) is np.ndarray and params.dtype == _FLOAT64 and params.shape == _SHAPE:
            data = params.tobytes()
            if data not in _FINITE:
                params, data = _params_of(policy)
        else:
            params, data = _params_of(policy)
        if params is None:  # not a linear policy: played here, on its own
            if run.recording:
                return PLACEHOLDER_REWARD
            self.episodes_played += 1
            return _play(policy, seed, None).total_reward
        key = (type(policy), data, seed)
        result = self._results.get(key)
        if result is None:
            if run.recording:
                run.recorded.setdefault(key, (policy, params))
                if len(run.recorded) > _MAX_RECORDED:
                    raise _GiveUpRecording()
                return PLACEHOLDER_REWARD
            self.asked += 1
            self._pending.setdefault(key, (policy, params))
            while key not in self._results:
                self._wait_for_round(run)
            result = self._results[key]
        if isinstance(result[1], BaseException):
            raise result[1]
        return result[1]

    def play_round(self):
        """Play every episode asked for or announced and not yet played, in one batch (and step by
        step those of policies that do not follow equation (1))."""
        requests, self._pending = self._pending, {}
        self.rounds += 1
        batch_keys, batch_params = [], []
        trusted_of = self._trusted
        for key, (policy, params) in requests.items():
            if key in self._results:
                continue
            trusted = trusted_of.get(key[:2])
            if trusted is None:
                trusted = self._is_trusted(key, policy, params)
            if trusted is True:
                batch_keys.append(key)
                batch_params.append(params)
            elif isinstance(trusted, BaseException):
                self._results[key] = (self.rounds, trusted)
            else:
                self._results[key] = (self.rounds, self._play_step_by_step(policy, key[2]))
        if batch_keys:
            rewards = _engine.play_batch(np.array(batch_params), np.array([key[2] for key in batch_keys], dtype=np.int64))
            for key, reward in zip(batch_keys, rewards.tolist()):
                self._results[key] = (self.rounds, reward)
            self.episodes_played += len(batch_keys)
        oldest = self.rounds - _KEEP_ROUNDS
        if oldest > 0 and len(self._results) > 200_000:
            self._results = {key: value for key, value in self._results.items() if value[0] > oldest}

    def _is_trusted(self, key, policy, params):
        trust_key = key[:2]
        trusted = self._trusted.get(trust_key)
        if trusted is None:
            try:
                trusted = _engine.agrees_with_equation_one(policy, params)
            except NotImplementedError as error:  # the TODO stub's TodoNotDone: every caller gets it
                trusted = error
            if len(self._trusted) > 200_000:
                self._trusted.clear()
            self._trusted[trust_key] = trusted
        return trusted

    def _play_step_by_step(self, policy, seed):
        self.episodes_played += 1
        self.step_by_step += 1
        if self._env is None:
            self._env = make_env()
        try:
            return _play(policy, seed, self._env).total_reward
        except Exception as error:  # noqa: BLE001 - raised again where the episode was asked for
            return error

    # --- record, then replay --------------------------------------------------------------------

    @contextlib.contextmanager
    def replaying(self, module, names, counted=None):
        """While the session runs, ``module.<name>`` (for each of ``names``) is recorded, then
        replayed, in the session's runs (batched only); calls of ``counted`` (one of the names)
        advance the progress."""
        originals = {name: getattr(module, name) for name in names}
        for name, function in originals.items():
            setattr(module, name, self._replayed(function, counts=name == counted))
        try:
            yield
        finally:
            for name, function in originals.items():
                setattr(module, name, function)

    def _record(self, run, function, args, kwargs):
        """Run ``function`` once with placeholder rewards; what it asked for is played in the next round."""
        state = run.random_state()
        run.recording, run.recorded = True, {}
        try:
            function(*args, **kwargs)
        except (Cancelled, KeyboardInterrupt):
            raise
        except BaseException:  # noqa: BLE001 - the real pass meets it again, or not
            pass
        finally:
            run.recording = False
            run.set_random_state(state)
        for key, request in run.recorded.items():
            if key not in self._results:
                self._pending.setdefault(key, request)
        run.recorded = {}

    def _replayed(self, function, counts):
        @functools.wraps(function)
        def replayed(*args, **kwargs):
            run = current_run()
            if run is None or run.session is not self or run.recording:
                return function(*args, **kwargs)
            if self.cancelled:
                raise Cancelled()
            outermost = run.replaying == 0
            if self.batched and outermost:  # an inner call's episodes were recorded with the outer one's
                self._record(run, function, args, kwargs)
            run.replaying += 1
            try:
                value = function(*args, **kwargs)
            finally:
                run.replaying -= 1
            if counts:
                run.evaluations += 1
                if not self._threaded:
                    self._after_round()
            return value

        return replayed

    # --- progress and the time limit ----------------------------------------------------------

    def fraction_done(self):
        if not self.expected_evaluations:
            return 0.0
        done = sum(min(run.evaluations, self.expected_evaluations) for run in self.runs)
        return done / (self.expected_evaluations * max(len(self.runs), 1))

    def _after_round(self):
        fraction = self.fraction_done()
        if self.progress is not None:
            self.progress.set(round(fraction * self.progress.total), self.progress_detail())
        elapsed = time.perf_counter() - self._started
        if self.max_seconds is not None and elapsed > 3.0 and fraction > 0.01:
            projected = elapsed / fraction
            if projected > self.max_seconds:
                too_slow = TooSlow(f"{self.describe} would take about {format_seconds(projected)} on this machine, "
                                   f"so the kit stopped it after {format_seconds(elapsed)}.", self.why_slow())
                if self._threaded:
                    raise too_slow
                self._too_slow = too_slow  # raised by run(), outside the code of the run
                raise Cancelled()

    def progress_detail(self):
        """'iteration 5 of 20': how far the slowest run still going has come."""
        if self.iterations is None or not self.runs:
            return ""
        going = [run.evaluations for run in self.runs if run.state != "done"]
        evaluations = min(going) if going else self.expected_evaluations
        iteration = min(max(evaluations - 1, 0) // EVALUATIONS_PER_ITERATION, self.iterations)
        return f"iteration {iteration} of {self.iterations}"

    def why_slow(self):
        """What made the work slow, in a sentence, from what was played so far."""
        if self.step_by_step > 0.5 * max(self.episodes_played, 1):
            return ("Most episodes were played step by step with your CartPoleLinearPolicy.__call__, because it does "
                    "not give the actions of equation (1) (TODO 1.1.1); fix it, or pass max_minutes=None to wait.")
        if self.rounds > 3 * max(sum(run.evaluations for run in self.runs) / max(len(self.runs), 1), 1):
            return ("Your code asks for its episodes one at a time in a way the kit cannot foresee (eval_params draws "
                    "different seeds each time it runs?); pass max_minutes=None to wait.")
        return "Pass max_minutes=None to wait for it."


def _params_of(policy):
    """The float64 parameters (4,) of a linear policy and their bytes, or (None, None) for any other callable."""
    if not isinstance(policy, CartPoleLinearPolicy):
        return None, None
    params = policy.params
    if type(params) is not np.ndarray or params.dtype != np.float64 or params.shape != (_engine.NUM_OBSERVATIONS,):
        try:  # the policy's params were replaced after it was made: read them as they are now
            params = np.array(params, dtype=np.float64).reshape(_engine.NUM_OBSERVATIONS)
        except (TypeError, ValueError):
            return None, None
    data = params.tobytes()
    if data not in _FINITE:
        if not np.isfinite(params).all():
            return None, None
        if len(_FINITE) > 500_000:
            _FINITE.clear()
        _FINITE.add(data)
    return params, data


_FINITE = set()  # the bytes of parameter vectors known to be finite
