"""Run the worker on a kit in a separate, sandboxed process, with limits, and talk to it.

Three ways to run it (``Sandbox.kind``), the strongest that works here chosen by ``isolation="auto"``:

``bwrap`` (bubblewrap, ``bwrap_sandbox.py``): the worker runs in new namespaces (no network, its own processes,
hostname and IPC), as an unprivileged user without capabilities (a root grader's: ``HOST_ID`` on the host, with
RLIMIT_NPROC, in a user namespace of the run's own: ``host_user_namespace``), and sees only:

* the operating system's ``/usr`` (and the ``/bin``, ``/lib`` links into it), read-only;
* the Python installation and the virtual environment that run it, read-only, at their paths;
* the kit under test (one composite copy of ``hwlib/``), read-only, as ``/kit``;
* the worker script, read-only, as ``/grader/worker.py``;
* a fresh, size-limited tmpfs as ``/tmp`` (its home is ``/tmp/home``), a private ``/proc`` and a
  minimal read-only ``/dev`` whose ``/dev/shm`` is a fresh tmpfs of 16 MiB;

and runs under the user fallback's seccomp filter (``confine.py``): it makes no file, socket or
namespace.

bubblewrap itself starts with an empty environment and reads its options from a pipe (``--args``),
so the sandbox's ``/proc/1`` (bubblewrap's init) shows neither the grader's environment nor the
host paths of the kit and the worker.

**Under bubblewrap a grading's runs of student code are forked by its zygote** (``Budget.zygote``;
``instructor/zygote.py`` holds it and the argument that each run stays what it was in a sandbox of
its own): one such sandbox per grading at a time (it serves its grader's gradings in turn), whose
PID 1 imports Python's packages and the grader's runtime once and forks each run when it begins. The user fallback keeps one process per run: its
runs are told apart by a user of their own, which a zygote would have to share or switch to (it
cannot without privileges). So do the trusted reference servers, which live across gradings.

``user`` (where bubblewrap cannot create namespaces, as in Docker's default seccomp profile, e.g.
Gradescope): an unprivileged user of its own per run, the same seccomp filter (no socket, no file
made anywhere), a private kit folder (``user_sandbox.py`` says what that does and does not hide).
The pool's users are for students' code: a trusted run (``start(..., trusted=True)``: a reference
server, no student code in its kit) is launched as ``none`` here, as the grader's own user
(``run_kind``).

``none``: a plain subprocess, with the same limits and messages but no isolation;
``Sandbox.isolated`` is then False and ``Sandbox.how`` says why. "auto" ends here where nothing
else works, but a ``Grader`` with a reference refuses to run students' code so
(``Grader.refusal``: fail closed); only the student edition's preview, or an explicit "none",
runs that way.

**A grading's runs take turns; gradings run side by side.** Sandboxes cannot hide every piece of
kernel state two live processes share: byte-range, OFD and flock locks on a file both bind
read-only, inotify on it, the timing of a shared CPU or cache. Hidden inputs are drawn from a secret
of each grading (``Grader.grade``), so what such a channel could carry between two gradings is
worth nothing (docs/grading.md says why), and the runs of different gradings overlap freely. Within
one grading they never do: every run of student code given the grading's ``Budget`` takes its
``turn``, so no run of a submission can answer for another run of it (every hidden run also comes
after all of the grading's visible runs: ``Grader.grade``). A run may be *started* early (its
sandbox made, Python, numpy, gymnasium and the grader's own runtime imported: trusted code only)
while another one executes, but it *begins* (``WorkerProcess.begin``, on the first message the
grader sends, before any code of the kit is imported) only once its grading's run before it has
ended and every process of it is dead: the sandbox's process-namespace init gone (bubblewrap), no
process of the sandbox left but its zygote (a grading's zygote), no process of the run's user left
(the user fallback). Trusted work runs alongside: the reference
servers (``trusted=True``, no student code), judging, reading submissions; so do the servers of a
preview's own kit (no hidden input: nothing to keep apart). A run's wall clock starts when it
begins. No lock file: nothing is shared between grading processes.

Every run has a CPU-time limit, an address-space limit, a file-size limit, an open-file limit
(``MAX_OPEN_FILES`` per process, which with the process limit bounds the pipes a run can fill)
(``prlimit`` before the worker starts, and again by the worker itself before it imports the kit),
and a wall-clock backstop (``WALL_FACTOR`` times the CPU limit plus ``WALL_SLACK``) against code
that sleeps or waits: a loaded machine slows a run down without turning it into a time-out. The runs of one
submission share a wall-clock ``Budget`` too: a run that begins with less of it left than its
backstop ends when the budget does, and one that begins with none left does not run. The worker's
error stream goes to a file, never a pipe, so a child that keeps it open cannot hold the grader;
every read of the answers and every write of a request ends at the run's deadline (each pipe has
a thread of its own, ``processes.Pipes``: Windows cannot ``select()`` a pipe), so a worker that
stops reading is killed then. At the end the whole sandbox is killed (the process namespace, the
run's user, or the process group and an environment token; on Windows the process tree, and on
macOS and Windows, without ``/proc``, no environment token is looked for). Windows has no CPU-time,
address-space, file-size or open-file limit: there the wall-clock backstop ends a run.

The grader's own process can be put under a memory limit too (``limit_own_memory``; the command
lines do), so that nothing a worker sends can take the trusted side down.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path

from hwtools.grade.in_sandbox.channel import ChannelTimeout
from hwtools.grade.in_sandbox.worker import set_limit
from hwtools.grade.kits import WORKER, worker_env, write_files
from hwtools.grade.processes import Pipes, kill_tree

try:  # macOS and Linux; Windows has none (its runs have no CPU or memory limit)
    import resource
except ImportError:
    resource = None
try:  # the instructor's kit (the student edition has no sandbox: hwtools/grade/instructor/ is not in it)
    from hwtools.grade.instructor.bwrap_sandbox import (bwrap_options, data_pipe, grader_makes_namespace,
                                                        host_user_namespace, options_pipe, probe_isolation,
                                                        readable_copy, sandbox_init, seccomp_program, wait_gone)
except ImportError:
    probe_isolation = None
NO_SANDBOX_HERE = "the student edition has no sandbox (the preview runs the student's own code, unsandboxed)"

GiB = 1024**3
DEFAULT_TIME_LIMIT = 60.0  # seconds of CPU time per worker run
DEFAULT_MEMORY_LIMIT = 1 * GiB  # address space per worker run
GRADER_MEMORY_LIMIT = 4 * GiB  # address space of the trusted grader itself (command lines)
WALL_FACTOR, WALL_SLACK = 3.0, 10.0  # the wall-clock backstop: WALL_FACTOR * CPU limit + WALL_SLACK
MAX_FILE_BYTES = 64 * 1024**2  # any one file a run writes (its error stream included)
MAX_OPEN_FILES = 16  # descriptors of each process of a run (the worker needs 7): bounds the pipes it holds
STDERR_TAIL = 4000  # characters of the worker's error stream kept
TOKEN_VARIABLE = "HWGRADE_SANDBOX"
KINDS = ("auto", "bwrap", "user", "none")
GONE_SECONDS = 30.0  # to wait for a killed sandbox's last process
BUDGET_WORDS = "the submission's time budget was used up"


_SURVIVORS = []  # set when a run's processes could not be killed: no run of student code begins after it
_LIVE = set()  # the runs of this process whose processes may be alive (end_every_run)


def end_every_run():
    """Kill every run this process started and has not ended, with all its processes (each in a session of its
    own, so the end of this process's own group misses them): for a grader told to stop (SIGTERM, the check
    cell's interrupt on macOS and Linux; on Windows the end of its process tree takes them)."""
    for worker in list(_LIVE):
        kill_tree(worker.process)


class Budget:
    """One grading's runs: the wall-clock seconds they may take together (each from its ``begin`` to
    its end; thread-safe; ``remaining()`` can go negative once spent), and its ``turn``, held by each
    of them from its ``begin`` until every process of it is dead. ``zygote``: the ``Zygote`` that forks
    its runs of student code (``instructor/zygote.py``), given back by ``close``."""

    def __init__(self, seconds, zygote=None):
        self.seconds, self.spent = float(seconds), 0.0
        self._lock, self.turn = threading.Lock(), threading.Lock()
        self.zygote = zygote

    def close(self):
        if self.zygote is not None:
            self.zygote.release()

    def remaining(self):
        with self._lock:
            return self.seconds - self.spent

    def spend(self, seconds):
        with self._lock:
            self.spent += seconds


def wall_limit(time_limit):
    """The wall-clock seconds a run of CPU limit ``time_limit`` may last at most."""
    return WALL_FACTOR * float(time_limit) + WALL_SLACK


def limit_own_memory(limit=GRADER_MEMORY_LIMIT):
    """Put this (the trusted) process under an address-space limit of ``limit`` bytes, unless a
    lower one is already set; returns the limit in force (None where the system has or takes no such
    limit: Windows, and macOS, which refuses a finite one: ``set_limit``)."""
    return set_limit("RLIMIT_AS", limit, hard=False)


class Sandbox:
    """Runs the worker on kits, isolated where it can be (``kind``, ``isolated``, ``how``).

    ``isolation``: "auto" (bubblewrap if it works, else the unprivileged-user fallback if it is set
    up, else a plain subprocess), "bwrap" or "user" (fail if that one does not work), or "none" (a
    plain subprocess, e.g. for benchmarks). ``time_limit``: CPU seconds per run (the wall clock
    is a backstop, ``wall_limit``); ``memory_limit``: bytes of address space per run.
    """

    def __init__(self, python=None, isolation="auto", time_limit=DEFAULT_TIME_LIMIT, memory_limit=DEFAULT_MEMORY_LIMIT):
        self.python = str(python or sys.executable)
        if isolation not in KINDS:
            raise ValueError(f"isolation must be one of {', '.join(map(repr, KINDS))}, got {isolation!r}")
        self.kind, self.how = "none", "isolation turned off (isolation='none')"
        reasons = []
        if isolation in ("auto", "bwrap"):
            works, how = probe_isolation(self.python) if probe_isolation else (False, NO_SANDBOX_HERE)
            if works:
                self.kind, self.how = "bwrap", how
            elif isolation == "bwrap":
                raise RuntimeError(f"no sandbox: {how}")
            reasons.append(how)
        if isolation in ("auto", "user") and self.kind == "none":
            try:
                from hwtools.grade.instructor import user_sandbox  # noqa: PLC0415 - also run as a command (python -m)
            except ImportError as error:  # Windows: no users to run code as
                works, how = False, f"not on this system ({error})"
            else:
                works, how = user_sandbox.probe(self.python)
            if works:
                self.kind, self.how = "user", f"{how} (bubblewrap: {reasons[0]})" if reasons else how
            elif isolation == "user":
                raise RuntimeError(f"no sandbox: {how}")
            reasons.append(f"no unprivileged-user fallback: {how}")
        if self.kind == "none" and isolation == "auto":
            self.how = "; ".join(reasons)
        self.isolated = self.kind != "none"
        self.time_limit = float(time_limit)
        self.memory_limit = int(memory_limit)
        if self.isolated:
            from hwtools.grade.instructor.cgroups import describe  # noqa: PLC0415 - Linux only

            self.how += "; " + describe(self.memory_limit)

    def run_kind(self, trusted=False):
        """How a run is launched: ``kind``, except that a trusted run (a reference server: no student
        code in it) under the user fallback is a plain subprocess of the grader's own user, so that
        it never shares a uid with a student's run and takes no user of the pool."""
        return "none" if trusted and self.kind == "user" else self.kind

    def limits(self, time_limit, kind=None):
        """prlimit's options and the worker's own limit arguments for a run of CPU limit ``time_limit``."""
        cpu = max(1, int(time_limit + 0.999))
        options = [f"--cpu={cpu}:{cpu + 2}", f"--as={self.memory_limit}", f"--fsize={MAX_FILE_BYTES}",
                   f"--nofile={MAX_OPEN_FILES}", "--core=0"]
        kind = kind or self.kind
        if kind == "user" or kind == "bwrap" and grader_makes_namespace():
            from hwtools.grade.instructor.user_sandbox import MAX_PROCESSES  # noqa: PLC0415

            options.append(f"--nproc={MAX_PROCESSES}")
        return options, [str(cpu), str(self.memory_limit), str(MAX_OPEN_FILES)]

    def command(self, kit_dir, time_limit, run_folder=None, kind=None, userns=None, program=None, zygote=None):
        """The command line of one run (``run_folder``: the user fallback's private folder; ``kind``:
        ``run_kind``'s, default ``self.kind``; ``userns``: bubblewrap's user namespace, where the
        grader makes it; ``program``: the descriptor bubblewrap reads the seccomp filter from;
        ``zygote``: the descriptor of a zygote's socket, for a grading's zygote, ``/grader/zygote.py``,
        instead of one run) and the options bubblewrap reads from a pipe (None for the other kinds)."""
        kind = kind or self.kind
        options, limits = self.limits(time_limit, kind)
        prlimit = [shutil.which("prlimit"), *options, "--"] if shutil.which("prlimit") else []
        if kind == "bwrap":
            arguments = ["/grader/worker.py", "/kit"] + limits if zygote is None else ["/grader/zygote.py", str(zygote)]
            return (prlimit + [shutil.which("bwrap"), "--args", "{fd}", "--info-fd", "{info}", "--",
                               os.path.abspath(self.python), "-B", "-s"] + arguments,
                    bwrap_options(self.python, kit_dir, program, userns, zygote is not None))
        if kind == "user":
            return prlimit + run_folder.command(self.python) + limits, None
        return prlimit + [self.python, "-B", "-s", str(WORKER), str(kit_dir)] + limits, None

    def start(self, kit, time_limit=None, trusted=False, budget=None):
        """Start one worker on ``kit`` (a folder, or the kit's files {relative path: text}, written once
        where the run reads them): a ``WorkerProcess`` to talk to (``send``/``receive``) and
        to end (``finish``, which also ends every process it started). Launching and limits live
        here; what the messages say is the caller's business. ``trusted``: the kit holds no student
        code (a reference server, ``run_kind``). ``budget``: the grading's ``Budget``: an untrusted
        run begins only when no other run of that grading is alive, and no other begins until every
        process of it is dead (the module docstring); with a zygote (``Budget.zygote``) it is forked there."""
        time_limit = float(time_limit or self.time_limit)
        if budget is not None and budget.zygote is not None and not trusted:
            return budget.zygote.start(kit, time_limit, budget)
        return WorkerProcess(self, kit, time_limit, trusted, budget)


class WorkerProcess:
    """One running worker: its standard input takes requests, its standard output gives answers,
    both npz messages (``worker.py``); its error stream goes to a file. ``deadline`` (monotonic
    seconds, the wall-clock backstop, counted from ``begin``) ends it at the latest."""

    def __init__(self, sandbox, kit_dir, time_limit, trusted=False, budget=None, zygote=None):
        self._prepare(sandbox, time_limit, trusted, budget)
        self._scratch = tempfile.TemporaryDirectory(prefix="hwgrade-run-", ignore_cleanup_errors=True)
        self._token = uuid.uuid4().hex
        env, cwd, fds, info, userns, program = {}, self._scratch.name, (), None, None, None
        try:
            if not isinstance(kit_dir, (str, os.PathLike)):  # the kit's files: written here, once
                kit_dir = write_files(kit_dir, Path(self._scratch.name) / "kit")
            elif self.kind == "bwrap" and zygote is None and grader_makes_namespace():
                kit_dir = readable_copy(kit_dir, self._scratch.name)  # the sandbox's user (HOST_ID) reads it
            if self.kind == "user":
                from hwtools.grade.instructor.user_sandbox import RunFolder  # noqa: PLC0415

                self._run_folder = RunFolder(kit_dir, WORKER)
                env, cwd = worker_env(str(self._run_folder.home)), str(self._run_folder.home)
            elif self.kind == "none":
                home = Path(self._scratch.name) / "home"
                home.mkdir()
                env = worker_env(str(home)) | {TOKEN_VARIABLE: self._token}
            if self.kind == "bwrap":
                program = data_pipe(seccomp_program())
                userns = host_user_namespace()
            command, options = sandbox.command(kit_dir, time_limit, self._run_folder, self.kind, userns, program, zygote)
            if self.kind != "none":  # the run as a whole bounded (processes, memory with tmpfs), where it can be
                from hwtools.grade.instructor.cgroups import RunGroup  # noqa: PLC0415 - Linux only

                self.group = RunGroup.make(sandbox.memory_limit)
                if self.group is not None:
                    command = self.group.wrap(command)
            if options is not None:
                info = os.pipe()
                fds = (options_pipe(options), info[1], program) + (() if userns is None else (userns,)) + \
                    (() if zygote is None else (zygote,))
                command = [part.replace("{fd}", str(fds[0])).replace("{info}", str(info[1])) for part in command]
            self._stderr = open(Path(self._scratch.name) / "stderr", "w+b")  # noqa: SIM115 - closed in finish
            try:
                self.process = subprocess.Popen(
                    command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._stderr, cwd=cwd, env=env,
                    start_new_session=True, close_fds=True, pass_fds=fds)
            finally:
                for fd in fds:
                    os.close(fd)
            _LIVE.add(self)
            self._pipes = Pipes(self.process.stdin, self.process.stdout)  # every read and write has a deadline
            if info is not None:
                self._init = sandbox_init(info[0], self.process.pid)
        except BaseException:
            self._cleanup()
            raise
        finally:
            if info is not None:
                os.close(info[0])
            for fd in () if fds else (program, userns, zygote):  # not handed to bubblewrap (an error before)
                if fd is not None:
                    os.close(fd)

    def _prepare(self, sandbox, time_limit, trusted, budget):
        """What every run holds before it is launched (here, or by a grading's zygote at its ``begin``)."""
        self.sandbox, self.time_limit, self.kind = sandbox, time_limit, sandbox.run_kind(trusted)
        self.budget, self.trusted = budget, trusted
        self.started = time.monotonic()
        self.deadline = self.started + wall_limit(time_limit)
        self.begun = self._holding = self._budget_bound = self._killed = False
        self._scratch = self._run_folder = self._init = self.group = None
        self.memory_peak = None  # bytes the whole run held at most, where it ran in a cgroup
        self.ended = threading.Event()  # set once the run's processes are gone (or given up on) and its turn is free

    def begin(self):
        """Start the run proper (once; ``send`` calls it): a run of a grading first waits for its
        turn, and its wall-clock limit (and the grading's budget) count from here. Raises
        ChannelTimeout when the budget is already spent: no code of the kit runs then."""
        if self.begun:
            return
        if self.budget is not None and not self.trusted:
            self.budget.turn.acquire()
            self._holding = True
        if _SURVIVORS and not self.trusted:
            raise RuntimeError(f"no run begins: {_SURVIVORS[0]}")
        self.begun = True
        self.started = time.monotonic()
        limit = wall_limit(self.time_limit)
        if self.budget is not None:
            left = self.budget.remaining()
            if left < limit:
                limit, self._budget_bound = max(0.0, left), True
        self.deadline = self.started + limit
        if self._budget_bound and limit <= 0:
            raise ChannelTimeout(BUDGET_WORDS)

    def send(self, message, deadline=None):
        """Write one request by ``deadline`` (default and at the latest: the run's). Raises
        BrokenPipeError/OSError when the worker no longer reads, ChannelTimeout when it does not
        read in time."""
        self.begin()
        deadline = self.deadline if deadline is None else min(deadline, self.deadline)
        try:
            self._pipes.send(message, deadline)
        except ChannelTimeout:
            raise ChannelTimeout(BUDGET_WORDS if self._budget_bound else
                                 f"the wall-clock limit of {wall_limit(self.time_limit):.0f} s was reached "
                                 "(the worker stopped reading)") from None

    def receive(self, deadline=None):
        """The next answer (a dict), or "status:detail" (timeout, ended, garbled)."""
        deadline = self.deadline if deadline is None else min(deadline, self.deadline)
        answer = self._pipes.receive(deadline)
        if answer == "ended:" and self._cpu_limit_reached():
            return f"timeout:the CPU-time limit of {self.sandbox.limits(self.time_limit, self.kind)[1][0]} s was reached"
        if isinstance(answer, str) and answer.startswith("timeout:"):
            if self._budget_bound and time.monotonic() >= self.deadline:
                return f"timeout:{BUDGET_WORDS}"
            return f"timeout:the wall-clock limit of {wall_limit(self.time_limit):.0f} s was reached (the code waited)"
        return answer

    def _cpu_limit_reached(self):
        """Whether the worker, its answers' channel closed, was killed by SIGKILL that the grader did
        not send: the CPU-time limit (its soft and hard limits are equal)."""
        try:
            code = self.process.wait(timeout=2.0)
        except subprocess.TimeoutExpired:
            return False
        if self.group is not None and self.group.oom_kills():
            return False  # killed for the run's memory bound, not the CPU limit
        if resource is None:
            return False  # no CPU-time limit on this system
        return not self._killed and code in (-signal.SIGKILL, 128 + signal.SIGKILL)

    def finish(self, graceful=True):
        """End the worker and everything it started; (exit code, last lines of its error stream, seconds).
        ``graceful``: give it until the deadline to exit on its own (it was told to), else kill now.
        A grading's next run begins only once every process of this one is dead."""
        try:
            code = _finish(self, self.deadline if graceful and self.begun else time.monotonic())
            if self.kind == "none":
                _kill_strays(self._token)
            return code, _tail(self._stderr), round(time.monotonic() - self.started, 3)
        finally:
            self._cleanup()

    def _cleanup(self):
        try:
            gone = True
            if self._run_folder is not None:
                gone = self._run_folder.end()
            if self._init is not None:
                gone = wait_gone(self._init, GONE_SECONDS) and gone
                os.close(self._init)
                self._init = None
            if self.group is not None:
                self.memory_peak = self.group.memory_peak()
                gone = self.group.close() and gone
                self.group = None
            if not gone and not self.trusted:
                _SURVIVORS.append("a process or a file of an earlier run of student code could not be removed")
            stream = getattr(self, "_stderr", None)
            if stream is not None:
                stream.close()
            if self._scratch is not None:
                self._scratch.cleanup()
        finally:
            _LIVE.discard(self)
            budget = self.budget
            if self.begun and budget is not None:
                budget.spend(time.monotonic() - self.started)
                self.budget = None
            if self._holding:
                self._holding = False
                budget.turn.release()
            self.ended.set()


def _finish(worker, deadline):
    """Wait for the worker until ``deadline``, then kill its whole process group; the exit code."""
    process = worker.process
    worker._pipes.end_requests()
    try:
        process.wait(timeout=max(0.0, min(deadline - time.monotonic(), 10.0)))
    except subprocess.TimeoutExpired:
        pass
    if process.returncode is None:
        worker._killed = True
    kill_tree(process)
    try:  # SIGKILL from root ends a stopped process too: only a process stuck in the kernel stays
        code = process.wait(timeout=GONE_SECONDS)
    except subprocess.TimeoutExpired:
        code = None
        _SURVIVORS.append("a worker did not end after SIGKILL")
    worker._pipes.close()
    return code


def _tail(stream):
    """The last STDERR_TAIL characters of the error-stream file (read from the end: it may be large)."""
    size = os.fstat(stream.fileno()).st_size
    stream.seek(max(0, size - STDERR_TAIL * 4))
    return stream.read(STDERR_TAIL * 4).decode("utf-8", "replace")[-STDERR_TAIL:]


def _kill_strays(token, rounds=5):
    """Without a sandbox: kill every process that still carries this run's token in its
    environment (children that left the worker's process group), until a scan finds none. A
    child that clears its environment escapes this: only a sandbox ends every process. (Where there
    is no ``/proc``, macOS and Windows, the kill of the process group or tree is all there is.)"""
    if not os.path.isdir("/proc"):
        return
    needle = f"{TOKEN_VARIABLE}={token}".encode()
    for _ in range(rounds):
        killed = 0
        for entry in os.listdir("/proc"):
            if not entry.isdigit() or int(entry) == os.getpid():
                continue
            try:
                with open(f"/proc/{entry}/environ", "rb") as handle:
                    if needle in handle.read().split(b"\0"):
                        os.kill(int(entry), signal.SIGKILL)
                        killed += 1
            except OSError:
                continue
        if not killed:
            return
        time.sleep(0.05)
