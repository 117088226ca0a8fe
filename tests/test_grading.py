"""The CI proof of the student edition and the autograder (instructor-only).

From the kit's own source it builds the student edition into a temporary folder and checks:

1. untouched, the student edition scores 0 on every automatically graded TODO, every tagged
   test fails on its stub while no untagged test does, and the README's test command runs it
   to the end (imports work, both notebooks open and run cell by cell);
2. for each TODO, putting back its solution alone makes exactly its tests pass, visible and
   hidden. Where the handout chains TODOs (``HANDOUT_CHAINS``) the earlier TODOs' solutions are
   put back too, and their tests pass as well; every other TODO's tests still fail;
3. the full solution kit scores every automatic point;
4. each realistic wrong solution in ``tests/wrong_solutions/`` loses points in its TODO;
5. the grader itself survives an endless loop, a swallowed timeout, a crashing interpreter and
   a test file that cannot be imported, and refuses to grade an hwlib from elsewhere.

Grading runs in subprocesses (see ``hwtools.grade``); each scenario grades only what it needs.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from pathlib import Path

import pytest

from hwtools.grade import TODO_BY_ID, TODOS, grade, prerequisites, tagged_test_files
from instructor.release import build_student_edition

REPO = Path(__file__).resolve().parents[1]
INSTRUCTOR_TESTS = REPO / "tests"
WRONG_SOLUTIONS = REPO / "tests" / "wrong_solutions"
NOTEBOOKS = sorted(path.name for path in (REPO / "notebooks").glob("*.ipynb"))

PROBLEMS = ("1", "2")  # the problems whose TODOs are tagged in the tests
GRADED_TODOS = [todo.id for todo in TODOS if todo.id.split(".")[0] in PROBLEMS]
AUTO_TODOS = [todo_id for todo_id in GRADED_TODOS if TODO_BY_ID[todo_id].auto]
# TODOs with tests: the automatically graded ones, and manual ones whose tests inform the person grading.
TAGGED = set().union(*tagged_test_files(INSTRUCTOR_TESTS).values())
TESTED_TODOS = [todo_id for todo_id in GRADED_TODOS if todo_id in TAGGED]

# The handout chains these TODOs: their tests call code written in earlier TODOs.
HANDOUT_CHAINS = {
    "1.3.1": {"1.1.1"},  # g(theta) plays episodes with the linear policy
    "1.3.2": {"1.1.1", "1.2.1", "1.3.1"},  # training climbs g by finite-difference gradients
    "1.3.3": {"1.1.1", "1.2.1", "1.3.1", "1.3.2"},  # a learning rate is judged by training with it
    "2.1.1": {"2.2.1", "1.2.1"},  # the derived gradient uses sigmoid; the kit checks it with problem 1's finite differences
    "2.2.2": {"2.2.1"},  # predict_prob applies the sigmoid
    "2.2.3": {"2.2.1"},  # the update computes probabilities with the sigmoid
    "2.3.1": {"2.2.1", "2.2.2", "2.2.3"},  # one-vs-rest trains and queries the two-class classifiers
}


def kit_env(kit):
    """The environment a kit's commands run in without installing it: its hwlib first."""
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTEST_ADDOPTS", None)
    env["PYTHONPATH"] = os.pathsep.join([str(kit)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    return env


@pytest.fixture(scope="module")
def student_kit(tmp_path_factory):
    out = tmp_path_factory.mktemp("student") / "kit"
    build_student_edition(REPO, out)
    return out


@pytest.fixture(scope="module")
def untouched_report(student_kit, tmp_path_factory):
    """The untouched student edition graded with its own grade command, as a student would."""
    json_file = tmp_path_factory.mktemp("untouched") / "grade.json"
    command = [sys.executable, "-m", "hwtools.grade", str(student_kit), "--json", str(json_file)]
    for todo in GRADED_TODOS:
        command += ["--todo", todo]
    result = subprocess.run(command, cwd=student_kit, env=kit_env(student_kit), capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    report = json.loads(json_file.read_text())
    assert "total:" in result.stdout
    return report


# --------------------------------------------------------------------------------------------
# 1. The untouched student edition
# --------------------------------------------------------------------------------------------


def test_untouched_student_edition_scores_zero(untouched_report):
    assert untouched_report["errors"] == []
    todos = {todo["id"]: todo for todo in untouched_report["todos"]}
    assert sorted(todos) == sorted(GRADED_TODOS)
    assert set(AUTO_TODOS) <= set(TESTED_TODOS)
    for todo_id in TESTED_TODOS:
        todo = todos[todo_id]
        assert todo["errors"] == [], todo_id
        assert todo["tests_total"] > 0, f"TODO {todo_id} has no visible test: students cannot grade it"
        assert todo["auto_earned"] == 0, todo_id
        not_failed = [test["nodeid"] for test in todo["tests"] if test["outcome"] != "failed"]
        assert not_failed == [], f"TODO {todo_id}: these tests do not fail on the stub: {not_failed}"
        assert all("NotImplementedError" in test["message"] or "None" in test["message"] for test in todo["tests"])
    for todo in untouched_report["todos"]:
        assert todo["auto_earned"] == 0
        if todo["id"] not in TESTED_TODOS:
            assert todo["tests_total"] == 0 and not TODO_BY_ID[todo["id"]].auto
    assert untouched_report["total"]["auto_earned"] == 0
    assert untouched_report["total"]["auto_possible"] == sum(TODO_BY_ID[t].auto for t in GRADED_TODOS)


def test_untouched_student_edition_runs_with_the_readme_command(student_kit, untouched_report, tmp_path):
    """`.venv/bin/python -m pytest` in the student kit (not installed: its hwlib comes first on
    the path; the browser test, which needs Chromium, is left to the instructor kit's CI)."""
    junit = tmp_path / "junit.xml"
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-m", "not browser", f"--junitxml={junit}", "-q", "--tb=no"],
        cwd=student_kit, env=kit_env(student_kit), capture_output=True, text=True,
    )
    # 1: tests failed. Not 2 (interrupted, e.g. a collection error), 3 (internal error), 4 (usage).
    assert result.returncode == 1, result.stdout[-3000:] + result.stderr[-3000:]
    outcomes = {_nodeid(student_kit, case): _outcome(case) for case in ElementTree.parse(junit).getroot().iter("testcase")}
    for notebook in NOTEBOOKS:
        cells = {name: outcome for name, outcome in outcomes.items() if name.startswith(f"notebooks/{notebook}::")}
        assert cells, f"{notebook} was not run"
        assert "passed" in cells.values(), f"no cell of {notebook} ran: {cells}"
    tagged = {test["nodeid"] for todo in untouched_report["todos"] for test in todo["tests"]}
    assert tagged and tagged <= set(outcomes)
    failing = {name for name, outcome in outcomes.items() if outcome == "failed" and name.startswith("tests/")}
    untagged_failing = {name for name in failing - tagged if name.split("::")[0] not in WHOLE_HOMEWORK_TESTS}
    assert untagged_failing == set(), "these tests fail on the untouched student edition but belong to no TODO"
    assert tagged <= failing


# Tests of the finished homework as a whole (they need every TODO), so they fail on the student
# edition until the end and belong to no single TODO.
WHOLE_HOMEWORK_TESTS = {"tests/test_report.py"}


def _nodeid(kit, case):
    """pytest's node id of a junit test case: "tests.test_x" + "test_y[1]" -> "tests/test_x.py::test_y[1]",
    "notebooks.p1.ipynb" + "Cell 3" -> "notebooks/p1.ipynb::Cell 3"."""
    classname, name = case.get("classname"), case.get("name")
    if classname.endswith(".ipynb"):
        return classname[: -len(".ipynb")].replace(".", "/") + ".ipynb::" + name
    parts = classname.split(".")
    for cut in range(len(parts), 0, -1):
        path = "/".join(parts[:cut]) + ".py"
        if (kit / path).is_file():
            return "::".join([path, *parts[cut:], name])
    return f"{classname}::{name}"


def _outcome(case):
    if case.find("failure") is not None or case.find("error") is not None:
        return "failed"
    return "skipped" if case.find("skipped") is not None else "passed"


# --------------------------------------------------------------------------------------------
# 2. One TODO's solution put back
# --------------------------------------------------------------------------------------------


def test_the_grader_knows_the_handouts_chains():
    for todo_id in TESTED_TODOS:
        assert set(prerequisites(todo_id)) == HANDOUT_CHAINS.get(todo_id, set()), todo_id


def _restored_ids(todo_id):
    return {todo_id} | HANDOUT_CHAINS.get(todo_id, set())


def _restore_id(todo_id):
    chained = sorted(HANDOUT_CHAINS.get(todo_id, set()))
    return f"{todo_id} alone" if not chained else f"{todo_id} with {'+'.join(chained)} (chained by the handout)"


@pytest.mark.parametrize("todo_id", TESTED_TODOS, ids=_restore_id)
def test_putting_back_one_solution_passes_exactly_its_tests(todo_id, tmp_path):
    restored = _restored_ids(todo_id)
    build_student_edition(REPO, tmp_path / "kit", keep=frozenset(restored))
    report = grade(tmp_path / "kit", tests_dir=INSTRUCTOR_TESTS, todo_ids=TESTED_TODOS)
    assert report.errors == []
    wrong = []
    for todo in TESTED_TODOS:
        result = report.grade_of(todo)
        assert result.errors == [], (todo, result.errors)
        assert result.tests, f"TODO {todo} has no tests"
        expected = "passed" if todo in restored else "failed"
        wrong += [f"{test.nodeid} [{todo}]: {test.outcome} ({test.message})" for test in result.tests if test.outcome != expected]
    assert wrong == [], f"with the solutions of {sorted(restored)} put back:\n" + "\n".join(wrong)
    for todo in TESTED_TODOS:
        assert report.grade_of(todo).earned == (TODO_BY_ID[todo].auto if todo in restored else 0)
    hidden = [test for todo in restored for test in report.grade_of(todo).tests if test.hidden]
    assert hidden, f"no hidden test of {sorted(restored)} was graded"


# --------------------------------------------------------------------------------------------
# 3. The full solution
# --------------------------------------------------------------------------------------------


def test_full_solution_scores_every_automatic_point():
    report = grade(REPO, todo_ids=GRADED_TODOS)
    assert report.errors == []
    for todo_id in TESTED_TODOS:
        result = report.grade_of(todo_id)
        failures = [f"{test.nodeid}: {test.outcome} ({test.message})" for test in result.tests if test.outcome != "passed"]
        assert failures == [] and result.errors == [], (todo_id, failures, result.errors)
        assert result.earned == TODO_BY_ID[todo_id].auto
    assert report.auto_earned == report.auto_possible == sum(TODO_BY_ID[t].auto for t in GRADED_TODOS)
    manual = {todo.id for todo in TODOS if todo.manual and todo.id in GRADED_TODOS}
    assert report.manual_possible == sum(TODO_BY_ID[t].manual for t in manual)


# --------------------------------------------------------------------------------------------
# 4. Realistic wrong solutions
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class WrongSolution:
    name: str
    mistake: str
    todo: str
    file: str
    blocks: tuple


def load_wrong_solution(path):
    header, blocks = {}, []
    for line in path.read_text(encoding="utf-8").split("\n"):
        if line.strip() == "# --- block":
            blocks.append([])
        elif blocks:
            blocks[-1].append(line)
        elif line.strip():
            match = re.fullmatch(r"#\s*(\w+):\s*(.*)", line.strip())
            assert match, f"{path}: bad header line {line!r}"
            header[match[1]] = match[2]
    return WrongSolution(path.stem, header["mistake"], header["todo"], header["file"], tuple("\n".join(b) for b in blocks))


WRONG = [load_wrong_solution(path) for path in sorted(WRONG_SOLUTIONS.glob("*.txt"))]
WRONG = [wrong for wrong in WRONG if wrong.todo.split(".")[0] in PROBLEMS]


def test_there_are_wrong_solutions_for_the_issues_mistakes():
    names = {wrong.name for wrong in WRONG}
    assert {"forward_difference"} <= names
    assert all(wrong.todo in AUTO_TODOS and wrong.blocks for wrong in WRONG)


@pytest.mark.parametrize("wrong", WRONG, ids=lambda wrong: f"{wrong.todo}-{wrong.name}")
def test_wrong_solution_loses_points(wrong, tmp_path):
    everything = frozenset(todo.id for todo in TODOS)
    build_student_edition(REPO, tmp_path / "kit", keep=everything, replace={(wrong.todo, wrong.file): list(wrong.blocks)})
    solution = (REPO / wrong.file).read_text()
    changed = (tmp_path / "kit" / wrong.file).read_text()
    assert all(block.strip().split("\n")[-1].strip() in changed for block in wrong.blocks)
    report = grade(tmp_path / "kit", tests_dir=INSTRUCTOR_TESTS, todo_ids=[wrong.todo])
    result = report.grade_of(wrong.todo)
    assert report.errors == [] and result.errors == []
    assert result.earned < TODO_BY_ID[wrong.todo].auto, f"{wrong.mistake}: still {result.earned} points"
    failed = [test for test in result.tests if test.outcome == "failed"]
    assert failed and not any("NotImplementedError" in test.message for test in failed)
    assert solution != changed


# --------------------------------------------------------------------------------------------
# 5. The grader under a student's worst code
# --------------------------------------------------------------------------------------------

MINI_PYPROJECT = """\
[tool.pytest.ini_options]
markers = ["todo(id): TODO", "hidden: hidden", "browser: browser"]
"""

MINI_TESTS = '''\
import os

import pytest

import hwlib


@pytest.mark.todo("1.1.1")
def test_passes():
    assert hwlib.ANSWER == 42


@pytest.mark.todo("1.1.1")
def test_loops_forever():
    while True:
        pass


@pytest.mark.todo("1.2.1")
def test_crashes_the_interpreter():
    os._exit(3)


@pytest.mark.todo("1.2.1")
def test_after_the_crash():
    assert hwlib.ANSWER == 42


@pytest.mark.todo("1.3.1")
def test_swallows_every_exception_while_looping():
    while True:
        try:
            while True:
                pass
        except BaseException:
            pass


@pytest.mark.todo("1.3.1")
def test_next_to_the_hard_hang():
    assert hwlib.ANSWER == 42
'''


def make_mini_kit(root, answer="42"):
    (root / "hwlib").mkdir(parents=True)
    (root / "hwlib" / "__init__.py").write_text(f"ANSWER = {answer}\n")
    (root / "tests").mkdir()
    (root / "pyproject.toml").write_text(MINI_PYPROJECT)
    return root


def test_grader_survives_endless_loops_crashes_and_broken_test_files(tmp_path):
    kit = make_mini_kit(tmp_path / "kit")
    (kit / "tests" / "test_mini.py").write_text(MINI_TESTS)
    (kit / "tests" / "test_broken.py").write_text('import pytest\nimport no_such_module\n\n\n@pytest.mark.todo("1.3.2")\ndef test_x():\n    pass\n')
    report = grade(kit, todo_ids=["1.1.1", "1.2.1", "1.3.1", "1.3.2"], timeout=2, jobs=1)
    outcomes = {test.nodeid.split("::")[1]: (test.outcome, test.message) for g in report.grades for test in g.tests}
    assert outcomes["test_passes"] == ("passed", "")
    assert outcomes["test_loops_forever"][0] == "failed" and "timed out after 2 s" in outcomes["test_loops_forever"][1]
    assert outcomes["test_crashes_the_interpreter"] == ("failed", "crashed the interpreter (exit status 3)")
    assert outcomes["test_after_the_crash"] == ("passed", "")
    assert outcomes["test_swallows_every_exception_while_looping"] == ("failed", "timed out (the interpreter had to be stopped)")
    assert outcomes["test_next_to_the_hard_hang"] == ("passed", "")
    assert report.grade_of("1.1.1").earned == 1.0  # 1 of 2 tests, 2 points
    assert report.grade_of("1.2.1").earned == 5.0  # 1 of 2 tests, 10 points
    assert report.grade_of("1.3.1").earned == 2.5  # 1 of 2 tests, 5 points
    broken = report.grade_of("1.3.2")
    assert broken.earned == 0 and "test_broken.py could not be imported" in broken.errors[0]
    assert "no_such_module" in broken.errors[0]


def test_grader_refuses_an_hwlib_from_outside_the_kit(tmp_path):
    kit = make_mini_kit(tmp_path / "kit")
    other = make_mini_kit(tmp_path / "other")
    (kit / "tests" / "test_elsewhere.py").write_text(
        f"import sys\nsys.path.insert(0, {str(other)!r})\nimport hwlib\nimport pytest\n\n\n"
        '@pytest.mark.todo("1.1.1")\ndef test_answer():\n    assert hwlib.ANSWER == 42\n'
    )
    report = grade(kit, todo_ids=["1.1.1"], jobs=1)
    assert report.grade_of("1.1.1").earned == 0
    assert report.errors and "not a file of the graded kit" in report.errors[0]


def test_grader_never_fills_in_a_missing_module_from_elsewhere(tmp_path):
    """A submission without hwlib/logreg.py scores nothing on problem 2, even where an editable
    install of the instructor's kit (CI's .venv has one) could supply the solution's module."""
    kit = tmp_path / "kit"
    build_student_edition(REPO, kit, keep=frozenset(todo.id for todo in TODOS))
    (kit / "hwlib" / "logreg.py").unlink()
    report = grade(kit, todo_ids=["2.2.1"], jobs=1)
    result = report.grade_of("2.2.1")
    assert result.earned == 0 and not any(test.outcome == "passed" for test in result.tests)
    assert result.errors and "could not be imported" in result.errors[0] and "logreg" in result.errors[0]
