"""The notebooks' check cells and day-one messages (hwtools/check_cell.py, hwtools/not_done.py, hwtools/notebook.py, hwtools/pytest_todo.py).

* ``check("1.2.1")`` prints the grader's verdict on each visible check: pass, or FAIL with the
  visible input, the expected value and the actual one; "not done yet" for an untouched TODO;
  the TODO another one waits for;
* its verdicts are those of the instructor's grade on the visible inputs (a student edition with
  wrong solutions, checked with its answer key, against the instructor's grade of the same code);
* an interrupt ends the grader's subprocess;
* in a kernel, a NameError for a value a cell stopped at a TODO could not make names that TODO;
* pytest's report of a failure names its TODO first.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from hwtools import check_cell
from hwtools.check_cell import CheckError, check_lines, grade_todo
from hwtools.grade import mistakes
from hwtools.not_done import not_done_in_text, not_done_todo, untouched_todos
from hwtools.notebook import assigned_names
import editions

pytestmark = pytest.mark.quick  # the quick tier (pyproject.toml)

KIT = Path(__file__).resolve().parents[2]
WRONG = KIT / "instructor" / "wrong_solutions"


# --------------------------------------------------------------------------------------------
# Reading what the grader says
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("kind", "message", "todo"), [
    ("TodoNotDone", "TODO 1.2.1 is not done yet: scalar_finite_diff in hwlib/finite_diff.py", "1.2.1"),
    ("TodoNotDone", "2.2.1", "2.2.1"),
    ("NotImplementedError", "TODO 1.3.1 is not done yet", "1.3.1"),
    ("NotImplementedError", "", None),  # a bare NotImplementedError names no TODO
    ("NotImplementedError", "TODO 2.2.1 is not part of this check", None),  # the grader's own stand-in
    ("ValueError", "TODO 1.2.1 is not done yet", None),
])
def test_not_done_todo_reads_what_a_stub_raises(kind, message, todo):
    assert not_done_todo(kind, message) == todo


def test_the_graders_text_of_an_error_is_read_too():
    assert not_done_in_text("TodoNotDone: TODO 1.1.1 is not done yet: __call__") == "1.1.1"
    assert not_done_in_text("ValueError: LEARNING_RATE is None: it is not set yet") == "1.3.3"
    assert not_done_in_text("ValueError: x must be finite") is None
    assert not_done_in_text("[0., 0.]") is None


def entry(checks, status="graded", todo="1.2.1", notes=()):
    return {"id": todo, "title": "central finite differences, eq. (3)", "status": status, "checks": checks,
            "notes": list(notes), "manual_possible": 0, "manual": "", "first_failure": None}


def a_check(description, passed, failed_on=None, actual=None):
    failure = None if actual is None else {"input": "x=[1.0, 2.0], h=0.5", "expected": "[2.0, 4.0]", "actual": actual}
    return {"check": description, "points": 5, "passed": passed, "failed_on": failed_on, "visible_inputs": 2,
            "hidden_inputs": 3, "visible_failure": failure}


def test_the_first_two_lines_say_what_is_wrong_then_one_line_per_check():
    """Issue 40.4: line 1 the TODO and expected against actual, line 2 the check that fails in one line;
    then a line per check and the line that rebuilds the input; the rest is one call away."""
    lines = check_lines(entry([a_check("one step for every coordinate", True),
                               a_check("a step per coordinate", False, "visible", "[0.0, 0.0]")]))
    assert lines[:2] == ["TODO 1.2.1 fails: expected [2.0, 4.0], actual [0.0, 0.0]", "  the check: a step per coordinate"]
    assert lines[2:5] == ["", "central finite differences, eq. (3): 1 of 2 visible checks pass",
                          "  pass  one step for every coordinate"]
    assert lines[5] == "  FAIL  a step per coordinate" and lines[-1].startswith('check("1.2.1", details=True) shows')
    detailed = check_lines(entry([a_check("one step for every coordinate", True),
                                  a_check("a step per coordinate", False, "visible", "[0.0, 0.0]")]), details=True)
    failing = detailed.index("  FAIL  a step per coordinate")
    assert [line.split()[0] for line in detailed[failing + 1:]] == ["expected:", "actual:", "input:"]
    assert detailed[failing + 3].endswith("x=[1.0, 2.0], h=0.5")


def test_a_known_mistake_is_named_in_the_second_line():
    """Issue 32.5, 40.4: the first lines say what is wrong and where; the mistake is not said twice."""
    check = a_check("a step per coordinate", False, "visible", "[0.0, 0.0]")
    check["visible_failure"] = {"mistake": "a forward difference, (f(x + h) - f(x)) / h", **check["visible_failure"]}
    lines = check_lines({**entry([check]), "mistake": {"id": "forward_difference",
                                                      "diagnosis": "a forward difference, (f(x + h) - f(x)) / h"}})
    assert lines[:2] == ["TODO 1.2.1 fails: expected [2.0, 4.0], actual [0.0, 0.0]",
                         "  a forward difference, (f(x + h) - f(x)) / h"], lines
    assert sum("a forward difference" in line for line in lines) == 1


def test_a_failure_shows_where_it_differs_and_the_tolerance_as_every_report_does():
    check = a_check("sigmoid far out", False, "visible", "2.06115e-09")
    check["visible_failure"].update(difference="differs most at index [0]: relative difference 80.5",
                                    tolerance="|actual - expected| <= 1e-12 * |expected| + 1e-15",
                                    summary="at index [0]: expected 2.0, actual 2.06115e-09")
    lines = check_lines(entry([check]))
    assert lines[0] == "TODO 1.2.1 fails: at index [0]: expected 2.0, actual 2.06115e-09"
    lines = check_lines(entry([check]), details=True)
    failing = lines.index("  FAIL  sigmoid far out")
    assert [line.split()[0] for line in lines[failing + 1:]] == ["expected:", "actual:", "difference:", "tolerance:",
                                                                 "input:"]
    assert lines[failing + 3].endswith("relative difference 80.5") and lines[failing + 4].endswith("+ 1e-15")


def test_a_failing_todo_prints_at_most_twelve_lines_never_broken_mid_word():
    """However many checks fail and however long the words: at most 12 lines, each at most WIDTH wide
    where it has a space to break at (JupyterLab breaks wider lines at any character)."""
    checks = [a_check(f"check {k}: " + "a long description of what is checked " * 3, False, "visible", "[0.0] " * 40)
              for k in range(6)]
    for check in checks:
        check["visible_failure"]["reproduce"] = ('from hwtools.cases import visible_case; f, x, h = '
                                                 'visible_case("1.2.1/equation-3/v0")  # then scalar_finite_diff(f, x, h)')
    lines = check_lines(entry(checks, notes=["a note " * 30, "another"]))
    assert len(lines) <= check_cell.MAX_LINES, lines
    assert all(len(line) <= check_cell.WIDTH for line in lines), [line for line in lines if len(line) > check_cell.WIDTH]
    assert lines[-1].startswith('check("1.2.1", details=True)')
    detailed = check_lines(entry(checks, notes=["a note"]), details=True)
    assert len(detailed) > check_cell.MAX_LINES and all(len(line) <= check_cell.WIDTH for line in detailed)


def test_a_note_that_costs_nothing_comes_first():
    """A 1.2.1 that returns a list passes; the note that it breaks 1.3.2's arithmetic is its second line."""
    passing = {**entry([a_check("a step per coordinate", True)]), "breaks_callers": "returns a list where the training code"
               " does arithmetic on the gradient (learning_rate * gradient): return an array (np.array(...))"}
    passing["notes"] = [f"not a failure, but your code {passing['breaks_callers']}"]
    lines = check_lines(passing)
    assert lines[0].endswith("the visible check passes")
    assert lines[1].startswith("  note: not a failure, but your code returns a list"), lines


