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
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from day_one import EDITION_TESTS_SECONDS, assert_edition_tests_pass, find_python, interrupt_a_check, kit_env, student_python, versions_tested
import foreign_os
from hwtools import files, handin, markers
from hwtools.report import words
from hwtools.not_done import untouched_todos
from hwtools.grade import AUTO_POINTS, blocks, submissions
from hwtools.grade.instructor import classroom
from hwtools.todos import TODO_BY_ID
from instructor.release import ReleaseError, kit_files, student_files

KIT = Path(__file__).resolve().parents[2]
P1 = "notebooks/p1_cartpole_finite_difference.ipynb"
P2 = "notebooks/p2_food_cutting_logistic_regression.ipynb"
LEFTOVERS = ("hwlib/.ipynb_checkpoints/cartpole-checkpoint.py", f"notebooks/.ipynb_checkpoints/{Path(P1).stem}-checkpoint.ipynb",
             "hwlib/logreg.py~", "hwlib/.finite_diff.py.swp")


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
    """``python *args`` in ``kit``; its output decoded as the system's code page writes it where it is not told
    otherwise (the Windows profile: cp1252)."""
    encoding = "cp1252" if (Path(python).parent.parent / "windows").exists() else "utf-8"
    return subprocess.run([str(python), *args], cwd=kit, env=kit_env(kit, python), capture_output=True,
                          encoding=encoding, errors="replace", timeout=timeout)


SYSTEMS = ("windows", "macos", "hub")
# Each system's student Python: Windows' the newest tested version, macOS's the oldest (a Mac's python.org or
# Homebrew Python), the hub's this one; where this machine has no such version, this one.
VERSION_OF = {"windows": -1, "macos": 0}


