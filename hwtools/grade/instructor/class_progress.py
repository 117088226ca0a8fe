"""The progress of grading a class on a terminal or in a log: done/total, time elapsed, an estimate
of the time left, and a line for each submission that was not simply graded. Student ids and
statuses are shown without control characters (a file name cannot forge a line)."""

from __future__ import annotations

import shutil
import threading
import time

from hwtools.grade.feedback import points
from hwtools.grade.instructor.gradebook import GRADED, NOT_ISOLATED
from hwtools.grade.safe_text import printable
from hwtools.todos import AUTO_POINTS



def _clock(seconds):
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60}:{rest % 60:02d}"


class Progress:
    """Done/total, time elapsed and an estimate of the time left, on ``stream``. On a terminal: one
    line rewritten in place every second, and a line of its own for each submission that was not
    simply graded (rejected, unreadable, timed out...); elsewhere (a log file): one line per
    submission."""

    def __init__(self, total, stream=None):
        self.total, self.stream = total, stream
        self.done = self.graded_now = 0
        self.started = time.monotonic()
        self.tty = bool(stream is not None and getattr(stream, "isatty", lambda: False)())
        self.last = ""
        self._lock = threading.Lock()
        self._stop = threading.Event()
        if self.tty:
            threading.Thread(target=self._tick, daemon=True, name="hwclass-progress").start()

    def line(self):
        elapsed = time.monotonic() - self.started
        left = self.total - self.done
        if left == 0:
            estimate = "done"
        elif self.graded_now == 0:
            estimate = "time left: estimating"
        else:
            estimate = f"about {_clock(elapsed / self.graded_now * left)} left"
        return f"[{self.done}/{self.total}] {_clock(elapsed)} elapsed, {estimate}"

    def _redraw(self):
        width = shutil.get_terminal_size((100, 24)).columns - 1
        self.stream.write("\r\x1b[K" + f"{self.line()}  {self.last}"[:width])
        self.stream.flush()

    def _tick(self):
        while not self._stop.wait(1.0):
            with self._lock:
                self._redraw()

    def update(self, student_result):
        if self.stream is None:
            return
        with self._lock:
            self.done += 1
            self.graded_now += student_result.result is not None and not student_result.reused
            what = printable(f"{student_result.student}: {student_result.status}")
            if student_result.result is not None:
                what += f", {points(student_result.auto_total)}/{points(AUTO_POINTS)}"
            what += " (saved earlier)" if student_result.reused else f" ({student_result.seconds:.1f} s)"
            if not self.tty:
                self.stream.write(f"{self.line()}  {what}\n")
                self.stream.flush()
                return
            if student_result.status not in (GRADED, NOT_ISOLATED):  # kept on the screen
                self.stream.write(f"\r\x1b[K{what}\n")
            self.last = what
            self._redraw()

    def close(self):
        self._stop.set()
        if self.stream is not None and self.tty:
            with self._lock:
                self._redraw()
                self.stream.write("\n")
                self.stream.flush()
