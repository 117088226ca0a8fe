"""The TODO blocks: find them, and read a submission's code without trusting it.

A block is fenced by two marker lines, ``### BEGIN <style> 1.2.1`` and ``### END <style> 1.2.1``,
whose style is SOLUTION in the instructor's kit and TODO in the student edition; a submission
may use either. Only the code between the markers is ever taken from a submission: everything
around it (signatures, door checks, the ``return`` after the block) comes from the reference kit.

``load_layout`` reads a kit's ``hwlib/`` (the reference's: its files and blocks, ``KitLayout``);
``read_submission`` takes each TODO's code from a submission's files, by that layout;
``check_body`` says whether a block stands alone. The kits built from them: ``kits.py``.
Standard library only: the grader's trusted process imports this module, never ``hwlib``.
"""

from __future__ import annotations

import ast
import functools
import os
import stat
import threading
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from hwtools import markers

MAX_FILE_BYTES = 1_000_000  # a submitted source file larger than this is not read
PACKAGE = "hwlib"


class SubmissionError(Exception):
    """A submission file that cannot be read (missing, a link, too large, not text Python can read)."""


def find_blocks(text, where="<text>"):
    """The fenced blocks of ``text`` (either style), in order, by the rules of ``hwtools.markers``
    (any line ends, markers with trailing white space or tabs). Unbalanced or nested markers raise
    SubmissionError."""
    try:
        return markers.find_blocks(markers.split_lines(text), lambda index: f"{where}:{index + 1}")
    except markers.MarkerError as error:
        raise SubmissionError(str(error)) from None


# --------------------------------------------------------------------------------------------
# Reading a submission without trusting it
# --------------------------------------------------------------------------------------------


def read_text(root, relative):
    """The text of ``root/relative`` as Python reads a source file (``markers.decode_python``: UTF-8
    or the encoding its coding line names, a BOM dropped, ``\\r\\n`` and ``\\r`` made ``\\n``), refusing
    links (of the file or any folder on the way), anything but a regular file, and files over
    MAX_FILE_BYTES."""
    root = Path(root)
    path = root
    for part in PurePosixPath(relative).parts:
        if part in ("", ".", ".."):
            raise SubmissionError(f"{relative}: not a plain relative path")
        path = path / part
        try:
            info = os.lstat(path)
        except FileNotFoundError:
            raise SubmissionError(f"{relative}: missing") from None
        if stat.S_ISLNK(info.st_mode):
            raise SubmissionError(f"{relative}: {path.relative_to(root)} is a symbolic link; only plain files are read")
    if not stat.S_ISREG(info.st_mode):
        raise SubmissionError(f"{relative}: not a regular file")
    if info.st_size > MAX_FILE_BYTES:
        raise SubmissionError(f"{relative}: {info.st_size} bytes, more than the {MAX_FILE_BYTES} read")
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    with os.fdopen(fd, "rb") as handle:
        data = handle.read(MAX_FILE_BYTES + 1)
    try:
        return markers.decode_python(data, relative)
    except markers.MarkerError as error:
        raise SubmissionError(str(error)) from None


@dataclass
class Submission:
    """The student's code per TODO (``bodies[todo]``: one tuple of lines per block) and what was
    seen while reading it (``problems[todo]``: why a TODO's code could not be taken)."""

    root: Path
    bodies: dict = field(default_factory=dict)
    problems: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    texts: dict = field(default_factory=dict)  # relative path -> text, of the files read


def _near_misses(text, todo):
    """Where the file has a line that names TODO ``todo``'s marker but is not one (``# BEGIN TODO 1.2.1``)."""
    lines = [(number, line.strip()) for number, line in enumerate(markers.split_lines(text), 1)
             if markers.near_miss(line) and todo in line]
    return "".join(f"; line {number} looks like a marker but is not one: {line[:80]!r}" for number, line in lines[:2])


NOT_USED = ("conftest.py", "sitecustomize.py", "usercustomize.py", "pytest.ini", "setup.cfg", "tox.ini")


def read_submission(root, layout):
    """Take each TODO's code from the files ``layout`` (a ``KitLayout`` of the reference) names, and
    note what else the submission changed (none of it is used)."""
    submission = Submission(Path(root))
    for relative, ref_blocks in layout.blocks_by_file.items():
        todos = [block.todo for block in ref_blocks]
        try:
            text = read_text(root, relative)
            blocks = find_blocks(text, relative)
        except SubmissionError as error:
            for todo in todos:
                submission.problems.setdefault(todo, str(error))
            continue
        submission.texts[relative] = text
        for todo in dict.fromkeys(todos):
            expected = sum(block.todo == todo for block in ref_blocks)
            found = [block.body for block in blocks if block.todo == todo]
            if len(found) != expected:
                submission.problems[todo] = (f"{relative}: expected {expected} block(s) marked "
                                             f"'### BEGIN TODO {todo}' ... '### END TODO {todo}', found {len(found)}"
                                             + _near_misses(text, todo))
            else:
                submission.bodies[todo] = tuple(found)
    changed = []
    for relative, reference_text in layout.files.items():
        try:
            text = submission.texts.get(relative) or read_text(root, relative)
        except SubmissionError:
            continue
        if skeleton(text) != skeleton(reference_text):
            changed.append(relative)
    if changed:
        submission.notes.append(f"{', '.join(changed)}: lines outside the TODO blocks differ from the kit's; they "
                                "are not used (each TODO is checked inside the kit's own files)")
    package = Path(root) / PACKAGE
    if package.is_dir() and not package.is_symlink():
        extra = sorted(relative for relative in (path.relative_to(root).as_posix() for path in package.rglob("*.py"))
                       if not markers.is_leftover(relative) and relative not in layout.files)
        if extra:
            submission.notes.append(f"{', '.join(extra[:5])}: not part of the kit; not used")
    present = []
    for name in NOT_USED:
        for relative in (name, f"{PACKAGE}/{name}"):
            if not os.path.lexists(Path(root) / relative):
                continue
            try:
                same = read_text(root, relative) == read_text(layout.root, relative)
            except SubmissionError:
                same = False
            if not same:
                present.append(relative)
    if present:
        submission.notes.append(f"{', '.join(present)}: not used; the grader runs no tests of the submission, only "
                                "the code between the TODO markers")
    return submission


