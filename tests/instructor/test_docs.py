"""The docs name only what the kit has, and a newcomer can read them: every file, folder, ``python -m``
module, ``module.name`` and link the README and ``docs/`` mention exists in this kit
(``tests/instructor/doc_mentions.py``), the README fits 10 KB and its TODO table is the kit's. The student
edition's README is checked against the edition itself, in ``tests/instructor/test_release.py``.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from doc_mentions import Kit, missing
from hwtools.todos import TODOS
from instructor.kit import kit_files

KIT = Path(__file__).resolve().parents[2]
STUDENT_README = "docs/student-README.md"  # the student edition's README.md: tests/instructor/test_release.py
NAMES = kit_files(KIT)
DOCS = sorted(name for name in NAMES if name.endswith(".md") and name != STUDENT_README)


@pytest.fixture(scope="module")
def kit():
    return Kit(KIT, NAMES)


@pytest.mark.parametrize("doc", DOCS)
def test_every_path_module_name_and_link_a_doc_mentions_exists(kit, doc):
    lacking = missing((KIT / doc).read_text(encoding="utf-8"), kit, doc)
    assert not lacking, f"{doc} names what the kit lacks: {lacking}"


def test_the_check_finds_what_a_doc_names_and_the_kit_lacks(kit):
    """The check above can fail: each kind of mention of something that is not there is found."""
    real = ("`hwlib/cartpole.py`: `CartPoleLinearPolicy.__call__`; `python -m hwtools.handin`; `hwtools.grade.grade_submission`; "
            "`HIDDEN_SEED` in `instructor/hidden_checks/__init__.py`; `hwlib/**/*.py`; `data/data.npz`; "
            "[grading](grading.md#the-sandbox), [readme](../README.md)")
    assert missing(real, kit, "docs/x.md") == []
    made_up = ("`hwlib/nope.py`; `python -m hwtools.nope`; `hwtools.grade.nope`; `hwlib/logreg.py`: `nope`; "
               "`NOPE` in `hwlib/settings.py`; `tests/*.nope`; [x](nope.md); [y](grading.md#nope); `hwlib/cartpole.py`: "
               "`CartPoleLinearPolicy.nope`")
    assert missing(made_up, kit, "docs/x.md") == [
        "path hwlib/nope.py", "path tests/*.nope", "python -m hwtools.nope", "module or name hwtools.nope",
        "module or name hwtools.grade.nope",
        "nope in hwlib/logreg.py", "CartPoleLinearPolicy.nope in hwlib/cartpole.py", "NOPE in hwlib/settings.py",
        "link nope.md", "link grading.md#nope (no such heading)"]


def test_the_readme_fits_10_kb_and_its_todo_table_is_the_kits():
    text = (KIT / "README.md").read_text(encoding="utf-8")
    assert len(text.encode("utf-8")) <= 10 * 1024
    rows = {match[1]: match[0] for match in re.finditer(r"(?m)^\| (\d\.\d\.\d) .*\|$", text)}
    assert set(rows) == {todo.id for todo in TODOS}, "one row per TODO of hwlib/machinery/todos.py"
    for todo in TODOS:
        for file, what in (part.partition(": ")[::2] for part in todo.code.split("; ")):
            if file.endswith(".py"):
                assert f"`{file}`" in rows[todo.id] and f"`{what.split()[-1]}`" in rows[todo.id], (todo.id, rows[todo.id])


TIME = r"\d+ min \d+ s|\d+(?:\.\d+)? (?:ms|s|min)\b"
DATED = rf"({TIME})[^.;|]{{0,80}}?\b(20\d\d-\d\d-\d\d)\b"


def _rows_by_date():
    rows = {}
    for line in (KIT / "benchmarks/RESULTS.md").read_text(encoding="utf-8").splitlines():
        if re.match(r"^\| 20\d\d-\d\d-\d\d \|", line):
            rows.setdefault(line[2:12], []).append(line)
    return rows


def test_a_time_the_docs_state_comes_from_a_dated_row_of_the_results():
    """Each time the README, requirements.txt or a doc states with its date is in a row of that date
    of benchmarks/RESULTS.md; the term's steps (docs/instructor.md) each give theirs so."""
    rows, wrong, seen = _rows_by_date(), [], 0
    for doc in ["requirements.txt", *DOCS]:  # DOCS: README.md and every other .md of the kit
        for time, date in re.findall(DATED, (KIT / doc).read_text(encoding="utf-8")):
            seen += 1
            if not any(re.search(rf"(?<![\d.]){re.escape(time)}", row) for row in rows.get(date, [])):
                wrong.append(f"{doc}: {time} ({date}) is in no row of {date} in benchmarks/RESULTS.md")
    assert seen >= 5 and not wrong, wrong
    steps = re.findall(r"^\| \d\. [^|]+\|[^|]+\| ([^|]+) \|$", (KIT / "docs/instructor.md").read_text(encoding="utf-8"), re.M)
    assert len(steps) == 9
    undated = [time for time in steps if re.search(TIME, time) and not re.search(DATED, time)]
    assert not undated, f"docs/instructor.md: the term's times without the date of their row: {undated}"
