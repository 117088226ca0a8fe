"""Removing and replacing files where another program may hold them open, on every system.

On Windows a file that another program holds open (a PDF viewer showing the report, an editor, an
antivirus scan of a fresh file) cannot be removed, renamed or replaced, nor can a folder that holds one
(PermissionError, WinError 32 or 5); a scan lets go within a second or two, a viewer only once closed.
So the kit retries briefly (``retrying``), replaces a file by writing beside it and swapping
(``replace_bytes``), and, where a file stays held, names it and the kind of program that usually holds
such a file (``held_open``, ``holder``). Standard library only.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

RETRY_SECONDS = 3.0  # how long a held file is waited for: an antivirus scan lets go within that
RETRY_STEP = 0.1
HOLDERS = {".pdf": "a PDF viewer (Acrobat, Edge, Preview) or a browser showing it",
           ".zip": "File Explorer showing the zip's contents, or an antivirus scan",
           ".tex": "an editor (TeXworks, TeXstudio, VS Code)", ".html": "a browser"}


def printable_output():
    """Let nothing this command prints stop it: where its output goes to a pipe or a file in a code page that
    lacks a character of a path or a name (Windows' cp1252 has no "Ł"), that character is written as an escape
    (``\\u0141``) instead of raising UnicodeEncodeError. The kit's own commands start Python in UTF-8 mode
    (``check_cell.child_env``): there nothing changes."""
    import sys  # noqa: PLC0415

    for stream in (sys.stdout, sys.stderr):
        if hasattr(stream, "reconfigure") and not (stream.encoding or "").lower().replace("-", "").startswith("utf"):
            stream.reconfigure(errors="backslashreplace")


def holder(path):
    """The kind of program that usually holds a file like ``path`` open."""
    return HOLDERS.get(Path(path).suffix.lower(), "another program (an editor, a viewer or an antivirus scan)")


def retrying(action, *args, seconds=None):
    """``action(*args)``, tried again for ``seconds`` (default ``RETRY_SECONDS``) while the system refuses it
    (PermissionError: a file held open on Windows); then the last error."""
    ends = time.monotonic() + (RETRY_SECONDS if seconds is None else seconds)
    while True:
        try:
            return action(*args)
        except PermissionError:
            if time.monotonic() >= ends:
                raise
            time.sleep(RETRY_STEP)


def held_open(path):
    """The first file at or under ``path`` that cannot be renamed now (held open by another program, on
    Windows), or None. Each file is renamed beside itself and back."""
    path = Path(path)
    files = [path] if path.is_file() else sorted(item for item in path.rglob("*") if item.is_file()) if path.is_dir() else []
    for item in files:
        probe = item.with_name(f"{item.name}.probe-{os.getpid()}")
        try:
            os.rename(item, probe)
        except PermissionError:
            return item
        except OSError:
            continue
        retrying(os.rename, probe, item)
    return None


def held_words(path):
    """What to tell a student about the held file ``path``."""
    return f"{path} is open in another program, probably {holder(path)}: close it and run this again"


def replace_bytes(path, data):
    """Write ``data`` to ``path``, beside it first, then swap (retried briefly); on failure the old file is kept
    whole and the error says which file is held."""
    path = Path(path)
    beside = path.with_name(f".{path.name}.new-{os.getpid()}")
    beside.write_bytes(data)
    try:
        retrying(os.replace, beside, path)
    except PermissionError:
        remove_quietly(beside)
        raise PermissionError(held_words(path)) from None


def remove_quietly(path):
    """Remove the file or folder ``path`` (retried briefly); True once it is gone, False where something in it
    stays held (left as it is: a temporary folder is not worth an error)."""
    path = Path(path)
    try:
        if path.is_dir() and not path.is_symlink():
            retrying(shutil.rmtree, path)
        elif path.exists() or path.is_symlink():
            retrying(os.unlink, path)
    except OSError:
        return False
    return True


@contextmanager
def scratch_folder(prefix, folder=None):
    """A new temporary folder (in ``folder``, default the system's), removed afterwards with ``remove_quietly``:
    retried briefly, and left where a program still holds a file of it (Chrome's profile a moment after it
    closed, an antivirus scan)."""
    path = Path(tempfile.mkdtemp(prefix=prefix, dir=folder))
    try:
        yield path
    finally:
        remove_quietly(path)
