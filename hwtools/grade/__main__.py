"""Command line: ``python -m hwtools.grade [SUBMISSION_DIR | STUDENT.zip] [--reference KIT_DIR] [--json FILE] [--todo ID]``,
or for a class ``python -m hwtools.grade SUBMISSIONS_DIR --gradebook grades.csv --feedback FEEDBACK_DIR [--jobs N]``
(a folder without ``hwlib/``: one folder or .zip per student; see ``classroom``)."""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
from pathlib import Path

from hwtools.files import printable_output
from hwtools.grade.feedback import render
from hwtools.grade.grader import (ANSWER_KEY, BUDGET_FACTOR, KIT_ROOT, SECRET_BYTES, Grader, GradingError, has_solutions,
                                  is_secret)
from hwtools.grade.blocks import load_layout
from hwtools.grade.sandbox import DEFAULT_MEMORY_LIMIT, DEFAULT_TIME_LIMIT, end_every_run, limit_own_memory
from hwtools.grade.submissions import Unusable, kit_file_names, open_submission
from hwtools.todos import TODO_BY_ID


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m hwtools.grade",
        description="Automatic points per handout TODO. The submission's code runs in a sandbox (bubblewrap) and "
                    "never decides its own points: each TODO is checked with the submission's code for that TODO "
                    "and the reference solution for the others.")
    parser.add_argument("submission", nargs="?", default=str(KIT_ROOT),
                        help="the kit to grade (a folder with hwlib/, or one student's .zip; default: this kit), or a folder of submissions "
                             "(one folder or .zip per student, named by student id) with --gradebook and --feedback")
    parser.add_argument("--gradebook", metavar="FILE.csv", help="a class: write the gradebook here (one row per student)")
    parser.add_argument("--feedback", metavar="FOLDER", help="a class: write one Markdown feedback file per student here")
    parser.add_argument("--roster", metavar="CANVAS.csv",
                        help="a class: Canvas's own gradebook export (Grades > Export); the Canvas import beside the "
                             "gradebook then has a row per student on it, matched by Canvas's ID")
    parser.add_argument("--similarity", metavar="FOLDER",
                        help="a class: compare the submissions' TODO blocks pair by pair, offline, and write "
                             "FOLDER/similarity.csv and FOLDER/similarity.html (with or without grading them)")
    parser.add_argument("--assignment", metavar="'TITLE (ID)'",
                        help="a class: the Canvas assignment to fill (its title or id in the roster, or 'Title (id)'; "
                             "default: the roster's only assignment)")
    parser.add_argument("--reference", metavar="KIT_DIR",
                        help="the instructor's kit to grade against (default: this kit if it holds the solutions, "
                             "else the student edition's answer key: visible checks only)")
    parser.add_argument("--answer-key", metavar="FILE", help=f"grade against this answer key (default: {ANSWER_KEY.name})")
    parser.add_argument("--json", metavar="FILE", help="also write the result as JSON to FILE")
    parser.add_argument("--todo", action="append", metavar="ID", help="grade only this TODO (repeatable)")
    parser.add_argument("--python", help="the Python that runs the homework's code (default: the reference kit's .venv)")
    parser.add_argument("--isolation", choices=("auto", "bwrap", "user", "none"), default="auto",
                        help="auto: bubblewrap where it works, else an unprivileged user per run where that is set up "
                             "(as root: python -m hwtools.grade.instructor.user_sandbox create); with neither, a submission other "
                             "than the reference kit itself is refused (the student edition's preview runs unsandboxed "
                             "and says NOT ISOLATED); bwrap, user: refuse to run without that one; none: no sandbox, "
                             "you accept running untrusted code as yourself")
    parser.add_argument("--time-limit", type=float, default=DEFAULT_TIME_LIMIT, metavar="SECONDS",
                        help=f"CPU-time limit per TODO's run; the wall clock stops it at 3x + 10 s, and a submission's "
                             f"runs take {BUDGET_FACTOR:g}x at most together (default {DEFAULT_TIME_LIMIT:g})")
    parser.add_argument("--memory-limit", type=int, default=DEFAULT_MEMORY_LIMIT // 2**20, metavar="MIB",
                        help=f"address-space limit per run in MiB (default {DEFAULT_MEMORY_LIMIT // 2**20})")
    parser.add_argument("--jobs", type=int, default=None,
                        help="one kit: runs prepared while another executes (default: 2, or 1 on one CPU); a class: "
                             "submissions graded side by side, their runs too (default: one per CPU)")
    parser.add_argument("--secret", metavar="HEX",
                        help="regrade with the hidden inputs of an earlier grading: its result's \"secret\" (--json); "
                             "by default each grading draws new hidden inputs")
    parser.add_argument("--brief", action="store_true", help="only the table, without the checks of each TODO")
    args = parser.parse_args(argv)
    printable_output()
    signal.signal(signal.SIGTERM, _stop)  # the check cell's interrupt: every run ends with this process
    limit_own_memory()  # the trusted side too: nothing a worker sends can take it past this
    unknown = [todo for todo in args.todo or () if todo not in TODO_BY_ID]
    if unknown:
        parser.error(f"unknown TODO id(s): {', '.join(unknown)}; the handout's are {', '.join(TODO_BY_ID)}")
    submission = Path(args.submission)
    one_zip = submission.is_file() and submission.suffix.lower() == ".zip"
    if not (submission / "hwlib").is_dir() and not one_zip:
        if submission.is_dir():
            try:
                from hwtools.grade.instructor import classroom  # noqa: PLC0415 - a folder of submissions
            except ImportError:
                parser.error(f"{submission}: a folder of submissions is graded with the instructor's kit; this one "
                             "(the student edition) grades one kit or one zip")
            if not args.similarity:
                return classroom.main(args, parser)
            try:
                from hwtools.grade.instructor import similarity  # noqa: PLC0415 - it needs copydetect
            except ImportError as error:
                parser.error(f"--similarity needs the instructor's requirements ({error}): "
                             ".venv/bin/pip install -r requirements.txt")
            return similarity.main(args, parser)
        parser.error(f"{submission}: neither a kit's folder (with hwlib/), nor a .zip, nor a folder of submissions")
    if args.gradebook or args.feedback or args.roster or args.assignment or args.similarity:
        what = "one student's zip" if one_zip else "a kit (it has hwlib/)"
        parser.error(f"{submission} is {what}; --gradebook, --feedback, --roster, --assignment and --similarity are "
                     "for a folder of submissions")
    reference = args.reference
    if reference is None and args.answer_key is None and has_solutions(KIT_ROOT):
        reference = KIT_ROOT
    try:
        grader = Grader(reference, answer_key=args.answer_key, python=args.python, isolation=args.isolation,
                        time_limit=args.time_limit, memory_limit=args.memory_limit * 2**20, jobs=args.jobs)
        if args.secret is not None and (grader.hidden is None or not is_secret(args.secret)):
            parser.error(f"--secret: expected the {2 * SECRET_BYTES} hex digits of an earlier grading's \"secret\" "
                         "(its --json), with a reference that has hidden checks")
        result = (grade_zip(grader, submission, args.todo, args.secret) if one_zip
                  else grader.grade(submission, todos=args.todo, secret=args.secret))
    except GradingError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except Unusable as error:
        print(f"error: {submission}: {error.text}", file=sys.stderr)
        return 2
    sys.stdout.write(render(result, details=not args.brief))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    return 0


def _stop(signum, _frame):
    end_every_run()
    os._exit(128 + signum)


def grade_zip(grader, path, todos=None, secret=None):
    """Grade one student's zip, read as a class's zips are read (``submissions.open_submission``)."""
    layout = grader.layout or load_layout(KIT_ROOT)  # the kit's file names, to know a zip of the bare files
    with open_submission(path, kit_file_names(layout)) as opened:
        result = grader.grade(opened.kit, todos=todos, secret=secret)
    result["submission"] = str(path)
    result["notes"][:0] = opened.notes
    return result


if __name__ == "__main__":
    sys.exit(main())
