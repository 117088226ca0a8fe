"""What macOS, Windows and a JupyterHub do differently, on this Linux box (a test aid, never shipped; issue 39).

A profile is installed in a student's virtual environment (``day_one.student_python(folder, system=...)``)
by a ``.pth`` line in its site-packages, ``import foreign_os; foreign_os.install("windows")``, so it runs
at the start of every Python process of that environment, whatever its environment variables: the
notebook kernel, ``python -m hwtools.grade``, the grader's worker (``python -B -s worker.py``, started
with a clean environment: ``-s`` leaves site-packages' ``.pth`` files on), the report and its kernels.
``stripped_path(folder, system)`` makes the programs the environment's ``PATH`` holds.

Each profile does what its system does (the CPython issues and docs each behaviour comes from are named
below, and in ``docs/development.md``). A behaviour that on the real system binds every program binds every
program here too where this box's other code copes (the refused address-space limit, "spawn", the code page of the
standard streams, the refused SIGINT wake-up); one that other code meets only through its own branches for
that system (this box's Jupyter, tornado and zmq take their Linux branches) binds the kit's own code only:
a call the kit asks for, i.e. whose nearest caller outside the standard library is kit code (a frame whose
module is in ``hwlib``/``hwtools``, or whose file lies under such a folder, the worker script included).

``"macos"``: no ``/proc``; no pidfd, ``sched_getaffinity``, ``epoll``, ``pipe2``; ``setrlimit`` of a
finite ``RLIMIT_AS`` or ``RLIMIT_DATA`` raises ``ValueError: current limit exceeds maximum limit``
(cpython#78783, #84698), for every caller; ``multiprocessing`` starts with "spawn"; ``sys.platform`` is
"darwin" to the kit's code (its caches go to ``~/Library/Caches``, it looks for browsers in
``/Applications`` and ``~/Applications``, where this box has none: a Mac with Safari only); no
bubblewrap, ``prlimit`` or Chromium on ``PATH``.

``"windows"``: the Unix-only modules (``UNIX_MODULES``) refused at import and the Unix-only names
(``UNIX_NAMES``: ``SIGKILL`` and ``SIGALRM`` among them, so no CPU-time limit and pytest-timeout's thread
method) hidden; ``select()`` takes sockets only; no ``/proc``; without UTF-8 mode (``PYTHONUTF8``,
``-X utf8``, PEP 540) a standard stream that is not a terminal is cp1252 (stdout and stdin strict, stderr
backslashreplace) unless ``PYTHONIOENCODING`` says otherwise, and the kit's ``open()`` and text pipes
without ``encoding=`` are cp1252 too (``locale.getencoding()`` there); a file held open by any process
cannot be removed, renamed or replaced, nor a folder that holds one (``PermissionError``, WinError 32:
the lock shim, ``held``); ``shutil.rmtree`` works by names, as there; SIGINT (Ctrl+C, Kernel >
Interrupt) reaches Python as Windows' console handler does, from another thread
(``_thread.interrupt_main``), so it wakes no blocking wait (cpython gh-74157); ``taskkill`` on ``PATH``
ends a process tree (``/T``), by parent ids as Windows does; no bubblewrap, ``prlimit`` or Chromium on ``PATH``,
and a Chrome where Windows installs one (``%PROGRAMFILES%``, here the environment's own ``Program Files``: a link
to this box's Chromium); ``sys.platform`` is "win32" and ``os.name`` "nt" to the kit's code (its caches go to
``%LOCALAPPDATA%``, it looks for browsers there and in ``%PROGRAMFILES%``, its worker gets a Windows environment:
``kits.worker_env``); a process started from outside the profile has the folders of a user's session
(``USERPROFILE``, the home; ``LOCALAPPDATA``, ``APPDATA``, ``PROGRAMFILES``), a child given an environment of its
own has what it was given, as on Windows (``_windows_session``).

``"hub"`` (a JupyterHub's single-user server): the home folder ``home`` is read-only to all Python code, the kit's
and every library's (``_read_only``: a write, folder, link or lock file made there is ``OSError`` EROFS, ``mkdir``
of what is there ``FileExistsError``, ``os.access(..., W_OK)`` false, as a read-only mount answers), with the
environment of a hub that works there (``_hub_session``): its spawner gives the server, and so every process that
inherits its environment, the home and the folders its administrator must point elsewhere (``HUB_FOLDERS``:
Jupyter's runtime files, which have no fallback; JupyterLab's settings and workspaces; IPython's and matplotlib's
folders, whose fallback is a temporary folder and a warning), here in the environment's own ``hub-scratch``; a
child the kit gives a home of its own (the grader's worker) keeps it. The shims are Python's: what C code writes
(Chromium's crash database in ``~/.config/chromium``, dconf's ``~/.cache/dconf``; fontconfig's cache, SQLite's
files, pdflatex) is not refused. Under a real read-only mount of the home (``unshare -m``, once, 2026-12-07)
those writers failed quietly, and the hub's hand-in, its PDF and the edition's tests passed as here. User
namespaces are off (the ``bwrap`` on ``PATH`` fails as it does there). Linux otherwise: ``prlimit`` and Debian's
Chromium on ``PATH`` (a course's hub image with the browser the report prints with).

With a ``home``, a process has that home (``HOME``; on Windows a child's ``USERPROFILE``, on a hub a child's
``HOME``, where it was given one) and none of this test run's cache variables (``HWLIB_CACHE_DIR``,
``XDG_CACHE_HOME``): the kit keeps its caches where that system does, in that home.

``install()`` (no argument) is ``install("windows")``, the profile of issue 32.7.
"""

