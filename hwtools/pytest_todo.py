"""pytest reports that name the TODO: every failure's first line says which TODO to work on.

Registered by the kit's top-level ``conftest.py``. For the student it does four things:

* a test that fails because a TODO is not done yet (its stub raised ``TodoNotDone``, or the
  failure's text says "TODO 1.2.1 is not done yet", as a notebook run by the test does, and that
  TODO's code is indeed still the stub) is
  reported in two lines, "TODO 1.2.1 is not done yet: scalar_finite_diff in hwlib/finite_diff.py"
  and what to do, instead of a traceback (``--tb=long`` adds the traceback after them);
* a test marked ``@pytest.mark.todo("1.2.1")`` that fails while that TODO's code is still the stub
  is reported the same way; any other failure of such a test starts with "TODO 1.2.1:" (in the
  summary line and on the first line of the failure);
* in a notebook, once a cell stops at a TODO not done yet, the cells after it are skipped with that
  reason, as Run All stops there too (nbval would otherwise run them all, each failing again);
* a browser test (marker ``browser``) is skipped when a TODO it needs is untouched (its block is
  still the stub): it would start JupyterLab and Chromium only to see the notebook stop there.
  Its ``todo`` markers say which TODOs it needs; without any, every TODO of the notebooks.

In the instructor's edition every TODO is done, so nothing of this changes a result there.
"""

from __future__ import annotations

import re

import pytest

from hwtools.not_done import not_done_todo, untouched_todos, where
from hwtools.todos import TODO_BY_ID

_NOT_DONE_TEXT = re.compile(r"\bTODO (\d+\.\d+\.\d+) is not done yet")
_stopped = {}  # notebook path -> the TODO its run stopped at
_untouched = None


def _marked_todos(item):
    return [str(todo) for mark in item.iter_markers("todo") for todo in mark.args]


def _chain(error):
    seen = []
    while error is not None and error not in seen:
        seen.append(error)
        error = error.__cause__ or error.__context__
    return seen


def _not_done_of_exception(error):
    for link in _chain(error):
        todo = not_done_todo(type(link).__name__, str(link), getattr(link, "todo", None))
        if todo in TODO_BY_ID:
            return todo
    return None


def _not_done_of_cell(item):
    """The TODO a notebook cell (an nbval item) stopped at, from the kernel's error output."""
    for output in getattr(item, "test_outputs", None) or ():
        if output.get("output_type") == "error":
            todo = not_done_todo(output.get("ename", ""), output.get("evalue", ""))
            if todo in TODO_BY_ID:
                return todo
    return None


def _is_notebook_cell(item):
    return type(item).__name__ == "IPyNbCell"


class TodoFirst:
    """A failure's report with one line naming the TODO before the usual text."""

    def __init__(self, first_line, original):
        self.first_line, self.original = first_line, original
        crash = getattr(original, "reprcrash", None)
        if crash is not None and hasattr(crash, "message"):
            crash.message = f"{first_line} | {crash.message}" if crash.message else first_line
        self.reprcrash = crash

    def toterminal(self, tw):
        tw.line(self.first_line, red=True, bold=True)
        if hasattr(self.original, "toterminal"):
            self.original.toterminal(tw)
        else:
            tw.line(str(self.original))

    def __str__(self):
        return f"{self.first_line}\n{self.original}"


def _not_done_lines(todo):
    return (f"TODO {todo} is not done yet: {where(todo)}\n"
            f"  Write it between ### BEGIN TODO {todo} and ### END TODO {todo}, save, and run the tests again.")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if not report.failed or call.excinfo is None:
        return
    full = item.config.option.tbstyle == "long"  # --tb=long: the whole traceback after the TODO line
    todo = _not_done_of_cell(item) if _is_notebook_cell(item) else _not_done_of_exception(call.excinfo.value)
    if todo is None and not _marked_todos(item):
        # e.g. a notebook run by the test stopped there; believed only of a TODO whose code is the stub
        named = _NOT_DONE_TEXT.search(str(report.longrepr))
        todo = named.group(1) if named and named.group(1) in _untouched_in(item.config) else None
    if todo is None:  # a test of a TODO whose code is still the stub fails because of that
        todo = next((marked for marked in _marked_todos(item) if marked in _untouched_in(item.config)), None)
    if todo is not None:
        if _is_notebook_cell(item):
            _stopped.setdefault(str(item.fspath), todo)
        report.longrepr = TodoFirst(_not_done_lines(todo), report.longrepr) if full else _not_done_lines(todo)
        return
    marked = _marked_todos(item)
    if marked:
        report.longrepr = TodoFirst(f"TODO {', '.join(dict.fromkeys(marked))}: {item.name} failed", report.longrepr)


def _untouched_in(config):
    """The TODOs still stubbed in the kit under test (pytest's root folder), read once per run."""
    global _untouched  # noqa: PLW0603 - read once per run
    if _untouched is None:
        try:
            _untouched = untouched_todos(config.rootpath)
        except Exception:  # noqa: BLE001 - never let this shortcut break a test run
            _untouched = []
    return _untouched


def pytest_runtest_setup(item):
    if _is_notebook_cell(item):
        todo = _stopped.get(str(item.fspath))
        if todo is not None:
            pytest.skip(f"TODO {todo} is not done yet: a cell above stopped there (Run All stops there too)")
        return
    if item.get_closest_marker("browser") is None:
        return
    needed = _marked_todos(item) or list(TODO_BY_ID)
    missing = [todo for todo in needed if todo in _untouched_in(item.config)]
    if missing:
        pytest.skip(f"TODO {missing[0]} is not done yet ({where(missing[0])}): this browser test runs the notebooks, "
                    f"which need {'it' if len(missing) == 1 else 'it and ' + ', '.join(missing[1:])}")


def pytest_terminal_summary(terminalreporter):
    untouched = _untouched_in(terminalreporter.config)
    if untouched:
        terminalreporter.write_line(f"TODOs not done yet (their code is still the stub): {', '.join(untouched)}")