# --------------------------------------------------------------------------------------------
# A kit's layout, and a block on its own
# --------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=32)  # the reference's files are compared with every submission's
def skeleton(text):
    """The lines outside the blocks (markers reduced to the TODO id), to compare two editions."""
    lines = markers.split_lines(text)
    try:
        blocks = find_blocks(text)
    except SubmissionError:
        return None
    out, position = [], 0
    for block in blocks:
        out.extend(line.rstrip() for line in lines[position:block.begin])
        out.append(f"<block {block.todo}>")
        position = block.end + 1
    out.extend(line.rstrip() for line in lines[position:])
    while out and not out[-1]:
        out.pop()
    return tuple(out)


@dataclass
class KitLayout:
    """A kit's ``hwlib`` package: every file's text and the blocks in each."""

    root: Path
    files: dict  # relative path ("hwlib/x.py") -> text
    blocks_by_file: dict  # relative path -> [Block] (files with blocks only)
    skeletons: dict  # relative path -> skeleton(text)

    @property
    def todos(self):
        return sorted({block.todo for blocks in self.blocks_by_file.values() for block in blocks},
                      key=lambda todo: tuple(int(part) for part in todo.split(".")))

    def reference_bodies(self):
        bodies = {}
        for blocks in self.blocks_by_file.values():
            for block in blocks:
                bodies.setdefault(block.todo, []).append(block.body)
        return {todo: tuple(found) for todo, found in bodies.items()}


def load_layout(root):
    """Read the ``hwlib`` package of the kit at ``root`` (sources only; links and the leftovers of editors,
    Jupyter and Python, ``markers.is_leftover``, skipped)."""
    root = Path(root)
    package = root / PACKAGE
    if not package.is_dir():
        raise SubmissionError(f"{root}: no {PACKAGE}/ folder")
    files, blocks_by_file, skeletons = {}, {}, {}
    for path in sorted(package.rglob("*.py")):
        relative = path.relative_to(root).as_posix()
        if markers.is_leftover(relative) or path.is_symlink():
            continue
        text = read_text(root, relative)
        files[relative] = text
        blocks = find_blocks(text, relative)
        if blocks:
            blocks_by_file[relative] = blocks
            skeletons[relative] = skeleton(text)
    return KitLayout(root, files, blocks_by_file, skeletons)


def reindent(body, indent):
    """``body`` (lines) moved to ``indent``: the common indentation of its code lines removed (a
    comment may stand further left), ``indent`` put in front of every non-blank line."""
    lines = [line.expandtabs(8) if "\t" in line[:len(line) - len(line.lstrip())] else line for line in body]
    code = [line for line in lines if line.strip() and not line.lstrip().startswith("#")]
    common = min((len(line) - len(line.lstrip()) for line in code), default=0)
    out = []
    for line in lines:
        if not line.strip():
            out.append("")
            continue
        width = len(line) - len(line.lstrip())
        out.append(indent + (line[common:] if width >= common else line.lstrip()))
    while out and not out[-1]:
        out.pop()
    return out


_PARSING = threading.Lock()


def parse(source):
    """``ast.parse(source)``, one thread at a time. The grader judges a submission's TODOs in threads,
    and CPython 3.11 keeps the AST builder's recursion count per interpreter: two threads parsing at
    once can fail with "SystemError: AST constructor recursion depth mismatch" (CPython gh-106905;
    seen in CI, tests/grader/test_protocol.py reproduces it)."""
    with _PARSING:
        return ast.parse(source)


def check_body(body, module_level):
    """None if ``body`` is a well-formed block on its own (balanced brackets and strings, valid
    syntax), else the reason. A block must stand alone so that it cannot swallow the kit's code."""
    lines = reindent(body, "" if module_level else "    ")
    source = "\n".join(lines) if module_level else "def _block():\n" + "\n".join(lines + ["    pass"])
    try:
        compile(source, "<your block>", "exec", dont_inherit=True)
    except SyntaxError as error:
        line = (error.lineno or 1) - (0 if module_level else 1)
        return f"line {max(line, 1)} of the block: {error.msg}"
    return None