from __future__ import annotations

import builtins
import errno
import importlib
import io
import os
import select
import shutil
import signal
import stat
import subprocess
import sys
import threading
import types

SYSTEMS = ("macos", "windows", "hub")
KIT_PACKAGES = frozenset({"hwlib", "hwtools"})
WINDOWS_AWARE = frozenset({"pytest_timeout"})  # libraries whose own Windows branch the kit's tests rely on
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
MAC_MISSING = {
    os: frozenset({"pidfd_open", "sched_getaffinity", "sched_setaffinity", "pipe2", "memfd_create", "posix_fallocate",
                   "eventfd", "splice"}),
    signal: frozenset({"pidfd_send_signal", "sigtimedwait", "sigwaitinfo"}),
    select: frozenset({"epoll", "devpoll"}),
}
MAC_REFUSED_LIMITS = ("RLIMIT_AS", "RLIMIT_DATA")
CODE_PAGE = "cp1252"
WINERROR_32 = "[WinError 32] The process cannot access the file because it is being used by another process"
PROGRAMS_LEFT_OUT = ("bwrap", "prlimit", "chromium", "google-chrome")  # names, and names that start so
CACHE_VARIABLES = ("HWLIB_CACHE_DIR", "XDG_CACHE_HOME", "MPLCONFIGDIR")  # this test run's (CI's), not a student's
PROGRAM_FILES = "Program Files"  # Windows': in the environment's folder (sys.prefix)
CHROME = ("Google", "Chrome", "Application", "chrome.exe")  # where Windows installs Chrome, under PROGRAM_FILES
HUB_SCRATCH = "hub-scratch"  # a hub's writable place for what its users' programs keep (/tmp, a volume): in sys.prefix
HUB_FOLDERS = {  # what a hub's administrator must point there, the home being read-only (each program's own variable)
    "JUPYTER_RUNTIME_DIR": "jupyter-runtime",  # jupyter_core: a server's and its kernels' files; no fallback
    "JUPYTERLAB_SETTINGS_DIR": "lab-user-settings",  # JupyterLab (and Notebook 7): the settings a user changes
    "JUPYTERLAB_WORKSPACES_DIR": "lab-workspaces",  # JupyterLab: the layout it saves as the user works
    "IPYTHONDIR": "ipython",  # IPython: its profile, history; else a temporary folder, with a warning
    "MPLCONFIGDIR": "matplotlib",  # matplotlib: its config and font cache; else a temporary folder, with a warning
}
_kit_files = {}
_system = None


def _kit_file(filename):
    if filename not in _kit_files:
        path = filename.replace("\\", "/")
        _kit_files[filename] = (not KIT_PACKAGES.isdisjoint(path.split("/")[:-1])
                                or path.endswith("/in_sandbox/worker.py"))
    return _kit_files[filename]


def _kit_globals(namespace, aware=frozenset()):
    name = namespace.get("__name__") or ""
    return name.partition(".")[0] in KIT_PACKAGES | aware or _kit_file(namespace.get("__file__") or "")


def _kit_frame(frame, aware=frozenset()):
    return _kit_globals(frame.f_globals, aware) or _kit_file(frame.f_code.co_filename)


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


