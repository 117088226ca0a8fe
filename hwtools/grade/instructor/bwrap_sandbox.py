"""The bubblewrap sandbox: the options that make it (``bwrap_options``, given to ``bwrap`` through a
pipe with ``--args``) and the probe that says whether it works here (``probe_isolation``).

What the options give the worker is in ``sandbox.py``'s docstring: new namespaces (no network, its
own processes, hostname and IPC), an unprivileged uid without capabilities, read-only ``/usr``,
Python and kit (``/kit``) and worker (``/grader/worker.py``), a fresh size-limited ``/tmp``, a
private ``/proc``, a minimal read-only ``/dev`` with a fresh size-limited ``/dev/shm``, and only the
worker's own environment. Every writable place is a tmpfs of the run's own, gone with it; and the
worker runs under the user fallback's seccomp filter (``confine.py``, compiled once by the system's
Python and loaded by bubblewrap, ``--seccomp``), so it makes no file there (bubblewrap cannot bound a
tmpfs's number of files, each of which holds kernel memory), no socket and no namespace (the same
as bubblewrap's ``--disable-userns``, which needs a user namespace that bubblewrap makes itself).
"""

from __future__ import annotations

import ctypes
import functools
import json
import os
import select
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path

from hwtools.grade.instructor.user_sandbox import CONFINE, SYSTEM_PYTHON
from hwtools.grade.kits import WORKER, worker_env

TMPFS_BYTES = 64 * 1024**2  # the run's /tmp
SHM_BYTES = 16 * 1024**2  # the run's /dev/shm (the rest of its /dev is read-only)
ZYGOTE_INIT = Path(__file__).resolve().parent / "zygote_init.py"  # a grading's zygote: its sandbox's PID 1
HOST_ID = 2_000_000_000  # a root grader's sandbox runs as this uid and gid on the host: no account's, never root's
CLONE_NEWUSER = 0x10000000


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


def _unshare_user():
    if ctypes.CDLL(None, use_errno=True).unshare(CLONE_NEWUSER) != 0:
        raise OSError(ctypes.get_errno(), "unshare(CLONE_NEWUSER) failed")


def grader_makes_namespace():
    """True for a root grader: it makes each run's user namespace (``host_user_namespace``), where
    RLIMIT_NPROC counts the run's processes."""
    return os.geteuid() == 0


