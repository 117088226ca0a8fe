"""The containers the grader meets, simulated on this machine: one where bubblewrap works (this
machine), and Gradescope's, where Docker's default seccomp profile makes bubblewrap fail (a fake
``bwrap`` first on PATH fails the same way) and the grader falls back to a user of its own per
run (the pool's users created as ``setup.sh`` creates them, and a Python those users can run, a
venv of its own with real copies of the packages, wherever this clone lives), and a broken one
where neither works (``setup.sh`` never ran: the users cannot run the Python).

On Gradescope the only copy of the reference is the bundle's ``source/``, which only root may
read. Here the clone the tests run from is another copy, which the pool's users could read if it
lives in a world-readable folder: ``hidden_from_pool`` takes its "other" permission bits away while
the fallback's tests run (and gives them back), so that what they prove holds wherever the clone
lives."""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

from hwtools.grade.instructor import user_sandbox

# What bubblewrap prints, as root in a container whose seccomp profile refuses unshare(CLONE_NEWUSER).
DOCKER_BWRAP = """#!/bin/sh
if [ "$1" = "--version" ]; then echo "bubblewrap 0.8.0"; exit 0; fi
echo "bwrap: Creating new namespace failed: Operation not permitted" >&2
exit 1
"""


def fake_bwrap_folder(folder):
    """A folder holding a ``bwrap`` that fails as Docker's seccomp makes it fail; put it first on PATH."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    script = folder / "bwrap"
    script.write_text(DOCKER_BWRAP)
    script.chmod(0o755)
    return folder


def user_sandbox_python():
    """(folder to delete, a Python the pool's users can run), after creating the pool's users; skips
    where the fallback cannot be set up (not root, no system Python)."""
    if os.geteuid() != 0:
        pytest.skip("the user sandbox needs the grader to run as root")
    if not Path(user_sandbox.SYSTEM_PYTHON).exists():
        pytest.skip(f"no {user_sandbox.SYSTEM_PYTHON}")
    user_sandbox.create_users()  # what setup.sh does on Gradescope
    folder = Path(tempfile.mkdtemp(prefix="hwgrade-test-python-"))  # not under pytest's root-only tmp folder
    folder.chmod(0o755)
    try:
        return folder, user_sandbox.runnable_python(folder / "venv")
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise


@contextlib.contextmanager
def hidden_from_pool(folder):
    """``folder`` (this clone) without its "other" permission bits while the block runs: the pool's
    users can neither enter nor list it, wherever it lives; the bits are given back after."""
    folder = Path(folder)
    mode = folder.stat().st_mode & 0o7777
    folder.chmod(mode & ~0o007)
    try:
        yield folder
    finally:
        folder.chmod(mode)


def unrunnable_python(folder):
    """A Python that root can run and the pool's users cannot (it sits in a folder only root may
    enter): the container where ``setup.sh`` never made a Python for them."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    folder.chmod(0o700)
    script = folder / "python"
    script.write_text("#!/bin/sh\nexec " + sys.executable + ' "$@"\n')
    script.chmod(0o700)
    return script