class _Wrapped:
    """``function`` behind ``check(args, kwargs)``, which raises where the system would refuse. Not a function, so
    that a class holding it (3.10's ``pathlib._NormalAccessor.stat = os.stat``) calls it unbound, as a builtin."""

    def __init__(self, function, check):
        self.__wrapped__, self._check = function, check
        self.__name__ = self.__qualname__ = getattr(function, "__name__", "call")
        self.__doc__ = function.__doc__

    def __call__(self, *args, **kwargs):
        self._check(args, kwargs)
        return self.__wrapped__(*args, **kwargs)


_wrap = _Wrapped


def _plain(function):
    """``function`` as an object a class attribute does not bind (3.10's ``_NormalAccessor.open = io.open``)."""
    return _Wrapped(function, lambda args, kwargs: None)


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


# --- the names one system lacks ----------------------------------------------------------------

def _foreign(module, hidden=frozenset(), aware=frozenset(), seen=None):
    """``module`` as the kit's code sees it on another system: without the names ``hidden`` (to the libraries
    ``aware`` too), and with ``seen`` ({name: value}: ``sys.platform``, ``os.name``) in place of this box's values
    (the kit's own branches for that system run; other code keeps Linux's)."""
    read, frame, seen = types.ModuleType.__getattribute__, sys._getframe, seen or {}

    class ForeignModule(types.ModuleType):
        def __getattribute__(self, name):
            if name in hidden and _kit_frame(frame(1), aware):
                raise AttributeError(f"module {module.__name__!r} has no attribute {name!r}")
            if name in seen and _kit_frame(frame(1)):
                return seen[name]
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

def _path_of(args, kwargs, names=("path", "file", "src")):
    if args:
        return args[0]
    return next((kwargs[name] for name in names if name in kwargs), None)


def _in_proc(path):
    if path is None or isinstance(path, int):
        return False
    try:
        path = os.fsdecode(path)
    except TypeError:
        return False
    if "proc" not in path:
        return False
    path = os.path.abspath(path)
    return path == "/proc" or path.startswith("/proc/")


def _no_proc(args, kwargs):
    path = _path_of(args, kwargs)
    if _in_proc(path) and _asked_by_kit(sys._getframe(2)):
        raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), os.fspath(path))


# --- Windows: the code page --------------------------------------------------------------------

def _code_page_streams():
    """The standard streams that are not a terminal in the ANSI code page, as Python on Windows opens them
    without UTF-8 mode or PYTHONIOENCODING (stdout strict, stderr backslashreplace)."""
    if sys.flags.utf8_mode or os.environ.get("PYTHONIOENCODING"):
        return
    for name, errors in (("stdin", "strict"), ("stdout", "strict"), ("stderr", "backslashreplace")):
        stream = getattr(sys, name, None)
        try:
            if stream is not None and not stream.isatty():
                stream.reconfigure(encoding=CODE_PAGE, errors=errors)
        except (AttributeError, ValueError, OSError):
            continue


def _text_mode(mode):
    return "b" not in mode


def _code_page_open(function):
    def call(file, mode="r", buffering=-1, encoding=None, *args, **kwargs):
        if encoding in (None, "locale") and _text_mode(mode) and not sys.flags.utf8_mode and \
                _asked_by_kit(sys._getframe(1)):
            encoding = CODE_PAGE
        return function(file, mode, buffering, encoding, *args, **kwargs)

    return _plain(call)


def _code_page_pipes():
    init = subprocess.Popen.__init__

    def __init__(self, *args, **kwargs):  # noqa: N807 - Popen's own
        text = kwargs.get("text") or kwargs.get("universal_newlines")
        if text and kwargs.get("encoding") in (None, "locale") and not sys.flags.utf8_mode and \
                _asked_by_kit(sys._getframe(1)):
            kwargs["encoding"] = CODE_PAGE
        init(self, *args, **kwargs)

    subprocess.Popen.__init__ = __init__


# --- Windows: a file held open cannot be removed or replaced (the lock shim) --------------------

def _open_elsewhere(path):
    """Whether any process (this one too) holds the regular file ``path`` open: a write lease is refused then."""
    import fcntl  # noqa: PLC0415 - this box's, for the shim itself

    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError:
        return False
    try:
        fcntl.fcntl(fd, fcntl.F_SETLEASE, fcntl.F_WRLCK)
    except OSError:
        return True
    else:
        fcntl.fcntl(fd, fcntl.F_SETLEASE, fcntl.F_UNLCK)
        return False
    finally:
        os.close(fd)


