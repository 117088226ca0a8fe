"""The entry point of every sandboxed grading process: ``python worker.py KIT_DIR [CPU_SECONDS MEMORY_BYTES OPEN_FILES]``,
or ``python worker.py --zygote FD``.

It sets its own limits, keeps its standard input and output for the grader's messages (and
sends whatever the homework prints to the error stream instead), puts ``KIT_DIR`` first on its
path and hands over to the loop the grader copied into that kit (``KIT_DIR/_hwgrade/runtime.py``,
see ``runtime.py``): a process is the student's worker or the reference server according to
the first message it gets. This file must run on its own (the sandbox mounts it alone as
``/grader/worker.py``), so it imports nothing of ``hwtools``.

``--zygote FD`` (``zygote``): the init (PID 1) of one grading's bubblewrap sandbox. It imports the
trusted code every run needs (numpy, gymnasium, the grader's own runtime, from ``/grader/_hwgrade``:
no kit code), then forks one run at a time on the grader's request over the Unix socket ``FD``
(``sandbox.Zygote`` is the grader's side, and its docstring the argument).
"""

from __future__ import annotations

import os
import sys
import time


def set_limit(name, value, hard=True):
    """Put this process under the resource limit ``name`` (``"RLIMIT_AS"``, ``"RLIMIT_CPU"``, ...) of ``value``,
    never above the hard limit in force: soft and hard both (``hard``), else the soft limit alone, and only
    where it is higher. The one way the student's side sets a limit. Returns the soft limit then in force, or
    None where this system enforces no such limit: no ``resource`` module (Windows), no such limit, or the
    system refuses it (macOS refuses a finite RLIMIT_AS or RLIMIT_DATA: ``ValueError``, cpython#78783), said
    by no message: the grader's wall clock still ends a run."""
    try:
        import resource  # noqa: PLC0415
    except ImportError:
        return None
    which = getattr(resource, name, None)
    if which is None:
        return None
    try:
        soft, top = resource.getrlimit(which)
        value = value if top == resource.RLIM_INFINITY else min(value, top)
        if hard:
            resource.setrlimit(which, (value, value))
            return value
        if soft == resource.RLIM_INFINITY or soft > value:
            resource.setrlimit(which, (value, top))
            soft = value
        return soft
    except (ValueError, OSError):
        return None


def _set_limits(cpu_seconds, memory_bytes, open_files, file_bytes=0):
    for name, value in (("RLIMIT_CPU", cpu_seconds), ("RLIMIT_AS", memory_bytes), ("RLIMIT_NOFILE", open_files),
                        ("RLIMIT_FSIZE", file_bytes)):
        if value:
            set_limit(name, value)


def _serve(kit_dir):
    """Keep standard input and output for the grader's messages (the homework's prints go to the error
    stream, never into the answers), put ``kit_dir`` first on the path: (requests, answers)."""
    requests, answers = os.dup(0), os.dup(1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    script_dir = os.path.dirname(os.path.abspath(__file__))
    sys.path[:] = [kit_dir] + [entry for entry in sys.path if entry and os.path.abspath(entry) != script_dir]
    sys.dont_write_bytecode = True
    return requests, answers


def main(argv):
    if argv[1] == "--zygote":
        return zygote(int(argv[2]))
    kit_dir = os.path.realpath(argv[1])
    _set_limits(*(int(argv[index]) if len(argv) > index else 0 for index in (2, 3, 4)))
    requests, answers = _serve(kit_dir)
    import importlib  # noqa: PLC0415

    runtime = importlib.import_module("_hwgrade.runtime")
    if not os.path.realpath(runtime.__file__).startswith(kit_dir + os.sep):
        print("the grader's runtime was not found in the kit", file=sys.stderr)
        return 3
    return runtime.main(kit_dir, requests, answers)


# --------------------------------------------------------------------------------------------
# The zygote: one grading's sandbox, its runs forked one at a time
# --------------------------------------------------------------------------------------------

PR_SET_DUMPABLE = 4
END_SECONDS = 20.0  # for a run's processes to be gone after SIGKILL


def zygote(control):
    """Serve the grader's requests on the Unix socket ``control`` (JSON, one a datagram), as the
    sandbox's PID 1: ``run`` (three descriptors: the run's requests, answers and error stream; its
    ``limits``) forks the run, ``wait`` {seconds} waits that long at most for its exit code, ``end``
    kills every other process of the sandbox and answers once none is left (``alone``). Non-dumpable,
    so no run can trace it or write its memory; and as its namespace's init it gets no signal from a
    run but SIGCHLD, the one it catches (``signal(7)``, ``pid_namespaces(7)``)."""
    if sys.platform != "linux":  # a zygote is PID 1 of a Linux sandbox (bubblewrap), nowhere else
        raise OSError(f"no zygote on {sys.platform}")
    import ctypes  # noqa: PLC0415
    import importlib  # noqa: PLC0415
    import json  # noqa: PLC0415
    import select  # noqa: PLC0415
    import signal  # noqa: PLC0415
    import socket  # noqa: PLC0415

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


def _reap(run, code, wake=None):
    """Reap every child that has exited (a run's orphans come to the sandbox's init, this process):
    (``run``'s exit code, whether no child is left)."""
    if sys.platform != "linux":  # a zygote is PID 1 of a Linux sandbox (bubblewrap), nowhere else
        raise OSError(f"no zygote on {sys.platform}")
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
    if sys.platform != "linux":  # a zygote is PID 1 of a Linux sandbox (bubblewrap), nowhere else
        raise OSError(f"no zygote on {sys.platform}")
    import signal  # noqa: PLC0415

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
    """The forked run: nothing of the zygote's kept but its trusted modules. Its descriptors are the
    grader's three and no other, its signals Python's, its limits set (CPU, address space, open files,
    file size) before any kit code is imported; then the worker's loop on ``/kit``, which holds this
    run's kit alone. Never returns."""
    if sys.platform != "linux":  # a zygote is PID 1 of a Linux sandbox (bubblewrap), nowhere else
        raise OSError(f"no zygote on {sys.platform}")
    import ctypes  # noqa: PLC0415
    import signal  # noqa: PLC0415

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
        requests, answers = _serve("/kit")
        code = runtime.main("/kit", requests, answers)
    finally:
        os._exit(code if isinstance(code, int) else 70)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
