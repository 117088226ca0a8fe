"""The student edition's version of a file around the homework: ``pyproject.toml`` running the notebooks
with ``--nbval-lax``. (The edition's README is a file of its own, ``docs/student-README.md``:
``instructor/release.py``.)
"""

from __future__ import annotations

import re

from instructor.kit import ReleaseError


def transform_pyproject(text, path):
    """Run the notebooks with --nbval-lax: stored without outputs, they cannot be compared."""
    lines = text.split("\n")
    for index, line in enumerate(lines):
        if line.strip().startswith("addopts") and re.search(r"--nbval(?![-\w])", line):
            lines[index] = re.sub(r"--nbval(?![-\w])", "--nbval-lax", line)
            return "\n".join(lines)
    raise ReleaseError(f"{path}:1: no 'addopts' line with --nbval to turn into --nbval-lax for the student edition")
