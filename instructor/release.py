"""Build the student edition of the kit from the instructor's kit (the one source of truth).

    python -m instructor.release student OUT_DIR [--source KIT_DIR] [--force] [--keep TODO ...]
    python -m instructor.release gradescope OUT.zip [--source KIT_DIR] [--force]   (see instructor/gradescope_bundle.py)
    python -m instructor.release check [--source KIT_DIR]   (the release gate and every known mistake: instructor/gate.py)

Both builds refuse, with one message and before writing anything, a kit that the release gate
finds not ready (``instructor/gate.py``: facts out of date or written as literals, a points table
that disagrees, an answer key older than the known mistakes); the student edition also refuses a
known mistake that no longer loses points (its answer key runs every one).

Solution code is fenced, in ``hwlib`` and in the notebooks' code cells, by comment lines

    ### BEGIN SOLUTION 1.2.1
    ### HINT: one line for the student (optional; else the hint table of instructor/stubs.py)
    ### STUB: a line of code the student starts from (optional, any number)
    ...
    ### END SOLUTION 1.2.1

and, in Markdown cells, by ``<!-- BEGIN SOLUTION 2.1.1 -->`` ... ``<!-- END SOLUTION 2.1.1 -->``
(the rules: ``hwtools/markers.py``, which the grader reads submissions with too). In the student
edition

* a fenced block in library code becomes the student's starting point between kept markers
  ``### BEGIN TODO 1.2.1`` / ``### END TODO 1.2.1``: the hint as a ``# TODO`` comment, the STUB
  lines and ``raise TodoNotDone("1.2.1")``, so the skeleton around it (signature, givens, return)
  reads as the student's start; a module-level block becomes the hint comment and ``NAME = None``
  (``instructor/stubs.py``), its hint comment wrapped (``HINT_WIDTH``);
* a fenced block in a notebook code cell becomes ``# TODO <id>: <hint>`` and its STUB lines, or
  ``raise TodoNotDone("<id>")`` (imported from ``hwlib``), between the same kept markers; in a
  Markdown cell it becomes ``YOUR ANSWER HERE``; every notebook's outputs, execution counts,
  execution timings and stored widget state are cleared (``instructor/notebooks.py``);
* instructor-only files (``INSTRUCTOR_ONLY`` in ``instructor/kit.py``: ``instructor/`` with this
  tool, the hidden checks and the wrong solutions; every folder of ``tests/`` but the student's own
  tests, ``STUDENT_TESTS``; the benchmarks whose reference loops spell out answers) are left out;
* ``pyproject.toml`` runs the notebooks with ``--nbval-lax`` (stored notebooks have no outputs
  to compare, so cells must only run without error; ``instructor/given_files.py``);
* the edition's ``README.md`` is ``docs/student-README.md`` (``STUDENT_README``), the students' one
  page; this kit's own README and ``docs/`` stay with the instructor.

The kit's files are those ``git ls-files --cached --others --exclude-standard`` lists (tracked
plus untracked, without git-ignored ones); outside a git repository, a sorted walk that skips
virtual environments, caches, build output and the course data. Every text file is written as
UTF-8 with ``\n`` line ends and no BOM, so a checkout with Windows line ends gives the same
edition. Nothing is written until every file has been transformed, and the output depends only
on the input (sorted, no timestamps), so two builds are byte-identical. A marker without its
pair, nested markers, mismatched ids or a block without a TODO id stop the build with
``file:line: message``.
"""

from __future__ import annotations

import argparse
import json
import os
import secrets
import shutil
import sys
from pathlib import Path

from hwtools.todos import TODO_BY_ID
from instructor import gate, gradescope_bundle
from instructor.given_files import transform_pyproject, transform_requirements
from instructor.kit import (HOMEWORK_FOLDERS, INSTRUCTOR_ONLY, STUDENT_TESTS, ReleaseError, file_blocks, find_blocks,
                            is_instructor_only, kit_files, read_text)
from instructor.notebooks import transform_notebook
from instructor.stubs import NOT_DONE_MODULE, transform_python

