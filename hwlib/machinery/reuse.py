"""The learning-rate sweep's result, kept between kernels: ``learning_rate_sweep(..., reuse=True)``.

After 1.3.2 a student edits 1.3.3 (``LEARNING_RATE``) or the report and runs the whole notebook again;
the sweep's 220 training runs then give the numbers they gave last time. So the notebook's sweep stores
its rewards, and a later sweep of the same code and settings reads them back instead of training again.

**The key** (``sweep_key``) is a SHA-256 of everything the rewards follow from: the sweep's arguments, every
setting of ``hwlib/settings.py`` but ``LEARNING_RATE`` (the one 1.3.3 changes), the source of every
``hwlib`` module the kernel had loaded when the sweep's module was imported (the student's 1.1.1-1.3.2
and the kit's engine, ``hwlib/machinery/``), and the versions of Python, NumPy and gymnasium. There is no
key, so nothing is read or stored, when the kernel runs other code than the files hold: a file changed
since it was imported (not restarted yet) or a function or class of those modules replaced (a notebook
cell that patches one). A stored result is also checked before it is used: one of its training runs (the
first rate, the first seed) is trained again and must give exactly the stored rewards, so code that
depends on something else (``settings.LEARNING_RATE`` inside the loop, a file, a global random state)
trains the whole sweep again.

**Where**: the user's cache folder (``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux, ``~/Library/Caches`` on
macOS, ``%LOCALAPPDATA%`` on Windows), in ``hwlib/``; ``HWLIB_CACHE_DIR`` names another folder (the tests
give every run a new one). One ``sweep-<key>.npz`` per result (about 40 kB), the newest ``KEEP`` kept.

**Never trusted blindly**: a file that is not this key's (another key inside, the wrong shape, rewards
outside [0, the episode cap], not finite, larger than ``MAX_BYTES``), that cannot be read (corrupt, cut
short), or that another user could have written (on POSIX: the folder or the file not the user's own, or
writable by others) is ignored and the sweep trains. A folder that cannot be written (a read-only home, an
odd file system) only means nothing is stored. Files are written beside their name and renamed into place,
so a reader never sees half of one; arrays are read with ``allow_pickle=False``.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import os
import re
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

FORMAT = 1  # the files' layout: a new one ignores the old files
KEEP = 16  # results kept in the folder; older ones are removed when a new one is stored
MAX_BYTES = 4 * 1024**2  # larger files are not read
FOLDER_VARIABLE = "HWLIB_CACHE_DIR"
NOT_KEYED_SETTINGS = ("LEARNING_RATE",)  # TODO 1.3.3: the sweep does not depend on it
_NAME = re.compile(r"^sweep-[0-9a-f]{64}\.npz$")
_READ_ERRORS = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile)


def _loaded_code():
    """{module name: (its file, SHA-256 of its source)} and the functions and classes in each (with the
    functions of those classes), for every ``hwlib`` module loaded now."""
    sources, objects = {}, {}
    for name, module in sorted(sys.modules.items()):
        path = getattr(module, "__file__", None)
        if not (name == "hwlib" or name.startswith("hwlib.")) or not path or name == "hwlib.settings":
            continue
        try:
            sources[name] = (path, hashlib.sha256(Path(path).read_bytes()).hexdigest())
        except OSError:
            sources[name] = (path, None)
        for attribute, value in vars(module).items():
            if inspect.isfunction(value) or inspect.isclass(value):
                objects[(name, attribute)] = value
                if inspect.isclass(value) and value.__module__ == name:
                    for member, function in vars(value).items():
                        if inspect.isfunction(function):
                            objects[(name, f"{attribute}.{member}")] = function
    return sources, objects


_SOURCES, _OBJECTS = _loaded_code()  # the code this kernel runs (hwlib/training.py imports this module last)


def running_code_digest():
    """A digest of the code this kernel runs for the sweep, or None when it is not what the files hold:
    a file changed since the kernel imported it, or a function or class of it replaced since."""
    digest = hashlib.sha256()
    for name, (path, source) in _SOURCES.items():
        try:
            now = hashlib.sha256(Path(path).read_bytes()).hexdigest()
        except OSError:
            return None
        if source is None or now != source:
            return None
        digest.update(f"{name}:{source}\n".encode())
    for (name, attribute), value in _OBJECTS.items():
        outer, _, member = attribute.partition(".")
        current = vars(sys.modules[name]).get(outer) if name in sys.modules else None
        if member:
            current = vars(current).get(member) if inspect.isclass(current) else None
        if current is not value:
            return None
    return digest.hexdigest()


def sweep_key(arguments, settings_module):
    """The key of a sweep with ``arguments`` (a dict of JSON-able values) under the settings and code this
    kernel runs; None when the kernel runs other code than its files hold (``running_code_digest``)."""
    code = running_code_digest()
    if code is None:
        return None
    import gymnasium  # noqa: PLC0415 - its version only

    settings = {name: repr(value) for name, value in sorted(vars(settings_module).items())
                if name.isupper() and name not in NOT_KEYED_SETTINGS}
    described = {"format": FORMAT, "arguments": arguments, "settings": settings, "code": code,
                 "versions": [sys.version, np.__version__, gymnasium.__version__]}
    return hashlib.sha256(json.dumps(described, sort_keys=True).encode()).hexdigest()


def folder():
    """Where results are kept (it may not exist yet), or None where no cache folder can be named."""
    if os.environ.get(FOLDER_VARIABLE):
        return Path(os.environ[FOLDER_VARIABLE])
    try:
        home = Path.home()
    except (RuntimeError, KeyError):
        return None
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or home / "AppData" / "Local"
    elif sys.platform == "darwin":
        base = home / "Library" / "Caches"
    else:
        base = os.environ.get("XDG_CACHE_HOME") or home / ".cache"
    return Path(base) / "hwlib"


def _own(path):
    """On POSIX: ``path`` is this user's and nobody else may write it (elsewhere: True)."""
    if not hasattr(os, "getuid"):
        return True
    status = path.stat()
    return status.st_uid == os.getuid() and not status.st_mode & 0o022