def test_a_check_that_fails_only_on_hidden_inputs_passes_on_the_visible_ones():
    lines = check_lines(entry([a_check("one step", False, "hidden"), a_check("steps", True)]))
    assert lines[0].endswith("all 2 visible checks pass") and "FAIL" not in "\n".join(lines)


def test_an_untouched_todo_is_not_done_yet():
    text = "TodoNotDone: TODO 1.2.1 is not done yet: scalar_finite_diff in hwlib/finite_diff.py"
    lines = check_lines(entry([a_check("one step", False, "visible", text), a_check("steps", False, "visible", text)]))
    assert lines == ["TODO 1.2.1 is not done yet: scalar_finite_diff in hwlib/finite_diff.py",
                     "  Write it between ### BEGIN TODO 1.2.1 and ### END TODO 1.2.1, save the file, and run this check again."]
    assert check_lines(entry([a_check("one step", False, "visible", "[0.0]")], status="not done yet"))[0] == \
        "TODO 1.2.1 is not done yet: scalar_finite_diff in hwlib/finite_diff.py"


def test_a_todo_waiting_for_another_names_it():
    text = "TodoNotDone: TODO 1.1.1 is not done yet: CartPoleLinearPolicy.__call__ in hwlib/cartpole.py"
    lines = check_lines(entry([a_check("mean reward", False, "visible", text)], todo="1.3.1"))
    said = " ".join(" ".join(lines).split())
    assert lines[0].startswith("TODO 1.3.1 (") and "TODO 1.1.1 (CartPoleLinearPolicy.__call__ in hwlib/cartpole.py)" \
        in said and "not done yet" in said


