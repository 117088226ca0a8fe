"""The student edition's versions of the files around the homework: ``pyproject.toml`` running the
notebooks with ``--nbval-lax``, and the README without its instructor-only parts and with a note for
students.
"""

from __future__ import annotations

import re

from instructor.kit import ReleaseError

STUDENT_NOTE = """\
> **Student edition.** The code of the handout's TODOs is yours to write. In `hwlib/` each one
> sits between `### BEGIN TODO 1.2.1` and `### END TODO 1.2.1` inside the function the handout
> names: write your code there and leave the two marker lines as they are (the grader reads your
> code from between them). In the notebooks a TODO is a `# YOUR CODE HERE` cell or a
> YOUR ANSWER HERE text. Until you fill them in, the tests of those TODOs fail.
> `.venv/bin/python -m hwtools.grade` checks your functions and prints your automatic points per
> TODO (the report items are graded by hand). The notebooks are stored without outputs, so
> `pytest` runs them with `--nbval-lax`: every cell must run without error, but outputs are not
> compared.
"""

INSTRUCTOR_BLOCK = re.compile(r"^[ \t]*<!--[ \t]*(?P<kind>BEGIN|END)[ \t]+INSTRUCTOR ONLY[ \t]*-->[ \t]*$")


def transform_pyproject(text, path):
    """Run the notebooks with --nbval-lax: stored without outputs, they cannot be compared."""
    lines = text.split("\n")
    for index, line in enumerate(lines):
        if line.strip().startswith("addopts") and re.search(r"--nbval(?![-\w])", line):
            lines[index] = re.sub(r"--nbval(?![-\w])", "--nbval-lax", line)
            return "\n".join(lines)
    raise ReleaseError(f"{path}:1: no 'addopts' line with --nbval to turn into --nbval-lax for the student edition")


def transform_readme(text, path):
    """Drop the instructor-only parts and add the student note after the title."""
    lines = text.split("\n")
    out, open_line = [], None
    for index, line in enumerate(lines):
        match = INSTRUCTOR_BLOCK.match(line)
        if match:
            if match["kind"] == "BEGIN":
                if open_line is not None:
                    raise ReleaseError(f"{path}:{index + 1}: nested BEGIN INSTRUCTOR ONLY (line {open_line + 1} is still open)")
                open_line = index
            else:
                if open_line is None:
                    raise ReleaseError(f"{path}:{index + 1}: END INSTRUCTOR ONLY without a BEGIN INSTRUCTOR ONLY")
                open_line = None
            continue
        if open_line is None:
            out.append(line)
    if open_line is not None:
        raise ReleaseError(f"{path}:{open_line + 1}: BEGIN INSTRUCTOR ONLY has no END INSTRUCTOR ONLY")
    title = next((index for index, line in enumerate(out) if line.startswith("# ")), -1)
    note = STUDENT_NOTE.rstrip("\n").split("\n")
    return "\n".join(out[:title + 1] + [""] + note + out[title + 1:])

