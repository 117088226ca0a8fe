"""A child process's pipes with deadlines, and the end of a child with its children, on every system.

The grader's side of a run talks to its worker over two pipes: it writes requests and reads
answers, and never waits past the run's deadline, whatever the worker does (stops reading, sends
a huge or garbled answer, never answers). ``select()`` cannot wait on a pipe on Windows, so each
pipe has a thread of its own: ``Pipes.receive`` waits for the reader thread's next answer until
the deadline, ``Pipes.send`` for the writer thread's write. Threads blocked on a pipe end when the
process (and every process that holds the pipe) is killed; until then they keep the pipe's file
open, so its descriptor is never reused under them.

``kill_tree`` ends a child started in a session of its own with every process of that session:
``os.killpg`` on macOS and Linux, ``taskkill /T`` on Windows.
"""

from __future__ import annotations

import os
import queue
import shutil
import signal
import struct
import subprocess
import threading
import time

from hwtools.grade.in_sandbox import channel
from hwtools.grade.in_sandbox.channel import ChannelTimeout

TIMEOUT_WORDS = "timeout:the wall-clock limit was reached"
KILL_SECONDS = 30.0  # for taskkill to end a tree on Windows


def kill_tree(process):
    """SIGKILL (or Windows' TerminateProcess) to ``process`` and every process of its session or
    tree; returns at once. ``process`` was started with ``start_new_session=True``."""
    try:
        if hasattr(os, "killpg"):
            os.killpg(process.pid, signal.SIGKILL)
        elif shutil.which("taskkill"):  # Windows
            subprocess.run(["taskkill", "/F", "/T", "/PID", str(process.pid)], capture_output=True,
                           timeout=KILL_SECONDS, check=False)
    except (ProcessLookupError, PermissionError, OSError, subprocess.TimeoutExpired):
        pass
    try:  # the process itself at least, wherever the tree could not be reached
        process.kill()
    except OSError:
        pass


def read_answer(stream):
    """The next message on the pipe ``stream`` (blocking), or "status:detail" when the worker
    closed it ("ended:") or wrote something that is not a message ("garbled:..."). Nothing larger
    than ``channel.MAX_MESSAGE_BYTES`` is read."""
    fd = stream.fileno()
    try:
        (length,) = struct.unpack(">Q", channel.read_exactly(fd, 8))
        if length > channel.MAX_MESSAGE_BYTES:
            return f"garbled:an answer of {length} bytes, more than the {channel.MAX_MESSAGE_BYTES} accepted"
        if length == 0:
            return "garbled:an empty answer"
        data = channel.read_exactly(fd, length)
    except (EOFError, OSError, ValueError):
        return "ended:"
    try:
        answer = channel.unpack(data)
    except Exception as error:  # noqa: BLE001 - anything the worker's side wrote is untrusted
        return f"garbled:an answer that is not a valid message ({type(error).__name__})"
    if not isinstance(answer, dict):
        return "garbled:an answer that is not a message"
    return answer


class Pipes:
    """The requests' pipe ``stdin`` and the answers' pipe ``stdout`` of one worker, each read or
    written by a thread of its own, every wait with a deadline. At most one answer waits here
    unread (the reader thread waits for it to be taken), so a worker cannot fill the grader's
    memory."""

    def __init__(self, stdin, stdout):
        self._stdin, self._stdout = stdin, stdout
        self._answers = queue.Queue(maxsize=1)
        self._final = None  # the status that ended the reader ("ended:", "garbled:..."), once known
        self._closed = threading.Event()
        self._writer = None
        self._reader = threading.Thread(target=self._read, daemon=True, name="worker-answers")
        self._reader.start()

    def _read(self):
        while not self._closed.is_set():
            answer = read_answer(self._stdout)
            if isinstance(answer, str):
                self._final = answer
            while not self._closed.is_set():
                try:
                    self._answers.put(answer, timeout=0.5)
                    break
                except queue.Full:
                    continue
            if isinstance(answer, str):
                return

    def receive(self, deadline):
        """The next answer (a dict) or "status:detail", by ``deadline`` (monotonic seconds)."""
        while True:
            if self._final is not None and self._answers.empty():
                return self._final
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return TIMEOUT_WORDS
            try:
                return self._answers.get(timeout=min(remaining, 0.5))
            except queue.Empty:
                continue

    def send(self, message, deadline):
        """Write ``message`` by ``deadline``: ChannelTimeout if the worker does not take it in time
        (the run is then over), OSError if it no longer reads."""
        if self._writer is not None and self._writer.is_alive():
            raise ChannelTimeout("the wall-clock limit was reached (the other side stopped reading)")
        failed = []

        def write():
            try:
                channel.write_message(self._stdin.fileno(), message)
            except OSError as error:
                failed.append(error)

        self._writer = threading.Thread(target=write, daemon=True, name="worker-requests")
        self._writer.start()
        self._writer.join(max(0.0, deadline - time.monotonic()))
        if self._writer.is_alive():
            raise ChannelTimeout("the wall-clock limit was reached (the other side stopped reading)")
        if failed:
            raise failed[0]

    def end_requests(self):
        """Close the requests' pipe (the worker reads its end: the sign to exit), unless a write is
        still blocked on it."""
        if self._writer is None or not self._writer.is_alive():
            try:
                self._stdin.close()
            except OSError:
                pass

    def close(self, wait=2.0):
        """After the worker was killed: stop the threads and close the pipes that no thread still
        uses (a pipe a surviving process holds stays open: its descriptor is never reused under a
        blocked thread)."""
        self._closed.set()
        for thread, stream in ((self._writer, self._stdin), (self._reader, self._stdout)):
            if thread is not None:
                thread.join(wait)
            if thread is None or not thread.is_alive():
                try:
                    stream.close()
                except OSError:
                    pass
