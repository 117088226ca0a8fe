"""Grade a class: a folder of submissions to one gradebook (CSV) and one Markdown feedback file per student.

    python -m hwtools.grade SUBMISSIONS_DIR --gradebook grades.csv --feedback FEEDBACK_DIR [--jobs N]
                            [--roster CANVAS_EXPORT.csv [--assignment "Title (id)"]]

``SUBMISSIONS_DIR`` holds one folder or one ``.zip`` per student, named by the student's id
(``alice/``, ``bob.zip``). Each holds the student's ``hwlib/`` (and, if they sent them, the
notebooks), at the top or up to two folders down (``bob.zip`` holding ``bob/hwlib/...`` or
``hw1/hwlib/...``); a submission of the bare library files (``finite_diff.py``, ``logreg.py``, ...
without their ``hwlib/`` folder) is read as ``hwlib/``, and a folder whose only content is one
``.zip`` is read as that zip.

The command line refuses, before it writes anything, a kit the release gate finds not ready
(``instructor/gate.py``: its facts out of date or written as literals, a points table that
disagrees, an answer key older than the known mistakes).

Nothing in a submission is trusted: ``submissions.py`` reads it (what is copied, what rejects
it), and the student's code then runs only in the grader's sandbox. This module runs the class:
it grades the submissions, saves each result, and writes the gradebook (``gradebook.py``), its
Canvas import (``canvas.py``: with ``--roster``, a row per student of Canvas's own export) and the
feedback (``class_feedback.py``), with a progress line (``class_progress.py``).

Submissions are read, prepared and judged side by side (``--jobs``, default one per CPU) by ONE
``Grader`` (the reference's answers are computed once for the class), their runs of student code
side by side, each in its own sandbox (``sandbox.py``: one run of a submission at a time). Each student's
result is saved as it finishes (``.<gradebook name>-state/<student>.json`` next to the
gradebook, keyed by a hash of the submission's files and of everything that decides the
points: the reference, the hidden checks, the grader's code and its limits), so an
interrupted run resumes where it stopped, and a rerun grades only what changed (delete that
folder to grade everything again). The saved file also keeps the grading's secret (the hidden
inputs are drawn from it, ``Grader.grade``) and the hash of the files it graded: a regrade of the
same files (the grader or a limit changed) draws the same hidden inputs; new files, a new secret.
The secret never reaches the gradebook or the feedback. The gradebook holds no time stamps:
grading the same folder twice writes the same bytes.

Time limits: the grader runs each TODO of a submission as one sandboxed run (10 runs), and
``--time-limit`` L bounds each run's CPU time (a wall-clock backstop of 3L + 10 s ends code that only
waits, so a busy machine slows runs without timing them out); all runs of one submission take at
most ``BUDGET_FACTOR`` x L of wall clock together, after which the TODOs not yet run fail as timed
out. Code that never ends costs its TODO; the others keep their points, and the status says
``timed out: <TODOs>``. Any failure while reading or grading one submission is that submission's
row (``grader error: ...`` when it is the grader's own, not saved, so a rerun tries it again); the
class goes on, and every feedback file is written (``submissions.file_name``: bounded and
collision-free names). Without a sandbox no submission is graded (``Grader.refusal``).
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

from hwtools import markers
from hwtools.grade import kits
from hwtools.grade.instructor import class_summary
from hwtools.grade.instructor.class_feedback import feedback_markdown
from hwtools.grade.grader import HIDDEN_CHECKS, KIT_ROOT, Grader, GradingError, has_solutions, is_secret
from hwtools.grade.instructor.canvas import RosterError, canvas_import, read_roster
from hwtools.grade.instructor.gradebook import StudentResult, gradebook_text, status_of
from hwtools.grade.instructor.class_progress import Progress
from hwtools.grade.safe_text import printable
from hwtools.grade.submissions import Unusable, file_name, kit_file_names, open_submission

STATE_VERSION = 1


def _umask():
    """The process's umask, read without changing it (Linux), else the usual 022."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    return 0o022


