"""Hand in: one command builds what the handout asks for (CS231n's ``collect_submission`` convention).

    python -m hwtools.handin ANDREW_ID [--name "Ada Lovelace"] [--out handin/] [--no-report]

writes into ``handin/`` (next to the kit's ``hwlib/`` unless ``--out`` says otherwise):

* ``ANDREW_ID.zip``: your code, ``hwlib/`` (every ``.py`` file) and ``notebooks/`` (the notebooks as
  saved), for Canvas. Before it says so, the command opens the zip with the grader's own reader
  (``hwtools.grade.classroom.open_submission``, the one that reads a class's zips) and reads the
  code of every TODO from it, so a zip it accepts is one the grader can grade; it names every TODO
  whose code is still the stub.
* ``ANDREW_ID.pdf``: the report (``python -m hwtools.report``, which runs both notebooks from a fresh
  kernel), for Gradescope; the whole report, its figures and, where the report writes it, the
  LaTeX source ``answers.tex``, are in ``handin/report/``.

The zip holds no time stamps: the same files give the same bytes.
"""

from __future__ import annotations

import argparse
import io
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

from hwtools.check import KIT_ROOT, untouched_todos
from hwtools.todos import TODO_BY_ID

ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # the earliest date a zip can hold: no time stamps
ANDREW_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
SKIPPED = {"__pycache__", ".ipynb_checkpoints"}


class HandinError(Exception):
    """Something the student must fix before handing in."""


def code_files(kit):
    """The files of the hand-in, as sorted paths relative to ``kit``: hwlib/**/*.py and notebooks/*.ipynb."""
    kit = Path(kit)
    found = []
    for pattern in ("hwlib/**/*.py", "notebooks/*.ipynb"):
        for path in kit.glob(pattern):
            relative = path.relative_to(kit)
            if path.is_file() and not path.is_symlink() and not SKIPPED & set(relative.parts):
                found.append(relative.as_posix())
    if not any(name.startswith("hwlib/") for name in found):
        raise HandinError(f"{kit}: no hwlib/ folder with Python files; run this from the kit")
    return sorted(found)


def write_zip(kit, out_path):
    """Write the zip of the code of the kit at ``kit`` to ``out_path``; returns the names in it."""
    names = code_files(kit)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in names:
            info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            archive.writestr(info, (Path(kit) / name).read_bytes())
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_bytes(buffer.getvalue())
    return names


def read_back(zip_path, kit):
    """Open the zip as the grader opens a student's zip and read every TODO's code from it.

    Returns ({TODO id: why its code cannot be read}, the files the reader took); raises HandinError
    when the reader refuses the zip."""
    from hwtools.grade import blocks, classroom  # noqa: PLC0415 - the grader's own reader

    try:
        layout = blocks.load_layout(kit)
    except blocks.SubmissionError as error:
        raise HandinError(f"the TODO markers in your files do not pair up: {error} (each TODO's code sits between "
                          "its ### BEGIN TODO and ### END TODO lines, as the kit gave them)") from None
    try:
        with classroom.open_submission(zip_path, classroom.kit_file_names(layout)) as opened:
            taken = sorted(path.relative_to(opened.kit).as_posix() for path in opened.kit.rglob("*") if path.is_file())
            read = blocks.read_submission(opened.kit, layout)
    except classroom.Unusable as error:
        raise HandinError(f"the grader's reader refuses {zip_path}: {error.text()}") from None
    return dict(read.problems), taken


def build_report(kit, out_dir, name):
    """Run the report (a subprocess, as a student would) into ``out_dir``; its PDF, or HandinError."""
    command = [sys.executable, "-m", "hwtools.report", str(out_dir), "--name", name]
    done = subprocess.run(command, cwd=kit, capture_output=True, text=True)
    if done.returncode != 0:
        lines = [line for line in (done.stderr + done.stdout).splitlines() if line.strip()]
        why = next((line for line in lines if "not done yet" in line), None) or "\n".join(lines[-12:])
        raise HandinError(f"the report could not be built (python -m hwtools.report):\n{why}")
    pdf = Path(out_dir) / "answers.pdf"
    if not pdf.is_file():
        raise HandinError(f"the report wrote no {pdf}")
    return pdf


def handin(andrew_id, kit=KIT_ROOT, out_dir=None, name=None, report=True, say=print):
    """Build the hand-in of the kit at ``kit``; returns {"zip": path, "pdf": path or None, "untouched": [...]}."""
    if not ANDREW_ID.fullmatch(andrew_id or ""):
        raise HandinError(f"{andrew_id!r} is not an Andrew ID (letters, digits, '.', '_' or '-'; it names the zip)")
    kit = Path(kit).resolve()
    out_dir = Path(out_dir).resolve() if out_dir else kit / "handin"
    zip_path = out_dir / f"{andrew_id}.zip"
    names = write_zip(kit, zip_path)
    problems, taken = read_back(zip_path, kit)
    if problems:
        lines = [f"  TODO {todo}: {why}" for todo, why in sorted(problems.items())]
        raise HandinError("the grader cannot read the code of these TODOs from your files:\n" + "\n".join(lines))
    left_out = sorted(set(names) - set(taken))
    if left_out:
        raise HandinError(f"the grader's reader leaves out {', '.join(left_out[:5])}: check those files")
    untouched = untouched_todos(kit)
    say(f"{zip_path}: {len(names)} files, {zip_path.stat().st_size / 1e6:.2f} MB; the grader's reader opens it and "
        f"finds the code of every TODO")
    for todo in untouched:
        say(f"  TODO {todo} ({TODO_BY_ID[todo].title}) is not done yet: its code is still the stub")
    result = {"zip": zip_path, "pdf": None, "untouched": untouched}
    if report:
        report_dir = out_dir / "report"
        if report_dir.exists():
            shutil.rmtree(report_dir)
        say("building the report (it runs both notebooks from a fresh kernel; about a minute) ...")
        pdf = build_report(kit, report_dir, f"{name} / {andrew_id}" if name else andrew_id)
        target = out_dir / f"{andrew_id}.pdf"
        shutil.copyfile(pdf, target)
        result["pdf"] = target
        say(f"{target}: the report (all its files, the LaTeX source included where written, are in {report_dir})")
    say("")
    say(f"Hand in {zip_path.name} on Canvas" + (f" and {andrew_id}.pdf on Gradescope." if report else "."))
    return result


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m hwtools.handin",
                                     description="Build the hand-in: ANDREW_ID.zip (your code, read back with the "
                                                 "grader's reader) and ANDREW_ID.pdf (the report).")
    parser.add_argument("andrew_id", metavar="ANDREW_ID", help="your Andrew ID: it names the zip and the PDF")
    parser.add_argument("--name", help="your name, for the report's name line (NAME / ANDREW_ID)")
    parser.add_argument("--out", metavar="FOLDER", help="where to write them (default: handin/ in the kit)")
    parser.add_argument("--no-report", action="store_true", help="only the zip, without running the notebooks")
    args = parser.parse_args(argv)
    try:
        handin(args.andrew_id, out_dir=args.out, name=args.name, report=not args.no_report)
    except HandinError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
