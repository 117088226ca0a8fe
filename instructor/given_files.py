"""The student edition's version of a file around the homework: ``pyproject.toml`` running the notebooks
with ``--nbval-lax``, and ``requirements.txt`` without what only the instructor's kit needs. (The edition's README is a file of its own, ``docs/student-README.md``:
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


INSTRUCTOR_ONLY_REQUIREMENT = "# Instructor's kit only:"


def transform_requirements(text, path):
    """``requirements.txt`` without the requirements only the instructor's kit needs: each line of
    the comment block that starts with INSTRUCTOR_ONLY_REQUIREMENT and the requirement after it."""
    kept, dropping = [], False
    for line in text.split("\n"):
        if line.startswith(INSTRUCTOR_ONLY_REQUIREMENT):
            dropping = True
        elif dropping and not line.startswith("#"):
            dropping = False
            if not line.strip():
                raise ReleaseError(f"{path}: an '{INSTRUCTOR_ONLY_REQUIREMENT}' comment without a requirement after it")
            continue
        if not dropping:
            kept.append(line)
    return "\n".join(kept)