def test_code_that_cannot_run_says_why_and_a_manual_todo_says_who_grades_it():
    lines = check_lines(entry([], status="not graded", notes=["your code for TODO 1.2.1 does not parse: line 2"]))
    assert " ".join(" ".join(lines).split()) == ("TODO 1.2.1 (central finite differences, eq. (3)): not checked (not "
                                                 "graded): your code for TODO 1.2.1 does not parse: line 2")
    manual = {**entry([], status="graded by hand", todo="1.1.2"), "manual_possible": 2, "manual": "report: the table"}
    said = " ".join(" ".join(check_lines(manual)).split())
    assert said.startswith("TODO 1.1.2 (") and "graded by hand: report: the table" in said


def test_untouched_todos_reads_the_stubs(tmp_path):
    assert untouched_todos(KIT) == []  # the instructor's edition holds every solution
    (tmp_path / "hwlib").mkdir()
    (tmp_path / "hwlib" / "finite_diff.py").write_text(textwrap.dedent("""\
        def scalar_finite_diff(f, x, h):
            ### BEGIN TODO 1.2.1
            # TODO 1.2.1: a hint
            raise TodoNotDone("1.2.1")
            ### END TODO 1.2.1
        def sigmoid(z):
            ### BEGIN TODO 2.2.1
            values = 1 / (1 + np.exp(-z))
            ### END TODO 2.2.1
        ### BEGIN TODO 1.3.3
        LEARNING_RATE = None  # TODO 1.3.3: a rate
        ### END TODO 1.3.3
        """))
    assert untouched_todos(tmp_path) == ["1.2.1", "1.3.3"]


def test_assigned_names_are_the_cells_top_level_names():
    source = "import numpy as np\nfrom a.b import c as d\nx, (y, *z) = 1, (2, 3)\nfor i in range(3):\n    w = i\n" \
             "def f():\n    inner = 1\nclass K: pass\nwith open('f') as handle: pass\nif (v := 3): pass\n"
    assert assigned_names(source) == {"np", "d", "x", "y", "z", "i", "w", "f", "K", "handle", "v"}
    assert assigned_names("x = (") == set()


# --------------------------------------------------------------------------------------------
# The real grader
# --------------------------------------------------------------------------------------------


def test_the_instructors_edition_passes_its_visible_checks():
    from hwtools.grade.checks import BEHAVIOURS_BY_TODO

    count = len(BEHAVIOURS_BY_TODO["2.2.1"])  # the check table decides how many there are
    lines = check_lines(grade_todo("2.2.1"))
    assert lines[0] == f"TODO 2.2.1 (sigmoid): all {count} visible checks pass"
    assert [line.split()[0] for line in lines[1:] if not line.startswith("        ")] == ["pass"] * count


def test_an_unknown_todo_is_refused():
    with pytest.raises(CheckError, match="not a TODO of the handout"):
        grade_todo("9.9.9")


def wrong_solution(name):
    text = (WRONG / name).read_text()
    header = dict(line[2:].split(": ", 1) for line in text.splitlines() if line.startswith("# ") and ": " in line[:12])
    blocks = [block.strip("\n") for block in text.split("# --- block")[1:]]
    return header["todo"], header["file"], blocks if len(blocks) > 1 else blocks[0]