def held(path):
    """The first file at or under ``path`` that some process holds open (Windows then refuses to remove,
    rename or replace it, or a folder above it), or None."""
    try:
        mode = os.lstat(path).st_mode
    except (OSError, TypeError, ValueError):
        return None
    if stat.S_ISREG(mode):
        return os.fspath(path) if _open_elsewhere(path) else None
    if stat.S_ISDIR(mode):
        for root, _, files in os.walk(path):
            for name in files:
                full = os.path.join(root, name)
                if stat.S_ISREG(os.lstat(full).st_mode) and _open_elsewhere(full):
                    return full
    return None


def _refuse_held(*paths):
    for path in paths:
        if path is not None and not isinstance(path, int) and held(path):
            raise PermissionError(errno.EACCES, WINERROR_32, os.fspath(path))


def lock_shim():
    """{(module, name): the shim} of the calls that refuse a held file, for ``install`` or a test's monkeypatch."""
    def one(args, kwargs):
        if _asked_by_kit(sys._getframe(2)):
            _refuse_held(_path_of(args, kwargs))

    def two(args, kwargs):
        if _asked_by_kit(sys._getframe(2)):
            _refuse_held(args[0] if args else kwargs.get("src"), args[1] if len(args) > 1 else kwargs.get("dst"))

    def writes(args, kwargs):  # a viewer shares its file for reading only: no one writes it meanwhile
        flags = args[1] if len(args) > 1 else kwargs.get("flags", 0)
        if flags & (os.O_WRONLY | os.O_RDWR | os.O_TRUNC | os.O_APPEND):
            one(args, kwargs)

    shims = {(os, name): _wrap(getattr(os, name), one) for name in ("remove", "unlink", "rmdir")}
    shims.update({(os, name): _wrap(getattr(os, name), two) for name in ("rename", "replace")})
    shims[os, "open"] = _wrap(os.open, writes)
    opener = io.open

    def held_open(file, mode="r", *args, **kwargs):
        if any(flag in mode for flag in "wa+") and _asked_by_kit(sys._getframe(1)):
            _refuse_held(file)
        return opener(file, mode, *args, **kwargs)

    shims[io, "open"] = shims[builtins, "open"] = _plain(held_open)
    shims[shutil, "_use_fd_functions"] = False  # rmtree by names, as on Windows
    return shims


# --- Windows: a user's session --------------------------------------------------------------------

def _windows_session():
    """The folders Windows gives every process of a user's session (``USERPROFILE`` the home, ``LOCALAPPDATA``,
    ``APPDATA``, ``PROGRAMFILES`` here the environment's own ``Program Files``), to a process started from outside
    the profile (this test run's environment: no ``USERPROFILE``), and so to every child that inherits them. A child
    given an environment of its own (the grader's worker, ``kits.worker_env``) has what it was given, as Windows
    passes it (subprocess docs: ``env`` must provide any variable the program needs). The home is ``USERPROFILE``,
    as Python's on Windows (``HOME`` follows it)."""
    if "USERPROFILE" not in os.environ:
        profile = os.path.expanduser("~")
        programs = os.path.join(sys.prefix, PROGRAM_FILES)
        os.environ.update({"USERPROFILE": profile, "LOCALAPPDATA": os.path.join(profile, "AppData", "Local"),
                           "APPDATA": os.path.join(profile, "AppData", "Roaming"), "PROGRAMFILES": programs,
                           "PROGRAMFILES(X86)": f"{programs} (x86)"})
    os.environ["HOME"] = os.environ["USERPROFILE"]


# --- Windows: Ctrl+C from another thread -------------------------------------------------------

def _interrupt_from_a_thread():
    """SIGINT no longer interrupts what the main thread waits in: a thread takes it and asks the main thread
    to raise KeyboardInterrupt at its next bytecode, as Windows' console control handler does."""
    if threading.current_thread() is not threading.main_thread():
        return
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    import _thread  # noqa: PLC0415

    def relay():
        while True:
            signal.sigwait({signal.SIGINT})
            _thread.interrupt_main()

    threading.Thread(target=relay, name="foreign-os-ctrl-c", daemon=True).start()


# --- macOS -------------------------------------------------------------------------------------

