"""Run the worker on a kit in a separate, sandboxed process, with limits, and talk to it.

With bubblewrap (``bwrap``) the worker runs in new namespaces (``--unshare-all``: no network, its
own processes, hostname and IPC), as an unprivileged user without capabilities, and sees only:

* the operating system's ``/usr`` (and the ``/bin``, ``/lib`` links into it), read-only;
* the Python installation and the virtual environment that run it, read-only;
* the kit under test (one composite copy of ``hwlib/``), read-only, as ``/kit``;
* the worker script, read-only, as ``/grader/worker.py``;
* a fresh, size-limited tmpfs as ``/tmp`` (its home is ``/tmp/home``), a private ``/proc`` and a
  minimal ``/dev``.

Not the instructor's kit, its hidden checks, the reference solutions of other TODOs, the
submission folder, or the network. Inputs and answers cross through the worker's standard
input and output as npz messages (``worker.py``); nothing is written for the grader to read. Every
run has a CPU-time limit and an address-space limit (``prlimit`` before the worker starts, and
again by the worker itself before it imports the kit), and a wall-clock limit after which the
whole sandbox is killed; ``--die-with-parent`` and the private process namespace end every
process the student's code started (a fork that outlives the run dies with the sandbox).

Where ``bwrap`` is missing or cannot create namespaces, the worker runs as a plain subprocess
with the same limits and messages but without isolation; ``Sandbox.isolated`` is then False
and the reason is in ``Sandbox.how``.
"""

from __future__ import annotations

import functools
import json
import os
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from hwtools.grade import worker as protocol

WORKER = Path(__file__).resolve().with_name("worker.py")
GiB = 1024**3
DEFAULT_TIME_LIMIT = 60.0  # seconds of wall clock per worker run
DEFAULT_MEMORY_LIMIT = 1 * GiB  # address space per worker run
TMPFS_BYTES = 64 * 1024**2
STDERR_TAIL = 4000  # characters of the worker's error stream kept
TOKEN_VARIABLE = "HWGRADE_SANDBOX"


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


@functools.lru_cache(maxsize=None)
def installed_kit(python):
    """Where ``python`` would import ``hwlib`` from outside any kit folder, if it is a copy inside
    its own installation (``pip install .`` without ``-e``): the sandbox could read that copy."""
    code = ("import importlib.util, os, sys; sys.path = [p for p in sys.path if p and os.path.isdir(p) and "
            "'site-packages' in p or p.startswith(sys.base_prefix)]; spec = importlib.util.find_spec('hwlib'); "
            "print(os.path.realpath(spec.origin) if spec and spec.origin else '')")
    try:
        origin = subprocess.run([python, "-I", "-c", code], capture_output=True, text=True, timeout=60,
                                cwd="/").stdout.strip()
    except (OSError, subprocess.TimeoutExpired):
        return ""
    return origin if origin and any(origin.startswith(path + os.sep) for path in python_paths(python)) else ""


@functools.lru_cache(maxsize=None)
def python_paths(python):
    """The folders a Python needs: its prefix (the venv), base prefix (the installation) and the
    folder of the real executable."""
    code = ("import sys, json, os; print(json.dumps([sys.prefix, sys.base_prefix, sys.exec_prefix, "
            "sys.base_exec_prefix, os.path.dirname(os.path.realpath(sys.executable))]))")
    output = subprocess.run([python, "-I", "-c", code], capture_output=True, text=True, check=True, timeout=60).stdout
    return tuple(dict.fromkeys(os.path.realpath(path) for path in json.loads(output)))


def _system_binds():
    args = ["--ro-bind", "/usr", "/usr"]
    for name in ("bin", "sbin", "lib", "lib32", "lib64", "libx32"):
        path = Path("/") / name
        if path.is_symlink():
            args += ["--symlink", os.readlink(path), str(path)]
        elif path.is_dir():
            args += ["--ro-bind", str(path), str(path)]
    return args


