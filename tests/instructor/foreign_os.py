"""Windows's gaps on this Linux box, for the kit's own code only (a test aid, never shipped; issue 32.7).

Imported at the start of every Python process of a student's virtual environment by a ``.pth`` line
(``day_one.student_python(folder, foreign=True)``): the notebook kernel, ``python -m hwtools.grade``
and the grader's worker (``python -B -s worker.py``: ``-s`` leaves site-packages' ``.pth`` files on).
Windows lacks more than macOS does, so code that runs here runs on both, as far as these go.

Kit code is a frame whose module is ``hwlib`` or ``hwtools`` (or in them), or whose code file lies
under a ``hwlib/`` or ``hwtools/`` folder (the kit's copies in temporary folders too, the worker
script run as ``__main__`` too). Only kit code is refused, so that the third-party code of this
Linux box (Jupyter, tornado, zmq, subprocess's internals) keeps working:

* importing a Unix-only module (``UNIX_MODULES``) raises ModuleNotFoundError;
* reading a Unix-only name of ``os``, ``signal`` or ``select`` (``UNIX_NAMES``, the Python docs'
  "Availability: Unix" or "Linux") raises AttributeError, so ``hasattr(os, "killpg")`` is False there;
* ``select.select`` raises OSError (WinError 10038) on anything that is not a socket, and 10022 on
  three empty lists, and ``/proc`` does not exist (``os.listdir``, ``os.scandir``, ``os.stat``,
  ``os.lstat``, ``os.open``, ``os.access``, ``os.readlink``, ``open``, and so ``os.path`` and
  ``pathlib``), when the kit asks: when the nearest caller outside the standard library is kit code
  (the standard library branches by system itself; a third-party library called by the kit has
  branches of its own for Windows, which this box does not take).

``install()`` does it; the ``.pth`` line is ``import foreign_os; foreign_os.install()``, so that a test
process can import this module without it. ``stripped_path(folder)`` makes the rest: a folder of
links to the system's programs but bubblewrap, ``prlimit`` and Chromium, for ``PATH``.
"""

from __future__ import annotations

import builtins
import errno
import importlib
import io
import os
import select
import signal
import stat
import sys
import types

KIT_PACKAGES = frozenset({"hwlib", "hwtools"})
UNIX_MODULES = frozenset({"fcntl", "resource", "pwd", "grp", "termios", "pty", "tty"})
UNIX_NAMES = {
    os: frozenset({
        "killpg", "setsid", "getsid", "getpgid", "setpgid", "getpgrp", "setpgrp", "getuid", "geteuid", "getgid",
        "getegid", "fork", "forkpty", "pidfd_open", "sched_getaffinity", "chown", "fchown", "lchown", "O_CLOEXEC",
        "WNOHANG", "WIFEXITED", "WEXITSTATUS", "WIFSIGNALED", "WTERMSIG", "wait3", "wait4", "pipe2", "mkfifo",
        "getloadavg", "sysconf", "nice", "uname",
        "fchmod",  # Windows only since 3.13
        "get_blocking", "set_blocking",  # on Windows' pipes only since 3.12
    }),
    signal: frozenset({
        "pidfd_send_signal", "SIGKILL", "SIGSTOP", "SIGCONT", "SIGHUP", "SIGALRM", "SIGQUIT", "SIGUSR1", "SIGUSR2",
        "SIGCHLD", "SIGPIPE", "alarm", "setitimer", "getitimer", "ITIMER_REAL", "pause", "pthread_kill",
        "pthread_sigmask", "sigwait", "siginterrupt",
    }),
    select: frozenset({"poll", "epoll", "devpoll", "kqueue"}),
}
PROGRAMS_LEFT_OUT = ("bwrap", "prlimit", "chromium", "google-chrome")  # names, and names that start so
_kit_files = {}


def _kit_file(filename):
    if filename not in _kit_files:
        path = filename.replace("\\", "/")
        _kit_files[filename] = (not KIT_PACKAGES.isdisjoint(path.split("/")[:-1])
                                or path.endswith("/in_sandbox/worker.py"))
    return _kit_files[filename]


def _kit_globals(namespace):
    name = namespace.get("__name__") or ""
    return name.partition(".")[0] in KIT_PACKAGES or _kit_file(namespace.get("__file__") or "")


def _kit_frame(frame):
    return _kit_globals(frame.f_globals) or _kit_file(frame.f_code.co_filename)


_STDLIB = os.path.dirname(os.__file__) + os.sep


