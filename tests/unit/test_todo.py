"""'Not done yet' (hwlib/machinery/todos.py): the one TODO table, and TodoNotDone, which every TODO's starting
code raises and which says which TODO and where its code goes."""

import ast
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

import hwlib
from hwlib.machinery.todos import TODO_BY_ID, TODOS, TodoNotDone
from hwtools.markers import is_leftover

KIT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"^[ \t]*### BEGIN (?:SOLUTION|TODO) (\d\.\d\.\d)", re.M)


def test_the_two_lines_name_the_todo_its_code_and_what_to_do():
    error = TodoNotDone("1.1.1")
    first, second = error.lines()
    assert first == "TODO 1.1.1 is not done yet: CartPoleLinearPolicy.__call__ in hwlib/cartpole.py"
    assert "### BEGIN TODO 1.1.1" in second and "### END TODO 1.1.1" in second and "Restart Kernel" in second
    assert str(error) == f"{first}\n{second}"  # what pytest prints, first line first
    assert [re.sub(r"\x1b\[[0-9;]*m", "", line) for line in error._render_traceback_()] == [first, second]
    assert isinstance(error, NotImplementedError) and error.todo == "1.1.1"
    assert "LEARNING_RATE" in TodoNotDone("1.3.3").lines()[1]
    assert TodoNotDone("9.9.9").lines()[0] == "TODO 9.9.9 is not done yet"
    for todo in [*TODO_BY_ID, "9.9.9"]:  # every second line: fix it, then restart and run everything again
        second = TodoNotDone(todo).lines()[1]
        assert f"### BEGIN TODO {todo}" in second and second.endswith("Kernel → Restart Kernel and Run All Cells."), second


def test_ipython_shows_the_two_lines_instead_of_a_traceback(capsys):
    from IPython.core.interactiveshell import InteractiveShell

    shell = InteractiveShell.instance()
    shell.run_cell("from hwlib import TodoNotDone\ndef f():\n    raise TodoNotDone('1.2.1')\nf()")
    shown = re.sub(r"\x1b\[[0-9;]*m", "", capsys.readouterr().out).strip().splitlines()
    assert shown == list(TodoNotDone("1.2.1").lines())  # no 'Traceback', no frames


def test_the_grader_reads_the_same_table_without_importing_hwlib():
    code = ("import sys\nfrom hwtools.todos import AUTO_POINTS, MANUAL_POINTS, TODOS\n"
            "print(repr([(t.id, t.title, t.auto, t.manual, t.manual_what, t.code) for t in TODOS]), AUTO_POINTS, MANUAL_POINTS)\n"
            "print(sorted(name for name in sys.modules if name.split('.')[0] == 'hwlib'))")
    done = subprocess.run([sys.executable, "-c", code], cwd=KIT, capture_output=True, text=True, check=True)
    table, loaded = done.stdout.strip().splitlines()
    assert table == f"{[(t.id, t.title, t.auto, t.manual, t.manual_what, t.code) for t in TODOS]!r} 39 21.0"
    assert loaded == "[]"  # the grader's trusted side never imports the package a student edits


def test_every_library_todo_is_in_the_table_and_its_module_can_raise_it():
    for path in sorted(path for path in (KIT / "hwlib").rglob("*.py") if not is_leftover(path.relative_to(KIT))):
        todos = BLOCK.findall(path.read_text(encoding="utf-8"))
        for todo in todos:
            assert TODO_BY_ID[todo].where[0] == path.relative_to(KIT).as_posix(), todo
        module = __import__("hwlib." + ".".join(path.relative_to(KIT / "hwlib").with_suffix("").parts), fromlist=["x"])
        if todos and path.name != "settings.py":  # settings' 1.3.3 stub is LEARNING_RATE = None
            assert module.TodoNotDone is TodoNotDone, path


