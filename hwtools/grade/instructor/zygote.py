"""A grading's zygote (bubblewrap only): one sandbox per grading whose PID 1 forks the grading's runs.

A grading under bubblewrap (``Grader._grading``) takes a ``Zygote`` (``Zygotes.take``): one bubblewrap sandbox built as a run's (``WorkerProcess``:
the same namespaces, seccomp filter, limits and cgroup) whose PID 1 is the trusted
``zygote_init.py``. It starts Python and imports numpy, gymnasium and the grader's runtime once
(from ``/grader/_hwgrade``, the grader's own copy), compiles (never runs) the grader's template of
the kit (every TODO a stub: no student's code, no reference solution), then forks each run of the
grading's student code when it begins (``ZygoteRun``), so a run costs a fork and the import of its
own TODO's file, not a Python and a kit (the grading benchmark's rows in ``benchmarks/RESULTS.md``).
What keeps each run what it was in a sandbox of its own:

* a run begins alone: at the end of each run the zygote kills every other process of its sandbox
  (``kill(-1, SIGKILL)``: as the namespace's init it is spared, and every process there is its
  descendant), reaps them until it has no child, and says so only when ``/proc`` then lists itself
  alone; a reply that does not come by its deadline, or does not say alone, kills the whole sandbox;
* it inherits nothing of the runs before it: it makes no file, socket, System V or POSIX IPC object
  or memory file (the seccomp filter refuses them all in the shared sandbox, so its ``/tmp`` and
  ``/dev/shm`` stay empty), holds the grader's three descriptors and no other (it closes every
  other before anything else), the zygote's environment (set by bubblewrap, never changed by a run),
  and sees its own kit alone in ``/kit``: a host folder bound read-only, where the grader writes the
  run's kit at its fork (only the files that differ from the kit before it: the grader's own files,
  which no run can change) and removes every file the kit does not have. The zygote is
  non-dumpable (``PR_SET_DUMPABLE`` 0), so no run can trace it, read its ``/proc`` files or write
  its memory; and as its namespace's init it receives no signal from a run but the SIGCHLD it
  catches (``pid_namespaces(7)``). Left over: the namespace's counter of process ids goes on from
  one run to the next, as the page cache does between any two runs (docs/grading.md says why
  neither carries anything of use);
* each forked run sets its own limits (CPU time, address space, open files, file size) and is the
  first process the kernel kills when the sandbox's memory runs out (``oom_score_adj`` 1000), before
  any code of its kit is imported, under the seccomp filter the whole sandbox runs under;
* its pipes, deadlines, wall-clock backstop, budget and turn are a run's (``WorkerProcess``); the
  cgroup bounds the sandbox (the zygote and the one run alive beside it);
* fail closed: a zygote that is gone (killed, out of memory) or misses a deadline is ``lost``, and
  every later run of its grading fails, in fixed words (``broker.STOPS["lost"]``).

A zygote serves one grading at a time, and once that grading is over (every run of it ended, its
processes gone), a later grading of the same grader (``Zygotes``), so that a class pays for its Python once per grading thread rather than per submission. A grading finds in it
what it would find in a new one: no run could change the zygote or anything that outlives the run
(above), and what is left between any two runs (the counter of process ids, the page cache) is
worth nothing between two gradings, each of which draws its hidden inputs from a secret of its own
(docs/grading.md).
"""

from __future__ import annotations

import json
import os
import signal
import socket
import tempfile
import threading
import time
from pathlib import Path

from hwtools.grade import kits
from hwtools.grade.processes import Pipes
from hwtools.grade.reference import spawn
from hwtools.grade.sandbox import GONE_SECONDS, MAX_FILE_BYTES, WorkerProcess, _tail

ZYGOTE_CPU = 3600.0  # CPU seconds of a grading's zygote itself (each run it forks sets its own limit)
SETUP_SECONDS = 120.0  # for a zygote to import what every run needs
LOST_WORDS = "the grading's sandbox was lost"
IDLE_SECONDS = 10.0  # an idle zygote ends after this long


class ZygoteLost(ConnectionError):
    """The grading's zygote is gone, or broke its protocol: no later run of the grading runs."""