def _refused_limits():
    import resource  # noqa: PLC0415

    setrlimit, refused = resource.setrlimit, {getattr(resource, name) for name in MAC_REFUSED_LIMITS}

    def mac_setrlimit(which, limits):
        if which in refused and any(value != resource.RLIM_INFINITY for value in limits):
            raise ValueError("current limit exceeds maximum limit")
        return setrlimit(which, limits)

    resource.setrlimit = mac_setrlimit


def _spawn():
    import multiprocessing.context as context  # noqa: PLC0415

    context._default_context._default_context = context._concrete_contexts["spawn"]  # what macOS's Python sets


# --- a JupyterHub: a read-only home ------------------------------------------------------------

def _hub_session(home):
    """What the hub's spawner gives its single-user server, and so every process that inherits its environment: the
    home ``home`` (``HOME``) and the folders its administrator must point away from a read-only home (``HUB_FOLDERS``,
    here in the environment's own ``HUB_SCRATCH``), to a process started from outside the profile (this test run's
    environment: its ``HOME`` unset, this box's user's or the hub's); a child the kit gave a home of its own (the
    grader's worker, ``kits.worker_env``) has what it was given, as on a hub."""
    import pwd  # noqa: PLC0415 - a hub is Linux

    given = os.environ.get("HOME")
    if given and os.path.realpath(given) not in (home, os.path.realpath(pwd.getpwuid(os.getuid()).pw_dir)):
        return
    os.environ["HOME"] = home
    scratch = os.path.join(sys.prefix, HUB_SCRATCH)
    os.makedirs(scratch, exist_ok=True)
    os.environ.update({variable: os.path.join(scratch, folder) for variable, folder in HUB_FOLDERS.items()})


def _read_only(home):
    """Every write under ``home`` by any Python code of this process refused as a read-only file system refuses it
    (``OSError`` EROFS; ``mkdir`` of what exists: ``FileExistsError``), and ``os.access(..., W_OK)`` false there."""
    def under(path, kwargs):
        if path is None or isinstance(path, int):
            return False
        try:
            path = os.fsdecode(path)
            if kwargs.get("dir_fd") is not None and not os.path.isabs(path):
                path = os.path.join(os.readlink(f"/proc/self/fd/{kwargs['dir_fd']}"), path)
            path = os.path.realpath(path)
        except (TypeError, ValueError, OSError):
            return False
        return path == home or path.startswith(home + os.sep)

    def refuse(path):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), os.fspath(path))

    def writes(args, kwargs):
        path = _path_of(args, kwargs)
        if under(path, kwargs):
            refuse(path)

    def makes(args, kwargs):  # a folder that is there: FileExistsError, as the kernel says first
        path = _path_of(args, kwargs)
        if under(path, kwargs) and not os.path.lexists(path):
            refuse(path)

    def moves(args, kwargs):  # from and to
        for path in (*args[:2], kwargs.get("src"), kwargs.get("dst")):
            if under(path, kwargs):
                refuse(path)

    def links(args, kwargs):  # to
        path = args[1] if len(args) > 1 else kwargs.get("dst")
        if under(path, kwargs):
            refuse(path)

    def os_open(args, kwargs):
        flags = args[1] if len(args) > 1 else kwargs.get("flags", 0)
        if flags & (os.O_WRONLY | os.O_RDWR | os.O_TRUNC | os.O_APPEND) or flags & os.O_CREAT and not os.path.lexists(
                _path_of(args, kwargs)):
            writes(args, kwargs)

    for name in ("remove", "unlink", "rmdir", "chmod", "utime", "truncate"):
        setattr(os, name, _wrap(getattr(os, name), writes))
    for name, check in (("rename", moves), ("replace", moves), ("link", links), ("symlink", links)):
        setattr(os, name, _wrap(getattr(os, name), check))
    os.mkdir, os.open = _wrap(os.mkdir, makes), _wrap(os.open, os_open)
    access, opener = os.access, io.open

    def hub_access(path, mode, *args, **kwargs):
        return access(path, mode, *args, **kwargs) and not (mode & os.W_OK and under(path, kwargs))

    def hub_open(file, mode="r", *args, **kwargs):
        if any(flag in mode for flag in "wax+") and under(file, {}):
            refuse(file)
        return opener(file, mode, *args, **kwargs)

    os.access, builtins.open, io.open = _plain(hub_access), _plain(hub_open), _plain(hub_open)


# --- install -----------------------------------------------------------------------------------