@pytest.fixture(scope="module")
def wrong_edition(tmp_path_factory):
    """A student edition with every solution but two wrong ones (and its answer key): flipped signs, as a
    student may well write them (1 / (1 + e^z), f(x - h) - f(x + h))."""
    from hwtools.todos import TODO_BY_ID

    replace = {}
    for name in ("sigmoid_wrong_sign.txt", "finite_diff_flipped_sign.txt"):
        todo, file, code = wrong_solution(name)
        replace[(todo, file)] = code
    kit = tmp_path_factory.mktemp("wrong") / "kit"
    editions.build(kit, tmp_path_factory, keep=frozenset(TODO_BY_ID), replace=replace)
    return kit


@pytest.fixture(scope="module")
def instructors_grade(wrong_edition):
    """The instructor's grade of the wrong edition, every TODO: one grading for the tests that compare with it."""
    from hwtools.grade import Grader

    with Grader(KIT) as grader:
        return grader.grade(wrong_edition)


@pytest.mark.parametrize("todo", ["2.2.1", "1.2.1"])
def test_the_check_gives_the_verdicts_of_the_instructors_grade_on_the_visible_inputs(wrong_edition, instructors_grade,
                                                                                    todo):
    preview = grade_todo(todo, kit=wrong_edition)  # the student edition: its answer key, visible checks only
    graded = next(e for e in instructors_grade["todos"] if e["id"] == todo)

    def visible(entry):
        return [(c["check"], c["passed"] or c["failed_on"] == "hidden", c.get("visible_failure")) for c in entry["checks"]]

    assert visible(preview) == visible(graded)
    assert not all(ok for _, ok, _ in visible(preview)), "a wrong solution fails a visible check"
    lines = check_lines(preview)
    assert any(line.startswith("  FAIL") for line in lines) and "expected" in lines[0] and "actual" in lines[0]
    named = {"2.2.1": "sigmoid_wrong_sign.txt", "1.2.1": "finite_diff_flipped_sign.txt"}[todo]  # the known mistake, in its words
    assert mistakes.read_wrong_solution(WRONG / named).diagnosis in " ".join(" ".join(lines).split()), lines


def test_the_preview_and_the_grade_agree_on_which_todo_lost_points(wrong_edition, instructors_grade, tmp_path):
    """1.2.1 and 2.2.1 wrong, everything else right: the preview runs the student's own 1.2.1 in
    1.3.2 and 1.3.3 (and 2.2.1 in 2.2.2-2.3.1), so their checks may fail there; they are shown as
    depending on the TODO at fault, keep their points, and the totals agree with the grade."""
    out = tmp_path / "preview.json"
    run = subprocess.run([sys.executable, "-m", "hwtools.grade", str(wrong_edition), "--json", str(out)],
                         cwd=wrong_edition, env={**os.environ, "PYTHONPATH": str(wrong_edition), "MPLBACKEND": "Agg"},
                         capture_output=True, text=True, timeout=1200)
    assert run.returncode == 0, run.stderr[-3000:]
    preview = json.loads(out.read_text())
    graded = instructors_grade
    lost = {result["one_mistake_one_place"]: {e["id"] for e in result["todos"] if e["auto_earned"] < e["auto_possible"]}
            for result in (preview, graded)}
    assert lost[False] == lost[True] == {"1.2.1", "2.2.1"}, lost
    assert preview["total"]["auto_earned"] == graded["total"]["auto_earned"]
    entries = {entry["id"]: entry for entry in preview["todos"]}
    blamed = {todo: entry["blamed_on"] for todo, entry in entries.items() if entry.get("blamed_on")}
    assert blamed and set(blamed) <= {"1.3.2", "1.3.3", "2.1.1", "2.2.2", "2.2.3", "2.3.1"}, blamed
    for todo, at_fault in blamed.items():
        assert at_fault == (["1.2.1"] if todo.startswith("1.") else ["2.2.1"]), (todo, at_fault)
        lines = check_lines(entries[todo])
        first = " ".join(" ".join(lines[:next(i for i, line in enumerate(lines)
                                              if line.lstrip().startswith(("pass ", "FAIL ")))]).split())  # wrapped
        assert f"probably caused by TODO {at_fault[0]}, which fails its own check" in first, first
        assert "mistake" not in entries[todo]  # a mistake its answers match is most likely the TODO at fault's
    assert not any(entry.get("blamed_on") for entry in graded["todos"])  # the grade runs the reference's 1.2.1
    notes = " ".join(entries["1.3.3"]["notes"])  # the 1.3.3 check says whose training code it ran
    assert "used your own code for TODOs 1.1.1, 1.2.1, 1.3.1, 1.3.2" in notes
    graded_notes = " ".join(next(e for e in graded["todos"] if e["id"] == "1.3.3")["notes"])
    assert "used the reference's code for TODOs 1.1.1, 1.2.1, 1.3.1, 1.3.2" in graded_notes