class Zygotes:
    """The zygotes of one ``Sandbox`` between its gradings: ``take`` gives a grading one that no other
    grading holds (an idle one made on the same template, else a new one, started by the spawner's
    thread, as bubblewrap's ``--die-with-parent`` needs: ``reference.spawn``); ``Zygote.release``
    gives it back. Idle ones end after ``IDLE_SECONDS``, and all of them with ``close``."""

    def __init__(self, sandbox):
        self.sandbox, self._idle, self._lock, self._timer = sandbox, [], threading.Lock(), None

    def take(self, template=None):
        """A zygote on the kit ``template`` ({relative path: text}) for one grading (``Budget.zygote``)."""
        key = kits.files_digest(template or {})
        while True:
            with self._lock:
                zygote = next((zygote for zygote in self._idle if zygote.key == key), None)
                if zygote is None:
                    return spawn(lambda: Zygote(self.sandbox, template, self, key))
                self._idle.remove(zygote)
            if zygote.process.process.poll() is None:  # its sandbox is still there
                return zygote
            zygote.close()

    def put(self, zygote):
        zygote.idle_since = time.monotonic()
        with self._lock:
            self._idle.append(zygote)
            if self._timer is None:
                self._timer = threading.Timer(IDLE_SECONDS, self._reap)
                self._timer.daemon = True
                self._timer.start()

    def _reap(self, everyone=False):
        now = time.monotonic()
        with self._lock:
            self._timer = None
            stale = [zygote for zygote in self._idle if everyone or now - zygote.idle_since >= IDLE_SECONDS]
            self._idle = [zygote for zygote in self._idle if zygote not in stale]
            if self._idle:
                self._timer = threading.Timer(IDLE_SECONDS, self._reap)
                self._timer.daemon = True
                self._timer.start()
        for zygote in stale:
            zygote.close()

    def close(self):
        """End every idle zygote (a later grading starts new ones)."""
        self._reap(everyone=True)


class Zygote:
    """The grader's side of one grading's zygote (the module docstring): it forks the grading's runs
    of student code one at a time (the grading's ``turn``). Its ``/kit`` is the host folder
    ``kits``: ``template`` ({relative path: text}, compiled by the zygote) when it starts, then the
    kit of each run from the run's fork on. The requests and replies go over a Unix socket pair
    made before the sandbox (so no socket is made inside it), the run's three descriptors with the
    request; each reply has a deadline, and a zygote that misses one, or says a run's processes
    outlived its end, is killed with its whole sandbox: ``lost``, and every later run of the grading
    fails (fail closed)."""

    def __init__(self, sandbox, template=None, pool=None, key=None):
        self.sandbox, self.lost, self._ready, self._closed = sandbox, None, False, False
        self._pool, self.key, self._running = pool, key, False
        self._lock = threading.Lock()
        self._folder = tempfile.TemporaryDirectory(prefix="hwgrade-zygote-", ignore_cleanup_errors=True)
        self.kits = Path(self._folder.name) / "kit"
        self.kits.mkdir()
        self.kits.chmod(0o755)  # the mount's root: readable by a root grader's sandbox user (HOST_ID) too
        self.channel, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        try:
            self._held = dict(template or {})  # what /kit holds
            kits.write_files(self._held, self.kits)
            self.process = WorkerProcess(sandbox, self.kits, ZYGOTE_CPU, zygote=theirs.detach())
        except BaseException:
            self.channel.close()
            self._folder.cleanup()
            raise
        self.group = self.process.group

    def start(self, kit, time_limit, budget):
        """A run of student code on ``kit`` (a folder, or its files {relative path: text}) in the
        grading of ``budget``, forked at its ``begin``."""
        return ZygoteRun(self, kit, time_limit, budget)

    def _receive(self, seconds):
        self.channel.settimeout(seconds)
        data = self.channel.recv(4096)
        if not data:
            raise ConnectionError("the zygote closed its socket")
        return json.loads(data)

    def _start(self):
        """(lock held) Wait for the zygote's imports, once; else it is lost."""
        if self.lost is None and not self._ready:
            try:
                self._ready = self._receive(SETUP_SECONDS) == {"op": "ready"}
            except (OSError, ValueError):
                pass
            if not self._ready:
                self._lose("it did not start")

    def ready(self):
        """Wait for the zygote's imports (a run does before its turn and its clock)."""
        with self._lock:
            self._start()

    def ask(self, request, expect, fds=(), seconds=GONE_SECONDS):
        """The zygote's reply ``expect`` to ``request`` (with descriptors ``fds``) within ``seconds``:
        else it is lost (ZygoteLost)."""
        with self._lock:
            self._start()
            if self.lost is None:
                try:
                    socket.send_fds(self.channel, [json.dumps(request).encode()], list(fds))
                    reply = self._receive(seconds)
                    if isinstance(reply, dict) and reply.get("op") == expect:
                        return reply
                except (OSError, ValueError):
                    pass
                self._lose(f"it did not answer {request['op']!r}")
            raise ZygoteLost(f"{LOST_WORDS} ({self.lost})")

    def fork(self, files, fds, limits):
        """Make ``/kit`` hold the kit ``files`` alone and fork a run on it, its descriptors ``fds``
        (requests, answers, error stream) and ``limits`` (CPU seconds, address space, open files,
        file size)."""
        with self._lock:
            try:
                if self.lost is None:
                    self._running = True  # from here until its end says it is gone
                    kits.write_files(files, self.kits, self._held)
                    self._held = dict(files)
            except OSError as error:
                self._lose(f"its kit could not be put in ({error})")
        self.ask({"op": "run", "limits": limits}, "started", fds)

    def wait(self, seconds):
        """The run's exit code once it has exited, waiting ``seconds`` at most (None: still running)."""
        return self.ask({"op": "wait", "seconds": seconds}, "status", seconds=seconds + GONE_SECONDS)["code"]

    def end(self):
        """End the run: every process of it killed and gone (the zygote alone in its sandbox, or the
        sandbox gone); its exit code."""
        reply = self.ask({"op": "end"}, "ended")
        with self._lock:
            if reply.get("alone") is not True:
                self._lose("a run's process outlived its end")
            self._running = False
        return reply.get("code")

    def _lose(self, why):
        """(lock held) Kill the sandbox with every process in it; no later run begins here."""
        self.lost = self.lost or why
        if not self._closed:
            self._closed = True
            self.channel.close()  # the zygote's sign to exit
            self.process.finish(graceful=False)

    def release(self):
        """The grading is over: back to its pool for a later grading if every run of it has ended
        (alone, never lost), else ended."""
        with self._lock:
            idle = self._pool is not None and self.lost is None and not self._running
        self._pool.put(self) if idle else self.close()

    def close(self):
        with self._lock:
            self._lose("closed")
            self._folder.cleanup()