def _asked_by_kit(frame):
    """Whether the nearest caller from ``frame`` on that is neither the standard library nor this module is kit code."""
    while frame is not None:
        filename = frame.f_code.co_filename
        if not (filename.startswith("<frozen ") or filename == __file__
                or filename.startswith(_STDLIB) and "-packages" not in filename[len(_STDLIB):]):
            return _kit_frame(frame)
        frame = frame.f_back
    return False


# --- the Unix-only modules ---------------------------------------------------------------------

_import, _import_module = builtins.__import__, importlib.import_module


def _no_module(name):
    return ModuleNotFoundError(f"No module named {name!r}", name=name)


def _guarded_import(name, globals=None, locals=None, fromlist=(), level=0):  # noqa: A002 - __import__'s own names
    if level == 0 and name.partition(".")[0] in UNIX_MODULES and _kit_globals(
            globals if globals is not None else sys._getframe(1).f_globals):
        raise _no_module(name)
    return _import(name, globals, locals, fromlist, level)


def _guarded_import_module(name, package=None):
    if name.partition(".")[0] in UNIX_MODULES and _kit_frame(sys._getframe(1)):
        raise _no_module(name)
    return _import_module(name, package)


# --- the Unix-only names -----------------------------------------------------------------------

def _hide(module, names):
    read = types.ModuleType.__getattribute__

    class ForeignModule(types.ModuleType):
        def __getattribute__(self, name):
            if name in names and _kit_frame(sys._getframe(1)):
                raise AttributeError(f"module {module.__name__!r} has no attribute {name!r}")
            return read(self, name)

    module.__class__ = ForeignModule


# --- select() on sockets only ------------------------------------------------------------------

_select = select.select


def _is_socket(item):
    try:
        fd = item if isinstance(item, int) else item.fileno()
        return stat.S_ISSOCK(os.fstat(fd).st_mode)
    except (OSError, ValueError, AttributeError, TypeError):
        return False


def _sockets_only_select(rlist, wlist, xlist, timeout=None):
    if _asked_by_kit(sys._getframe(1)):
        items = [*rlist, *wlist, *xlist]
        if not items:
            raise OSError(errno.EINVAL, "[WinError 10022] An invalid argument was supplied")
        if not all(_is_socket(item) for item in items):
            raise OSError(errno.ENOTSOCK, "[WinError 10038] An operation was attempted on something that is not a socket")
    return _select(rlist, wlist, xlist, timeout)


# --- no /proc ----------------------------------------------------------------------------------

def _in_proc(path):
    if isinstance(path, int):
        return False
    try:
        path = os.fsdecode(path)
    except TypeError:
        return False
    if "proc" not in path:
        return False
    path = os.path.abspath(path)
    return path == "/proc" or path.startswith("/proc/")


def _without_proc(function):
    def call(*args, **kwargs):
        path = args[0] if args else kwargs.get("path", kwargs.get("file"))
        if path is not None and _in_proc(path) and _asked_by_kit(sys._getframe(1)):
            raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), os.fspath(path))
        return function(*args, **kwargs)

    call.__name__ = call.__qualname__ = function.__name__
    call.__doc__ = function.__doc__
    return call


def install():
    """Take the facilities away (once per process)."""
    if getattr(builtins.__import__, "__module__", None) == __name__:
        return
    builtins.__import__, importlib.import_module = _guarded_import, _guarded_import_module
    for module, names in UNIX_NAMES.items():
        _hide(module, names)
    select.select = _sockets_only_select
    for name in ("stat", "lstat", "open", "access", "readlink", "listdir", "scandir"):
        setattr(os, name, _without_proc(getattr(os, name)))
    builtins.open = io.open = _without_proc(io.open)


def stripped_path(folder):
    """A new folder ``folder`` of links to every program of this system's PATH folders but bubblewrap,
    ``prlimit`` and Chromium (``PROGRAMS_LEFT_OUT``), for ``PATH``; returns it."""
    folder = os.path.abspath(folder)
    os.makedirs(folder)
    for directory in ("/usr/local/sbin", "/usr/local/bin", "/usr/sbin", "/usr/bin", "/sbin", "/bin"):
        if not os.path.isdir(directory):
            continue
        for name in sorted(os.listdir(directory)):
            link = os.path.join(folder, name)
            if not name.startswith(PROGRAMS_LEFT_OUT) and not os.path.lexists(link):
                os.symlink(os.path.join(directory, name), link)
    return folder