def find_submissions(folder, skip=()):
    """{student id: [paths]} of the submissions in ``folder``: each folder and each file (a ``.zip``;
    anything else is listed too, to be reported as unreadable), by name without ``.zip``; the leftovers
    of editors and tools (``markers.is_leftover``: names starting with a dot, ``__MACOSX``, ``*~``, ...)
    and the paths in ``skip`` (the gradebook, the feedback folder) are left out."""
    folder = Path(folder)
    skip = {os.path.realpath(path) for path in skip}
    found = {}
    for item in sorted(folder.iterdir(), key=lambda item: item.name):
        if markers.is_leftover(item.name) or os.path.realpath(item) in skip:
            continue
        student = item.name[:-4] if item.name.lower().endswith(".zip") and not item.is_dir() else item.name
        found.setdefault(student, []).append(item)
    return found


def grading_fingerprint(grader):
    """A hash of everything, besides the submission, that decides a result: the reference's
    ``hwlib``, its hidden checks, the grader's own code and the tables it reads, the limits, the
    Python and the sandbox. A saved result is reused only under the same fingerprint."""
    digest = hashlib.sha256(f"state {STATE_VERSION}\0".encode())
    digest.update(kits.files_digest(grader.layout.files).encode())
    hidden = Path(grader.reference) / HIDDEN_CHECKS
    digest.update(hidden.read_bytes() if hidden.is_file() else b"no hidden checks")
    grade = Path(__file__).resolve().parents[1]  # every module of the grader, in its folders too (checks/, in_sandbox/)
    for path in sorted(grade.rglob("*.py")) + [grade.parent / "todos.py"]:
        digest.update(path.relative_to(grade.parent).as_posix().encode() + b"\0" + path.read_bytes())
    box = grader.sandbox
    for part in (box.python, box.isolated, box.how, box.time_limit, box.memory_limit):
        digest.update(f"\0{part}".encode())
    return digest.hexdigest()