def test_a_preview_takes_only_its_own_turn_and_no_lock_file(wrong_edition, monkeypatch, tmp_path):
    """Issue 30.7, restated by issue 42.5: the preview runs the student's own code in its runs and in
    the servers of its own kit (1.3.2 calls the student's 1.2.1 there). It has no hidden input, so
    nothing in it is kept from other gradings (docs/grading.md): its runs take only its own grading's
    turn, the servers of the student's own kit run beside them, and it takes no lock file (a hub's
    home may be read-only)."""
    from hwtools.grade import Grader, sandbox

    started, real = [], sandbox.Sandbox.start

    def recorded(self, kit_dir, time_limit=None, trusted=False, budget=None):
        started.append(budget)
        return real(self, kit_dir, time_limit=time_limit, trusted=trusted, budget=budget)

    monkeypatch.setattr(sandbox.Sandbox, "start", recorded)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))  # a home with nothing in it: nothing may be made there
    grader = Grader(answer_key=wrong_edition / "hwtools" / "grade" / "answer_key.json", isolation="none")
    entry = grader.grade(wrong_edition, todos=["1.3.2"])["todos"][0]
    assert entry["status"] == "graded", entry
    runs, servers = [budget for budget in started if budget], [budget for budget in started if not budget]
    assert runs and servers, started  # its run and a server of the student's own kit, which takes no turn
    assert len(set(map(id, runs))) == 1, "one grading: one turn"
    assert not (tmp_path / "home").exists()


def test_a_check_cell_names_the_todo_at_fault(wrong_edition):
    lines = check_lines(grade_todo("1.3.2", kit=wrong_edition))
    assert "probably caused by TODO 1.2.1, which fails its own check" in " ".join(" ".join(lines[:2]).split()), lines


@pytest.mark.parametrize("line", ["STEP = undefined_step", "import sys; sys.exit(3)"])
def test_a_kit_that_raises_while_imported_names_the_error_and_its_line(wrong_edition, tmp_path, line):
    """Issue 32: the student's own hwlib/finite_diff.py raises at import time (a NameError at module
    level, sys.exit): the check names that error and where, not a worker that "ended (sys.exit?)"."""
    import shutil

    kit = shutil.copytree(wrong_edition, tmp_path / "kit")
    path = kit / "hwlib" / "finite_diff.py"
    lines = path.read_text(encoding="utf-8").splitlines()
    at = lines.index("import numpy as np") + 1
    path.write_text("\n".join(lines[:at] + [line] + lines[at:]) + "\n", encoding="utf-8")
    lines = check_lines(grade_todo("1.2.1", kit=kit))
    first = " ".join(" ".join(lines[:next(i for i, text in enumerate(lines) if text.lstrip().startswith("FAIL "))]).split())
    error = "NameError: name 'undefined_step' is not defined" if "STEP" in line else "SystemExit: 3"
    assert f"{error} (raised while hwlib was imported at hwlib/finite_diff.py line {at + 1})" in first, lines
    assert "sys.exit or os._exit" not in " ".join(lines)


def test_an_interrupt_ends_the_graders_subprocess(monkeypatch):
    started = []
    real_popen = subprocess.Popen

    class Interrupted(real_popen):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            started.append(self)
            self.waits = 0

        def poll(self):  # the check waits in short steps (issue 39): the interrupt comes during the first
            self.waits += 1
            if self.waits == 1:
                raise KeyboardInterrupt
            return super().poll()

    monkeypatch.setattr(check_cell.subprocess, "Popen", Interrupted)
    with pytest.raises(KeyboardInterrupt):
        grade_todo("2.2.1")
    assert len(started) == 1 and started[0].poll() is not None  # ended, not left running


