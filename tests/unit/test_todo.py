"""'Not done yet' (hwlib/machinery/todos.py): the one TODO table, and TodoNotDone, which every TODO's starting
code raises and which says which TODO and where its code goes."""

import re
import subprocess
import sys
from pathlib import Path

from hwlib.machinery.todos import AUTO_POINTS, MANUAL_POINTS, TODO_BY_ID, TODOS, TodoNotDone
from hwtools.markers import is_leftover

KIT = Path(__file__).resolve().parents[2]
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
    assert table == f"{[(t.id, t.title, t.auto, t.manual, t.manual_what, t.code) for t in TODOS]!r} {AUTO_POINTS} {MANUAL_POINTS}"
    assert loaded == "[]"  # the grader's trusted side never imports the package a student edits


def test_every_library_todo_is_in_the_table_and_its_module_can_raise_it():
    for path in sorted(path for path in (KIT / "hwlib").rglob("*.py") if not is_leftover(path.relative_to(KIT))):
        todos = BLOCK.findall(path.read_text(encoding="utf-8"))
        for todo in todos:
            assert TODO_BY_ID[todo].where[0] == path.relative_to(KIT).as_posix(), todo
        module = __import__("hwlib." + ".".join(path.relative_to(KIT / "hwlib").with_suffix("").parts), fromlist=["x"])
        if todos and path.name != "settings.py":  # settings' 1.3.3 stub is LEARNING_RATE = None
            assert module.TodoNotDone is TodoNotDone, path

