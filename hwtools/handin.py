"""Hand in: one command builds what the handout asks for (CS231n's ``collect_submission`` convention).

    python -m hwtools.handin ANDREW_ID [--name "Ada Lovelace"] [--out handin/] [--no-report]

It checks first and writes nothing until then:

1. the zip is built in memory and opened with the grader's own reader (``hwtools.grade.submissions
   .open_submission``, the one that reads a class's zips), which must find the code of every TODO;
   otherwise it stops, naming the TODO and the file, and writes nothing;
2. the visible checks run, each as the notebook's ``check("1.2.1")`` cell runs it
   (``hwtools.check_cell``), and it says which fail and whether training converges (TODO 1.3.3). A
   failing check does not stop the hand-in: it is yours to decide.

Then it writes into ``handin/`` (next to the kit's ``hwlib/`` unless ``--out`` says otherwise):

* ``ANDREW_ID.zip``: your code, ``hwlib/`` (every ``.py`` file) and ``notebooks/`` (the notebooks as
  saved), for Canvas. No time stamps: the same files give the same bytes. What editors and Jupyter
  leave beside your files (``.ipynb_checkpoints/``, ``*~``, ``.swp``; ``markers.is_leftover``) is
  left out, as every reader of the kit leaves it out.
* ``ANDREW_ID.pdf``: the PDF to upload to Gradescope. First the report (``python -m hwtools.report``,
  which runs both notebooks from a fresh kernel); its files, and the LaTeX source ``answers.tex`` for
  your words, are in ``handin/report/``. Once you have written your words in ``handin/report/answers.tex``
  and compiled it there (``pdflatex answers.tex``, which writes ``handin/report/answers.pdf``), the next
  hand-in copies that PDF here (``upload_pdf``), or says it is older than your ``answers.tex``.
  A new report is built beside the previous one and replaces it only once complete, your words carried
  into its ``answers.tex`` and every file of yours kept (``report/words.py``); where a file of the old
  report is held open (a PDF viewer on Windows), the old one is kept whole and it says which file.
  Without a Chrome, Edge or Chromium there is no report PDF: the rest is put in place all the same, and
  it says how to make the PDF.

Each step says how long it took; at the end, the whole hand-in's time.
"""

from __future__ import annotations

import argparse
import io
import os
import re
import shutil
import sys
import time
import zipfile
from pathlib import Path

from hwtools import markers
from hwtools.check_cell import CheckError, check_lines, grade_todo, run_polled
from hwtools.files import held_open, held_words, printable_output, remove_quietly, replace_bytes, retrying, scratch_folder
from hwtools.grade.judging import visible_view
from hwtools.not_done import KIT_ROOT

ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # the earliest date a zip can hold: no time stamps
ANDREW_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
TRAINING = "1.3.3"  # the TODO whose check trains with the student's LEARNING_RATE
# What the report costs, said before it starts (the real time is said after): benchmarks/bench_dayone.py --done,
# 2026-12-02, 2 cores at load 3-7: 1 min 32 s to 2 min 18 s.
REPORT_TIME = "1.5 to 2.5 minutes on 2 cores with other programs running"
REPORT_SECONDS = 3600.0  # the report's own cells have their limits (CELL_TIMEOUT); this bounds the whole


class HandinError(Exception):
    """Something the student must fix before handing in."""


def code_files(kit):
    """The files of the hand-in, as sorted paths relative to ``kit``: hwlib/**/*.py and notebooks/*.ipynb,
    without the leftovers of editors, Jupyter and Python (``markers.is_leftover``) and without links."""
    kit = Path(kit)
    found = []
    for pattern in ("hwlib/**/*.py", "notebooks/*.ipynb"):
        for path in kit.glob(pattern):
            relative = path.relative_to(kit).as_posix()
            if path.is_file() and not path.is_symlink() and not markers.is_leftover(relative):
                found.append(relative)
    if not any(name.startswith("hwlib/") for name in found):
        raise HandinError(f"{kit}: no hwlib/ folder with Python files; run this from the kit")
    clash = markers.name_clash(found)
    if clash:
        raise HandinError(f"{clash[0]} and {clash[1]} are one file on macOS and Windows (their names differ only in "
                          "letter case or Unicode normalisation), and the grader refuses such a zip: rename or delete "
                          "one (nothing was written)")
    return sorted(found)


