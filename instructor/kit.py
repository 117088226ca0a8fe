"""The instructor's kit as the release tools see it: which files it has, which of them stay with the
instructor, and the solution blocks in them (read by ``hwtools.markers`` with the instructor's rules).

Both editions start here: the student edition (``instructor/release.py``) and the Gradescope
bundle (``instructor/gradescope_bundle.py``).
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path, PurePosixPath

from hwtools import markers
from hwtools.todos import TODO_BY_ID

# The student's own tests: those of what a student writes (tests/unit/: the TODOs' functions and their
# "not done yet" messages) and the fixture they share (tests/conftest.py), beside the notebooks, which
# pytest runs with --nbval-lax; they end in a few minutes. Every other folder of tests/ tests the kit
# itself (its given code, the report, JupyterLab, the grader, the release) and stays with the instructor,
# and so does a folder added later, until it is named here.
STUDENT_TESTS = ("tests/conftest.py", "tests/unit/")

# Left out of the student edition: path prefixes relative to the kit (folders end with "/").
INSTRUCTOR_ONLY = (
    "instructor/",  # the release tool, hidden checks, wrong solutions: one folder
    "hwtools/grade/instructor/",  # the grader's Linux sandboxes, class runs, gradebook and Gradescope: one folder
    # The instructor's guides and the measurements (the edition's README.md is docs/student-README.md:
    # STUDENT_README in instructor/release.py).
    "docs/",
    "benchmarks/RESULTS.md",
    "tests/",  # but STUDENT_TESTS
    # Its per-sample reference loop spells out the gradient of 2.1.1 and the labels of 2.3.1.
    "benchmarks/bench_logreg.py",
    "benchmarks/requirements-bench.txt",
    "benchmarks/bench_grading.py",  # it grades against the reference solution
    "benchmarks/bench_classroom.py",
    "benchmarks/bench_dayone.py",  # it builds a student edition with the solutions kept
    "benchmarks/bench_similarity.py",  # the similarity report's: instructor-only, like the report itself
)

# Only the homework holds solution blocks; tooling elsewhere (the grader) may talk about markers freely.
HOMEWORK_FOLDERS = ("hwlib/", "notebooks/")

# Never part of a kit, whatever git says: the leftovers of editors, Jupyter and Python at any depth
# (``markers.is_leftover``: .ipynb_checkpoints/, .venv/, __pycache__/, *~, .*.swp, ...), build output
# at the top, and the package metadata pip writes.
SKIPPED_TOP = {"build", "dist", "test-artifacts"}
SKIPPED_SUFFIXES = (".egg-info",)

SOLUTION = ("SOLUTION",)  # the instructor's kit fences solutions with SOLUTION markers only


class ReleaseError(Exception):
    """A problem in the source kit, located as ``file:line: message``."""


# --------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------


def kit_files(source):
    """The kit's files, as sorted POSIX paths relative to ``source``. A file git tracks that looks
    like a leftover (``markers.is_leftover``) stops the build: either it is one, committed by
    mistake, or it is the kit's and its name belongs in ``markers.KIT_DOT_NAMES``."""
    source = Path(source)
    names = None
    if (source / ".git").exists() and shutil.which("git"):
        result = subprocess.run(
            ["git", "-C", str(source), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
            capture_output=True, check=False,
        )
        tracked = subprocess.run(["git", "-C", str(source), "ls-files", "-z", "--cached"], capture_output=True, check=False)
        if result.returncode == 0 and tracked.returncode == 0:
            names = [name for name in result.stdout.decode("utf-8").split("\0") if name]
            committed = [name for name in tracked.stdout.decode("utf-8").split("\0") if name and markers.is_leftover(name)]
            if committed:
                raise ReleaseError(f"{committed[0]}: git tracks it, but it looks like an editor's or a tool's leftover "
                                   "(hwtools/markers.py, is_leftover); remove it from git (git rm --cached), or, if it "
                                   "is the kit's own, add its name to KIT_DOT_NAMES there")
    if names is None:
        names = [path.relative_to(source).as_posix() for path in source.rglob("*") if path.is_file() or path.is_symlink()]
    return sorted(name for name in set(names) if _is_kit_file(source, name))


def _is_kit_file(source, name):
    parts = PurePosixPath(name).parts
    if markers.is_leftover(name) or parts[0] in SKIPPED_TOP or any(part.endswith(SKIPPED_SUFFIXES) for part in parts):
        return False
    if parts[0] == "data" and (name.endswith(".npz") or (len(parts) > 1 and parts[1] == "audio")):
        return False  # the course's data is never copied
    path = source / name
    return path.is_file() and not path.is_symlink()


def _under(name, prefixes):
    return any(name == prefix or (prefix.endswith("/") and name.startswith(prefix)) for prefix in prefixes)


def is_instructor_only(name):
    return not _under(name, STUDENT_TESTS) and _under(name, INSTRUCTOR_ONLY)


def read_text(data, name):
    """The text of a kit file's bytes with ``\\n`` line ends and no BOM, whatever the checkout or the
    editor wrote (Git for Windows writes ``\\r\\n``): Python files as Python reads them
    (``markers.decode_python``; the kit's are UTF-8), any other file as UTF-8. None for a file that
    is not text (NUL bytes, not UTF-8): it is copied as it is."""
    if name.endswith(".py"):
        try:
            encoding = markers.python_encoding(data, name)
            text = markers.decode_python(data, name)
        except markers.MarkerError as error:
            raise ReleaseError(str(error)) from None
        if encoding not in ("utf-8", "utf-8-sig"):
            raise ReleaseError(f"{name}: declares the {encoding} encoding; the kit's Python files are UTF-8 "
                               "(the student edition writes them so)")
        return text
    if b"\0" in data:
        return None
    try:
        return markers.normalise_newlines(data.decode("utf-8").removeprefix("\ufeff"))
    except UnicodeDecodeError:
        return None


# --------------------------------------------------------------------------------------------
# Solution blocks
# --------------------------------------------------------------------------------------------


def find_blocks(lines, where, style="code"):
    """The solution blocks of ``lines`` (strings without line ends), by the instructor's rules:
    SOLUTION markers with one of the handout's ids, nothing that looks like a marker and is not one,
    each END indented like its BEGIN. ``where(index)`` names line ``index`` in errors; ``style`` is
    "code" (``### BEGIN SOLUTION id``) or "markdown" (``<!-- BEGIN SOLUTION id -->``)."""
    try:
        return markers.find_blocks(lines, where, style, SOLUTION, known=TODO_BY_ID, strict=True)
    except markers.MarkerError as error:
        raise ReleaseError(str(error)) from None


def file_blocks(path, name=None):
    """(block, the lines it indexes into, style) for every solution block of one kit file: a Python
    file, or the code and Markdown cells of a notebook; any other file has none. ``name`` (default:
    ``path``) locates errors."""
    path = Path(path)
    if path.suffix not in (".py", ".ipynb"):
        return []
    try:
        return markers.file_blocks(name or str(path), path.read_bytes(), SOLUTION, known=TODO_BY_ID, strict=True)
    except markers.MarkerError as error:
        raise ReleaseError(str(error)) from None
