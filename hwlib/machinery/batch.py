"""How the kit plays the episodes of your training runs together.

Your code is plain and sequential: ``eval_params`` loops over its rollouts and calls
``run_policy`` once per episode, training loops over iterations, the learning-rate sweep trains
run after run. Played one by one, the sweep's episodes would take more than an hour.
``Session.run(tasks)`` (used by ``hwlib/training.py``) makes the same code fast, from the outside:
while a session runs, ``Session.replaying`` puts the session's own functions in place of
``run_policy``, ``eval_params`` and ``scalar_finite_diff`` in ``hwlib.policy_search`` (where your
code looks them up) and puts yours back afterwards. Your files are not changed.

1. **Record, then replay** (``replay.py``). ``eval_params`` and ``scalar_finite_diff``, as
   your training calls them, run twice per call: first with placeholder rewards, which tells the
   kit exactly which episodes the call asks for, whatever seeds it uses; then for real, after all
   of them were played in one batch. Nothing is played that the code does not ask for. (Once a
   run's ``eval_params`` has shown that its seeds follow from its arguments, the first pass of
   its calls is skipped.)
2. **Runs side by side.** Several tasks (the sweep's 220 training runs) run in threads, one at a
   time in a fixed order, each until it waits for episodes; then the main thread plays what all
   of them wait for in one batch (``episodes.py``). The order never depends on timing, so a
   sweep gives the same numbers every time.
3. **Episodes without a seed** (``run_policy(policy)``) start where the next ``reset()`` of the
   run's own environment (seeded once with the training run's seed) starts them, so they too are
   the same in the batched run and in the plain loop (``batched=False``), and from one run to the next.
   An ``eval_params`` with its own ``gym.make("CartPole-v1")`` loop plays in a kit environment
   whose episodes are played in the same batches (``replay.KitEnv``).
4. **Checked, not trusted**: a parameter vector's episodes are played with the kit's copy of
   equation (1) only after ``episodes.agrees_with_equation_one``; others are played step by step
   with the policy's own ``__call__``. Results are kept by (policy class, parameters, seed), and
   an episode is a pure function of those, so the rewards are those of the plain loop.
5. **Stopping**: Kernel → Interrupt (KeyboardInterrupt in the main thread), an error in one run,
   or the ``on_round`` callback (the progress bar and the time limit of ``hwlib/training.py``)
   stops every run within a second; no thread is left behind.
"""

from __future__ import annotations

import collections
import ctypes
import functools
import random
import threading
import time

import numpy as np

from hwlib.cartpole import NUM_OBSERVATIONS, make_env
from hwlib.machinery import episodes
from hwlib.machinery.replay import (CLASSES, PLACEHOLDER_REWARD, Cancelled, GiveUpRecording, KitEnv, OwnEnv, Redo,
                                    Replaying, RunMemory, class_code, policy_of)
from hwlib.machinery.validation import check_policy, check_seed

__all__ = ["EVALUATIONS_PER_ITERATION", "PLACEHOLDER_REWARD", "Cancelled", "Session", "current_run"]

EVALUATIONS_PER_ITERATION = 2 * NUM_OBSERVATIONS + 1  # eq. (3) on 4 coordinates, then g(new params)
_KEEP_ROUNDS = 4  # results are kept for this many batches after they were played
_MAX_RECORDED = 100_000  # a recording pass that asks for more than this is given up
_JOIN_SECONDS = 1.0  # how long a stopped run's thread may take to end
_WATCH_CALLS = 3  # recorded calls during which a run is watched for draws from the global random generators


class _Current(threading.local):
    run = None  # the _Run this thread works for


_current = _Current()


def current_run():
    """The run this thread works for, or None."""
    return _current.run


class _Run:
    """One task of a session, and what it is doing."""

    def __init__(self, session, index, task, env_seed):
        self.session, self.index, self.task = session, index, task
        self.own = OwnEnv(env_seed)  # where its unseeded episodes start
        self._watch, self._globals_used = _WATCH_CALLS, False
        self.recording = False
        self.replaying = 0  # depth of replayed calls running for real
        self.recorded = {}  # key -> (policy, params), in the order asked for
        self.making = None  # (code, params) of the eval_params call whose code may make a KitEnv now
        self.longest = -1  # the longest episode a KitEnv served in the real pass running now (-1: no KitEnv)
        self.memory = RunMemory()  # what the run has shown about the seeds it asks for
        self.evaluations = 0  # real (second) passes of the first replayed function
        self.state = "ready"  # ready | running | waiting | done
        self.go = threading.Event()  # set when this run's thread may go on
        self.result = self.error = None

    def random_state(self):
        """The state of the run's own environment's generator, and numpy's and Python's global ones
        while they are watched."""
        watching = self._globals_used or self._watch > 0
        return self.own.state(), np.random.get_state() if watching else None, random.getstate() if watching else None

    def set_random_state(self, state):
        """Put the random state back. The global generators are slow to save; they are watched for the
        first few calls, and from then on only if the run's code drew from them."""
        env_state, numpy_state, python_state = state
        self.own.set_state(env_state)
        if numpy_state is None:
            return
        now = np.random.get_state()
        if numpy_state[2] != now[2] or not np.array_equal(numpy_state[1], now[1]) or python_state != random.getstate():
            self._globals_used = True
            np.random.set_state(numpy_state)
            random.setstate(python_state)
        elif not self._globals_used:
            self._watch -= 1