# --------------------------------------------------------------------------------------------
# Day one in a kernel, and in pytest's report
# --------------------------------------------------------------------------------------------

DAY_ONE_CELLS = [
    "import hwtools.notebook\nclass TodoNotDone(NotImplementedError):\n    pass",
    "def stub():\n    raise TodoNotDone('TODO 1.3.1 is not done yet: eval_params in hwlib/policy_search.py')",
    "ok = 1\nrun = stub()",
    "print(run)",
    "summary = run",
    "print(summary)",
    "print(never_defined)",
    "### BEGIN TODO 2.3.2\nraise TodoNotDone('TODO 2.3.2 is not done yet')\n### END TODO 2.3.2",
    "print(X_train)",
]


def test_a_name_a_cell_could_not_make_says_which_todo_it_waits_for(tmp_path):
    import nbformat
    from nbclient import NotebookClient

    notebook = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(source) for source in DAY_ONE_CELLS])
    NotebookClient(notebook, timeout=120, allow_errors=True, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    shown = ["\n".join(out.get("traceback", [])) for cell in notebook.cells for out in cell.outputs if out.output_type == "error"]
    assert "TODO 1.3.1 is not done yet: `run` is made by a cell above that stopped at TODO 1.3.1." in shown[1]
    assert shown[1].count("\n") == 1  # two lines, no traceback
    assert "TODO 1.3.1 is not done yet: `run`" in shown[2]
    assert "TODO 1.3.1 is not done yet: `summary`" in shown[3]  # a cell that stopped on such a name passes it on
    assert "NameError" in shown[4] and "never_defined" in shown[4] and "TODO" not in shown[4]  # any other NameError as always
    assert "TODO 2.3.2 is not done yet: `X_train` is made by your code in the cell of TODO 2.3.2." in shown[6]


def test_pytest_names_the_todo_first(tmp_path):
    (tmp_path / "conftest.py").write_text('pytest_plugins = ("hwtools.pytest_todo",)\n')
    (tmp_path / "hwlib").mkdir()  # the kit under test: TODO 2.3.1 is still the stub
    (tmp_path / "hwlib" / "logreg.py").write_text("def fit():\n    ### BEGIN TODO 2.3.1\n    raise TodoNotDone('2.3.1')\n"
                                                  "    ### END TODO 2.3.1\n")
    (tmp_path / "test_x.py").write_text(textwrap.dedent("""\
        import pytest

        class TodoNotDone(NotImplementedError):
            pass

        def test_untouched():
            raise TodoNotDone("TODO 1.2.1 is not done yet: scalar_finite_diff in hwlib/finite_diff.py")

        @pytest.mark.todo("2.2.1")
        def test_wrong():
            assert 1 == 2, "sigmoid(0) should be 0.5"

        def test_a_notebook_that_stopped():
            assert False, "the notebook failed: TODO 2.3.1 is not done yet: fit in hwlib/logreg.py"

        def test_says_done_todo_is_not():
            assert False, "TODO 1.1.1 is not done yet (but its code is there: this failure is kept whole)"
        """))
    done = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-o", "addopts=",
                           "-o", 'markers=todo(id): t', str(tmp_path)], capture_output=True, text=True, cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": str(KIT)})
    out = done.stdout
    sections = {name: out.split(f"_ {name} _")[1].lstrip("_").strip().splitlines() for name in
                ("test_untouched", "test_wrong", "test_a_notebook_that_stopped")}
    assert sections["test_untouched"][0] == "TODO 1.2.1 is not done yet: scalar_finite_diff in hwlib/finite_diff.py"
    assert "Traceback" not in "\n".join(sections["test_untouched"][:3]) and "raise TodoNotDone" not in out
    assert sections["test_wrong"][0] == "TODO 2.2.1: test_wrong failed"
    assert "sigmoid(0) should be 0.5" in out  # the rest of the failure is still there
    assert sections["test_a_notebook_that_stopped"][0].startswith("TODO 2.3.1 is not done yet: ")
    assert "this failure is kept whole" in out and "def test_says_done_todo_is_not" in out
    assert "4 failed" in out and "TODOs not done yet (their code is still the stub): 2.3.1" in out
