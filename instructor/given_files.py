"""The student edition's versions of the files around the homework: test files without their hidden
tests, and ``pyproject.toml`` running the notebooks with ``--nbval-lax``. (The edition's README is a
file of its own, ``docs/student-README.md``: ``instructor/release.py``.)
"""

from __future__ import annotations

import ast
import re

from instructor.kit import ReleaseError

HIDDEN_MARK = re.compile(r"(?:pytest\.)?mark\.hidden\b(?:\(\))?")


def drop_hidden_tests(text, path):
    """``text`` of a test file without its top-level tests (functions or classes) decorated
    ``@pytest.mark.hidden``. A hidden mark anywhere else (``pytestmark``, a method) is an error:
    a whole test file that stays with the instructor is listed in ``INSTRUCTOR_ONLY`` (``instructor/kit.py``)."""
    if not HIDDEN_MARK.search(text):
        return text
    tree = ast.parse(text)
    lines = text.split("\n")
    drop = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            if any(HIDDEN_MARK.fullmatch(ast.unparse(decorator)) for decorator in node.decorator_list):
                first = min(decorator.lineno for decorator in node.decorator_list)
                end = node.end_lineno
                while end < len(lines) and not lines[end].strip():  # the blank lines after it
                    end += 1
                drop.update(range(first - 1, end))
    leftover = [index + 1 for index, line in enumerate(lines) if index not in drop and HIDDEN_MARK.search(line)]
    if leftover:
        raise ReleaseError(f"{path}:{leftover[0]}: only top-level tests can be marked hidden here; "
                           "list a whole instructor-only test file in INSTRUCTOR_ONLY (instructor/kit.py)")
    kept = [line for index, line in enumerate(lines) if index not in drop]
    while len(kept) > 1 and not kept[-1].strip() and not kept[-2].strip():
        kept.pop()  # a file that ended with a dropped test ends with one newline, as before
    return "\n".join(kept)



def transform_pyproject(text, path):
    """Run the notebooks with --nbval-lax: stored without outputs, they cannot be compared."""
    lines = text.split("\n")
    for index, line in enumerate(lines):
        if line.strip().startswith("addopts") and re.search(r"--nbval(?![-\w])", line):
            lines[index] = re.sub(r"--nbval(?![-\w])", "--nbval-lax", line)
            return "\n".join(lines)
    raise ReleaseError(f"{path}:1: no 'addopts' line with --nbval to turn into --nbval-lax for the student edition")