class ZygoteRun(WorkerProcess):
    """One run of student code forked by its grading's ``Zygote`` at its ``begin``: the same pipes,
    deadlines, turn, budget and answers as a run in a sandbox of its own."""

    def __init__(self, zygote, kit, time_limit, budget):  # noqa: PLW0231 - launched at its begin, by the zygote
        self._prepare(zygote.sandbox, time_limit, False, budget)
        self.zygote, self._forked, self._oom_kills = zygote, False, 0
        self.files = kits.read_files(kit) if isinstance(kit, (str, os.PathLike)) else dict(kit)
        self._stderr = tempfile.TemporaryFile()  # noqa: SIM115 - closed in finish
        requests, answers = os.pipe(), os.pipe()
        self._ends = [requests[0], answers[1]]  # the run's, handed to the zygote
        self._pipes = Pipes(open(requests[1], "wb", buffering=0), open(answers[0], "rb", buffering=0))  # noqa: SIM115

    def _close_ends(self):
        for fd in self._ends:
            os.close(fd)
        self._ends = []

    def begin(self):
        if self.begun:
            return
        try:
            self.zygote.ready()  # its imports, before the turn and the run's clock
            super().begin()
            group = self.zygote.group
            self._oom_kills = group.oom_kills() if group is not None and not self.zygote.lost else 0
            cpu, memory, files = (int(limit) for limit in self.sandbox.limits(self.time_limit, self.kind)[1])
            self.zygote.fork(self.files, self._ends + [self._stderr.fileno()], [cpu, memory, files, MAX_FILE_BYTES])
            self._forked = True
        finally:
            self._close_ends()  # the run's ends are the zygote's now (or no one's): the answers end at its end

    def receive(self, deadline=None):
        if not self._forked and self.zygote.lost:
            return f"lost:{LOST_WORDS}"
        return super().receive(deadline)

    def _cpu_limit_reached(self):
        try:
            code = self.zygote.wait(2.0)
        except ZygoteLost:
            return False
        group = self.zygote.group
        if group is not None and not self.zygote.lost and group.oom_kills() > self._oom_kills:
            return False  # killed for the sandbox's memory bound
        return code == -signal.SIGKILL  # the grader kills a forked run only at its end (the CPU limit: soft = hard)

    def finish(self, graceful=True):
        try:
            self._close_ends()
            self._pipes.end_requests()
            code = None
            if self._forked:
                try:
                    if graceful and self.begun:
                        self.zygote.wait(max(0.0, min(self.deadline - time.monotonic(), 10.0)))
                    code = self.zygote.end()
                except ZygoteLost:
                    pass
                group = self.zygote.group
                self.memory_peak = group.memory_peak() if group is not None and not self.zygote.lost else None
            self._pipes.close()
            return code, _tail(self._stderr), round(time.monotonic() - self.started, 3)
        finally:
            self._cleanup()
