"""Run the worker on a kit in a separate, sandboxed process, with limits, and talk to it.

Three ways to run it (``Sandbox.kind``), the strongest that works here chosen by ``isolation="auto"``:

``bwrap`` (bubblewrap, ``bwrap_sandbox.py``): the worker runs in new namespaces (``--unshare-all``: no network, its own
processes, hostname and IPC), as an unprivileged user without capabilities, and sees only:

* the operating system's ``/usr`` (and the ``/bin``, ``/lib`` links into it), read-only;
* the Python installation and the virtual environment that run it, read-only, at their paths;
* the kit under test (one composite copy of ``hwlib/``), read-only, as ``/kit``;
* the worker script, read-only, as ``/grader/worker.py``;
* a fresh, size-limited tmpfs as ``/tmp`` (its home is ``/tmp/home``), a private ``/proc`` and a
  minimal ``/dev``.

bubblewrap itself starts with an empty environment and reads its options from a pipe (``--args``),
so the sandbox's ``/proc/1`` (bubblewrap's init) shows neither the grader's environment nor the
host paths of the kit and the worker.

``user`` (where bubblewrap cannot create namespaces, as in Docker's default seccomp profile, e.g.
Gradescope): an unprivileged user of its own per run, no network sockets, a private kit folder
(``user_sandbox.py`` says what that does and does not hide).

``none``: a plain subprocess, with the same limits and messages but no isolation;
``Sandbox.isolated`` is then False and ``Sandbox.how`` says why.

Every run has a CPU-time limit, an address-space limit, a file-size limit (``prlimit`` before the
worker starts, and again by the worker itself before it imports the kit), and a wall-clock
backstop (``WALL_FACTOR`` times the CPU limit plus ``WALL_SLACK``) against code that sleeps or
waits: a loaded machine slows a run down without turning it into a time-out. The worker's error
stream goes to a file, never a pipe, so a child that keeps it open cannot hold the grader; every
read of the answers is bounded by the deadline. At the end the whole sandbox is killed (the
process namespace, the run's user, or the process group and an environment token).

The grader's own process can be put under a memory limit too (``limit_own_memory``; the command
lines do), so that nothing a worker sends can take the trusted side down.
"""

from __future__ import annotations

import os
import resource
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from hwtools.grade import worker as protocol
from hwtools.grade.bwrap_sandbox import bwrap_options, options_pipe, probe_isolation, worker_env

WORKER = Path(__file__).resolve().with_name("worker.py")
GiB = 1024**3
DEFAULT_TIME_LIMIT = 60.0  # seconds of CPU time per worker run
DEFAULT_MEMORY_LIMIT = 1 * GiB  # address space per worker run
GRADER_MEMORY_LIMIT = 4 * GiB  # address space of the trusted grader itself (command lines)
WALL_FACTOR, WALL_SLACK = 3.0, 10.0  # the wall-clock backstop: WALL_FACTOR * CPU limit + WALL_SLACK
MAX_FILE_BYTES = 64 * 1024**2  # any one file a run writes (its error stream included)
STDERR_TAIL = 4000  # characters of the worker's error stream kept
TOKEN_VARIABLE = "HWGRADE_SANDBOX"
KINDS = ("auto", "bwrap", "user", "none")


@dataclass
class RunOutcome:
    """What came back from one worker run: ``answers[i]`` answers ``requests[i]`` (fewer if the run
    ended early). ``status``: ok, timeout, ended (the worker stopped before answering everything),
    or garbled (an answer that is not a valid message)."""

    answers: list = field(default_factory=list)
    status: str = "ok"
    detail: str = ""
    stderr_tail: str = ""
    seconds: float = 0.0
    exit_code: int | None = None


def wall_limit(time_limit):
    """The wall-clock seconds a run of CPU limit ``time_limit`` may last at most."""
    return WALL_FACTOR * float(time_limit) + WALL_SLACK