def bwrap_command(python, kit_dir, worker=WORKER):
    """The bubblewrap command line that runs ``worker`` on ``kit_dir`` (without the worker's arguments)."""
    args = ["bwrap", "--unshare-all", "--unshare-user", "--uid", "65534", "--gid", "65534", "--cap-drop", "ALL",
            "--die-with-parent", "--new-session", "--hostname", "sandbox"]
    args += _system_binds()
    # /tmp first: a Python installed under /tmp (a CI checkout there) is bound on top of it, not hidden by it
    args += ["--proc", "/proc", "--dev", "/dev", "--size", str(TMPFS_BYTES), "--tmpfs", "/tmp", "--dir", "/tmp/home"]
    for path in python_paths(python):
        if not path.startswith("/usr/"):
            args += ["--ro-bind", path, path]
    venv_python = os.path.abspath(python)
    args += ["--ro-bind", str(kit_dir), "/kit", "--ro-bind", str(worker), "/grader/worker.py",
             "--chdir", "/tmp", "--clearenv"]
    for key, value in _worker_env("/tmp/home").items():
        args += ["--setenv", key, value]
    return args + ["--", venv_python, "-B", "-s", "/grader/worker.py", "/kit"]


def _worker_env(home):
    return {"PATH": "/usr/bin:/bin", "HOME": home, "TMPDIR": "/tmp" if home.startswith("/tmp/") else home,
            "LANG": "C.UTF-8", "MPLBACKEND": "Agg", "PYTHONHASHSEED": "0", "PYTHONDONTWRITEBYTECODE": "1",
            "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


@functools.lru_cache(maxsize=None)
def probe_isolation(python):
    """(True, how) if bwrap can run ``python`` in new namespaces here, else (False, why not)."""
    if shutil.which("bwrap") is None:
        return False, "bubblewrap (bwrap) is not installed (Debian/Ubuntu: apt-get install bubblewrap)"
    with tempfile.TemporaryDirectory(prefix="hwgrade-probe-") as kit:
        command = bwrap_command(python, kit)
        command = command[:command.index("--") + 1] + [os.path.abspath(python), "-c", "import numpy"]
        try:
            result = subprocess.run(command, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
        except (OSError, subprocess.TimeoutExpired) as error:
            return False, f"bwrap could not start: {error}"
    if result.returncode != 0:
        reason = " ".join(result.stderr.split())[:300]
        return False, f"bwrap cannot create a sandbox here ({reason or 'exit code ' + str(result.returncode)})"
    version = subprocess.run(["bwrap", "--version"], capture_output=True, text=True).stdout.strip()
    how = f"{version or 'bubblewrap'}: no network, read-only Python and kit, private /tmp, /proc and users"
    copy = installed_kit(python)
    if copy:
        how += (f"; WARNING: {python} has a copy of hwlib installed at {os.path.dirname(copy)} (pip install "
                "without -e), which the sandbox can read: reinstall with pip install -e .")
    return True, how


class Sandbox:
    """Runs the worker on kits, isolated where bubblewrap works (``isolated``, ``how``).

    ``isolation``: "auto" (bubblewrap if it works, else a plain subprocess), "bwrap" (fail if it
    does not work) or "none" (a plain subprocess, e.g. for benchmarks).
    """

    def __init__(self, python=None, isolation="auto", time_limit=DEFAULT_TIME_LIMIT, memory_limit=DEFAULT_MEMORY_LIMIT):
        self.python = str(python or sys.executable)
        if isolation not in ("auto", "bwrap", "none"):
            raise ValueError(f"isolation must be 'auto', 'bwrap' or 'none', got {isolation!r}")
        if isolation == "none":
            self.isolated, self.how = False, "isolation turned off (isolation='none')"
        else:
            self.isolated, self.how = probe_isolation(self.python)
            if isolation == "bwrap" and not self.isolated:
                raise RuntimeError(f"no sandbox: {self.how}")
        self.time_limit = float(time_limit)
        self.memory_limit = int(memory_limit)

    def command(self, kit_dir, time_limit):
        cpu = max(1, int(time_limit + 0.999))
        limits = [str(cpu), str(self.memory_limit)]
        if self.isolated:
            command = bwrap_command(self.python, kit_dir) + limits
        else:
            command = [self.python, "-B", "-s", str(WORKER), str(kit_dir)] + limits
        if shutil.which("prlimit"):
            command = ["prlimit", f"--cpu={cpu}:{cpu + 2}", f"--as={self.memory_limit}", "--"] + command
        return command

    def start(self, kit_dir, time_limit=None):
        """Start one worker on ``kit_dir``: a ``WorkerProcess`` to talk to (``send``/``receive``) and
        to end (``finish``, which also ends every process it started). Launching and limits live
        here; what the messages say is the caller's business."""
        return WorkerProcess(self, kit_dir, float(time_limit or self.time_limit))

    def run(self, kit_dir, requests, time_limit=None):
        """Run the cases of ``requests`` (each ``{"cases": [{id, probe, args}, ...]}``) on a worker on
        ``kit_dir``, one by one, with the grader's protocol (``broker.run_cases``; no function is
        served); the grader's runtime is copied into the kit if it is not there. Returns a RunOutcome
        whose ``answers[i]["results"]`` answer ``requests[i]``. For tests: the grader drives its runs
        itself (``grader.py``)."""
        from hwtools.grade import broker, reference  # noqa: PLC0415 - the loop is the broker's; it does not import this module

        for relative, text in reference.runtime_files().items():
            target = Path(kit_dir) / relative
            if not target.exists():
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_text(text, encoding="utf-8")
        cases = [(case["id"], case["probe"], case["args"]) for request in requests for case in request["cases"]]
        ran, results = broker.run_cases(self.start(kit_dir, time_limit), None, cases, [], None)
        outcome = RunOutcome(status=ran.status, detail=ran.detail, stderr_tail=ran.stderr_tail, seconds=ran.seconds,
                             exit_code=ran.exit_code)
        for request in requests:
            answered = [dict(results[case["id"]], id=case["id"]) for case in request["cases"] if case["id"] in results]
            if len(answered) < len(request["cases"]):
                break
            outcome.answers.append({"results": answered})
        return outcome


class WorkerProcess:
    """One running worker: its standard input takes requests, its standard output gives answers,
    both npz messages (``worker.py``). ``deadline`` (monotonic seconds) ends it at the latest."""

    def __init__(self, sandbox, kit_dir, time_limit):
        self.sandbox, self.time_limit = sandbox, time_limit
        self.started = time.monotonic()
        self.deadline = self.started + time_limit
        self._scratch = tempfile.TemporaryDirectory(prefix="hwgrade-run-")
        self._token = uuid.uuid4().hex
        env = None
        if not sandbox.isolated:
            home = Path(self._scratch.name) / "home"
            home.mkdir()
            env = _worker_env(str(home)) | {TOKEN_VARIABLE: self._token}
        self.process = subprocess.Popen(
            sandbox.command(kit_dir, time_limit), stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            cwd=self._scratch.name, env=env, start_new_session=True, close_fds=True)
        self._tail = _Tail(self.process.stderr)

    def send(self, message):
        """Write one request (raises BrokenPipeError/OSError when the worker no longer reads)."""
        protocol.write_message(self.process.stdin.fileno(), message)

    def receive(self, deadline=None):
        """The next answer (a dict), or "status:detail" (timeout, ended, garbled)."""
        return _read_answer(self.process.stdout.fileno(), self.deadline if deadline is None else min(deadline, self.deadline))

    def finish(self, graceful=True):
        """End the worker and everything it started; (exit code, last lines of its error stream, seconds).
        ``graceful``: give it until the deadline to exit on its own (it was told to), else kill now."""
        try:
            code = _finish(self.process, self.deadline if graceful else time.monotonic())
            if not self.sandbox.isolated:
                _kill_strays(self._token)
            self._tail.join()
            return code, self._tail.text(), round(time.monotonic() - self.started, 3)
        finally:
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


def _finish(process, deadline):
    """Wait for the worker until ``deadline``, then kill its whole process group; the exit code."""
    try:
        process.stdin.close()
    except OSError:
        pass
    try:
        process.wait(timeout=max(0.0, min(deadline - time.monotonic(), 10.0)))
    except subprocess.TimeoutExpired:
        pass
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    code = process.wait()
    process.stdout.close()
    return code


def _kill_strays(token, rounds=5):
    """Without a sandbox: kill every process that still carries this run's token in its
    environment (children that left the worker's process group), until a scan finds none."""
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


class _Tail:
    """Reads a stream to its end in a thread, keeping only its last STDERR_TAIL characters."""

    def __init__(self, stream):
        self._stream, self._data = stream, b""
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self):
        try:
            for chunk in iter(lambda: self._stream.read1(65536), b""):
                self._data = (self._data + chunk)[-STDERR_TAIL * 4:]
        except (OSError, ValueError):
            pass

    def join(self):
        self._thread.join(timeout=5)
        try:
            self._stream.close()
        except OSError:
            pass

    def text(self):
        return self._data.decode("utf-8", "replace")[-STDERR_TAIL:]
