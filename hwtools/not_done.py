"""Which TODO is not done yet: from an exception, from the grader's words, or from the files.

An untouched TODO's stub raises ``TodoNotDone("1.2.1")`` (the student edition's, ``instructor/stubs.py``).
The readers that turn that into "TODO 1.2.1 is not done yet: scalar_finite_diff in
hwlib/finite_diff.py" instead of a traceback use this module: the check cells
(``hwtools.check_cell``), the notebook's day-one hooks (``hwtools.notebook``) and the pytest plugin
(``hwtools.pytest_todo``). Standard library only: nothing of the homework runs here.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from hwtools.todos import TODO_BY_ID

KIT_ROOT = Path(__file__).resolve().parents[1]
_TODO_ID = re.compile(r"\b(\d+\.\d+\.\d+)\b")
_NOT_PART = "not part of this check"  # the grader's stub for a TODO that a check does not run


def not_done_todo(error_type, message, todo=None):
    """The TODO id that an exception says is not done yet, or None.

    ``error_type`` is the exception's class name, ``message`` its text (``todo``: its ``todo``
    attribute, if any). A stub raises ``TodoNotDone("1.2.1")``; a ``NotImplementedError`` whose
    text names a TODO counts too. The grader's own stand-in for a TODO outside a check ("... is not
    part of this check") does not.
    """
    message = str(message)
    if _NOT_PART in message:
        return None
    if error_type == "TodoNotDone":
        if todo:
            return str(todo)
        found = _TODO_ID.search(message)
        return found.group(1) if found else None
    if error_type == "NotImplementedError":
        found = re.search(r"\bTODO (\d+\.\d+\.\d+)\b", message)
        return found.group(1) if found else None
    return None


def _module_level_names():
    """{NAME: TODO id} of the TODOs that are a module-level setting ("hwlib/settings.py: LEARNING_RATE")."""
    names = {}
    for todo in TODO_BY_ID.values():
        file, _, what = todo.code.partition(": ")
        if file.endswith(".py") and what.isidentifier() and what.isupper():
            names[what] = todo.id
    return names


def not_done_in_text(text):
    """The TODO id named by the first "TypeName: message" error in a text (the grader's words for
    an error of the student's code), or None. A setting still None ("LEARNING_RATE is None") is
    its TODO not done yet."""
    match = re.match(r"\s*(\w+): (.*)", str(text), re.S)
    if not match:
        return None
    setting = re.match(r"(\w+) is None\b", match.group(2))
    if setting and setting.group(1) in _module_level_names():
        return _module_level_names()[setting.group(1)]
    return not_done_todo(match.group(1), match.group(2))


def where(todo):
    """"scalar_finite_diff in hwlib/finite_diff.py": where TODO ``todo``'s code goes (``Todo.where``:
    its library part where it names a notebook cell too)."""
    file, what = TODO_BY_ID[todo].where
    if file.endswith(".ipynb"):
        return f"{what} of {file}"
    return f"{what} in {file}" if what else file


def untouched_todos(kit=KIT_ROOT):
    """The TODO ids (in the handout's order) whose every code block in ``hwlib/`` and the notebooks'
    code cells is still the student edition's stub: comments, ``pass``, ``raise TodoNotDone(...)``
    or ``NAME = None``. Read from the files; nothing is run. (In the instructor's edition: none.)"""
    from hwtools.grade.blame import untouched  # noqa: PLC0415 - the grader's reading of a stub
    from hwtools.grade.blocks import SubmissionError, find_blocks  # noqa: PLC0415 - the grader's marker reader
    from hwtools.markers import is_leftover  # noqa: PLC0415

    kit = Path(kit)
    bodies = {}
    sources = [path.read_text(encoding="utf-8") for path in sorted((kit / "hwlib").rglob("*.py"))
               if not is_leftover(path.relative_to(kit))]
    for path in sorted((kit / "notebooks").glob("*.ipynb")):
        try:
            cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
        except (OSError, ValueError, KeyError):
            continue
        sources += ["".join(cell["source"]) for cell in cells if cell.get("cell_type") == "code"]
    for text in sources:
        try:
            blocks = find_blocks(text.replace("\r\n", "\n"))
        except SubmissionError:
            continue
        for block in blocks:
            bodies.setdefault(block.todo, []).append(block.body)
    return [todo for todo in TODO_BY_ID if todo in bodies and all(untouched(body) for body in bodies[todo])]