class StateStore:
    """Saved results, one JSON file per student, written atomically as each one finishes."""

    def __init__(self, folder, fingerprint):
        self.folder = Path(folder)
        self.fingerprint = fingerprint

    def key(self, digest):
        return hashlib.sha256(f"{self.fingerprint}\0{digest}".encode()).hexdigest()

    def _path(self, student):
        return self.folder / f"{file_name(student)}.json"

    def load(self, student, digest):
        try:
            data = json.loads(self._path(student).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        if not isinstance(data, dict) or data.get("key") != self.key(digest) or data.get("student") != student:
            return None
        return data

    def secret(self, student, digest):
        """The secret of the saved grading of the same files (``digest``) as this student's, under any
        grading fingerprint (a regrade), or None (no such grading: a new secret is drawn)."""
        try:
            data = json.loads(self._path(student).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        if not isinstance(data, dict) or data.get("student") != student or data.get("files") != digest:
            return None
        return data["secret"] if is_secret(data.get("secret")) else None

    def save(self, student, digest, status, result, notes, secret=None):
        self.folder.mkdir(parents=True, exist_ok=True)
        data = {"version": STATE_VERSION, "student": student, "key": self.key(digest), "status": status,
                "notes": notes, "result": result, "files": digest, "secret": secret}
        _write_atomically(self._path(student), json.dumps(data, indent=1, sort_keys=True) + "\n")


def _write_atomically(path, text):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="") as stream:
            stream.write(text)
            os.fchmod(stream.fileno(), 0o666 & ~_umask())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _public(result, student):
    """The result with the paths of this machine replaced by what a student may read, and without
    the grading's secret (the state keeps it beside the result)."""
    result = dict(result)
    result["submission"] = student
    result["reference"] = "the instructor's reference solution"
    result.pop("seconds", None)
    result.pop("secret", None)
    return result


def grade_one(grader, path, student, kit_names, store=None):
    """Read and grade one submission; a ``StudentResult``. With ``store``, a saved result for the
    same files and grading is reused, and a new one is saved."""
    started = time.monotonic()
    paths = path if isinstance(path, list) else [path]
    if len(paths) > 1:
        names = ", ".join(item.name for item in paths)
        return StudentResult(student, f"rejected: more than one submission under this id ({names})")
    try:
        with open_submission(paths[0], kit_names) as opened:
            if store is not None:
                saved = store.load(student, opened.digest)
                if saved is not None:
                    return StudentResult(student, saved["status"], saved["result"], saved["notes"], reused=True)
            secret = store.secret(student, opened.digest) if store is not None else None  # a regrade: the same inputs
            graded = grader.grade(opened.kit, secret=secret)
            result = _public(graded, student)
            status = status_of(result)
            if store is not None and "grader error" not in status:  # a grader's own failure is tried again
                store.save(student, opened.digest, status, result, opened.notes, graded.get("secret"))
            return StudentResult(student, status, result, opened.notes, seconds=time.monotonic() - started)
    except Unusable as unusable:
        return StudentResult(student, unusable.text, seconds=time.monotonic() - started)


def _write_if_changed(path, text):
    path = Path(path)
    try:
        if path.read_text(encoding="utf-8") == text:
            return
    except OSError:
        pass
    _write_atomically(path, text)


@dataclass
class ClassReport:
    """What ``grade_class`` did: ``students`` (StudentResult, sorted by id), the paths written, and
    how many submissions were graded now, reused from the saved state, or not gradable."""

    students: list
    gradebook: Path
    feedback: Path
    state: Path
    graded_now: int = 0
    reused: int = 0
    not_graded: int = 0
    errors: list = field(default_factory=list)
    canvas: object = None  # the canvas.CanvasImport written beside the gradebook


def cpu_count():
    """The CPUs this process may run on (a container's or a cpuset's share, where the system says)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def state_folder(gradebook):
    gradebook = Path(gradebook)
    return gradebook.parent / f".{gradebook.stem}-state"


def canvas_file(gradebook):
    """Where the class run writes the Canvas import beside ``gradebook`` (grades.csv: grades-canvas.csv)."""
    return gradebook.with_name(f"{gradebook.stem}-canvas.csv")


def grade_class(submissions, gradebook, feedback, reference=None, *, jobs=None, grader=None, progress=None,
                roster=None, assignment=None, **grader_options):
    """Grade every submission in the folder ``submissions`` against ``reference`` (the instructor's
    kit) and write the gradebook CSV ``gradebook`` and one Markdown file per student in ``feedback``.

    ``jobs``: submissions graded side by side (default: one per CPU), their runs too (``sandbox.py``).
    ``grader``: a ``Grader`` to use (its reference answers are computed once, for the whole
    class); else one is made with ``grader_options`` (python, isolation, time_limit,
    memory_limit). ``progress``: a text stream for the progress line (None: silent). ``roster`` (a
    ``canvas.Roster``, Canvas's own export) and ``assignment`` (its column): what the Canvas import
    beside the gradebook is written for (``canvas.canvas_import``). Returns a ``ClassReport``. A
    submission that cannot be read gets 0 and its reason; the others are graded.
    """
    submissions, gradebook, feedback = Path(submissions), Path(gradebook), Path(feedback)
    if not submissions.is_dir():
        raise GradingError(f"{submissions}: not a folder of submissions")
    jobs = int(jobs or cpu_count())
    if jobs < 1:
        raise GradingError(f"jobs must be at least 1, got {jobs}")
    if grader is None:
        if reference is None:
            raise GradingError("grading a class needs the instructor's kit as the reference (--reference KIT_DIR)")
        grader = Grader(reference, jobs=1, **grader_options)
    if grader.reference is None:
        raise GradingError("grading a class needs the instructor's kit as the reference, not an answer key: "
                           "the hidden checks decide points too")
    try:  # a roster or an assignment the Canvas import cannot use stops here, before anything is graded
        canvas_import([], roster, assignment)
    except ValueError as error:
        raise GradingError(str(error)) from None
    refused = grader.refusal()
    if refused:  # fail closed: no sandbox, no student code
        raise GradingError(refused)
    state = state_folder(gradebook)
    store = StateStore(state, grading_fingerprint(grader))
    skip = (gradebook, canvas_file(gradebook), feedback, state) + ((roster.path,) if roster is not None else ())
    found = find_submissions(submissions, skip=skip)
    kit_names = kit_file_names(grader.layout)
    meter = Progress(len(found), progress)
    if progress is not None:
        how = grader.sandbox.how if grader.sandbox.isolated else f"NOT ISOLATED: {grader.sandbox.how}"
        progress.write(f"grading {len(found)} submission(s) in {submissions}, {jobs} at a time; sandbox: {how}\n")
        progress.flush()
    results, errors = [], []

    def task(student):
        try:
            student_result = grade_one(grader, found[student], student, kit_names, store)
        except GradingError:
            raise
        except Exception as error:  # noqa: BLE001 - one submission's failure is its own row, the class goes on
            student_result = StudentResult(student, f"grader error: {type(error).__name__}: {str(error)[:300]}")
        if student_result.status.startswith("grader error") or "; grader error" in student_result.status:
            errors.append(f"{student}: {student_result.status}")
        return student_result

    pool = ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="hwclass")
    try:
        futures = [pool.submit(task, student) for student in sorted(found)]
        for future in as_completed(futures):
            student_result = future.result()
            results.append(student_result)
            meter.update(student_result)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        meter.close()
        if progress is not None:
            progress.write(f"stopped: {sum(r.result is not None and not r.reused for r in results)} graded now and "
                           "saved; the submissions being graded finish and are saved before the program ends. Run the "
                           "same command again to go on from there.\n")
        raise
    pool.shutdown(wait=True)
    meter.close()
    results.sort(key=lambda item: item.student)
    _write_atomically(gradebook, gradebook_text(results))
    canvas = canvas_import(results, roster, assignment)  # the same totals for Canvas's import
    _write_atomically(canvas_file(gradebook), canvas.text)
    class_summary.write(results, gradebook)  # beside it: each check's pass rate, each named mistake's count
    feedback.mkdir(parents=True, exist_ok=True)
    for student_result in results:
        try:
            _write_if_changed(feedback / f"{file_name(student_result.student)}.md", feedback_markdown(student_result))
        except Exception as error:  # noqa: BLE001 - one student's file must not cost the others theirs
            errors.append(f"{student_result.student}: the feedback file could not be written "
                          f"({type(error).__name__}: {error})")
    report = ClassReport(results, gradebook, feedback, state, errors=errors, canvas=canvas)
    for student_result in results:
        if student_result.result is None:
            report.not_graded += 1
        elif student_result.reused:
            report.reused += 1
        else:
            report.graded_now += 1
    return report


def main(args, parser):
    """The command line's batch mode (``python -m hwtools.grade SUBMISSIONS_DIR --gradebook ... --feedback ...``)."""
    if not args.gradebook or not args.feedback:
        parser.error(f"{args.submission}: no hwlib/ folder, so it is read as a folder of submissions (one folder or "
                     ".zip per student): give --gradebook FILE.csv and --feedback FOLDER (or give a kit's folder "
                     "to grade one kit)")
    for option, given in (("--todo", args.todo), ("--json", args.json), ("--answer-key", args.answer_key)):
        if given:
            parser.error(f"{option} is for grading one kit; a folder of submissions is graded whole")
    if args.jobs is not None and args.jobs < 1:
        parser.error(f"--jobs must be at least 1, got {args.jobs}")
    reference = args.reference
    if reference is None:
        if not has_solutions(KIT_ROOT):
            parser.error("grading a class needs the instructor's kit: pass --reference KIT_DIR")
        reference = KIT_ROOT
    try:
        roster = read_roster(args.roster) if args.roster else None
    except RosterError as error:
        print(f"error: --roster {error}", file=sys.stderr)
        return 2
    try:  # the release gate (instructor/gate.py): a kit not ready to grade with is refused before anything is written
        from instructor import gate  # noqa: PLC0415 - the instructor's kit's own tools
    except ImportError:
        parser.error("grading a class needs the instructor's kit's instructor/ folder (its release gate)")
    try:
        gate.check(reference, "the class run")
    except gate.Refused as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    try:
        report = grade_class(args.submission, args.gradebook, args.feedback, reference, jobs=args.jobs,
                             progress=sys.stderr, roster=roster, assignment=args.assignment, python=args.python,
                             isolation=args.isolation, time_limit=args.time_limit,
                             memory_limit=args.memory_limit * 2**20)
    except GradingError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    print(f"{len(report.students)} submission(s): {report.graded_now} graded now, {report.reused} unchanged since "
          f"the saved results, {report.not_graded} not gradable (status in the gradebook)")
    print(f"gradebook: {report.gradebook}")
    canvas = report.canvas
    print(f"for Canvas: {canvas_file(report.gradebook)} ({canvas.rows} row(s), column {printable(canvas.assignment)!r}"
          + (f"; {len(canvas.blank)} roster student(s) without a submission, left blank" if roster else "") + ")")
    for submission, why in sorted(canvas.not_written.items()):
        print(f"not in the Canvas import: {printable(submission)}: {printable(why)}", file=sys.stderr)
    for note in canvas.notes:
        print(f"note: {printable(note)}")
    print(f"feedback: {report.feedback}/ (one .md per student)")
    for error in report.errors:
        print(f"grader error (not saved; rerun to retry): {error}", file=sys.stderr)
    return 1 if report.errors else 0