def zip_bytes(kit, names):
    """The zip of the files ``names`` of the kit at ``kit``, as bytes: sorted, no time stamps."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in names:
            info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            archive.writestr(info, (Path(kit) / name).read_bytes())
    return buffer.getvalue()


def read_back(zip_path, kit):
    """Open the zip as the grader opens a student's zip and read every TODO's code from it.

    Returns ({TODO id: why its code cannot be read}, the files the reader took); raises HandinError
    when the reader refuses the zip."""
    from hwtools.grade import blocks, submissions  # noqa: PLC0415 - the grader's own reader

    try:
        layout = blocks.load_layout(kit)
    except blocks.SubmissionError as error:
        raise HandinError(f"the TODO markers in your files do not pair up: {error} (each TODO's code sits between "
                          "its ### BEGIN TODO and ### END TODO lines, as the kit gave them)") from None
    try:
        with submissions.open_submission(zip_path, submissions.kit_file_names(layout)) as opened:
            taken = sorted(path.relative_to(opened.kit).as_posix() for path in opened.kit.rglob("*") if path.is_file())
            read = blocks.read_submission(opened.kit, layout)
    except submissions.Unusable as error:
        raise HandinError(f"the grader's reader refuses the zip: {error.text}") from None
    return dict(read.problems), taken


def checked_zip(kit, andrew_id):
    """(the zip's bytes, its file names) once the grader's reader has read every TODO's code from it;
    else HandinError. Nothing is written but a temporary copy, deleted at once."""
    names = code_files(kit)
    data = zip_bytes(kit, names)
    with scratch_folder("hwhandin-") as scratch:
        trial = scratch / f"{andrew_id}.zip"
        trial.write_bytes(data)
        problems, taken = read_back(trial, kit)
    if problems:
        lines = [f"  TODO {todo}: {why}" for todo, why in sorted(problems.items())]
        raise HandinError("the grader cannot read the code of these TODOs from your files (nothing was written):\n"
                          + "\n".join(lines) + "\nEach TODO's code goes between its ### BEGIN TODO and ### END TODO "
                          "lines, in the file the kit gave; put back what is missing and run this again.")
    left_out = sorted(set(names) - set(taken))
    if left_out:
        raise HandinError(f"the grader's reader leaves out {', '.join(left_out[:5])} (nothing was written): check "
                          "those files")
    return data, names


def visible_checks(kit, say=print):
    """Run every TODO's visible checks as its check cell does; say a line per TODO (all of a failing
    one's lines) and whether training converges. Returns the ids of the TODOs whose checks do not pass."""
    from hwtools.grade.checks import GRADED_TODOS  # noqa: PLC0415 - the TODOs that have checks

    failing = []
    for todo in GRADED_TODOS:
        try:
            entry = grade_todo(todo, kit=kit)
        except CheckError as error:
            say(f"  TODO {todo}: the check could not run ({error})")
            failing.append(todo)
            continue
        entry = visible_view(entry)
        lines = check_lines(entry)
        if entry["status"] == "graded" and all(check["passed"] for check in entry["checks"]):
            say(f"  {lines[0]}")
        else:
            failing.append(todo)
            say("\n".join(f"  {line}" for line in lines))
    if TRAINING in GRADED_TODOS:
        say(f"  training with your LEARNING_RATE {'does NOT converge' if TRAINING in failing else 'converges'} within "
            f"7 iterations (the check of TODO {TRAINING})")
    return failing


def build_report(kit, out_dir, name):
    """Run the report (a subprocess, as a student would) into ``out_dir``; its PDF (None where no browser printed
    it: the rest of the report is written), or HandinError. Its pipes carry UTF-8, and an interrupt ends it."""
    command = [sys.executable, "-m", "hwtools.report", str(out_dir), "--name", name]
    with scratch_folder("hwhandin-") as scratch:
        try:
            code, stdout, stderr = run_polled(command, kit, scratch, REPORT_SECONDS)
        except CheckError as error:  # it ran over its time
            raise HandinError(f"the report could not be built (python -m hwtools.report): {error}") from None
    if code != 0:
        lines = [line for line in (stderr + stdout).splitlines() if line.strip()]
        why = next((line for line in lines if "not done yet" in line), None) or "\n".join(lines[-12:])
        raise HandinError(f"the report could not be built (python -m hwtools.report):\n{why}")
    pdf = Path(out_dir) / "answers.pdf"
    return pdf if pdf.is_file() else None


def _no_browser():
    from hwtools.report.chromium import NO_BROWSER  # imported only here: hwtools.report loads matplotlib (1.5 s)

    return NO_BROWSER


def minutes(seconds):
    """``seconds`` as a student reads a wait: "48 s", "2 min 05 s"."""
    return f"{seconds:.0f} s" if seconds < 60 else f"{int(seconds // 60)} min {int(seconds % 60):02d} s"


def _written(path):
    return time.strftime("%Y-%m-%d %H:%M", time.localtime(path.stat().st_mtime))


def write_report(kit, out_dir, andrew_id, name, say=print):
    """Build the report beside ``out_dir/report`` and put it in place once complete, the student's words and
    files kept (``_keep_students``); the report's PDF becomes ``out_dir/ANDREW_ID.pdf``. Either both are
    replaced or neither: where a file of the old ones is held open (Windows), the old ones are kept whole and
    HandinError names that file. Returns the PDF's path (None, and a previous PDF removed, without one)."""
    report_dir, target = out_dir / "report", out_dir / f"{andrew_id}.pdf"
    building = out_dir / f".report-building-{os.getpid()}"
    remove_quietly(building)
    try:
        pdf = build_report(kit, building, f"{name} / {andrew_id}" if name else andrew_id)
        if pdf is not None:  # report/ keeps no answers.pdf of its own: one there is the student's, from answers.tex
            pdf = retrying(pdf.rename, out_dir / f".{andrew_id}.pdf.new-{os.getpid()}")
        if report_dir.is_dir():
            _keep_students(report_dir, building, say)
    except BaseException as error:
        remove_quietly(building)
        if isinstance(error, HandinError) and report_dir.exists():
            raise HandinError(f"{error}\nYour previous report in {report_dir} (written {_written(report_dir)}) is "
                              "kept as it was.") from None
        raise
    if report_dir.exists():
        say(f"  it replaces the previous report in {report_dir} (written {_written(report_dir)})")
    _swap(report_dir, building, target, pdf, say)
    return target if pdf is not None else None


def _keep_students(report_dir, building, say):
    """Carry into the new report in ``building`` what the student wrote in the old one: their words in
    answers.tex (``words.write_answers``) and every file of theirs the report does not write (a figure of their
    own, the answers.pdf pdflatex made, answers.new.tex)."""
    from hwtools.report.words import AS_WRITTEN, write_answers  # noqa: PLC0415 - standard library only

    note = write_answers(building, (building / AS_WRITTEN).read_text(encoding="utf-8"), words_from=report_dir)
    if note:
        say(f"  {note}")
    for path in sorted(report_dir.rglob("*")):
        relative = path.relative_to(report_dir)
        kept = building / relative
        if path.is_file() and not kept.exists() and not any(part.startswith(".") for part in relative.parts):
            kept.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(path, kept)


def _swap(report_dir, building, target, pdf, say):
    """Put the folder ``building`` in place of ``report_dir`` and the file ``pdf`` (None: none) in place of
    ``target``, both or neither (the old ones kept whole, and HandinError naming the file held open)."""
    old = report_dir.with_name(f".report-old-{os.getpid()}")
    undo = []
    try:
        if report_dir.exists():
            _move(report_dir, old, report_dir)
            undo.append((old, report_dir))
        _move(building, report_dir, report_dir)
        undo.append((report_dir, building))
        if pdf is not None:
            _move(pdf, target, target)
        elif target.exists():
            retrying(target.unlink)
    except (HandinError, OSError) as error:
        for moved, back in reversed(undo):
            retrying(os.rename, moved, back)
        remove_quietly(building)
        if pdf is not None:
            remove_quietly(pdf)
        why = error if isinstance(error, HandinError) else held_words(target)
        raise HandinError(f"{why}. The new report is not written; your previous report"
                          + (f" ({report_dir}, {target.name})" if report_dir.exists() else "") + " is kept whole.") from None
    if not remove_quietly(old):
        held = held_open(old)
        say(f"  the previous report stays in {old}: " + (held_words(held) if held else "it could not be removed")
            + " (then remove that folder)")


def _move(source, destination, shown):
    """``os.replace`` retried briefly; where something stays held, HandinError naming the file."""
    try:
        retrying(os.replace, source, destination)
    except PermissionError:
        held = held_open(shown) if shown.exists() else None
        raise HandinError(held_words(held or shown)) from None


def _shown(path, kit):
    """``path`` as the student finds it: from the kit's folder, where they run this, if it is in it."""
    return path.relative_to(kit).as_posix() if path.is_relative_to(kit) else str(path)


def upload_pdf(out_dir, andrew_id, say=print):
    """The PDF to upload, ``out_dir/ANDREW_ID.pdf``, made the student's where their answers.tex has words of theirs
    and they compiled it since (``report/answers.pdf``, newer than ``report/answers.tex``); None, said, where their
    words are in no PDF yet. The report's own PDF otherwise."""
    from hwtools.report.words import has_words  # noqa: PLC0415

    report_dir, target = out_dir / "report", out_dir / f"{andrew_id}.pdf"
    tex, own = report_dir / "answers.tex", report_dir / "answers.pdf"
    if not has_words(report_dir):
        return target if target.is_file() else None
    if own.is_file() and own.stat().st_mtime >= tex.stat().st_mtime:
        if not target.is_file() or target.read_bytes() != own.read_bytes():
            try:
                replace_bytes(target, own.read_bytes())
            except PermissionError as error:
                raise HandinError(f"{error} (your compiled report {own} is not copied)") from None
            say(f"{target}: your compiled answers.tex, with your words (a copy of {own})")
        return target
    say(f"your words in {tex} are in no PDF yet: {own.name} there is "
        + ("older than your answers.tex" if own.is_file() else "not made yet")
        + f": compile it (in {report_dir}: pdflatex answers.tex, twice; or on Overleaf, into {own}) and run this again")
    return None


def handin(andrew_id, kit=KIT_ROOT, out_dir=None, name=None, report=True, say=print):
    """Build the hand-in of the kit at ``kit``; returns {"zip": path, "pdf": path or None, "failing": [TODO ids
    whose visible checks do not pass]}."""
    if not ANDREW_ID.fullmatch(andrew_id or ""):
        raise HandinError(f"{andrew_id!r} is not an Andrew ID (letters, digits, '.', '_' or '-'; it names the zip)")
    started = time.monotonic()
    kit = Path(kit).resolve()
    out_dir = Path(out_dir).resolve() if out_dir else kit / "handin"
    zip_path = out_dir / f"{andrew_id}.zip"
    data, names = checked_zip(kit, andrew_id)
    say(f"{len(names)} files; the grader's reader opens their zip and finds the code of every TODO")
    step = time.monotonic()
    say("the visible checks, as each check(...) cell runs them:")
    failing = visible_checks(kit, say)
    say(f"  ({minutes(time.monotonic() - step)}) "
        + (f"TODO {', '.join(failing)} {'does' if len(failing) == 1 else 'do'} not pass {'its' if len(failing) == 1 else 'their'} "
           "visible checks; you may still hand in, and fix and hand in again before the deadline."
           if failing else "every visible check passes."))
    out_dir.mkdir(parents=True, exist_ok=True)
    for place in (zip_path, out_dir / f"{andrew_id}.pdf", out_dir / "report"):  # before minutes of the report
        held = held_open(place)
        if held is not None:
            raise HandinError(f"{held_words(held)} (nothing was written)")
    replaced = zip_path.is_file() and zip_path.read_bytes() != data
    try:
        replace_bytes(zip_path, data)
    except PermissionError as error:
        raise HandinError(f"{error} (the zip is not written; the earlier one is kept)") from None
    say(f"{zip_path}: {len(data) / 1e6:.2f} MB" + (f" (it replaces the earlier {zip_path.name}, of other files)" if replaced else ""))
    result = {"zip": zip_path, "pdf": None, "failing": failing}
    if report:
        step = time.monotonic()
        say(f"building the report: both notebooks run from a fresh kernel, then the PDF is printed ({REPORT_TIME}) ...")
        pdf = write_report(kit, out_dir, andrew_id, name, say)
        say(f"{pdf}: the report ({minutes(time.monotonic() - step)}; all its files, answers.tex for your words "
            f"included, are in {out_dir / 'report'})" if pdf else
            f"{out_dir / 'report'}: the report without its PDF ({minutes(time.monotonic() - step)}): {_no_browser()}")
    result["pdf"] = upload_pdf(out_dir, andrew_id, say)
    say("")
    say(f"Hand in {_shown(zip_path, kit)} on Canvas" + (f" and {_shown(result['pdf'], kit)} on Gradescope." if result["pdf"] else
                                            " and, once made, the report's PDF on Gradescope (see above)." if report or
                                            (out_dir / "report").is_dir() else ".")
        + f" (hand-in took {minutes(time.monotonic() - started)})")
    return result


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m hwtools.handin",
                                     description="Build the hand-in: ANDREW_ID.zip (your code, read back with the "
                                                 "grader's reader, after the visible checks) and ANDREW_ID.pdf (the report).")
    parser.add_argument("andrew_id", metavar="ANDREW_ID", help="your Andrew ID: it names the zip and the PDF")
    parser.add_argument("--name", help="your name, for the report's name line (NAME / ANDREW_ID)")
    parser.add_argument("--out", metavar="FOLDER", help="where to write them (default: handin/ in the kit)")
    parser.add_argument("--no-report", action="store_true", help="only the zip, without running the notebooks")
    args = parser.parse_args(argv)
    printable_output()
    try:
        handin(args.andrew_id, out_dir=args.out, name=args.name, report=not args.no_report)
    except HandinError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted: the zip and the report are as they were before, unless said above", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