class Session(Replaying):
    """Runs tasks with their episodes played together. ``batched=False``: every episode on its own
    (the plain loop, for comparisons), the runs one after another.

    ``on_round(session)`` is called in the main thread after every batch (and, with one run, after
    every counted call, see ``replaying``); an exception it raises stops every run and is raised
    by ``run``.
    """

    def __init__(self, batched=True, on_round=None):
        self.batched, self.on_round = batched, on_round
        self._stopped_by = None  # what on_round raised inside a run's own code
        self._results = {}  # key -> reward, or the exception playing it raised
        self._played = collections.deque()  # the keys played in each of the last rounds
        self._pending = {}  # key -> (policy, params): to be played in the next round
        self._trusted = {}  # (policy class, params bytes) -> True, False or the TodoNotDone its probe raised
        self._back = threading.Event()  # set when the thread that had its turn waits or ends
        self._threaded = False
        self.cancelled = False
        self.runs = []
        self.rounds = self.episodes_played = self.step_by_step = self.asked = 0
        self._env = self._drawing = None
        self.started = None
        self.not_replayed = None  # why the session makes no more KitEnvs (replay.py), or None
        self.checked_up_to = 0  # KitEnv episodes up to this length were checked against a plain pass

    # --- running the tasks --------------------------------------------------------------------

    _current_run = staticmethod(current_run)

    def run(self, tasks, env_seeds=None):
        """Run the callables ``tasks``; returns their results in order. The first error any of them
        raises is raised here (the others are stopped first). ``env_seeds[i]`` is the seed of the
        first reset of task i's own environment, where its unseeded episodes start (default: i)."""
        seeds = list(range(len(tasks))) if env_seeds is None else list(env_seeds)
        self.runs = [_Run(self, index, task, seed) for index, (task, seed) in enumerate(zip(tasks, seeds))]
        self.started = time.perf_counter()
        try:
            if len(self.runs) > 1 and self.batched:
                self._run_threads()
            else:
                for run in self.runs:
                    self._run_inline(run)
        except Cancelled:
            if self._stopped_by is not None:
                raise self._stopped_by from None
            raise
        finally:
            if self._env is not None:
                self._env.close()
                self._env = None
            for run in self.runs:
                run.own.close()
        return [run.result for run in self.runs]

    def _run_inline(self, run):
        previous_run, _current.run = current_run(), run
        try:
            run.state = "running"
            run.result = run.task()
        finally:
            run.state = "done"
            _current.run = previous_run

    def _run_threads(self):
        self._threaded = True
        threads = [threading.Thread(target=self._work, args=(run,), daemon=True, name=f"hwlib-run-{run.index}")
                   for run in self.runs]
        for thread in threads:
            thread.start()
        try:
            self._rounds_in_turn()
        except BaseException:
            self._stop(threads)
            raise
        for thread in threads:
            thread.join()

    def _rounds_in_turn(self):
        """Every run goes on, in order, until it waits for episodes or ends (the first error of one is
        raised); then the episodes they all wait for are played in one batch; again."""
        while True:
            for run in self.runs:
                if run.state == "ready":
                    self._hand_over(run)
                    if run.error is not None and not isinstance(run.error, Cancelled):
                        raise run.error
            if not any(run.state == "waiting" for run in self.runs):
                return
            self.play_round()
            for run in self.runs:
                if run.state == "waiting":
                    run.state = "ready"
            if self.on_round is not None:
                self.on_round(self)

    def _hand_over(self, run):
        """Let ``run``'s thread go on until it waits for episodes or ends."""
        run.state = "running"
        self._back.clear()
        run.go.set()
        waits = 0
        while not self._back.wait(0.05):  # a timeout, so that Kernel → Interrupt is seen at once
            waits += 1
            if waits % 20 == 0 and self.on_round is not None:  # busy for a second: progress and time limit
                self.on_round(self)

    def _work(self, run):
        _current.run = run
        run.go.wait()
        try:
            if not self.cancelled:
                run.result = run.task()
        except BaseException as error:  # noqa: BLE001 - handed to the main thread
            run.error = error
        finally:
            run.state = "done"
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

    def _routed(self, run_policy):
        """What stands in for ``run_policy`` while the session runs: in one of its runs, the episode is
        played through the session (``_route``); anywhere else, and with an ``env`` of its own, by
        ``run_policy`` itself."""

        @functools.wraps(run_policy)
        def routed(policy, seed=None, env=None):
            run = _current.run
            if run is None or run.session is not self or (env is not None and type(env) is not KitEnv):
                return run_policy(policy, seed, env)
            check_policy(policy)
            if env is not None:
                return env.play(policy, seed)
            return self._route(run, policy, None if seed is None else check_seed(seed, "seed"))

        return routed

    def _route(self, run, policy, seed):
        """An episode a run asks for, its arguments checked. Called for every episode the training
        asks for, so it is written for speed."""
        if self.cancelled:
            raise Cancelled()
        if not self.batched:  # the plain loop; an unseeded episode is the next reset() of the run's env
            self.episodes_played += 1
            if seed is None:
                env, first_seed = run.own.for_reset()
                return episodes.play_from(policy, first_seed, env)
            return episodes.play_from(policy, seed, make_env())
        if seed is None:  # it starts where the next reset() of the run's own env starts it
            seed = run.own.next_start()
        params = episodes.linear_params(policy)
        if params is None:  # not a linear policy: played here, on its own
            if run.recording:
                return PLACEHOLDER_REWARD
            self.episodes_played += 1
            return episodes.play_from(policy, seed, make_env())
        key = (class_code(type(policy)), params.tobytes(), seed)
        if run.memory.asked is not None:
            run.memory.asked.append(key)
        result = self._results.get(key)
        if result is None:
            if run.recording:
                run.recorded.setdefault(key, (policy, params))
                if len(run.recorded) > _MAX_RECORDED:
                    raise GiveUpRecording()
                return PLACEHOLDER_REWARD
            if run.memory.foresaw and key not in self._pending:  # foreseen wrongly: start again, recorded
                raise Redo()
            self.asked += 1
            self._pending.setdefault(key, (policy, params))
            while key not in self._results:
                self._wait_for_round(run)
            result = self._results[key]
        if isinstance(result, BaseException):
            raise result
        return result

    def play_round(self):
        """Play every episode asked for or announced and not yet played, in one batch (and step by
        step those of policies that do not follow equation (1))."""
        batch_keys, params, starts = self._take_requests()
        self._store(batch_keys, episodes.play_batch(params, starts=starts) if batch_keys else None)

    def _take_requests(self):
        """The episodes asked for and not yet played: those of policies that follow equation (1)
        as ``(keys, params (K, 4), starts (K, 4))`` for one batch; the others are played here,
        step by step (or get the TodoNotDone their policy's check raised)."""
        requests, self._pending = self._pending, {}
        self.rounds += 1
        results, trusted_of = self._results, self._trusted
        batch_keys, made = [], {}
        self._played.append([])
        for key, (policy, params) in requests.items():
            if key in results:
                continue
            trusted = trusted_of.get(key[:2])
            if trusted is True:  # the usual case: no policy needs to be made or asked
                batch_keys.append(key)
                continue
            if policy is None:  # foreseen: the policy is the key's class with these parameters, made once
                policy = made.get(key[:2])
                if policy is None:
                    try:
                        policy = made[key[:2]] = policy_of(CLASSES[key[0]], params)
                    except Exception as error:  # noqa: BLE001 - the call that asks for it meets it
                        results[key] = error
                        self._played[-1].append(key)
                        continue
            if trusted is None:
                trusted = self._is_trusted(key, policy, params)
            if trusted is True:
                batch_keys.append(key)
            else:  # False: step by step; or the TodoNotDone the policy's check raised
                results[key] = self._play_step_by_step(policy, key[2]) if trusted is False else trusted
                self._played[-1].append(key)
        if not batch_keys:
            return batch_keys, None, None
        params = np.frombuffer(b"".join([key[1] for key in batch_keys]), dtype=np.float64).reshape(-1, NUM_OBSERVATIONS)
        return batch_keys, params, episodes.starts_of([key[2] for key in batch_keys])

    def _store(self, batch_keys, rewards):
        """Keep the rewards of a batch (None: nothing was batched); forget what is old."""
        results = self._results
        if batch_keys:
            results.update(zip(batch_keys, rewards.tolist()))
            self.episodes_played += len(batch_keys)
            self._played[-1].extend(batch_keys)
        while len(self._played) > _KEEP_ROUNDS and len(results) > 200_000:
            for key in self._played.popleft():
                results.pop(key, None)

    def _is_trusted(self, key, policy, params):
        trust_key = key[:2]
        trusted = self._trusted.get(trust_key)
        if trusted is None:
            try:
                trusted = episodes.agrees_with_equation_one(policy, params)
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
            return episodes.play_from(policy, seed, self._env)
        except Exception as error:  # noqa: BLE001 - raised again where the episode was asked for
            return error