__all__ = [  # what the tests and the other tools take from here (the pieces live in the modules named above)
    "ANSWER_KEY", "HOMEWORK_FOLDERS", "INSTRUCTOR_ONLY", "STUDENT_README", "STUDENT_TESTS", "ReleaseError",
    "build_student_edition", "file_blocks", "find_blocks", "is_instructor_only", "kit_files", "main", "student_files", "transform_notebook", "transform_python",
]

ANSWER_KEY = "hwtools/grade/answer_key.json"  # written by the build: the visible checks' expected values
STUDENT_README = "docs/student-README.md"  # written as the edition's README.md


def student_files(source, keep=frozenset(), replace=None):
    """{relative path: (bytes, executable)} of the student edition, built in memory.

    ``keep``: TODO ids whose solutions stay; ``replace``: {(TODO id, relative path): code} put in
    place of that TODO's blocks in that file (the grader's proof uses both).
    """
    source = Path(source).resolve()
    replace = replace or {}
    names = kit_files(source)
    require_not_done = NOT_DONE_MODULE in names
    files = {}
    for name in names:
        if name == "README.md" or (is_instructor_only(name) and name != STUDENT_README):
            continue  # the kit's README is the instructor's; the edition's is STUDENT_README
        path = source / name
        data = path.read_bytes()
        executable = bool(path.stat().st_mode & 0o111)
        text = read_text(data, name)
        file_replace = {todo: code for (todo, file), code in replace.items() if file == name}
        if text is None:
            pass  # not text: copied as it is
        elif name.endswith(".py") and name.startswith(HOMEWORK_FOLDERS):
            text = transform_python(text, name, keep, file_replace, require_not_done=require_not_done)
        elif name.endswith(".ipynb"):
            text = transform_notebook(text, name, keep, file_replace, not_done=require_not_done)
        elif name == "pyproject.toml":
            text = transform_pyproject(text, name)
        elif name == "requirements.txt":
            text = transform_requirements(text, name)
        files["README.md" if name == STUDENT_README else name] = (data if text is None else text.encode("utf-8"), executable)
    missing = sorted(f"{file} (TODO {todo})" for todo, file in replace if file not in files)
    if missing:
        raise ReleaseError(f"{missing[0]}: no such file in the student edition to put a replacement into")
    return files


def build_student_edition(source, out_dir, keep=frozenset(), replace=None, force=False, answer_key=True):
    """Write the student edition of the kit in ``source`` into ``out_dir``. Returns the file list.

    With ``answer_key`` the grader's answer key for the visible checks (``ANSWER_KEY``: the
    reference's values on the visible inputs, nothing about hidden ones) is written too, so that
    ``python -m hwtools.grade`` works in the student edition; it runs the reference sandboxed.

    The edition is written into a temporary folder beside ``out_dir`` and renamed into place once
    complete (an earlier edition there, with ``force``, is replaced only then): a build that fails,
    or is interrupted, leaves ``out_dir`` as it was and no half-built folder.
    """
    source, out_dir = Path(source).resolve(), Path(out_dir).resolve()
    if out_dir == source or source.is_relative_to(out_dir):
        raise ReleaseError(f"{out_dir}: the output folder must not be the kit or contain it")
    files = student_files(source, keep, replace)
    if out_dir.exists() or out_dir.is_symlink():
        if not out_dir.is_dir() or out_dir.is_symlink():
            raise ReleaseError(f"{out_dir}: exists and is not a folder")
        if any(out_dir.iterdir()):
            if not force:
                raise ReleaseError(f"{out_dir}: not empty (pass --force to replace an earlier student edition)")
            if not ((out_dir / "hwlib").is_dir() and (out_dir / "pyproject.toml").is_file()):
                raise ReleaseError(f"{out_dir}: not empty and not a kit; refusing to delete it")
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    building = _sibling(out_dir, "building")
    try:
        for name, (data, executable) in sorted(files.items()):
            target = building / name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
            target.chmod(0o755 if executable else 0o644)
        names = sorted(files)
        if answer_key:
            from hwtools.grade import GradingError, write_answer_key  # noqa: PLC0415 - only the full build needs the grader

            try:
                write_answer_key(source, building / ANSWER_KEY)
            except GradingError as error:  # the grader refuses the reference kit: one line, not a traceback
                raise ReleaseError(f"the answer key cannot be written: {error}") from None
            table = json.loads((building / ANSWER_KEY).read_text(encoding="utf-8"))["mistakes"]
            losing_nothing = gate.mistakes_losing_nothing(table)
            if losing_nothing:
                raise ReleaseError(str(gate.Refused("the student edition", losing_nothing)))
            names = sorted([*names, ANSWER_KEY])
        _move_into_place(building, out_dir)
    except BaseException:
        shutil.rmtree(building, ignore_errors=True)
        raise
    return names