def host_user_namespace():
    """A root grader's: a descriptor of a new user namespace whose uid and gid 65534 are HOST_ID on
    the host and 65533 root's (None for any other grader). bubblewrap (``--userns``) makes the
    sandbox in it as 65533, so it mounts whatever root may reach (a Python under ``/root``), then
    runs the worker as 65534 without capabilities and with ``no_new_privs`` (it cannot become
    65533). Made by bwrap itself, the sandbox's uid would be root's on the host, which
    RLIMIT_NPROC never binds; as HOST_ID its processes are counted in this namespace alone, at
    most MAX_PROCESSES (``Sandbox.limits``)."""
    if not grader_makes_namespace():
        return None
    try:
        holder = subprocess.Popen(["/bin/sleep", "60"], preexec_fn=_unshare_user, env={}, close_fds=True,  # noqa: PLW1509
                                  stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except subprocess.SubprocessError:
        raise OSError("no user namespace can be made here (unshare refused)") from None
    try:
        for name in ("uid_map", "gid_map"):
            with open(f"/proc/{holder.pid}/{name}", "w", encoding="ascii") as handle:
                handle.write(f"65533 0 1\n65534 {HOST_ID} 1\n")
        return os.open(f"/proc/{holder.pid}/ns/user", os.O_RDONLY)
    finally:
        holder.kill()
        holder.wait()


def readable_copy(kit_dir, folder):
    """A copy of ``kit_dir`` in ``folder`` (root's own, 0700: no other user reaches it) that the
    sandbox's user (HOST_ID) may read: mounted as ``/kit``, only the copy's own modes count."""
    copy = Path(shutil.copytree(kit_dir, Path(folder) / "kit", symlinks=False))
    for path in [copy, *copy.rglob("*")]:
        path.chmod(0o755 if path.is_dir() else 0o644)
    return copy


@functools.lru_cache(maxsize=None)
def seccomp_program():
    """The run's seccomp filter (``confine.py``), compiled by the system's Python (BPF bytes)."""
    try:
        result = subprocess.run([SYSTEM_PYTHON, "-I", str(CONFINE), "--bpf"], capture_output=True, timeout=60, env={},
                                stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired) as error:
        raise OSError(f"{SYSTEM_PYTHON} cannot compile the sandbox's seccomp filter ({error})") from None
    if result.returncode != 0 or not result.stdout or len(result.stdout) % 8:
        raise OSError(f"{SYSTEM_PYTHON} cannot compile the sandbox's seccomp filter (Debian/Ubuntu: apt-get install "
                      f"python3-seccomp): {' '.join(result.stderr.decode(errors='replace').split())[-200:]}")
    return result.stdout


def bwrap_options(python, kit_dir, program, userns=None, zygote=False):
    """bubblewrap's options (given to it through a pipe, not on its command line) that run a
    Python on ``kit_dir`` with ``WORKER`` as ``/grader/worker.py`` under the seccomp filter read
    from descriptor ``program`` (``data_pipe(seccomp_program())``), in user namespace ``userns`` (a
    descriptor from ``host_user_namespace``, else in one of bwrap's own). ``zygote``: the command,
    ``ZYGOTE_INIT`` as ``/grader/zygote.py``, is the sandbox's PID 1 (no init of bubblewrap's), beside
    the grader's runtime as ``/grader/_hwgrade``."""
    users = ["--unshare-user"] if userns is None else ["--userns", str(userns)]
    args = ["--seccomp", str(program), "--unshare-ipc", "--unshare-pid", "--unshare-net", "--unshare-uts",
            "--unshare-cgroup-try", *users, "--uid", "65534", "--gid", "65534", "--cap-drop", "ALL", "--die-with-parent",
            "--new-session", "--hostname", "sandbox"]
    args += _system_binds()
    # /tmp first: a Python installed under /tmp (a CI checkout there) is bound on top of it, not hidden by it
    args += ["--proc", "/proc", "--dev", "/dev", "--size", str(SHM_BYTES), "--tmpfs", "/dev/shm", "--remount-ro", "/dev",
             "--size", str(TMPFS_BYTES), "--tmpfs", "/tmp", "--dir", "/tmp/home"]
    for path in python_paths(python):
        if not path.startswith("/usr/"):
            args += ["--ro-bind", path, path]
    args += ["--as-pid-1", "--ro-bind", str(WORKER.parent), "/grader/_hwgrade", "--ro-bind", str(ZYGOTE_INIT),
             "/grader/zygote.py"] if zygote else []
    args += ["--ro-bind", str(kit_dir), "/kit", "--ro-bind", str(WORKER), "/grader/worker.py",
             "--remount-ro", "/",  # the sandbox's root is a tmpfs without a size limit: read-only once built
             "--chdir", "/tmp", "--clearenv"]
    for key, value in worker_env("/tmp/home").items():
        args += ["--setenv", key, value]
    return args


def options_pipe(options):
    """A pipe's read end holding bubblewrap's options, NUL-separated (``bwrap --args FD``)."""
    return data_pipe(b"".join(option.encode() + b"\0" for option in options))


def data_pipe(data):
    """A pipe's read end holding ``data``, written whole (bubblewrap reads it: ``--args``, ``--seccomp``)."""
    read, write = os.pipe()
    try:
        if len(data) > 60_000:  # a pipe holds 64 KiB before the writer blocks
            raise ValueError("what bubblewrap reads does not fit in a pipe")
        os.write(write, data)
    finally:
        os.close(write)
    return read


@functools.lru_cache(maxsize=None)
def probe_isolation(python):
    """(True, how) if bwrap can run ``python`` in new namespaces here, else (False, why not)."""
    bwrap = shutil.which("bwrap")
    if bwrap is None:
        return False, "bubblewrap (bwrap) is not installed (Debian/Ubuntu: apt-get install bubblewrap)"
    if shutil.which("prlimit") is None:  # no run without its limits (processes, file size, open files...)
        return False, "prlimit (util-linux) is missing, so no run's limits can be set"
    try:
        program = seccomp_program()
    except OSError as error:
        return False, f"no seccomp filter, so no run: {error}"
    with tempfile.TemporaryDirectory(prefix="hwgrade-probe-") as kit:
        fds = ()
        try:
            userns = host_user_namespace()
            fds = (data_pipe(program),) + (() if userns is None else (userns,))
            fds = (options_pipe(bwrap_options(python, kit, fds[0], userns)), *fds)
            code = "import numpy; open('/grader/worker.py').close()"  # both readable by the sandbox's user
            result = subprocess.run([bwrap, "--args", str(fds[0]), "--", os.path.abspath(python), "-c", code],
                                    capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL, env={},
                                    pass_fds=fds)
        except (OSError, subprocess.TimeoutExpired) as error:
            return False, f"bwrap could not start: {error}"
        finally:
            for fd in fds:
                os.close(fd)
    if result.returncode != 0:
        reason = " ".join(result.stderr.split())[:300]
        return False, f"bwrap cannot create a sandbox here ({reason or 'exit code ' + str(result.returncode)})"
    version = subprocess.run([bwrap, "--version"], capture_output=True, text=True, env={}).stdout.strip()
    how = f"{version or 'bubblewrap'}: no network, read-only Python and kit, private /tmp, /proc and users"
    copy = installed_kit(python)
    if copy:
        how += (f"; WARNING: {python} has a copy of hwlib installed at {os.path.dirname(copy)} (pip install "
                "without -e), which the sandbox can read: reinstall with pip install -e .")
    return True, how


def sandbox_init(info_fd, bwrap_pid, wait=60.0):
    """A pidfd of the bubblewrap sandbox's process-namespace init, read from ``bwrap --info-fd``
    (None if bubblewrap ended before making it): when it has exited, every process of the sandbox
    has (the kernel kills and reaps a namespace's processes before its init exits)."""
    data, give_up = b"", time.monotonic() + wait
    while time.monotonic() < give_up:
        if not select.select([info_fd], [], [], give_up - time.monotonic())[0]:
            continue
        chunk = os.read(info_fd, 4096)
        if not chunk:
            break
        data += chunk
    try:
        child = int(json.loads(data.decode())["child-pid"])
        pidfd = os.pidfd_open(child)
    except (ValueError, KeyError, TypeError, OSError):
        return None
    try:  # the pid is bubblewrap's child (not a process that reused a freed pid)
        with open(f"/proc/{child}/stat", encoding="ascii", errors="replace") as stat:
            parent = int(stat.read().rsplit(")", 1)[1].split()[1])
    except (OSError, ValueError, IndexError):
        parent = None
    if parent != bwrap_pid:
        os.close(pidfd)
        return None
    return pidfd


def wait_gone(pidfd, gone_seconds):
    """Kill the sandbox's init (and so every process of its namespace) and wait until it is gone;
    False if it is still there after gone_seconds."""
    try:
        signal.pidfd_send_signal(pidfd, signal.SIGKILL)
    except ProcessLookupError:
        pass
    return bool(select.select([pidfd], [], [], gone_seconds)[0])