@pytest.fixture(scope="module")
def edition(tmp_path_factory):
    """The filled student edition with leftovers, in a folder named as a student's may be ("Łukasz Zoë/hw1":
    letters outside Windows' code page), made by the release command."""
    root = tmp_path_factory.mktemp("student-path")
    kit = root / "Łukasz Zoë" / "hw1"
    built = subprocess.run([sys.executable, "-m", "instructor.release", "student", str(kit)], cwd=KIT,
                           capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, built.stderr
    stubs = {name: (kit / name).read_bytes() for name in ("hwlib/cartpole.py", "hwlib/logreg.py", P1)}
    fill(kit)
    leave_leftovers(kit, {name: (data, None) for name, data in stubs.items()})
    for name in ("data.npz", "audio"):  # the course's data, where this kit has it, put where the student puts it
        if (KIT / "data" / name).exists():
            (kit / "data" / name).symlink_to((KIT / "data" / name).resolve())
    return kit


@pytest.fixture(scope="module")
def pythons(tmp_path_factory):
    """{system: its student Python, made at first use}: ``foreign_os``'s profile in every process of it."""
    made, root = {}, tmp_path_factory.mktemp("pythons")
    versions = versions_tested()

    def python(system):
        if system not in made:
            base = find_python(versions[VERSION_OF[system]]) if system in VERSION_OF else None
            home = None if system == "windows" else root / f"{system}-home"  # a Mac user's home; the hub's, read-only
            if home is not None:
                home.mkdir()
            made[system] = student_python(root / system, system=system, home=home, base=base)
            (made[system].parent.parent / system).touch()  # which system it is, for run()
        return made[system]

    return python


@pytest.fixture(scope="module")
def path(edition, pythons):
    """(the filled student edition with leftovers, the Windows profile's Python: the newest tested version)."""
    python = pythons("windows")
    assert run(python, edition, "-c", "import instructor", timeout=120).returncode == 1
    return edition, python


# --------------------------------------------------------------------------------------------
# The student's path on each system (issue 39): an interrupted check and the preview, with the same points and words
# as on Linux. (Every cell of both notebooks, the check cells and the sweep among them, runs in a kernel of each
# system's Python in the report, one per system: tests/notebooks/test_report.py, test_other_systems.py.)
# --------------------------------------------------------------------------------------------


def looping(edition, name):
    """A copy of ``edition`` whose TODO 1.2.1 loops for ever (as a student's may), in a folder beside it."""
    kit = edition.parent / name
    shutil.copytree(edition, kit, symlinks=True, ignore=shutil.ignore_patterns("handin"))
    code = kit / "hwlib" / "finite_diff.py"
    code.write_text(re.sub(r"(### BEGIN TODO 1\.2\.1\n).*?(\n\s*### END TODO 1\.2\.1)", r"\1    while True:\n        pass\2",
                           code.read_text(encoding="utf-8"), flags=re.S), encoding="utf-8")
    return kit


@pytest.mark.timeout(1800)
@pytest.mark.parametrize("system", SYSTEMS)
def test_kernel_interrupt_ends_a_looping_check_its_grader_and_its_worker(edition, pythons, system):
    """Kernel > Interrupt while a check runs a TODO that never ends: the cell ends with KeyboardInterrupt at
    once (within a second on this box, benchmarks/RESULTS.md; asserted with room for a loaded machine, far below
    the run's wall-clock backstop), and neither the grader nor its worker is left. Made to fail once: on the kit of e0973d3 the Windows
    profile's cell ended after 190.1 s (the wall-clock backstop: the interrupt did not wake
    ``communicate(timeout=1800)``), and on Linux and macOS the worker was left looping (the grader was killed,
    not its worker's session)."""
    result = interrupt_a_check(pythons(system), looping(edition, f"loop-{system}"), "1.2.1")
    assert result["status"] == "error" and result["error"] == "KeyboardInterrupt", result
    assert result["seconds"] < 10 and not result["left"], result


def preview(python, kit, out):
    """{"result": the preview's result, "said": what decides points and words in it: the totals and, per TODO,
    its status, points, notes, mistake, blame and checks' verdicts}."""
    done = run(python, kit, "-m", "hwtools.grade", "--json", str(out), timeout=900)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    result = json.loads(out.read_text(encoding="utf-8"))
    return {"result": result, "said": {"total": result["total"], "todos": [
        {key: entry.get(key) for key in ("id", "status", "auto_earned", "notes", "mistake", "blame")}
        | {"checks": [(check["check"], check["passed"]) for check in entry["checks"]]} for entry in result["todos"]]}}


@pytest.fixture(scope="module")
def linux_preview(edition, tmp_path_factory):
    """The preview of the filled edition with a plain Python of this Linux box."""
    python = student_python(tmp_path_factory.mktemp("linux") / "venv")
    return preview(python, edition, tmp_path_factory.mktemp("linux-preview") / "preview.json")


@pytest.mark.timeout(1800)
@pytest.mark.parametrize("system", SYSTEMS)
def test_the_preview_gives_every_point_with_the_words_it_gives_on_linux(edition, pythons, linux_preview, system, tmp_path):
    said = preview(pythons(system), edition, tmp_path / "preview.json")["said"]
    assert said["total"]["auto_earned"] == AUTO_POINTS
    assert said == linux_preview["said"]


@pytest.mark.timeout(EDITION_TESTS_SECONDS + 60)
def test_the_filled_student_editions_own_tests_pass_beside_the_editors_leftovers(path):
    kit, python = path
    assert_edition_tests_pass(python, kit, encoding="cp1252")


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


def fake_report(numbers="1"):
    """A stand-in for the report command (``handin.build_report``): the files it writes, answers.tex under its
    stamp with ``numbers`` in it, and answers.pdf naming the --name it was given."""
    def report(kit, folder, name):
        folder.mkdir(parents=True)
        (folder / "answers.pdf").write_bytes(f"%PDF {name} {numbers}".encode())
        (folder / "p1_training_curve.pdf").write_bytes(f"%PDF figure {numbers}".encode())
        words.write_answers(folder, ANSWERS.format(numbers=numbers))
        return folder / "answers.pdf"

    return report


ANSWERS = "\\section*{{1.3.3}}\n% Your words: how you chose the rate.\n\nrate: {numbers}\n\\end{{document}}\n"


def test_a_report_replaces_the_previous_one_only_once_complete(tmp_path, monkeypatch):
    said = []
    out_dir = tmp_path / "handin"
    out_dir.mkdir()
    monkeypatch.setattr(handin, "build_report", fake_report())
    first = handin.write_report(tmp_path, out_dir, "alovelac", "Ada", said.append)
    assert first == out_dir / "alovelac.pdf" and first.read_bytes() == b"%PDF Ada / alovelac 1" and not said
    assert not (out_dir / "report" / "answers.pdf").exists()  # one there is the student's own, from answers.tex
    handin.write_report(tmp_path, out_dir, "alovelac", "Ada L.", said.append)
    assert (out_dir / "alovelac.pdf").read_bytes() == b"%PDF Ada L. / alovelac 1"
    assert len(said) == 1 and "replaces the previous report" in said[0]

    def failing(kit, folder, name):
        folder.mkdir(parents=True)
        (folder / "half.html").write_text("x")
        raise handin.HandinError("the report could not be built (python -m hwtools.report):\nTODO 1.2.1 is not done yet")

    monkeypatch.setattr(handin, "build_report", failing)
    with pytest.raises(handin.HandinError, match=r"not done yet\nYour previous report in .* is kept as it was"):
        handin.write_report(tmp_path, out_dir, "alovelac", "Ada", said.append)
    assert sorted(path.name for path in out_dir.iterdir()) == ["alovelac.pdf", "report"]
    assert (out_dir / "alovelac.pdf").read_bytes() == b"%PDF Ada L. / alovelac 1"


def test_the_students_words_and_files_survive_every_later_report(tmp_path, monkeypatch):
    """Issue 39.2: the words written in handin/report/answers.tex, and a file of the student's beside it, survive a
    later hand-in's report; a PDF they compiled from it since is what the hand-in names for upload; one older
    than their answers.tex is said to be so."""
    said = []
    out_dir, report_dir = tmp_path / "handin", tmp_path / "handin" / "report"
    monkeypatch.setattr(handin, "checked_zip", lambda kit, andrew_id: (b"zip", ["hwlib/cartpole.py"]))
    monkeypatch.setattr(handin, "visible_checks", lambda kit, say: [])
    monkeypatch.setattr(handin, "build_report", fake_report("1"))
    result = handin.handin("alovelac", kit=tmp_path, out_dir=out_dir, say=said.append)
    assert result["pdf"] == out_dir / "alovelac.pdf" and said[-1].startswith(
        "Hand in handin/alovelac.zip on Canvas and handin/alovelac.pdf on Gradescope.")
    tex = report_dir / "answers.tex"
    tex.write_text(tex.read_text().replace("the rate.\n", "the rate.\nBy the sweep: Łukasz's way.\n"), encoding="utf-8")
    (report_dir / "sketch.png").write_bytes(b"my own figure")
    os.utime(tex, (tex.stat().st_mtime - 10,) * 2)
    (report_dir / "answers.pdf").write_bytes(b"%PDF compiled by pdflatex, with my words")  # newer than answers.tex
    said.clear()
    result = handin.handin("alovelac", kit=tmp_path, out_dir=out_dir, report=False, say=said.append)
    assert (out_dir / "alovelac.pdf").read_bytes() == b"%PDF compiled by pdflatex, with my words"
    assert result["pdf"] == out_dir / "alovelac.pdf" and "and handin/alovelac.pdf on Gradescope" in said[-1]
    said.clear()
    monkeypatch.setattr(handin, "build_report", fake_report("2"))
    result = handin.handin("alovelac", kit=tmp_path, out_dir=out_dir, say=said.append)
    assert tex.read_text(encoding="utf-8").split("\n", 1)[1] == ANSWERS.format(numbers="2").replace(
        "the rate.\n", "the rate.\nBy the sweep: Łukasz's way.\n")
    assert (report_dir / "sketch.png").read_bytes() == b"my own figure"
    assert (report_dir / "p1_training_curve.pdf").read_bytes() == b"%PDF figure 2"
    text = "\n".join(said)
    assert "your words are kept in the new answers.tex" in text, text
    assert result["pdf"] is None and "answers.pdf there is older than your answers.tex" in text, text
    assert "pdflatex answers.tex" in text and "once made, the report's PDF on Gradescope" in said[-1]
    assert sorted(path.name for path in out_dir.iterdir()) == ["alovelac.pdf", "alovelac.zip", "report"]


@pytest.mark.parametrize("held", ["alovelac.pdf", "report/answers.tex", "report/answers.pdf", "alovelac.zip"])
def test_a_file_held_open_keeps_the_old_hand_in_whole_and_is_named(tmp_path, monkeypatch, held):
    """Windows refuses to remove, rename or replace a file another program holds open (a PDF viewer, an editor;
    foreign_os's lock shim does so here): the hand-in then keeps the old report and PDF whole, says which file is
    held and by what kind of program, and leaves nothing half made; once it is closed, the hand-in goes through."""
    for (module, name), shim in foreign_os.lock_shim().items():
        monkeypatch.setattr(module, name, shim)
    monkeypatch.setattr(handin, "checked_zip", lambda kit, andrew_id: (b"zip 2", ["hwlib/cartpole.py"]))
    monkeypatch.setattr(handin, "visible_checks", lambda kit, say: [])
    monkeypatch.setattr(files, "RETRY_SECONDS", 0.2)
    out_dir = tmp_path / "handin"
    monkeypatch.setattr(handin, "build_report", fake_report("1"))
    handin.handin("alovelac", kit=tmp_path, out_dir=out_dir, say=lambda line: None)
    (out_dir / "report" / "answers.pdf").write_bytes(b"%PDF mine")
    (out_dir / "alovelac.zip").write_bytes(b"zip 1")
    before = {path.relative_to(out_dir).as_posix(): path.read_bytes() for path in out_dir.rglob("*") if path.is_file()}
    monkeypatch.setattr(handin, "build_report", fake_report("2"))
    with open(out_dir / held, "rb"):  # noqa: PTH123 - a viewer holding it
        with pytest.raises(handin.HandinError) as raised:
            handin.handin("alovelac", kit=tmp_path, out_dir=out_dir, say=lambda line: None)
    kind = {"pdf": "a PDF viewer", "tex": "an editor", "zip": "File Explorer"}[held.rpartition(".")[2]]
    assert f"{out_dir / held} is open in another program, probably {kind}" in str(raised.value), raised.value
    after = {path.relative_to(out_dir).as_posix(): path.read_bytes() for path in out_dir.rglob("*") if path.is_file()}
    assert after == before
    handin.handin("alovelac", kit=tmp_path, out_dir=out_dir, say=lambda line: None)
    assert (out_dir / "alovelac.zip").read_bytes() == b"zip 2" and b"rate: 2" in (out_dir / "report/answers.tex").read_bytes()


@pytest.mark.parametrize("held", ["alovelac.pdf", "report/answers.pdf", "report/p1_training_curve.pdf"])
def test_a_file_opened_while_the_report_builds_keeps_the_old_report_whole(tmp_path, monkeypatch, held):
    """The same where the file is opened while the new report is built: the new one is not put in place, the old
    report and its PDF stay as they were, and nothing is left half made."""
    for (module, name), shim in foreign_os.lock_shim().items():
        monkeypatch.setattr(module, name, shim)
    monkeypatch.setattr(files, "RETRY_SECONDS", 0.2)
    out_dir = tmp_path / "handin"
    out_dir.mkdir()
    monkeypatch.setattr(handin, "build_report", fake_report("1"))
    handin.write_report(tmp_path, out_dir, "alovelac", "Ada", lambda line: None)
    (out_dir / "report" / "answers.pdf").write_bytes(b"%PDF mine")
    before = {path.relative_to(out_dir).as_posix(): path.read_bytes() for path in out_dir.rglob("*") if path.is_file()}
    viewer = []

    def report_while_opened(kit, folder, name):
        viewer.append(open(out_dir / held, "rb"))  # noqa: PTH123, SIM115 - a viewer opening it meanwhile
        return fake_report("2")(kit, folder, name)

    monkeypatch.setattr(handin, "build_report", report_while_opened)
    try:
        with pytest.raises(handin.HandinError) as raised:
            handin.write_report(tmp_path, out_dir, "alovelac", "Ada", lambda line: None)
    finally:
        viewer[0].close()
    assert f"{out_dir / held} is open in another program, probably a PDF viewer" in str(raised.value), raised.value
    assert "your previous report" in str(raised.value) and "is kept whole" in str(raised.value)
    after = {path.relative_to(out_dir).as_posix(): path.read_bytes() for path in out_dir.rglob("*") if path.is_file()}
    assert after == before


