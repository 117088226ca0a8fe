"""What the notebooks import from the kit's tools: ``check`` and day-one messages.

``check("1.2.1")`` prints the grader's verdict on each visible check of one TODO (``hwtools.check_cell``
runs it in a subprocess, on the files as saved).

Importing this module in a notebook also makes a cell that needs a value of an earlier cell say
which TODO it waits for: when a cell stopped at a TODO that is not done yet (its stub raised
``TodoNotDone``), the names that cell would have set are remembered, and a later ``NameError``
for one of them reads "TODO 1.3.1 is not done yet: `run` comes from a cell above that stopped
there" instead of a traceback. Every other error is shown as IPython always shows it. A cell that
stops at a TODO also scrolls JupyterLab to itself: *Run All* starts by scrolling to the notebook's
last cell, and the student should see where it stopped.
"""

from __future__ import annotations

import ast
import os
import re
import sys

from hwtools.check_cell import check_lines, grade_todo
from hwtools.not_done import KIT_ROOT, not_done_todo
from hwtools.todos import TODO_BY_ID

_loaded = {}  # hwlib module file -> its modification time when this kernel had it loaded


def check(todo, details=False):
    """Run TODO ``todo``'s visible checks through the kit's grader and print what they say: for a
    failing TODO what is wrong in the first two lines and at most 12 lines in all; ``details=True``
    adds each failing check's input, values and tolerance."""
    lines = check_lines(grade_todo(todo), details=details)
    lines += _stale_lines(todo)
    print("\n".join(lines))


def _remember_loaded():
    for name, module in list(sys.modules.items()):
        path = getattr(module, "__file__", None)
        if (name == "hwlib" or name.startswith("hwlib.")) and path and path not in _loaded:
            try:
                _loaded[path] = os.stat(path).st_mtime
            except OSError:
                pass


def _stale_lines(todo):
    """A line when the TODO's file changed after this kernel loaded it (the notebook still runs the old code)."""
    file = TODO_BY_ID[todo].code.partition(": ")[0]
    path = str((KIT_ROOT / file).resolve())
    _remember_loaded()
    if path not in _loaded:
        return []
    try:
        changed = os.stat(path).st_mtime > _loaded[path]
    except OSError:
        return []
    if not changed:
        return []
    return [f"({file} changed after this notebook's kernel loaded it: the cells above still run the old code. "
            "Kernel > Restart Kernel and Run All Cells runs your new code.)"]


# --------------------------------------------------------------------------------------------
# Day one: a NameError that comes from a TODO not done yet says which TODO
# --------------------------------------------------------------------------------------------


def assigned_names(source):
    """The names a cell's code sets at the top level (assignments, imports, defs, loop and with
    targets), not those inside functions; empty if it does not parse."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return set()
    names, pending = set(), list(tree.body)
    while pending:
        node = pending.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((alias.asname or alias.name).split(".")[0] for alias in node.names if alias.name != "*")
            continue
        if isinstance(node, ast.Lambda):
            continue
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        pending.extend(ast.iter_child_nodes(node))
    return names


class DayOne:
    """The kernel hooks: ``post_run_cell`` remembers what a cell stopped at a TODO could not set,
    ``name_error`` (IPython's custom handler for NameError) names that TODO.

    A notebook TODO's own cell (``### BEGIN TODO 2.3.2`` ... in the cell) sets names only once it
    is written: until then a name that no cell has set is taken to be one it will make."""

    def __init__(self, shell):
        self.shell = shell
        self.missing = {}  # name -> the TODO id whose cell could not set it
        self.seen = set()  # every name some cell has set or tried to set
        self.open_cells = []  # notebook TODOs whose own cell stopped at them, oldest first

    def todo_of(self, error):
        if error is None:
            return None
        todo = not_done_todo(type(error).__name__, str(error), getattr(error, "todo", None))
        if todo is None and isinstance(error, NameError):
            todo = self._owner(getattr(error, "name", None))
        return todo

    def _owner(self, name):
        if name in self.missing:
            return self.missing[name]
        if name is not None and name not in self.seen and self.open_cells:
            return self.open_cells[-1]
        return None

    def post_run_cell(self, result):
        try:
            source = self.shell.transform_cell(result.info.raw_cell)
        except Exception:  # noqa: BLE001 - a cell IPython itself could not transform
            return
        todo = self.todo_of(result.error_in_exec)
        if todo is not None:
            self.show_in_view()
        own = set(_BLOCK.findall(source))
        if todo is not None and todo in own and todo not in self.open_cells:
            self.open_cells.append(todo)
        elif todo is None:
            self.open_cells = [cell for cell in self.open_cells if cell not in own]
        user = self.shell.user_ns
        for name in assigned_names(source):
            self.seen.add(name)
            if todo is not None and name not in user:
                self.missing[name] = todo
            elif name in user:
                self.missing.pop(name, None)

    def show_in_view(self):
        """Scroll JupyterLab to this cell's message: Run All scrolls to the notebook's last cell
        when it starts, so without this the student would not see where it stopped. An invisible
        output (JavaScript, run only in the live session; empty text otherwise)."""
        try:
            self.shell.display_pub.publish(data={"application/javascript": _SCROLL_TO_CELL, "text/plain": ""}, metadata={})
        except Exception:  # noqa: BLE001 - a front end without displays
            pass

    def name_error(self, shell, etype, value, tb, tb_offset=None):
        name = getattr(value, "name", None)
        todo = self._owner(name)
        if todo is None or name in shell.user_ns:
            shell.showtraceback((etype, value, tb), tb_offset=tb_offset, running_compiled_code=True)
            return None
        where = "your code in the cell of TODO" if name not in self.missing else "a cell above that stopped at TODO"
        shell._showtraceback(etype, value, [
            f"TODO {todo} is not done yet: `{name}` is made by {where} {todo}.",
            f"Do TODO {todo}, then run the cells from there again (Kernel > Restart Kernel and Run All Cells)."])
        return None


_SCROLL_TO_CELL = """(() => {
  let tries = 0;
  const show = () => {
    const cell = element.closest('.jp-Cell');
    if (cell) { (cell.querySelector('.jp-Cell-outputArea') || cell).scrollIntoView({block: 'center'}); }
    else if (tries++ < 40) { setTimeout(show, 50); }
  };
  setTimeout(show, 0);
})();"""
_BLOCK = re.compile(r"^[ \t]*###[ \t]*BEGIN[ \t]+(?:TODO|SOLUTION)[ \t]+(\d+(?:\.\d+)+)", re.M)


def install(shell=None):
    """Install the day-one hooks in the running IPython kernel (once); returns them, or None outside IPython."""
    if shell is None:
        try:
            from IPython import get_ipython  # noqa: PLC0415 - only inside a kernel
        except ImportError:
            return None
        shell = get_ipython()
    if shell is None or not hasattr(shell, "events"):
        return None
    hooks = getattr(shell, "_hwtools_day_one", None)
    if hooks is None:
        hooks = shell._hwtools_day_one = DayOne(shell)
        shell.events.register("post_run_cell", hooks.post_run_cell)
        if not shell.custom_exceptions:  # never replace a handler someone else set
            shell.set_custom_exc((NameError,), hooks.name_error)
    return hooks


_remember_loaded()
install()
