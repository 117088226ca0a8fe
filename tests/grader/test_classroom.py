"""Grading a class: a generated folder of 30 submissions (correct ones, each wrong solution, each
cheat but the two that wait longest, an empty one, a zip with ../ paths, a zip with a 200 MB file, a
damaged zip, one that never ends) graded in one run on 2 jobs; every gradebook cell is the expected
one; a rerun writes the same bytes and grades nothing; a killed run resumes; and the reader refuses
what it must.

One ``Grader`` serves the module (as it serves a class): the reference's answers are computed once.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import shutil
import signal
import struct
import subprocess
import sys
import time
import tracemalloc
import unicodedata
import zipfile
from pathlib import Path

import numpy as np
import pytest

from hwtools.grade import AUTO_POINTS, TODOS, TODO_BY_ID, Grader, blocks, checks, kits, submissions
from hwtools.grade.instructor import classroom
from hwtools.grade.checks.verdicts import show
from hwtools.grade.instructor.gradebook import gradebook_header
from hwtools.grade.grader import BUDGET_FACTOR, read_answer_key
import editions
import test_grading as proof  # the grader's proof builds the wrong solutions and cheats

KIT = Path(__file__).resolve().parents[2]
TOTAL_COLUMN = f"auto total (/{AUTO_POINTS:g})"  # the gradebook's total column

TIME_LIMIT = 5.0  # per TODO's run: twice what the whole reference kit takes; the endless loop costs it once
# What a submission's runs may take together, by the wall clock: far more than they need on a machine shared with
# other gradings and test runs (they run side by side), since no test here is about the budget (test_sandbox's is).
BUDGET = 60 * TIME_LIMIT
JOBS = 2
HUGE = 200_000_000  # the 200 MB file: zeros, compressed to almost nothing, never written out
AUTO_TODOS = [todo.id for todo in TODOS if todo.auto]
# Wrong solutions in the class (one or more for each TODO with automatic points) and what each keeps
# of its own TODO's points; every other TODO keeps all of its own. Every wrong solution is graded
# alone in test_checks.py; the class shows a class run gives these the same cells.
# The wrong solutions in the class, each with the checks of its TODO whose points it keeps (the points: the TODO table).
WRONG_KEPT = {"forward_difference": (), "labels_not_one_vs_rest": (), "learning_rate_too_large": (),
              "logreg_gradient_descent": (), "logreg_mean_gradient": (), "one_vs_rest_inverted_labels": (),
              "policy_gradient_descent": ("records-reward",), "policy_mirror_image": (),
              "predict_prob_without_bias": ("zero-bias",), "sigmoid_wrong_sign": (), "single_rollout": ("repeatable",)}

# Cheats left out of the class: each holds its runs for seconds (a lock's timeouts, a child holding the error
# stream), and each is graded alone in test_grading.py; the class keeps the one that never ends.
SLOW_CHEATS = {"lock_channel", "stderr_holding_child"}

pytestmark = pytest.mark.timeout(900)


@pytest.fixture(scope="module")
def grader():
    return Grader(KIT, time_limit=TIME_LIMIT, jobs=1, budget=BUDGET)


@pytest.fixture(scope="module")
def layout():
    return blocks.load_layout(KIT)


@pytest.fixture(scope="module")
def answer_key(tmp_path_factory):
    return read_answer_key(editions.answer_key_file(tmp_path_factory))


def zip_folder(folder, archive_path, prefix=""):
    """Zip every file under ``folder`` with paths starting ``prefix``."""
    with zipfile.ZipFile(archive_path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for path in sorted(Path(folder).rglob("*")):
            if path.is_file():
                archive.write(path, prefix + path.relative_to(folder).as_posix())
    return archive_path


def write_huge_zip(path, inner="hwlib/finite_diff.py"):
    """A zip whose ``inner`` file holds HUGE zero bytes, deflated to a few hundred kB."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        info = zipfile.ZipInfo(inner)
        info.compress_type = zipfile.ZIP_DEFLATED
        with archive.open(info, "w", force_zip64=True) as stream:
            chunk = bytes(1_000_000)
            for _ in range(HUGE // len(chunk)):
                stream.write(chunk)
    return path


def full():
    return {todo: TODO_BY_ID[todo].auto for todo in AUTO_TODOS}


def zero():
    return {todo: 0.0 for todo in AUTO_TODOS}


class Class:
    """The generated class: folder, and per student the expected status and points."""

    def __init__(self, folder):
        self.folder = folder
        self.expected = {}

    def expect(self, student, status, points):
        assert student not in self.expected
        self.expected[student] = (status, points)


def graded(grader, base="graded"):
    """The status of a graded submission on this machine (the sandbox may be unavailable)."""
    if grader.sandbox.isolated:
        return base
    return "not isolated" if base == "graded" else f"{base}; not isolated"


@pytest.fixture(scope="module")
def a_class(tmp_path_factory, grader, layout, answer_key):
    from instructor.release import build_student_edition

    folder = tmp_path_factory.mktemp("class") / "submissions"
    folder.mkdir()
    scratch = tmp_path_factory.mktemp("scratch")
    made = Class(folder)

    # Correct: a folder, and a zip of a whole student edition one folder down, with macOS leftovers.
    kits.write_submission(layout, folder / "correct-folder", others="reference")
    made.expect("correct-folder", graded(grader), full())
    edition = scratch / "edition"
    build_student_edition(KIT, edition, keep=frozenset(TODO_BY_ID), answer_key=False)
    zip_folder(edition, folder / "correct-zip.zip", prefix="correct-zip/")
    with zipfile.ZipFile(folder / "correct-zip.zip", "a") as archive:
        archive.writestr("__MACOSX/correct-zip/hwlib/._cartpole.py", b"\x00\x05\x16\x07 resource fork")
    made.expect("correct-zip", graded(grader), full())

    # Wrong solutions, zipped one folder down: its own TODO loses, every other keeps its points.
    for name, kept in WRONG_KEPT.items():
        if not (proof.WRONG / f"{name}.txt").is_file():  # an offering deleted it (the release named it: no longer a mistake)
            continue
        todo, _, bodies = proof.parse_wrong_solution(proof.WRONG / f"{name}.txt")
        kit = kits.write_submission(layout, scratch / "wrong" / name / "hw1", {todo: bodies}, others="reference")
        zip_folder(kit.parent, folder / f"wrong-{name}.zip")
        made.expect(f"wrong-{name}", graded(grader), full() | {todo: sum(TODO_BY_ID[todo].check_points[key] for key in kept)})

    # Each cheat, as a folder (one of them holds a link).
    for path in [path for path in proof.CHEAT_FILES if path.stem not in SLOW_CHEATS]:
        cheat = proof.parse_cheat(path)
        student = f"cheat-{path.stem}"
        proof.build_cheat(layout, cheat, folder / student, answer_key)
        if cheat["links"]:
            made.expect(student, f"rejected: {cheat['links'][0]} is a link; only plain files are read", zero())
            continue
        if cheat["others"] == "reference":
            (own,) = cheat["loses"]
            points = full() | {own: cheat["points"] - (AUTO_POINTS - TODO_BY_ID[own].auto)}
        else:
            assert cheat["points"] == 0
            points = zero()
        timed_out = graded(grader, f"timed out: {', '.join(cheat['bodies'])}")
        if "time limit" in cheat["expect"]:
            status = timed_out
        elif "MemoryError" in cheat["expect"]:
            # Each case fills memory up to the limit again, and the kernel's page zeroing is CPU
            # time the run is charged with: on a loaded machine the fills may pass the CPU limit
            # first. Either way the same TODO, and only it, loses its points.
            status = frozenset({graded(grader), timed_out})
        else:
            status = graded(grader)
        made.expect(student, status, points)

    # Nothing to grade, or nothing that may be read.
    (folder / "empty").mkdir()
    made.expect("empty", "empty", zero())
    with zipfile.ZipFile(folder / "traversal.zip", "w") as archive:
        archive.writestr("hw1/hwlib/finite_diff.py", (KIT / "hwlib" / "finite_diff.py").read_text())
        archive.writestr("hw1/../../escaped.py", "print('outside')\n")
    made.expect("traversal", "rejected: a path that leaves the submission in the zip: 'hw1/../../escaped.py'", zero())
    write_huge_zip(folder / "huge.zip")
    made.expect("huge", f"rejected: hwlib/finite_diff.py: 200 MB, more than the {submissions.size_text(blocks.MAX_FILE_BYTES)}"
                        " read per file", zero())
    (folder / "damaged.zip").write_bytes(b"PK\x03\x04" + bytes(100))
    made.expect("damaged", "unreadable: not a zip file (no end-of-archive record)", zero())
    return made


def read_gradebook(path):
    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    return rows[0], {row[0]: dict(zip(rows[0], row)) for row in rows[1:]}, [row[0] for row in rows[1:]]


def auto_column(todo):
    info = TODO_BY_ID[todo]
    return f"{info.id} {info.title} (/{info.auto:g})"


@pytest.fixture(scope="module")
def first_run(a_class, grader, tmp_path_factory):
    out = tmp_path_factory.mktemp("out")
    progress = io.StringIO()
    started = time.monotonic()
    report = classroom.grade_class(a_class.folder, out / "grades.csv", out / "feedback", grader=grader, jobs=JOBS,
                                   progress=progress)
    return report, out, progress.getvalue(), time.monotonic() - started


def test_the_class_has_thirty_submissions_of_every_kind(a_class):
    assert len(a_class.expected) >= 30
    assert {"empty", "traversal", "huge", "damaged", "cheat-endless_loop"} <= set(a_class.expected)
    assert sum(path.suffix == ".zip" for path in a_class.folder.iterdir()) >= 14
    assert os.path.getsize(a_class.folder / "huge.zip") < 2_000_000


def test_every_gradebook_cell_is_the_expected_one(a_class, first_run):
    report, out, _, _ = first_run
    header, rows, order = read_gradebook(out / "grades.csv")
    assert header == gradebook_header()
    assert header[:2] == ["student", "status"] and header[-1] == "notes"
    assert [auto_column(todo) for todo in AUTO_TODOS] == header[2:2 + len(AUTO_TODOS)]
    assert header[2 + len(AUTO_TODOS)] == TOTAL_COLUMN
    manual = [column for column in header if " by hand: " in column]
    assert manual == [f"{todo.id} by hand: {todo.manual_what if todo.auto else todo.title} (/{todo.manual:g})"
                      for todo in TODOS if todo.manual]
    assert "1.1.2 by hand: hand-tuning the policy (/2)" in manual and "2.1.1 by hand: " in manual[-2]
    assert order == sorted(a_class.expected), "one row per student, sorted by id"
    for student, (status, points) in a_class.expected.items():
        row = rows[student]
        assert row["status"] in (status if isinstance(status, frozenset) else {status}), (student, row)
        for todo in AUTO_TODOS:
            assert float(row[auto_column(todo)]) == points[todo], (student, todo, row)
        assert float(row[TOTAL_COLUMN]) == pytest.approx(sum(points.values())), student
        assert all(row[column] == "" for column in manual), "manual points are left for the TA"
    assert rows["cheat-endless_loop"]["notes"] == "2.2.1 time limit"
    assert report.graded_now + report.reused + report.not_graded == len(a_class.expected)
    assert report.not_graded == 5 and not report.errors  # link, empty, traversal, huge, damaged


def test_the_class_run_writes_canvas_s_gradebook_import_beside_the_gradebook(a_class, first_run):
    # Without a roster (tests/grader/test_canvas.py has the roster and Canvas's importer): Student, ID,
    # SIS User ID, SIS Login ID, Section first, then the assignment; a "Points Possible" row; each
    # submission's id as its SIS Login ID.
    _, out, _, _ = first_run
    with open(out / "grades-canvas.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    assert rows[0][:5] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section"] and len(rows[0]) == 6
    assert rows[1][0].strip() == "Points Possible" and float(rows[1][5]) == AUTO_POINTS
    _, gradebook_rows, order = read_gradebook(out / "grades.csv")
    total = next(column for column in gradebook_rows[order[0]] if column.startswith("auto total"))
    assert [row[3] for row in rows[2:]] == order and all(row[1] == row[2] == "" for row in rows[2:])
    for row in rows[2:]:
        assert float(row[5]) == float(gradebook_rows[row[3]][total]) and 0 <= float(row[5]) <= AUTO_POINTS
        assert row[0] == row[3] and not row[0].startswith(("=", "+", "-", "@"))


def test_each_student_gets_markdown_feedback_that_shows_no_hidden_input(a_class, first_run, grader):
    _, out, _, _ = first_run
    feedback = {path.stem: path.read_text(encoding="utf-8") for path in (out / "feedback").glob("*.md")}
    assert set(feedback) == set(a_class.expected)
    wrong = feedback["wrong-forward_difference"]
    assert f"Automatic points: **{AUTO_POINTS - TODO_BY_ID['1.2.1'].auto:g} of {AUTO_POINTS:g}**" in wrong and "## 1.2.1 central finite differences" in wrong
    assert "First failing check:" in wrong and "expected:" in wrong and "actual:" in wrong
    assert "rejected: a path that leaves the submission" in feedback["traversal"]
    assert "Nothing of this submission was run" in feedback["huge"]
    assert "on a hidden input (hidden inputs are not shown" in feedback["cheat-hardcoded_visible"]
    case_sets = [grader.cases]  # and each grading's own hidden inputs (drawn from the secret its state keeps)
    for saved in classroom.state_folder(out / "grades.csv").glob("*.json"):
        secret = json.loads(saved.read_text(encoding="utf-8"))["secret"]
        if secret is not None:
            assert secret not in "".join(feedback.values()) + (out / "grades.csv").read_text(encoding="utf-8")
            case_sets.append(grader.case_sets(secret))
    assert len(case_sets) > 10
    hidden_inputs = {show(value) for sets in case_sets for todo in checks.GRADED_TODOS for _, _, args in sets[todo].hidden
                     for value in args.values() if isinstance(value, np.ndarray) and np.unique(value).size >= 3}
    assert hidden_inputs
    for student, text in feedback.items():
        for shown in hidden_inputs:
            assert shown not in text, (student, shown)
        for line in grader._scrub.lines:
            assert line not in text, student
        assert str(a_class.folder) not in text and "hwclass-" not in text, "no path of the grading machine"


def test_progress_counts_done_of_total_with_the_time_left(a_class, first_run):
    _, _, progress, _ = first_run
    lines = progress.splitlines()
    total = len(a_class.expected)
    assert lines[0].startswith(f"grading {total} submission(s)")
    counted = [line for line in lines if re.match(rf"\[\d+/{total}\] \d+:\d\d elapsed, ", line)]
    assert len(counted) == total  # not a terminal: one line per submission
    assert "left" in counted[total // 2] and counted[-1].split("]")[0] == f"[{total}/{total}"


def test_a_rerun_writes_the_same_bytes_and_grades_nothing(a_class, first_run, grader):
    report, out, _, _ = first_run
    before = {path.name: path.read_bytes() for path in (out / "feedback").iterdir()}
    gradebook = (out / "grades.csv").read_bytes()
    calls = []
    grader.grade = lambda *args, **kwargs: calls.append(args) or Grader.grade(grader, *args, **kwargs)
    try:
        again = classroom.grade_class(a_class.folder, out / "grades.csv", out / "feedback", grader=grader, jobs=JOBS)
    finally:
        del grader.grade
    assert calls == [] and again.graded_now == 0
    assert again.reused == report.graded_now + report.reused
    assert (out / "grades.csv").read_bytes() == gradebook
    assert {path.name: path.read_bytes() for path in (out / "feedback").iterdir()} == before
    assert not re.search(rb"\d{4}-\d\d-\d\d|\d\d:\d\d:\d\d", gradebook), "no time stamps in the gradebook"


def test_a_changed_submission_is_graded_again_and_only_it(a_class, first_run, grader, tmp_path):
    _, out, _, _ = first_run
    copy = tmp_path / "submissions"
    shutil.copytree(a_class.folder, copy, symlinks=True)
    state = classroom.state_folder(out / "grades.csv")
    shutil.copytree(state, classroom.state_folder(tmp_path / "grades.csv"))
    target = copy / "correct-folder" / "hwlib" / "logreg.py"
    target.write_text(target.read_text().replace("### END TODO 2.2.1", "# changed after the deadline\n"
                                                 "    ### END TODO 2.2.1", 1))
    # and one regrade of the same files (as when the grader changed: its saved key is stale)
    saved = {path.stem: json.loads(path.read_text()) for path in classroom.state_folder(tmp_path / "grades.csv").iterdir()}
    stale = classroom.state_folder(tmp_path / "grades.csv") / "wrong-forward_difference.json"
    stale.write_text(json.dumps(saved["wrong-forward_difference"] | {"key": "stale"}))
    report = classroom.grade_class(copy, tmp_path / "grades.csv", tmp_path / "feedback", grader=grader, jobs=JOBS)
    assert report.graded_now == 2
    changed = next(result for result in report.students if result.student == "correct-folder")
    assert not changed.reused and changed.auto_total == AUTO_POINTS
    now = {path.stem: json.loads(path.read_text()) for path in classroom.state_folder(tmp_path / "grades.csv").iterdir()}
    assert now["wrong-forward_difference"]["secret"] == saved["wrong-forward_difference"]["secret"], "a regrade: its inputs"
    assert now["wrong-forward_difference"]["result"] == saved["wrong-forward_difference"]["result"]
    assert now["correct-folder"]["secret"] != saved["correct-folder"]["secret"], "new files: a new grading's secret"


def test_the_saved_results_are_stale_once_any_module_of_the_grader_changes(monkeypatch, tmp_path):
    """A saved result is reused only under the same grading: a changed check (checks/), probe
    (in_sandbox/) or TODO table makes every saved result stale."""
    from types import SimpleNamespace

    fake = SimpleNamespace(layout=SimpleNamespace(files={}), reference=tmp_path,
                           sandbox=SimpleNamespace(python="python", isolated=True, how="", time_limit=1.0, memory_limit=1))
    before = classroom.grading_fingerprint(fake)
    read_bytes = Path.read_bytes
    grade = Path(classroom.__file__).resolve().parents[1]
    for changed in (grade / "checks" / "p1_cartpole.py", grade / "in_sandbox" / "probes.py", grade / "judging.py",
                    grade.parent / "todos.py"):
        monkeypatch.setattr(Path, "read_bytes", lambda path, changed=changed: read_bytes(path) + b"#" * (path == changed))
        assert classroom.grading_fingerprint(fake) != before, changed
    monkeypatch.setattr(Path, "read_bytes", read_bytes)
    assert classroom.grading_fingerprint(fake) == before


def test_a_killed_run_resumes_without_grading_again_what_was_saved(a_class, first_run, grader, tmp_path):
    _, out, _, _ = first_run
    subset = tmp_path / "submissions"
    subset.mkdir()
    students = ["correct-folder", "wrong-forward_difference", "wrong-single_rollout", "wrong-sigmoid_wrong_sign",
                "wrong-policy_mirror_image", "wrong-predict_prob_without_bias", "empty"]
    for student in students:
        source = a_class.folder / student
        if source.is_dir():
            shutil.copytree(source, subset / student)
        else:
            shutil.copy(a_class.folder / f"{student}.zip", subset)
    gradebook, feedback = tmp_path / "grades.csv", tmp_path / "feedback"
    state = classroom.state_folder(gradebook)
    command = [sys.executable, "-m", "hwtools.grade", str(subset), "--gradebook", str(gradebook), "--feedback",
               str(feedback), "--jobs", "1", "--time-limit", f"{BUDGET / BUDGET_FACTOR:g}"]  # BUDGET: none loops
    process = subprocess.Popen(command, cwd=KIT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.monotonic() + 300
    while not (state.is_dir() and any(state.glob("*.json"))) and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.communicate()
    saved = sorted(path.stem for path in state.glob("*.json"))
    assert 1 <= len(saved) < 6, saved  # killed after the first results were saved, before the end
    assert not gradebook.exists()
    for path in state.glob("*.json"):
        json.loads(path.read_text())  # written whole or not at all

    with Grader(KIT, time_limit=BUDGET / BUDGET_FACTOR, jobs=1) as same:  # the command's grading: its saved results hold
        report = classroom.grade_class(subset, gradebook, feedback, grader=same, jobs=JOBS)
    assert report.reused == len(saved) and report.graded_now == 6 - len(saved)
    _, rows, _ = read_gradebook(gradebook)
    _, everyone, _ = read_gradebook(out / "grades.csv")
    assert rows == {student: everyone[student] for student in students}


# --------------------------------------------------------------------------------------------
# Reading a submission without trusting it (no grading: fast)
# --------------------------------------------------------------------------------------------


def read(path, layout):
    try:
        with submissions.open_submission(path, submissions.kit_file_names(layout)) as opened:
            files = sorted(p.relative_to(opened.kit).as_posix() for p in opened.kit.rglob("*") if p.is_file())
            return "ok", files, opened.digest, opened.notes
    except submissions.Unusable as unusable:
        return unusable.text, [], None, []


@pytest.fixture(scope="module")
def a_kit(layout, tmp_path_factory):
    folder = tmp_path_factory.mktemp("kit") / "kit"
    kits.write_submission(layout, folder, others="reference")
    shutil.copytree(KIT / "notebooks", folder / "notebooks")
    return folder


def test_the_kit_is_found_at_the_top_or_up_to_two_folders_down(a_kit, layout, tmp_path):
    status, files, digest, _ = read(a_kit, layout)
    assert status == "ok" and "hwlib/finite_diff.py" in files and any(f.startswith("notebooks/") for f in files)
    assert all(f.startswith("hwlib/") and f.endswith(".py") or f.endswith(".ipynb") for f in files)
    for prefix in ("", "alice/", "alice/hw1/"):
        archive = zip_folder(a_kit, tmp_path / f"depth{prefix.count('/')}.zip", prefix=prefix)
        assert read(archive, layout)[2] == digest, prefix  # the same files, the same digest: no regrading
    too_deep = zip_folder(a_kit, tmp_path / "deep.zip", prefix="a/b/c/")
    assert read(too_deep, layout)[0].startswith("unreadable: no hwlib/ folder")
    (tmp_path / "holder").mkdir()
    shutil.copy(tmp_path / "depth1.zip", tmp_path / "holder" / "upload.zip")  # a folder whose content is one zip
    status, _, nested_digest, notes = read(tmp_path / "holder", layout)
    assert status == "ok" and nested_digest == digest and notes == ["read from upload.zip"]


def test_two_kits_in_one_submission_are_not_guessed_between(a_kit, layout, tmp_path):
    shutil.copytree(a_kit / "hwlib", tmp_path / "sub" / "one" / "hwlib")
    shutil.copytree(a_kit / "hwlib", tmp_path / "sub" / "two" / "hwlib")
    assert read(tmp_path / "sub", layout)[0] == "unreadable: more than one copy of the kit (one/, two/); send one"


def test_bare_library_files_are_read_as_hwlib(a_kit, layout, tmp_path):
    flat = tmp_path / "flat"
    flat.mkdir()
    for name in submissions.kit_file_names(layout):
        shutil.copy(a_kit / "hwlib" / name, flat / name)
    status, files, _, notes = read(flat, layout)
    assert status == "ok" and files == sorted(f"hwlib/{name}" for name in submissions.kit_file_names(layout))
    assert "read as hwlib/" in notes[0]


def test_junk_and_virtual_environments_are_ignored_links_in_the_kit_are_refused(a_kit, layout, tmp_path):
    folder = tmp_path / "alice"
    shutil.copytree(a_kit, folder)
    (folder / ".venv" / "bin").mkdir(parents=True)
    (folder / ".venv" / "bin" / "python").symlink_to("/usr/bin/python3")
    (folder / "__MACOSX").mkdir()
    (folder / "__MACOSX" / "._hwlib").write_bytes(b"\0")
    assert read(folder, layout)[0] == "ok"
    (folder / "hwlib" / "extra.py").symlink_to("/etc/passwd")
    assert read(folder, layout)[0] == "rejected: hwlib/extra.py is a link; only plain files are read"
    (folder / "hwlib" / "extra.py").unlink()
    link = tmp_path / "link-to-alice"
    link.symlink_to(folder)
    assert read(link, layout)[0] == "rejected: the submission is a link; only plain folders and files are read"


@pytest.mark.parametrize("name, why", [
    ("/etc/cron.d/evil", "a path that leaves the submission in the zip: '/etc/cron.d/evil'"),
    ("hw1/../../evil.py", "a path that leaves the submission in the zip: 'hw1/../../evil.py'"),
    ("hw1\\..\\..\\evil.py", "a path that leaves the submission in the zip: 'hw1\\\\..\\\\..\\\\evil.py'"),
    ("C:/Windows/evil.py", "a path that leaves the submission in the zip: 'C:/Windows/evil.py'"),
])
def test_zip_paths_that_leave_the_submission_reject_it(a_kit, layout, tmp_path, name, why):
    archive = zip_folder(a_kit, tmp_path / "s.zip")
    with zipfile.ZipFile(archive, "a") as handle:
        handle.writestr(name, "x")
    assert read(archive, layout)[0] == f"rejected: {why}"


@pytest.mark.parametrize("other", [
    "hwlib/FINITE_DIFF.py",  # letter case: one file on macOS and Windows
    "HWLIB/finite_diff.py",
    "hwlib/finite_diff.py/x.py",  # a folder with a file's name
])
def test_names_that_are_one_file_on_macos_or_windows_reject_the_zip(a_kit, layout, tmp_path, other):
    archive = zip_folder(a_kit, tmp_path / "s.zip")
    with zipfile.ZipFile(archive, "a") as handle:
        handle.writestr(other, "def finite_diff(*args):\n    return 0\n")
    status = read(archive, layout)[0]
    assert status.startswith("rejected: ") and "one file on macOS and Windows" in status, status
    assert "finite_diff.py" in status


def test_unicode_forms_of_one_name_reject_the_zip_and_the_folder(a_kit, layout, tmp_path):
    composed, decomposed = "hwlib/caf\u00e9.py", "hwlib/cafe\u0301.py"  # NFC (Windows, Linux) and NFD (macOS)
    archive = zip_folder(a_kit, tmp_path / "s.zip")
    with zipfile.ZipFile(archive, "a") as handle:
        handle.writestr(composed, "x = 1\n")
        assert read(archive, layout)[0] == "ok"  # one such file is fine
        handle.writestr(decomposed, "x = 2\n")
    assert "one file on macOS and Windows" in read(archive, layout)[0]
    folder = tmp_path / "alice"
    shutil.copytree(a_kit, folder)
    (folder / "hwlib" / "Logreg.py").write_text("x = 1\n")  # this file system keeps both
    status = read(folder, layout)[0]
    assert status.startswith("rejected: hwlib/Logreg.py and hwlib/logreg.py are one file"), status


def test_a_link_in_a_zip_is_refused(a_kit, layout, tmp_path):
    archive = zip_folder(a_kit, tmp_path / "s.zip")
    with zipfile.ZipFile(archive, "a") as handle:
        info = zipfile.ZipInfo("hwlib/secret.py")
        info.create_system = 3
        info.external_attr = 0o120777 << 16
        handle.writestr(info, "/work/main/hwlib/finite_diff.py")
    assert read(archive, layout)[0] == "rejected: hwlib/secret.py is a link; only plain files are read"


def test_a_huge_file_is_refused_by_its_declared_size_before_any_byte_is_extracted(layout, tmp_path, monkeypatch):
    archive = write_huge_zip(tmp_path / "huge.zip", inner="hw1/notebooks/p1.ipynb")
    with zipfile.ZipFile(archive, "a") as handle:  # a kit beside it, so that the notebook is one of its files
        handle.writestr("hw1/hwlib/finite_diff.py", "x = 1\n")
    opened = []
    monkeypatch.setattr(zipfile.ZipFile, "open", lambda *args, **kwargs: opened.append(args) or 1 / 0)
    assert read(archive, layout)[0] == "rejected: hw1/notebooks/p1.ipynb: 200 MB, more than the 20 MB read per file"
    assert opened == []


def test_a_file_with_more_bytes_than_declared_is_refused(a_kit, layout, tmp_path):
    archive = tmp_path / "lying.zip"
    body = b"# " + b"x" * 5000 + b"\n"
    with zipfile.ZipFile(archive, "w", compression=zipfile.ZIP_STORED) as handle:
        handle.writestr("hwlib/finite_diff.py", body)
    data = bytearray(archive.read_bytes())
    for signature, offset in ((b"PK\x03\x04", 22), (b"PK\x01\x02", 24)):  # the uncompressed size, in both headers
        start = data.find(signature)
        data[start + offset:start + offset + 4] = (100).to_bytes(4, "little")
    archive.write_bytes(bytes(data))
    status = read(archive, layout)[0]
    assert status.startswith(("rejected: hwlib/finite_diff.py: more bytes than", "unreadable: a damaged")), status


def test_too_many_entries_too_many_bytes_empty_and_damaged(a_kit, layout, tmp_path, monkeypatch):
    archive = zip_folder(a_kit, tmp_path / "s.zip")
    monkeypatch.setattr(submissions, "MAX_ENTRIES", 5)
    assert read(archive, layout)[0].startswith("rejected: a zip of ")
    monkeypatch.undo()
    monkeypatch.setattr(submissions, "MAX_SUBMISSION_BYTES", 100_000)
    assert read(archive, layout)[0].startswith("rejected: ") and "read per submission" in read(archive, layout)[0]
    monkeypatch.undo()
    with zipfile.ZipFile(tmp_path / "empty.zip", "w"):
        pass
    (tmp_path / "zero.zip").write_bytes(b"")
    (tmp_path / "nothing").mkdir()
    for empty in ("empty.zip", "zero.zip", "nothing"):
        assert read(tmp_path / empty, layout)[0] == "empty", empty
    (tmp_path / "notes.txt").write_text("hello")
    assert read(tmp_path / "notes.txt", layout)[0] == "unreadable: not a folder or a .zip file"
    broken = bytearray(archive.read_bytes())
    start = broken.find(b"PK\x03\x04", 10)
    broken[start + 40:start + 200] = bytes(160)  # damage compressed data
    (tmp_path / "broken.zip").write_bytes(bytes(broken))
    assert read(tmp_path / "broken.zip", layout)[0].startswith(("unreadable: a damaged", "rejected: "))


def test_duplicate_ids_and_formula_like_names(layout, grader, tmp_path):
    folder = tmp_path / "submissions"
    kits.write_submission(layout, folder / "dup", others="stub")
    zip_folder(folder / "dup", folder / "dup.zip")
    (folder / "=HYPERLINK(1)").mkdir()
    (folder / ".DS_Store").write_bytes(b"\0")
    report = classroom.grade_class(folder, tmp_path / "grades.csv", tmp_path / "feedback", grader=grader, jobs=1)
    header, rows, order = read_gradebook(tmp_path / "grades.csv")
    assert order == ["'=HYPERLINK(1)", "dup"]
    assert rows["dup"]["status"] == "rejected: more than one submission under this id (dup, dup.zip)"
    assert rows["'=HYPERLINK(1)"]["status"] == "empty"
    assert report.graded_now == 0


def test_command_line_needs_a_gradebook_for_a_folder_of_submissions(tmp_path):
    (tmp_path / "alice").mkdir()
    result = subprocess.run([sys.executable, "-m", "hwtools.grade", str(tmp_path)], cwd=KIT, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 2 and "--gradebook" in result.stderr and "folder of submissions" in result.stderr
    result = subprocess.run([sys.executable, "-m", "hwtools.grade", str(KIT), "--gradebook", str(tmp_path / "g.csv")],
                            cwd=KIT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "is a kit" in result.stderr


def lying_zip(path, entries=600_000):
    """A zip whose central directory holds ``entries`` records while its end record declares one
    (the issue's 54 MB zip of 600,000 entries, written record by record in a second)."""
    records = []
    for number in range(entries):
        name = f"f{number}".encode()
        records.append(struct.pack("<4s6H3I5H2I", b"PK\x01\x02", 20, 20, 0, 0, 0, 0, 0, 0, 0, len(name), 0, 0, 0, 0,
                                   0, 0) + name)
    directory = b"".join(records)
    end = struct.pack("<4s4H2IH", b"PK\x05\x06", 0, 0, 1, 1, len(directory), 0, 0)
    path.write_bytes(directory + end)
    return path


def test_a_zip_whose_end_record_lies_about_its_entries_is_rejected_with_bounded_memory(layout, tmp_path,
                                                                                      monkeypatch):
    archive = lying_zip(tmp_path / "many.zip")
    assert archive.stat().st_size > 5_000_000
    monkeypatch.setattr(zipfile.ZipFile, "__init__", lambda *args, **kwargs: 1 / 0)  # never parsed by zipfile
    tracemalloc.start()
    try:
        status = read(archive, layout)[0]
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert status == (f"rejected: a zip of more than {submissions.MAX_ENTRIES} entries (counted in its central "
                      "directory), more than are read")
    assert peak < 16 * 2**20, f"{peak / 2**20:.0f} MiB to count the entries"


FORGED = "\r\x1b[2Kbob: graded, 39 of 39\x1b[0m\u202e"  # rewrites the instructor's terminal line, reverses text


def test_control_characters_never_reach_the_gradebook_the_feedback_or_the_terminal(layout, grader, tmp_path):
    folder = tmp_path / "submissions"
    kits.write_submission(layout, folder / f"mallory{FORGED}", {"2.2.1": (
        f"import warnings\nwarnings.warn({FORGED!r})\nvalues = 0.5 * (1.0 + np.tanh(0.5 * z))")}, others="reference")
    with zipfile.ZipFile(folder / f"eve{FORGED}.zip", "w") as archive:
        archive.writestr(f"hw1/../{FORGED}.py", "x = 1\n")
        archive.writestr("hw1/hwlib/finite_diff.py", "x = 1\n")
    (folder / f"trudy{FORGED}").mkdir()
    (folder / f"trudy{FORGED}" / f"{FORGED}.txt").write_text("no kit here")
    progress = io.StringIO()
    report = classroom.grade_class(folder, tmp_path / "grades.csv", tmp_path / "feedback", grader=grader, jobs=1,
                                   progress=progress)
    assert len(report.students) == 3 and report.graded_now == 1
    shown = {"gradebook": (tmp_path / "grades.csv").read_text(encoding="utf-8"), "progress": progress.getvalue()}
    shown |= {path.name: path.read_text(encoding="utf-8") for path in (tmp_path / "feedback").glob("*.md")}
    for where, text in shown.items():
        assert not [char for char in text if char != "\n" and unicodedata.category(char) in ("Cc", "Cf")], where
        assert "x1b" in text and "2Kbob: graded, 39 of 39" in text, where  # shown, escaped
    assert "rejected: a path that leaves the submission" in shown["gradebook"]


# --------------------------------------------------------------------------------------------
# One submission's failure is its own verdict; file names cannot collide; memory stays bounded
# --------------------------------------------------------------------------------------------

DEEP = "x = " + "-" * 3000 + "1\nvalues = 1.0 / (1.0 + np.exp(-z))"  # compile() raises RecursionError


def test_odd_ids_long_ids_and_a_block_too_deep_to_compile_each_get_their_own_row_and_feedback(layout, grader,
                                                                                            tmp_path):
    """Ids that once shared a file (a plain id equal to another's safe name), a 245-character id
    (its feedback's temporary file name was too long), and a block nested too deeply for Python's
    compiler (RecursionError escaped the grader): every row and every feedback file is written,
    each to its own file, and the deep block costs only its TODO."""
    folder = tmp_path / "submissions"
    kits.write_submission(layout, folder / "deep", {"2.2.1": DEEP}, others="reference")
    (folder / "Ana María").mkdir(parents=True)
    (folder / "Ana_Mar_a-8358ed27.zip").write_bytes(b"PK\x03\x04" + bytes(100))
    long_id = "a" * 245
    (folder / long_id).mkdir()
    report = classroom.grade_class(folder, tmp_path / "grades.csv", tmp_path / "feedback", grader=grader, jobs=1)
    _, rows, order = read_gradebook(tmp_path / "grades.csv")
    assert sorted(order) == sorted(["deep", "Ana María", "Ana_Mar_a-8358ed27", long_id])
    assert rows["Ana María"]["status"] == "empty" and rows[long_id]["status"] == "empty"
    assert rows["Ana_Mar_a-8358ed27"]["status"].startswith("unreadable")
    assert rows["deep"]["status"] == graded(grader) and float(rows["deep"][TOTAL_COLUMN]) == AUTO_POINTS - TODO_BY_ID["2.2.1"].auto
    assert not report.errors, report.errors
    written = {path.name: path.read_text(encoding="utf-8") for path in (tmp_path / "feedback").glob("*.md")}
    assert len(written) == 4 and all(len(name) <= 123 for name in written)
    assert written[f"{submissions.file_name('Ana María')}.md"] != written["Ana_Mar_a-8358ed27.md"]
    assert "unreadable" in written["Ana_Mar_a-8358ed27.md"] and "empty" in written["~Ana%20Mar%C3%ADa.md"]
    assert "cannot be compiled (RecursionError: nested too deeply" in written["deep.md"]
    names = [submissions.file_name(student) for student in ("a", "A", "~a", "%7Ea", "a" * 101, "a" * 100 + "b",
                                                              "Ana María", "Ana_Mar_a-8358ed27", ".x", "x/y")]
    assert len(set(names)) == len(names) and all(len(name) <= 119 for name in names)


def test_a_class_of_big_answers_keeps_the_grader_under_600_mib(layout, tmp_path, answer_key):
    """Submissions that answer every case with 8 MB (tests/grader/cheats/big_answers.txt): the grader once
    kept every run's answers to the class's end (three of them: 1.3 GB). Graded in a fresh process
    on 2 jobs; its peak memory (VmHWM, the reference servers are processes of their own) stays low."""
    cheat = proof.parse_cheat(proof.CHEATS / "big_answers.txt")
    folder = tmp_path / "submissions"
    for number in range(2):  # each with code of its own: no run is reused; two graded at once
        own = dict(cheat, bodies={todo: f"{body}\n# big{number}" for todo, body in cheat["bodies"].items()})
        proof.build_cheat(layout, own, folder / f"big{number}", answer_key)
    code = ("import json, sys; from hwtools.grade import Grader; from hwtools.grade.instructor import classroom; "
            f"grader = Grader({str(KIT)!r}, time_limit={TIME_LIMIT}, jobs=1, budget={BUDGET}); "
            f"report = classroom.grade_class({str(folder)!r}, {str(tmp_path / 'g.csv')!r}, {str(tmp_path / 'fb')!r}, "
            "grader=grader, jobs=2); "
            "peak = [line.split()[1] for line in open('/proc/self/status') if line.startswith('VmHWM:')][0]; "
            "print(json.dumps([[s.status for s in report.students], int(peak)]))")
    run = subprocess.run([sys.executable, "-c", code], cwd=KIT, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    statuses, peak_kib = json.loads(run.stdout.strip().splitlines()[-1])
    assert len(statuses) == 2 and all(status in ("graded", "not isolated") for status in statuses), statuses
    assert peak_kib < 600 * 1024, f"the grader peaked at {peak_kib / 1024:.0f} MiB"
