"""The sweep's runs in two halves that take turns, so that both cores work.

``batch.py``'s ``Session`` runs its tasks in threads, one at a time; what they wait for is
played in one batch. On a machine with two cores or more, a helper process
(``physics.py``) plays one half's batch while the other half's code runs here, and this
process plays the rest of the batch once that code has run (``_Split`` chooses how much each
plays, so that neither waits long). An episode's reward depends only on its key and each half's
runs go on in a fixed order, so the numbers are those of one batch for all runs.
"""

from __future__ import annotations

import os
import time

import numpy as np

from hwlib.machinery import episodes, physics


MIN_HELPER_BATCH = 1000  # a smaller batch is played here: the helper process is not worth starting for it


def rounds_side_by_side(session):
    """Two halves of the runs take turns: while one half's code runs here, the episodes the
    other half waits for are played, the first part of them by the helper process and the rest
    here, once the code has run, so both cores work (``_Split`` chooses the part). Each half's
    runs go on in a fixed order and an episode's reward depends only on its key, so the numbers
    are those of ``Session._rounds_in_turn``. The helper process ends before this returns."""
    helper = _Helper()
    try:
        _take_turns(session, helper)
    finally:
        helper.close()


def _take_turns(session, helper):
    halves, in_flight, turn, split = (session.runs[0::2], session.runs[1::2]), None, 0, _Split()
    while True:
        runs, started = halves[turn], time.perf_counter()
        session.go_on(runs)  # what they ask for goes into session._pending
        split.ran(time.perf_counter() - started)
        if in_flight is not None:  # the other half's batch: the part played here, then the helper's
            keys, params, starts, cut, waiting = in_flight
            in_flight, started = None, time.perf_counter()
            here = episodes.play_batch(params[cut:], starts=starts[cut:]) if cut < len(keys) else np.zeros(0)
            parts = [(len(keys) - cut, time.perf_counter() - started)]
            there = helper.collect(params[:cut], starts[:cut], parts) if cut else np.zeros(0)
            split.played(parts)
            session.store(keys, np.concatenate([there, here]))
            session.round_done(waiting)
        if any(run.state == "waiting" for run in runs):
            keys, params, starts = session.take_requests()
            if not keys:
                session.store(keys, None)
                session.round_done(runs)
            else:
                cut = split.cut(len(keys)) if len(keys) >= MIN_HELPER_BATCH else 0
                in_flight = keys, params, starts, helper.submit(params[:cut], starts[:cut]) if cut else 0, runs
        elif in_flight is None and not any(run.state in ("ready", "waiting") for run in session.runs):
            return
        turn = 1 - turn


class _Helper:
    """The helper process, started with the first batch it is given; if it cannot start or
    stops answering, every batch is played here from then on."""

    def __init__(self):
        self.process, self.failed = None, False

    def submit(self, params, starts):
        """Hand it the batch; returns how many episodes it plays (0: none, play them here)."""
        if self.failed:
            return 0
        try:
            if self.process is None:
                self.process = physics.HelperProcess(episodes.constants())
            self.process.submit(params, starts)
        except physics.HelperFailed:
            self.close()
            self.failed = True
            return 0
        return len(params)

    def collect(self, params, starts, parts):
        """The rewards of the batch submitted (``params``, ``starts``): the helper's, or played here."""
        started = time.perf_counter()
        try:
            rewards, seconds = self.process.collect()
        except physics.HelperFailed:
            self.close()
            self.failed = True
            rewards, seconds = episodes.play_batch(params, starts=starts), time.perf_counter() - started
        parts.append((len(params), seconds))
        return rewards

    def close(self):
        if self.process is not None:
            self.process.close()
            self.process = None


class _Split:
    """How much of a batch the helper plays (its first ``cut`` episodes): as much as keeps both
    cores busy, from what earlier turns took. The batch submitted at the end of turn t is played
    while turn t + 1's code runs; that code costs about what turn t - 3's did (the same half, two
    of its rounds before: training alternates gradient and update rounds), and an episode of the
    batch about what one of turn t - 4's batch did. With nothing measured yet, the helper plays all."""

    def __init__(self):
        self.turn = -1
        self.code = {}  # turn -> seconds its code ran
        self.per_episode = {}  # turn -> seconds per episode of the batch submitted at its end

    def ran(self, seconds):
        self.turn += 1
        self.code[self.turn] = seconds

    def played(self, parts):
        """The batch of the turn before was played: ``parts`` is [(episodes, seconds), ...]."""
        episodes = sum(count for count, _ in parts)
        if episodes:
            self.per_episode[self.turn - 1] = sum(seconds for _, seconds in parts) / episodes

    def cut(self, episodes):
        code, per_episode = self.code.get(self.turn - 3), self.per_episode.get(self.turn - 4)
        if code is None or per_episode is None:
            return episodes
        play = episodes * per_episode
        if play <= code:
            return episodes
        return min(episodes, int(round(episodes * (code + play) / (2 * play))))


def usable_cores():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1
