"""CI passes wherever the clone lives: the user fallback's and Gradescope's cases, run from a copy of
this kit in the other kind of place than this clone's own (where the rest of the suite runs them):
inside a folder only root may enter (``mktemp -d``, mode 0700) or inside world-readable folders
(``/tmp/X/b/kit``, parents 0755).

The first once failed every user-fallback case (the fallback's Python was a venv whose ``.pth``
pointed into the clone's ``.venv``, which the pool's users could not reach); the second let the
borrowing cheat read the clone's own reference. Each copy holds the kit's files as a clone has them
(tracked and untracked, never ignored ones); it runs with this test run's Python (no ``.venv`` of
its own: installing one is ``.ci/run``'s job), its own code first on the path. Slow (a few
minutes): it runs in CI with the rest.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

KIT = Path(__file__).resolve().parents[2]
CASES = [
    "tests/grader/test_sandbox.py::test_no_network[user]",
    "tests/grader/test_sandbox.py::test_the_user_sandbox_runs_as_a_user_of_its_own_on_a_kit_only_it_can_read",
    "tests/grader/test_gradescope.py::test_a_correct_submission_earns_every_point[docker]",
    "tests/grader/test_gradescope.py::test_a_submission_cannot_borrow_the_reference_from_another_run_s_kit",
]

pytestmark = pytest.mark.timeout(1800)


def copy_of_the_kit(target):
    """The kit's files (as ``git ls-files`` lists them, untracked ones too, never ignored ones) in ``target``."""
    listed = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"], cwd=KIT,
                            capture_output=True, check=True, timeout=120).stdout.decode().split("\0")
    for name in filter(None, listed):
        source = KIT / name
        if source.is_file() and not source.is_symlink():
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target / name)
    return target


def world_readable(path):
    """True if every user may enter ``path`` and each folder above it."""
    return all(folder.stat().st_mode & 0o001 for folder in [path, *path.parents])


@pytest.fixture()
def clone():
    """A copy in the other kind of place: ``private``, /tmp/tmp.../kit in a 0700 folder, where this
    clone is world-readable; else ``world-readable``, /tmp/tmp.../b/kit, parents 0755."""
    if os.geteuid() != 0:
        pytest.skip("the user fallback needs the grader to run as root")
    top = Path(tempfile.mkdtemp())  # mode 0700, as mktemp -d makes it
    try:
        if world_readable(KIT):
            kit = top / "kit"
        else:
            top.chmod(0o755)
            (top / "b").mkdir(mode=0o755)
            kit = top / "b" / "kit"
        kit.mkdir()
        kit.chmod(0o755)
        yield copy_of_the_kit(kit)
    finally:
        shutil.rmtree(top, ignore_errors=True)


def test_the_user_fallback_and_gradescope_cases_pass_wherever_the_clone_lives(clone):
    env = dict(os.environ, PYTHONPATH=str(clone), MPLBACKEND="Agg")
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-o", "addopts=", *CASES],
                         cwd=clone, env=env, capture_output=True, text=True, timeout=1700)
    tail = (run.stdout + run.stderr)[-3000:]
    assert run.returncode == 0, tail
    assert f"{len(CASES)} passed" in run.stdout, tail
    assert "from " + str(clone) in subprocess.run(
        [sys.executable, "-c", "import hwtools; print('from', hwtools.__path__[0])"], cwd=clone, env=env,
        capture_output=True, text=True, timeout=60).stdout  # the copy's own grader ran