def install(system="windows", home=None):
    """Make this process behave as on ``system`` (once per process); ``home``: the user's home there (a hub's is
    read-only)."""
    global _system
    if system not in SYSTEMS:
        raise ValueError(f"system must be one of {', '.join(SYSTEMS)}, got {system!r}")
    if _system is not None:
        return
    _system = system
    for variable in CACHE_VARIABLES if home is not None else ():
        os.environ.pop(variable, None)
    if system == "hub":
        home = os.path.realpath(home or os.path.expanduser("~"))
        _hub_session(home)
        _read_only(home)
        return
    if home is not None:
        os.environ["HOME"] = os.path.realpath(home)  # for this process and those it starts
    windows = system == "windows"
    hidden = UNIX_NAMES if windows else MAC_MISSING
    seen = {sys: {"platform": "win32"}, os: {"name": "nt"}} if windows else {sys: {"platform": "darwin"}}
    for module in {**hidden, **seen}:
        _foreign(module, hidden.get(module, ()), WINDOWS_AWARE if windows else frozenset(), seen.get(module))
    for name in ("stat", "lstat", "open", "access", "readlink", "listdir", "scandir"):
        setattr(os, name, _wrap(getattr(os, name), _no_proc))
    opener = _wrap(io.open, _no_proc)
    if system == "macos":
        builtins.open = io.open = opener
        _refused_limits()
        _spawn()
        return
    _windows_session()
    builtins.__import__, importlib.import_module = _guarded_import, _guarded_import_module
    select.select = _sockets_only_select
    io.open = opener
    for (module, name), shim in lock_shim().items():
        setattr(module, name, shim)
    builtins.open = io.open = _code_page_open(io.open)
    _code_page_streams()
    _code_page_pipes()
    _interrupt_from_a_thread()


TASKKILL = '''#!{python}
"""taskkill /F [/T] /PID N, as Windows' ends a process (tree): by parent ids, the orphans left out."""
import os, signal, sys
args = [arg.upper() for arg in sys.argv[1:]]
pid = int(sys.argv[1:][args.index("/PID") + 1])
children = {{}}
for entry in os.listdir("/proc"):
    try:
        with open(f"/proc/{{entry}}/stat") as handle:
            children.setdefault(int(handle.read().rpartition(")")[2].split()[1]), []).append(int(entry))
    except (OSError, ValueError):
        continue
tree, pending = [], [pid]
while pending:
    tree.append(pending.pop())
    pending += children.get(tree[-1], []) if "/T" in args else []
for one in tree:
    try:
        os.kill(one, signal.SIGKILL)
    except OSError:
        pass
print(f"SUCCESS: the process with PID {{pid}} has been terminated.")
'''
NO_USERNS = '''#!/bin/sh
echo "bwrap: No permissions to creating new namespace, likely because the kernel does not allow non-privileged user namespaces" >&2
exit 1
'''


def stripped_path(folder, system="windows"):
    """A new folder ``folder`` of links to every program of this system's PATH folders but bubblewrap,
    ``prlimit`` and Chromium (``PROGRAMS_LEFT_OUT``; a hub: but bubblewrap), for ``PATH``, with what ``system``
    has instead (Windows: ``taskkill``, and a Chrome where Windows installs one, in the environment's
    ``Program Files`` beside ``folder``: a link to this box's Chromium; a hub: a ``bwrap`` that cannot make
    namespaces); returns it."""
    folder = os.path.abspath(folder)
    os.makedirs(folder)
    for directory in ("/usr/local/sbin", "/usr/local/bin", "/usr/sbin", "/usr/bin", "/sbin", "/bin"):
        if not os.path.isdir(directory):
            continue
        for name in sorted(os.listdir(directory)):
            link = os.path.join(folder, name)
            if not name.startswith(("bwrap",) if system == "hub" else PROGRAMS_LEFT_OUT) and not os.path.lexists(link):
                os.symlink(os.path.join(directory, name), link)
    own = {"windows": {"taskkill": TASKKILL.format(python=sys.executable)}, "hub": {"bwrap": NO_USERNS}}.get(system, {})
    for name, text in own.items():
        path = os.path.join(folder, name)
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(text)
        os.chmod(path, 0o755)
    browser = system == "windows" and (shutil.which("chromium") or shutil.which("google-chrome"))
    if browser:
        chrome = os.path.join(os.path.dirname(folder), PROGRAM_FILES, *CHROME)
        os.makedirs(os.path.dirname(chrome))
        os.symlink(browser, chrome)
    return folder
