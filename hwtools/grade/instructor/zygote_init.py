"""The zygote: PID 1 of one grading's bubblewrap sandbox, which forks the grading's runs one at a time.

``python /grader/zygote.py FD`` (bound read-only there, beside ``/grader/_hwgrade``, the grader's own
``in_sandbox/``; ``zygote.Zygote`` is the grader's side, and its docstring the argument). It
imports the trusted code every run needs (numpy, gymnasium, the grader's runtime) and compiles,
never runs, the kit ``/kit`` holds when it starts: the grader's template, every TODO a stub
(``compile_kit``). Then it serves the grader's requests on the Unix socket ``FD`` (JSON, one a
datagram): ``run`` (three descriptors: the run's requests, answers and error stream; its
``limits``) forks the run on the kit the grader has just put in ``/kit``, ``wait`` {seconds}
waits that long at most for its exit code, ``end`` kills every other process of the sandbox and
answers once none is left (``alone``). Non-dumpable, so no run can trace it or write its memory;
and as its namespace's init it gets no signal from a run but SIGCHLD, the one it catches
(``signal(7)``, ``pid_namespaces(7)``).

Standard library and ``_hwgrade`` only: this file runs in the sandbox, without ``hwtools``.
"""

from __future__ import annotations

import ctypes
import importlib
import importlib.machinery
import json
import os
import select
import signal
import socket
import sys
import time

from _hwgrade.worker import _serve, _set_limits

PR_SET_DUMPABLE = 4
END_SECONDS = 20.0  # for a run's processes to be gone after SIGKILL
KIT = "/kit"


def main(control):
    if os.getpid() != 1 or ctypes.CDLL(None, use_errno=True).prctl(PR_SET_DUMPABLE, 0, 0, 0, 0) != 0:
        return 4
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # Python's handler would let a run's SIGINT through
    wake, woken = os.pipe()
    os.set_blocking(wake, False)
    os.set_blocking(woken, False)
    signal.set_wakeup_fd(woken)
    signal.signal(signal.SIGCHLD, lambda *_: None)
    sys.dont_write_bytecode = True
    runtime = importlib.import_module("_hwgrade.runtime")  # /grader/_hwgrade: the grader's own, not the kit's
    runtime._warm()
    compile_kit(KIT)
    here = os.path.dirname(os.path.abspath(__file__))  # a run's path: its kit and the installation's
    sys.path[:] = [entry for entry in sys.path if entry and os.path.abspath(entry) != here]
    if os.listdir("/proc/self/task") != [str(os.getpid())]:
        return 5  # a fork copies one thread: the zygote must have no other
    channel = socket.socket(fileno=control)
    channel.send(b'{"op": "ready"}')
    run, code = None, None
    while True:
        if select.select([channel, wake], [], [])[0] != [channel]:
            code = _reap(run, code, wake)[0]
            continue
        data, fds, _, _ = socket.recv_fds(channel, 4096, 4)
        request = json.loads(data) if data else {"op": "exit"}
        op = request.get("op")
        if op == "run" and run is None and len(fds) == 3:
            run, code = os.fork(), None
            if run == 0:
                _run(runtime, fds, request["limits"], channel, (wake, woken))
            reply = {"op": "started"}
        elif op == "wait" and run is not None:
            give_up = time.monotonic() + float(request["seconds"])
            while code is None and time.monotonic() < give_up:
                select.select([wake], [], [], max(0.0, give_up - time.monotonic()))
                code = _reap(run, code, wake)[0]
            reply = {"op": "status", "code": code}
        elif op == "end":
            code, alone = _end(run, code)
            run = None
            reply = {"op": "ended", "code": code, "alone": alone}
        else:
            return 0 if op == "exit" else 6
        for fd in fds:
            os.close(fd)
        channel.send(json.dumps(reply).encode())


def compile_kit(kit):
    """Compile (never run) every module of the kit in ``kit``, the grader's template (each TODO a
    stub: no student's code and no reference solution), and have each run's imports take the
    compiled code of a file whose bytes are the template's, rather than compile it again (about
    three quarters of a run's import of ``hwlib``). A file that differs (the student's block) is
    compiled by the run itself. The code is the one the run would compile: the same bytes, path
    and flags (``SourceLoader.source_to_code``'s defaults); and a run changes only its own copy."""
    compiled = {}
    for folder, _, names in os.walk(kit):
        for name in names:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                with open(path, "rb") as handle:
                    data = handle.read()
                compiled[path] = (data, compile(data, path, "exec", dont_inherit=True))
    loader = importlib.machinery.SourceFileLoader
    original = loader.source_to_code

    def source_to_code(self, data, path, *args, **options):
        known = compiled.get(path)
        if known is not None and known[0] == data and not args and options.get("_optimize", -1) == -1:
            return known[1]
        return original(self, data, path, *args, **options)

    loader.source_to_code = source_to_code


def _reap(run, code, wake=None):
    """Reap every child that has exited (a run's orphans come to the sandbox's init, this process):
    (``run``'s exit code, whether no child is left)."""
    try:
        while wake is not None and os.read(wake, 512):
            pass
    except BlockingIOError:
        pass
    try:
        while True:
            pid, status = os.waitpid(-1, os.WNOHANG)
            if pid == 0:
                return code, False
            if pid == run:
                code = os.waitstatus_to_exitcode(status)
    except ChildProcessError:
        return code, True


def _end(run, code):
    """Kill every process of the sandbox but this one (``kill(-1)`` spares the caller and the namespace's
    init, both this process), again until none is left to reap; (the run's exit code, whether /proc
    then shows this process alone)."""
    give_up = time.monotonic() + END_SECONDS
    while time.monotonic() < give_up:
        try:
            os.kill(-1, signal.SIGKILL)
        except ProcessLookupError:
            pass
        code, none_left = _reap(run, code)
        if none_left:
            return code, [entry for entry in os.listdir("/proc") if entry.isdigit()] == ["1"]
        time.sleep(0.005)
    return code, False


def _run(runtime, fds, limits, channel, wakeup):
    """The forked run: nothing of the zygote's kept but its trusted modules and compiled template.
    Its descriptors are the grader's three and no other, its signals Python's, its limits set (CPU,
    address space, open files, file size) before any kit code is imported; then the worker's loop
    on ``/kit``, which holds this run's kit alone. Never returns."""
    code = 70
    try:
        signal.set_wakeup_fd(-1)
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        channel.close()
        for target, fd in enumerate(fds):
            os.dup2(fd, target)
        os.closerange(3, 1 << 20)
        # dumpable again (its own /proc files its own, as any process's), and the first the kernel
        # kills when the sandbox's memory runs out (raising it needs no privilege; the zygote stays 0)
        ctypes.CDLL(None).prctl(PR_SET_DUMPABLE, 1, 0, 0, 0)
        adjust = os.open("/proc/self/oom_score_adj", os.O_WRONLY)
        os.write(adjust, b"1000")
        os.close(adjust)
        _set_limits(*limits)
        if "numpy.random" in sys.modules:  # a fresh process's draw, not the zygote's state for every run
            sys.modules["numpy.random"].seed()
        requests, answers = _serve(KIT)
        code = runtime.main(KIT, requests, answers)
    finally:
        os._exit(code if isinstance(code, int) else 70)


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1])))