def load(key, shape, max_value):
    """The rewards stored under ``key`` (float64, ``shape``, finite, in [0, ``max_value``]), or None."""
    where = folder()
    if key is None or where is None:
        return None
    path = where / f"sweep-{key}.npz"
    try:
        if not path.is_file() or not _own(where) or not _own(path) or path.stat().st_size > MAX_BYTES:
            return None
        with open(path, "rb") as handle, np.load(handle, allow_pickle=False) as stored:  # closed even when np.load fails
            if str(stored["key"]) != key:
                return None
            rewards = np.array(stored["rewards"])
    except _READ_ERRORS:
        return None
    if rewards.dtype != np.float64 or rewards.shape != tuple(shape) or not np.isfinite(rewards).all():
        return None
    if rewards.min(initial=0.0) < 0.0 or rewards.max(initial=0.0) > max_value:
        return None
    return rewards


def store(key, rewards):
    """Keep ``rewards`` under ``key``, if the folder can be written (True when stored)."""
    where = folder()
    if key is None or where is None:
        return False
    temporary = None
    try:
        where.mkdir(mode=0o700, parents=True, exist_ok=True)
        if not _own(where):
            return False
        with tempfile.NamedTemporaryFile(dir=where, prefix=".sweep-", suffix=".tmp", delete=False) as handle:
            temporary = Path(handle.name)
            np.savez(handle, key=np.array(key), rewards=np.asarray(rewards, dtype=np.float64))
        os.replace(temporary, where / f"sweep-{key}.npz")
        temporary = None
    except OSError:
        return False
    finally:
        if temporary is not None:
            _remove(temporary)
    try:
        kept = sorted((path for path in where.iterdir() if _NAME.match(path.name)), key=lambda path: path.stat().st_mtime)
    except OSError:
        kept = []
    for old in kept[:-KEEP]:
        _remove(old)
    return True


def _remove(path):
    try:
        path.unlink()
    except OSError:  # gone already, or open elsewhere (Windows): it goes next time
        pass