STUDENT_CALLS = """
import json, numpy as np
from hwlib import *
from hwlib import TodoNotDone
from hwlib.landscape import reward_slice
from hwlib.training import learning_rate_sweep, run_training
X, y = np.ones((4, 2)), np.array([0, 1, 0, 1])
two = TwoClassLogisticRegressionClassifier(2)
calls = {
    "policy": lambda: CartPoleLinearPolicy([0.0] * 4)(np.zeros(4)),
    "run_policy": lambda: run_policy(CartPoleLinearPolicy([0.0] * 4), seed=0),
    "random policies": lambda: random_policy_rewards(10, seed=0),
    "landscape": lambda: reward_slice(np.zeros(4), grid_size=3, num_episodes=1),
    "finite differences": lambda: scalar_finite_diff(lambda v: 0.0, [1.0], 0.1),
    "eval_params": lambda: eval_params([0.0] * 4, 2, seed=0),
    "training": lambda: train_cartpole_policy(1, learning_rate=0.001),
    "training with the settings": lambda: run_training(1),
    "sweep": lambda: learning_rate_sweep([0.001], num_seeds=2, num_training_iterations=1),
    "sigmoid": lambda: sigmoid(0.0),
    "predict_prob": lambda: two.predict_prob(X),
    "gradient step": lambda: two.gradient_ascent_step(X, y, 0.1),
    "one-vs-rest": lambda: MultiClassLogisticRegressionClassifier(2, 2).fit(X, y, 0.1, 1),
    "gradient": lambda: log_likelihood_gradient(np.zeros(3), X, y),
}
raised = {}
for name, call in calls.items():
    try:
        call()
        raised[name] = "nothing"
    except TodoNotDone as error:
        raised[name] = [error.todo, type(error).__name__, str(error).splitlines()[0]]
    except Exception as error:
        raised[name] = repr(error)
print(json.dumps(raised))
"""


@pytest.mark.hidden  # it builds the student edition with the release tool, which only the instructor has
class TestTheStudentEditionsStubs:
    """What the release writes in place of each solution: stubs that raise TodoNotDone, naming their TODO."""

    @pytest.fixture(scope="class")
    @classmethod
    def student_edition(cls, tmp_path_factory):
        out = tmp_path_factory.mktemp("student") / "kit"
        subprocess.run([sys.executable, "-m", "instructor.release", "student", str(out), "--no-answer-key"],
                       cwd=KIT, check=True, capture_output=True)
        return out

    def test_every_stub_in_the_student_edition_raises_todo_not_done(self, student_edition):
        for path in (student_edition / "hwlib").rglob("*.py"):
            text = path.read_text(encoding="utf-8")
            for todo in BLOCK.findall(text):
                if path.name == "settings.py":
                    assert re.search(rf"^LEARNING_RATE = None  # TODO {todo}", text, re.M)
                else:
                    assert f'raise TodoNotDone("{todo}")' in text, (path.name, todo)
            ast.parse(text)

    def test_on_day_one_every_entry_point_names_the_first_todo_it_needs(self, student_edition):
        done = subprocess.run([sys.executable, "-c", STUDENT_CALLS], cwd=student_edition, capture_output=True, text=True,
                              env={"PYTHONPATH": str(student_edition), "MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"})
        assert done.returncode == 0, done.stderr
        raised = json.loads(done.stdout.strip().splitlines()[-1])
        expected = {
            "policy": "1.1.1", "run_policy": "1.1.1", "random policies": "1.1.1", "landscape": "1.1.1",
            "finite differences": "1.2.1", "eval_params": "1.3.1", "training": "1.3.1",
            "training with the settings": "1.3.3", "sweep": "1.1.1", "sigmoid": "2.2.1", "predict_prob": "2.2.2",
            "gradient step": "2.2.3", "one-vs-rest": "2.3.1", "gradient": "2.1.1",
        }
        for name, todo in expected.items():
            assert raised[name][:2] == [todo, "TodoNotDone"], (name, raised[name])
            where, what = TODO_BY_ID[todo].where
            assert raised[name][2].startswith(f"TODO {todo} is not done yet: {what} in {where}")
        assert hwlib.__file__.startswith(str(KIT))  # the kit under test here is the instructor's, untouched