def limit_own_memory(limit=GRADER_MEMORY_LIMIT):
    """Put this (the trusted) process under an address-space limit of ``limit`` bytes, unless a
    lower one is already set; returns the limit in force."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    if soft == resource.RLIM_INFINITY or soft > limit:
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
        soft = limit
    return soft


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
            works, how = probe_isolation(self.python)
            if works:
                self.kind, self.how = "bwrap", how
            elif isolation == "bwrap":
                raise RuntimeError(f"no sandbox: {how}")
            reasons.append(how)
        if isolation in ("auto", "user") and self.kind == "none":
            from hwtools.grade import user_sandbox  # noqa: PLC0415 - also run as a command (python -m)

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

    def limits(self, time_limit):
        """prlimit's options and the worker's own limit arguments for a run of CPU limit ``time_limit``."""
        cpu = max(1, int(time_limit + 0.999))
        options = [f"--cpu={cpu}:{cpu + 2}", f"--as={self.memory_limit}", f"--fsize={MAX_FILE_BYTES}"]
        if self.kind == "user":
            from hwtools.grade.user_sandbox import MAX_PROCESSES  # noqa: PLC0415

            options.append(f"--nproc={MAX_PROCESSES}")
        return options, [str(cpu), str(self.memory_limit)]

    def command(self, kit_dir, time_limit, run_folder=None):
        """The command line of one run (``run_folder``: the user fallback's private folder) and the
        options bubblewrap reads from a pipe (None for the other kinds)."""
        options, limits = self.limits(time_limit)
        prlimit = [shutil.which("prlimit"), *options, "--"] if shutil.which("prlimit") else []
        if self.kind == "bwrap":
            return (prlimit + [shutil.which("bwrap"), "--args", "{fd}", "--", os.path.abspath(self.python), "-B", "-s",
                               "/grader/worker.py", "/kit"] + limits, bwrap_options(self.python, kit_dir))
        if self.kind == "user":
            return prlimit + run_folder.command(self.python) + limits, None
        return prlimit + [self.python, "-B", "-s", str(WORKER), str(kit_dir)] + limits, None

    def start(self, kit_dir, time_limit=None):
        """Start one worker on ``kit_dir``: a ``WorkerProcess`` to talk to (``send``/``receive``) and
        to end (``finish``, which also ends every process it started). Launching and limits live
        here; what the messages say is the caller's business."""
        return WorkerProcess(self, kit_dir, float(time_limit or self.time_limit))

    def run(self, kit_dir, requests, time_limit=None):
        """Send ``requests`` (each ``{"cases": [...]}``) one after the other to a worker on
        ``kit_dir``; the next is sent only when the previous one is answered. Returns a RunOutcome."""
        worker = self.start(kit_dir, time_limit)
        outcome = RunOutcome()
        try:
            for request in requests:
                worker.send(request)
                answer = worker.receive()
                if isinstance(answer, str):
                    outcome.status, outcome.detail = answer.split(":", 1)
                    break
                if not isinstance(answer.get("results"), list):
                    outcome.status, outcome.detail = "garbled", "an answer without results"
                    break
                outcome.answers.append(answer)
            else:
                worker.send({"op": "exit"})
        except (BrokenPipeError, OSError):
            outcome.status, outcome.detail = "ended", "the worker stopped reading its requests"
        finally:
            outcome.exit_code, outcome.stderr_tail, outcome.seconds = worker.finish(graceful=outcome.status == "ok")
        if outcome.status == "ended":
            outcome.detail = _ended_detail(outcome.exit_code, outcome.detail)
        return outcome


class WorkerProcess:
    """One running worker: its standard input takes requests, its standard output gives answers,
    both npz messages (``worker.py``); its error stream goes to a file. ``deadline`` (monotonic
    seconds, the wall-clock backstop) ends it at the latest."""

    def __init__(self, sandbox, kit_dir, time_limit):
        self.sandbox, self.time_limit = sandbox, time_limit
        self.started = time.monotonic()
        self.deadline = self.started + wall_limit(time_limit)
        self._killed = False
        self._scratch = tempfile.TemporaryDirectory(prefix="hwgrade-run-")
        self._token = uuid.uuid4().hex
        self._run_folder = None
        env, cwd, fds = {}, self._scratch.name, ()
        try:
            if sandbox.kind == "user":
                from hwtools.grade.user_sandbox import RunFolder  # noqa: PLC0415

                self._run_folder = RunFolder(kit_dir, WORKER)
                env, cwd = worker_env(str(self._run_folder.home)), str(self._run_folder.home)
            elif sandbox.kind == "none":
                home = Path(self._scratch.name) / "home"
                home.mkdir()
                env = worker_env(str(home)) | {TOKEN_VARIABLE: self._token}
            command, options = sandbox.command(kit_dir, time_limit, self._run_folder)
            if options is not None:
                fds = (options_pipe(options),)
                command = [part.replace("{fd}", str(fds[0])) for part in command]
            self._stderr = open(Path(self._scratch.name) / "stderr", "w+b")  # noqa: SIM115 - closed in finish
            try:
                self.process = subprocess.Popen(
                    command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._stderr, cwd=cwd, env=env,
                    start_new_session=True, close_fds=True, pass_fds=fds)
            finally:
                for fd in fds:
                    os.close(fd)
        except BaseException:
            self._cleanup()
            raise

    def send(self, message):
        """Write one request (raises BrokenPipeError/OSError when the worker no longer reads)."""
        protocol.write_message(self.process.stdin.fileno(), message)

    def receive(self, deadline=None):
        """The next answer (a dict), or "status:detail" (timeout, ended, garbled)."""
        deadline = self.deadline if deadline is None else min(deadline, self.deadline)
        answer = _read_answer(self.process.stdout.fileno(), deadline)
        if answer == "ended:" and self._cpu_limit_reached():
            return f"timeout:the CPU-time limit of {self.sandbox.limits(self.time_limit)[1][0]} s was reached"
        if isinstance(answer, str) and answer.startswith("timeout:"):
            return f"timeout:the wall-clock limit of {wall_limit(self.time_limit):.0f} s was reached (the code waited)"
        return answer

    def _cpu_limit_reached(self):
        """Whether the worker, its answers' channel closed, was killed by SIGKILL that the grader did
        not send: the CPU-time limit (its soft and hard limits are equal)."""
        try:
            code = self.process.wait(timeout=2.0)
        except subprocess.TimeoutExpired:
            return False
        return not self._killed and code in (-signal.SIGKILL, 128 + signal.SIGKILL)

    def finish(self, graceful=True):
        """End the worker and everything it started; (exit code, last lines of its error stream, seconds).
        ``graceful``: give it until the deadline to exit on its own (it was told to), else kill now."""
        try:
            code = _finish(self, self.deadline if graceful else time.monotonic())
            if self.sandbox.kind == "none":
                _kill_strays(self._token)
            if self._run_folder is not None:
                self._run_folder.end()
            return code, _tail(self._stderr), round(time.monotonic() - self.started, 3)
        finally:
            self._cleanup()

    def _cleanup(self):
        if self._run_folder is not None:
            self._run_folder.end()
        stream = getattr(self, "_stderr", None)
        if stream is not None:
            stream.close()
        self._scratch.cleanup()


def _read_answer(fd, deadline):
    """The next message on ``fd``, or "status:detail" if none comes in time or it is not valid."""
    buffer = b""
    need = 8
    length = None
    while True:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return "timeout:the wall-clock limit was reached"
        ready, _, _ = select.select([fd], [], [], remaining)
        if not ready:
            continue
        chunk = os.read(fd, min(1 << 20, need - len(buffer)))
        if not chunk:
            return "ended:"
        buffer += chunk
        if len(buffer) < need:
            continue
        if length is None:
            length = int.from_bytes(buffer[:8], "big")
            if length > protocol.MAX_MESSAGE_BYTES:
                return f"garbled:an answer of {length} bytes, more than the {protocol.MAX_MESSAGE_BYTES} accepted"
            buffer, need = b"", length
            if length == 0:
                return "garbled:an empty answer"
            continue
        try:
            answer = protocol.unpack(buffer)
        except Exception as error:  # noqa: BLE001 - anything the worker's side wrote is untrusted
            return f"garbled:an answer that is not a valid message ({type(error).__name__})"
        if not isinstance(answer, dict):
            return "garbled:an answer that is not a message"
        return answer


def _finish(worker, deadline):
    """Wait for the worker until ``deadline``, then kill its whole process group; the exit code."""
    process = worker.process
    try:
        process.stdin.close()
    except OSError:
        pass
    try:
        process.wait(timeout=max(0.0, min(deadline - time.monotonic(), 10.0)))
    except subprocess.TimeoutExpired:
        pass
    if process.returncode is None:
        worker._killed = True
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    code = process.wait()
    process.stdout.close()
    return code


def _tail(stream):
    """The last STDERR_TAIL characters of the error-stream file (read from the end: it may be large)."""
    size = os.fstat(stream.fileno()).st_size
    stream.seek(max(0, size - STDERR_TAIL * 4))
    return stream.read(STDERR_TAIL * 4).decode("utf-8", "replace")[-STDERR_TAIL:]


def _kill_strays(token, rounds=5):
    """Without a sandbox: kill every process that still carries this run's token in its
    environment (children that left the worker's process group), until a scan finds none. A
    child that clears its environment escapes this: only a sandbox ends every process."""
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


def _ended_detail(code, detail):
    if detail:
        return detail
    if code is None:
        return "the worker ended before answering"
    if code > 128 and code - 128 in signal.Signals._value2member_map_:  # bubblewrap passes a signal on as 128 + it
        code = 128 - code
    if code < 0:
        name = signal.Signals(-code).name if -code in signal.Signals._value2member_map_ else str(-code)
        why = {"SIGXCPU": " (the CPU-time limit)", "SIGKILL": " (killed: a limit was reached)",
               "SIGXFSZ": " (the file-size limit: too much output?)"}.get(name, "")
        return f"the worker was ended by {name}{why} before answering"
    return f"the worker ended with exit code {code} before answering (sys.exit or os._exit in the code?)"