def _move_into_place(building, out_dir):
    """Rename the finished edition ``building`` to ``out_dir``, an earlier edition there deleted after."""
    if not out_dir.exists():
        building.rename(out_dir)
        return
    earlier = _sibling(out_dir, "earlier")
    out_dir.rename(earlier / "edition")
    try:
        building.rename(out_dir)
    except BaseException:
        (earlier / "edition").rename(out_dir)  # put the earlier edition back
        raise
    finally:
        shutil.rmtree(earlier, ignore_errors=True)


def _sibling(out_dir, what):
    """A new empty folder beside ``out_dir``, hidden by its leading dot (made with the usual permissions)."""
    folder = out_dir.parent / f".{out_dir.name}.{what}-{os.getpid()}-{secrets.token_hex(4)}"
    folder.mkdir()
    return folder


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m instructor.release", description="Build an edition of the kit.")
    commands = parser.add_subparsers(dest="edition", required=True)
    student = commands.add_parser("student", help="the student edition: solutions replaced by stubs, no outputs, no instructor files")
    student.add_argument("out_dir", help="folder to write the student edition into (new or empty)")
    student.add_argument("--source", default=str(Path(__file__).resolve().parents[1]), help="the instructor's kit (default: this kit)")
    student.add_argument("--force", action="store_true", help="replace an earlier student edition in OUT_DIR")
    student.add_argument("--keep", action="append", default=[], metavar="TODO", help="keep this TODO's solution (for checking the tests)")
    student.add_argument("--no-answer-key", action="store_true",
                         help="skip the grader's answer key (then the student edition's grader has nothing to compare with)")
    gradescope_bundle.add_parser(commands, Path(__file__).resolve().parents[1])
    checked = commands.add_parser("check", help="the release gate (facts, points table, answer keys) and every known "
                                                "mistake re-run on the visible checks under these facts; changes nothing")
    checked.add_argument("--source", default=str(Path(__file__).resolve().parents[1]), help="the instructor's kit (default: this kit)")
    args = parser.parse_args(argv)
    if args.edition == "gradescope":
        return args.run(args)
    if args.edition == "check":
        return check_command(args.source)
    unknown = [todo for todo in args.keep if todo not in TODO_BY_ID]
    if unknown:
        parser.error(f"unknown TODO id(s) for --keep: {', '.join(unknown)}")
    try:
        gate.check(args.source, "the student edition", skip=args.out_dir)
        names = build_student_edition(args.source, args.out_dir, keep=frozenset(args.keep), force=args.force,
                                      answer_key=not args.no_answer_key)
    except (ReleaseError, gate.Refused) as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    print(f"student edition: {len(names)} files in {args.out_dir}")
    return 0


def check_command(source):
    """``python -m instructor.release check``: the gate, then every known mistake on the visible checks."""
    from hwtools.grade import Grader, GradingError, checks  # noqa: PLC0415 - the grader only for this command

    found = gate.problems(source)
    if not any(problem.startswith("points table:") for problem in found):  # else the grader refuses to start
        try:
            with Grader(source) as grader:
                table = [known for todo in checks.GRADED_TODOS for known in grader.known_mistakes(todo)]
            found += gate.mistakes_losing_nothing(table)
            print(f"{len(table)} known mistakes re-run on the visible checks", file=sys.stderr)
        except GradingError as error:
            found.append(f"the grader: {error}")
    if found:
        print(f"error: {gate.Refused('the release', found)}", file=sys.stderr)
        return 1
    print(f"{source}: ready to release (facts, points table, answer keys, known mistakes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
