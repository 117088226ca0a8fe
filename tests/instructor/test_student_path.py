"""The student's plain path, as CI runs it (issue 22): the student edition is built with the release
command, filled with the reference solutions, and left with what editing leaves behind (JupyterLab's
checkpoints of a library file and of a notebook, holding the stubs as first saved; an editor's backup
``logreg.py~``; vim's swap file ``.finite_diff.py.swp``). Then, with a Python that has the kit's
packages but not the instructor's (``instructor`` cannot be imported), and that takes from the kit's
own code, in every process (the kernel, the grader, its workers), what Windows lacks (issue 32.7,
``foreign_os.py``: the Unix-only modules and names, ``select()`` of a pipe, ``/proc``; no bubblewrap,
``prlimit`` or Chromium on ``PATH``; made to fail once against the kit of 2780067: the edition's
pytest had 12 notebook cells fail, each notebook's first cell at ``import fcntl``,
``hwtools/grade/sandbox.py:63``, through ``hwtools.check_cell``, then ``check`` a NameError in every
check cell; hand-in stopped at the same import; with that import made optional, ``limit_own_memory``
stopped at ``resource``; and in today's edition, ``_kill_strays`` without its ``/proc`` check gives
"the grader failed on this TODO's code (FileNotFoundError: ... '/proc')"):

* the edition's own test command, ``python -m pytest`` (its unit tests and its notebooks), passes
  within its time limits;
* ``python -m hwtools.handin ID --no-report`` runs the visible checks, says they pass and that training
  converges, and writes a zip without the leftovers, which the instructor's grader
  (``python -m hwtools.grade ID.zip``) grades in full; with a learning rate that does not converge it
  says so and hands in all the same. (The report, which runs both notebooks again, is built in the
  student edition's hand-in test, ``tests/instructor/test_student_edition.py``: one report per test run.)

And, without a sandbox or a notebook run: every reader of a kit's files leaves the leftovers out
(``markers.is_leftover``): the grader's layout and submission readers, a class's folder, hand-in, the
release's file list and the check of untouched TODOs; hand-in replaces a report only once the new
one is complete.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from day_one import kit_env, student_python
from hwtools import handin, markers
from hwtools.not_done import untouched_todos
from hwtools.grade import AUTO_POINTS, blocks, submissions
from hwtools.grade.instructor import classroom
from hwtools.todos import TODO_BY_ID
from instructor.release import ReleaseError, kit_files, student_files

KIT = Path(__file__).resolve().parents[2]
P1 = "notebooks/p1_cartpole_finite_difference.ipynb"
LEFTOVERS = ("hwlib/.ipynb_checkpoints/cartpole-checkpoint.py", f"notebooks/.ipynb_checkpoints/{Path(P1).stem}-checkpoint.ipynb",
             "hwlib/logreg.py~", "hwlib/.finite_diff.py.swp")
EDITION_TESTS_SECONDS = 1500  # the edition's whole pytest: about 2.5 min at load 3-6 on 2 cores


def leave_leftovers(kit, stubs):
    """Put beside the files of ``kit`` what JupyterLab and editors leave: checkpoints and a backup that
    hold the stubs (``stubs``: {relative path: bytes} of the untouched edition), and a swap file."""
    for leftover in LEFTOVERS:
        target = kit / leftover
        target.parent.mkdir(parents=True, exist_ok=True)
        if leftover.endswith(".swp"):
            target.write_bytes(b"b0VIM 9.0\0\0\0junk")
            continue
        original = re.sub(r"\.ipynb_checkpoints/(.*)-checkpoint", r"\1", leftover).removesuffix("~")
        target.write_bytes(stubs[original][0])


def fill(kit):
    """Write the reference solutions into the TODO blocks of the student edition at ``kit`` (each file
    as the release writes it with every solution kept: the student's file with the blocks filled in)."""
    filled = student_files(KIT, keep=frozenset(TODO_BY_ID))
    for name, (data, _) in filled.items():
        if name.startswith(("hwlib/", "notebooks/")):
            (kit / name).write_bytes(data)


def run(python, kit, *args, timeout):
    return subprocess.run([str(python), *args], cwd=kit, env=kit_env(kit, python), capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope="module")
def path(tmp_path_factory):
    """(the filled student edition with leftovers, its Python)."""
    root = tmp_path_factory.mktemp("student-path")
    kit = root / "student"
    built = subprocess.run([sys.executable, "-m", "instructor.release", "student", str(kit)], cwd=KIT,
                           capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, built.stderr
    stubs = {name: (kit / name).read_bytes() for name in ("hwlib/cartpole.py", "hwlib/logreg.py", P1)}
    fill(kit)
    leave_leftovers(kit, {name: (data, None) for name, data in stubs.items()})
    for name in ("data.npz", "audio"):  # the course's data, where this kit has it, put where the student puts it
        if (KIT / "data" / name).exists():
            (kit / "data" / name).symlink_to((KIT / "data" / name).resolve())
    python = student_python(root / "venv", foreign=True)
    assert run(python, kit, "-c", "import instructor", timeout=120).returncode == 1
    return kit, python


@pytest.mark.timeout(EDITION_TESTS_SECONDS + 60)
def test_the_filled_student_editions_own_tests_pass_beside_the_editors_leftovers(path):
    kit, python = path
    assert re.search(r"^timeout = \d+$", (kit / "pyproject.toml").read_text(), re.M)  # a limit for every test
    done = run(python, kit, "-m", "pytest", "-q", "-p", "no:cacheprovider", timeout=EDITION_TESTS_SECONDS)
    summary = done.stdout.strip().splitlines()[-1] if done.stdout.strip() else ""
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert re.fullmatch(r"=* ?\d+ passed(, \d+ skipped)? in .*", summary.strip("= ")), summary
    assert "notebooks/p2_food_cutting_logistic_regression.ipynb" in run(
        python, kit, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", timeout=300).stdout


@pytest.mark.timeout(900)
def test_hand_in_checks_then_writes_a_zip_the_instructors_grader_grades_in_full(path, tmp_path):
    kit, python = path
    done = run(python, kit, "-m", "hwtools.handin", "alovelac", "--no-report", timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    out = done.stdout
    assert "finds the code of every TODO" in out and "every visible check passes" in out
    assert "training with your LEARNING_RATE converges within 7 iterations" in out
    assert out.index("every visible check passes") < out.index("alovelac.zip")  # the checks come before the zip
    assert re.search(r"hand-in took \d+ s|hand-in took \d+ min", out)
    zip_path = kit / "handin" / "alovelac.zip"
    with zipfile.ZipFile(zip_path) as archive:
        names = archive.namelist()
    assert "hwlib/cartpole.py" in names and P1 in names
    assert not set(LEFTOVERS) & set(names), names
    graded = subprocess.run([sys.executable, "-m", "hwtools.grade", str(zip_path), "--json", str(tmp_path / "grade.json"),
                             "--brief"], cwd=KIT, capture_output=True, text=True, timeout=600)
    assert graded.returncode == 0, graded.stdout[-2000:] + graded.stderr[-2000:]
    result = json.loads((tmp_path / "grade.json").read_text())
    assert result["reference"] == str(KIT) and result["submission"] == str(zip_path)
    assert result["total"]["auto_earned"] == AUTO_POINTS, [(e["id"], e["auto_earned"]) for e in result["todos"]]


def test_the_grader_says_why_it_cannot_read_one_zip(tmp_path):
    (tmp_path / "alovelac.zip").write_text("not a zip")
    done = subprocess.run([sys.executable, "-m", "hwtools.grade", str(tmp_path / "alovelac.zip")], cwd=KIT,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and done.stderr.strip() == (f"error: {tmp_path / 'alovelac.zip'}: unreadable: not a zip "
                                                            "file (no end-of-archive record)"), done.stderr


@pytest.mark.timeout(900)
def test_hand_in_says_when_training_does_not_converge_and_still_hands_in(path, tmp_path):
    kit, python = path
    copy = tmp_path / "student"
    shutil.copytree(kit, copy, symlinks=True, ignore=shutil.ignore_patterns("handin"))
    settings = copy / "hwlib" / "settings.py"
    settings.write_text(re.sub(r"(?m)^LEARNING_RATE = .*$", "LEARNING_RATE = 1e-9", settings.read_text()))
    done = run(python, copy, "-m", "hwtools.handin", "alovelac", "--no-report", timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    out = done.stdout
    assert "training with your LEARNING_RATE does NOT converge within 7 iterations" in out
    assert "TODO 1.3.3 does not pass its visible checks; you may still hand in" in out
    assert "FAIL" in out and (copy / "handin" / "alovelac.zip").is_file()


# --------------------------------------------------------------------------------------------
# Every reader of a kit's files leaves the leftovers out (no sandbox, no notebook run)
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("name", "leftover"), [
    ("hwlib/.ipynb_checkpoints/cartpole-checkpoint.py", True), ("notebooks/.ipynb_checkpoints/p1-checkpoint.ipynb", True),
    ("hwlib/logreg.py~", True), ("hwlib/.finite_diff.py.swp", True), ("hwlib/.cartpole.py.swo", True),
    ("hwlib/__pycache__/cartpole.cpython-311.pyc", True), ("hwlib/#cartpole.py#", True), ("hwlib/.#cartpole.py", True),
    (".DS_Store", True), ("__MACOSX/hwlib/._cartpole.py", True), (".venv/lib/site.py", True), (".git/HEAD", True),
    ("venv/bin/python", True), (".virtual_documents/notebooks/p1.ipynb", True), ("hwlib\\.ipynb_checkpoints\\x.py", True),
    ("hwlib/cartpole.py", False), ("notebooks/p1_cartpole_finite_difference.ipynb", False), (".ci/run", False),
    (".gitignore", False), ("tests/grader/natural_solutions/.gitattributes", False), ("hwlib/plots/cartpole.py", False),
    ("hwlib/_todo.py", False), ("README.md", False),
])
def test_is_leftover(name, leftover):
    assert markers.is_leftover(name) is leftover
    assert markers.is_leftover(Path(name)) is leftover


def homework_files(kit, files):
    """Write the hwlib/ and notebooks/ files of ``files`` ({relative path: (bytes, executable)}) under ``kit``."""
    for name, (data, _) in files.items():
        if name.startswith(("hwlib/", "notebooks/")):
            (kit / name).parent.mkdir(parents=True, exist_ok=True)
            (kit / name).write_bytes(data)
    return kit


@pytest.fixture
def kit_with_leftovers(tmp_path):
    """This kit's hwlib/ and notebooks/ with the solutions, beside leftovers that hold the student edition's stubs."""
    kit = homework_files(tmp_path / "kit", {name: ((KIT / name).read_bytes(), False) for name in kit_files(KIT)})
    leave_leftovers(kit, student_files(KIT))
    return kit


def test_the_graders_readers_leave_the_leftovers_out(kit_with_leftovers, tmp_path):
    kit = kit_with_leftovers
    layout = blocks.load_layout(kit)
    assert "hwlib/cartpole.py" in layout.files and not set(LEFTOVERS) & set(layout.files)
    read = blocks.read_submission(kit, layout)
    assert not read.problems and not read.notes, (read.problems, read.notes)
    with submissions.open_submission(kit, submissions.kit_file_names(layout)) as opened:
        taken = sorted(path.relative_to(opened.kit).as_posix() for path in opened.kit.rglob("*") if path.is_file())
    assert "hwlib/cartpole.py" in taken and P1 in taken and not set(LEFTOVERS) & set(taken)
    archive = tmp_path / "alovelac.zip"
    with zipfile.ZipFile(archive, "w") as out:
        for path in sorted(kit.rglob("*")):
            if path.is_file():
                out.write(path, f"alovelac/{path.relative_to(kit).as_posix()}")
    with submissions.open_submission(archive, submissions.kit_file_names(layout)) as opened:
        zipped = sorted(path.relative_to(opened.kit).as_posix() for path in opened.kit.rglob("*") if path.is_file())
    assert zipped == taken


def test_a_class_folder_lists_students_not_leftovers(tmp_path):
    for folder in ("bob", ".ipynb_checkpoints", "__MACOSX"):
        (tmp_path / folder).mkdir()
    for file in ("alice.zip", "alice.zip~", ".DS_Store", ".carol.zip.swp"):
        (tmp_path / file).write_bytes(b"x")
    assert sorted(classroom.find_submissions(tmp_path)) == ["alice", "bob"]


def test_hand_in_leaves_the_leftovers_out(kit_with_leftovers):
    names = handin.code_files(kit_with_leftovers)
    assert "hwlib/cartpole.py" in names and P1 in names and not set(LEFTOVERS) & set(names)


def test_hand_in_refuses_two_files_that_are_one_on_macos_or_windows(kit_with_leftovers):
    (kit_with_leftovers / "hwlib" / "CartPole.py").write_text("x = 1\n")
    with pytest.raises(handin.HandinError, match=r"hwlib/CartPole\.py and hwlib/cartpole\.py are one file on macOS"):
        handin.code_files(kit_with_leftovers)


def test_an_untouched_todo_is_seen_whatever_its_checkpoint_holds(tmp_path):
    kit = homework_files(tmp_path / "kit", student_files(KIT))
    leave_leftovers(kit, student_files(KIT, keep=frozenset(TODO_BY_ID)))  # leftovers that hold the solutions
    assert {"1.1.1", "1.2.1", "2.2.1"} <= set(untouched_todos(kit))


def test_the_release_leaves_the_leftovers_out_and_refuses_a_tracked_one(kit_with_leftovers):
    kit = kit_with_leftovers
    names = kit_files(kit)
    assert "hwlib/cartpole.py" in names and not set(LEFTOVERS) & set(names)
    if shutil.which("git") is None:
        pytest.skip("needs git")
    git = ["git", "-C", str(kit), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run([*git, "init", "-q"], check=True)
    names = kit_files(kit)  # untracked files are the kit's too, the leftovers still left out
    assert "hwlib/cartpole.py" in names and not set(LEFTOVERS) & set(names)
    subprocess.run([*git, "add", "hwlib/cartpole.py", "hwlib/logreg.py~"], check=True)
    with pytest.raises(ReleaseError, match=r"hwlib/logreg\.py~: git tracks it, but it looks like an editor's"):
        kit_files(kit)


# --------------------------------------------------------------------------------------------
# Hand-in writes nothing before it has checked, and replaces a report only once the new one is complete
# --------------------------------------------------------------------------------------------


def test_a_report_replaces_the_previous_one_only_once_complete(tmp_path, monkeypatch):
    said = []
    out_dir = tmp_path / "handin"
    out_dir.mkdir()

    def report(kit, folder, name):
        folder.mkdir(parents=True)
        (folder / "answers.pdf").write_bytes(f"%PDF {name}".encode())
        return folder / "answers.pdf"

    monkeypatch.setattr(handin, "build_report", report)
    first = handin.write_report(tmp_path, out_dir, "alovelac", "Ada", said.append)
    assert first.read_bytes() == b"%PDF Ada / alovelac" and not said
    handin.write_report(tmp_path, out_dir, "alovelac", "Ada L.", said.append)
    assert (out_dir / "alovelac.pdf").read_bytes() == b"%PDF Ada L. / alovelac"
    assert len(said) == 1 and "replaces the previous report" in said[0]

    def failing(kit, folder, name):
        folder.mkdir(parents=True)
        (folder / "half.html").write_text("x")
        raise handin.HandinError("the report could not be built (python -m hwtools.report):\nTODO 1.2.1 is not done yet")

    monkeypatch.setattr(handin, "build_report", failing)
    with pytest.raises(handin.HandinError, match=r"not done yet\nYour previous report in .* is kept as it was"):
        handin.write_report(tmp_path, out_dir, "alovelac", "Ada", said.append)
    assert sorted(path.name for path in out_dir.iterdir()) == ["alovelac.pdf", "report"]
    assert (out_dir / "report" / "answers.pdf").read_bytes() == b"%PDF Ada L. / alovelac"


def test_a_report_without_a_pdf_is_kept_and_says_how_to_make_one(tmp_path, monkeypatch):
    """Where no browser prints answers.pdf (the report says how to make it and writes the rest), hand-in puts
    that report in place, removes the PDF of an earlier one and says the same; the zip is written first."""
    said = []
    out_dir = tmp_path / "handin"
    out_dir.mkdir()
    (out_dir / "alovelac.pdf").write_bytes(b"%PDF an earlier report")

    def report(kit, folder, name):
        folder.mkdir(parents=True)
        (folder / "answers.tex").write_text(name)
        return None

    monkeypatch.setattr(handin, "build_report", report)
    monkeypatch.setattr(handin, "checked_zip", lambda kit, andrew_id: (b"zip", ["hwlib/cartpole.py"]))
    monkeypatch.setattr(handin, "visible_checks", lambda kit, say: [])
    result = handin.handin("alovelac", kit=tmp_path, out_dir=out_dir, say=said.append)
    assert result == {"zip": out_dir / "alovelac.zip", "pdf": None, "failing": []}
    assert sorted(path.name for path in out_dir.iterdir()) == ["alovelac.zip", "report"]
    assert (out_dir / "report" / "answers.tex").read_text() == "alovelac"
    words = "\n".join(said)
    assert f"{out_dir / 'report'}: the report without its PDF" in words and "set HWLIB_CHROMIUM" in words, words
    assert "Hand in alovelac.zip on Canvas and the report's PDF on Gradescope." in words
