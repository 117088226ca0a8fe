"""Grades into Canvas with no hand edits (``hwtools/grade/instructor/canvas.py``).

Canvas cannot be run here, so this file re-implements, from canvas-lms's own source, the two ends
the class run meets: the gradebook export an instructor downloads (``GradebookExporter#csv_data``:
its header, the Muted and Points Possible rows, sortable names, ``="..."`` around a name that starts
with "=") and the gradebook import that reads the kit's file back (``GradebookImporter``: the header
rules of ``header?``/``update_column_count``, ``Assignment.title_and_id`` and the assignment lookup
of ``parse_assignments``, the student lookup of ``process_student``: Canvas ID, then SIS User ID,
then SIS Login ID, then exact name or sortable name, else a new student; the Points Possible row;
blank grades). A course with tricky names (commas, quotes, accents, a name that starts with "=",
two students called John Smith) goes through both: every row of the kit's import is matched by
Canvas ID, no student and no assignment is new, and every grade lands on its student.
"""

from __future__ import annotations

import csv
import io
import re
import subprocess
import sys
from pathlib import Path

import pytest

from hwtools.grade import AUTO_POINTS, Grader
from hwtools.todos import MANUAL_POINTS
from hwtools.grade.feedback import points
from hwtools.grade.instructor import canvas, classroom
from hwtools.grade.instructor.gradebook import StudentResult

KIT = Path(__file__).resolve().parents[2]
pytestmark = [pytest.mark.timeout(120)]

# --------------------------------------------------------------------------------------------
# A course, as Canvas holds it, and its export
# --------------------------------------------------------------------------------------------

STUDENTS = [  # (id, name, sortable name, SIS User ID, login = SIS Login ID, section)
    (1001, "Jane Doe", "Doe, Jane", "900001", "ajdoe", "Section A"),
    (1002, "John Smith", "Smith, John", "900002", "jsmith1@andrew.cmu.edu", "Section A"),
    (1003, "John Smith", "Smith, John", "900003", "jsmith2@andrew.cmu.edu", "Section B"),
    (1004, "Zoë Łukasz-Żółć", "Łukasz-Żółć, Zoë", "900004", "zlukasz", "Section B"),
    (1005, "Seán \"Shane\" O'Brien", "O'Brien, Seán \"Shane\"", "900005", "sobrien", "Section A"),
    (1006, "=cmd|' /C calc'!A0", "=cmd|' /C calc'!A0", "900006", "eve", "Section B"),
    (1007, "Ana María de la Cruz, Jr.", "de la Cruz, Jr., Ana María", "ACRUZ", "acruz@gmail.com", "Section A"),
    (1008, "Nobody Handedin", "Handedin, Nobody", "900008", "nhanded", "Section B"),
    (1009, "Test Student", "Student, Test", "", "", "Section A"),  # Canvas's Student View user
]
ASSIGNMENTS = [  # (id, title, points possible)
    (501, "Homework 0", 10),
    (502, "Homework 1 (code)", AUTO_POINTS),  # the automatic points
    (503, "Homework 1, report", MANUAL_POINTS),
]
ASSIGNMENT = "Homework 1 (code) (502)"  # Canvas's title_with_id of 502


def canvas_export(students=STUDENTS, assignments=ASSIGNMENTS, include_sis_id=True, separator=",", bom=False):
    """The gradebook CSV Canvas exports (GradebookExporter#csv_data, totals without grading standard)."""
    rows = [["Student", "ID"] + (["SIS User ID"] if include_sis_id else []) + ["SIS Login ID", "Section"]
            + [f"{title} ({number})" for number, title, _ in assignments]
            + ["Current Points", "Final Points", "Current Score", "Unposted Current Score", "Final Score",
               "Unposted Final Score"]]
    filler = [""] * (4 + include_sis_id)
    rows.append(filler + ["Manual Posting" if number == 503 else "" for number, _, _ in assignments] + [""] * 6)
    rows.append(["    Points Possible"] + filler[1:] + [points(most) for _, _, most in assignments] + ["(read only)"] * 6)
    for number, _, sortable, sis_user, login, section in students:
        name = f'="{sortable}"' if re.match(r"^\s*=", sortable) else sortable
        rows.append([name, str(number)] + ([sis_user] if include_sis_id else []) + [login, section]
                    + ["7", "", ""][:len(assignments)] + ["7", "7", "70", "70", "10", "10"])
    stream = io.StringIO()
    csv.writer(stream, delimiter=separator, lineterminator="\r\n").writerows(rows)
    return ("\ufeff" if bom else "") + stream.getvalue()


# --------------------------------------------------------------------------------------------
# Canvas's gradebook importer, re-implemented from its source
# --------------------------------------------------------------------------------------------

NON_ASSIGNMENT = re.compile("Current Score|Current Points|Current Grade|Final Score|Final Points|Final Grade|"
                            "Override Score|Override Grade|Override Status")


def ruby_to_i(text):
    """Ruby's String#to_i: the leading integer, 0 when there is none."""
    found = re.match(r"\s*([+-]?\d+)", text.replace("_", ""))
    return int(found[1]) if found else 0


def canvas_reads(text, students=STUDENTS, assignments=ASSIGNMENTS):
    """What GradebookImporter makes of ``text``: {"rows": [(how the student was found, Canvas id or
    None), ...], "grades": {Canvas id or the row's name: {assignment id or "new: title": grade}},
    "assignments": [(how, id or "new: title")], "points_possible": {...}}. Raises ValueError for an
    invalid header, as the importer stops with "Invalid header row"."""
    text = text.removeprefix("\ufeff")
    lines = text.splitlines()
    counts = {}
    for separator in (",", ";"):  # identify_delimiter: the first 3 lines split evenly
        sizes = {len(next(csv.reader([line], delimiter=separator))) for line in lines[:3]}
        counts[separator] = sizes.pop() if len(sizes) == 1 else 0
    separator = ";" if counts[";"] > counts[","] else ","
    rows = [row for row in csv.reader(io.StringIO(text), delimiter=separator)
            if not re.fullmatch(r"[;, ]*", separator.join(row))]
    header = rows[0]
    if not (len(header) > 3 and "Student" in header[0] and "ID" in header[1]):
        raise ValueError("Invalid header row")
    columns, sis_user, sis_login = 3, None, None
    if re.search(r"SIS\s+Login\s+ID", header[2]):
        sis_login, columns = 2, 4
    elif re.search(r"SIS\s+User\s+ID", header[2]) and re.search(r"SIS\s+Login\s+ID", header[3]):
        extra = 1 if re.search(r"Integration\s+ID", header[4]) else 0
        sis_user, sis_login, columns = 2, 3, 5 + extra
        if re.search(r"Root\s+Account", header[4 + extra]):
            columns += 1
    if "Section" not in header[columns - 1]:
        raise ValueError("Invalid header row")
    by_number = {number: (number, title) for number, title, _ in assignments}
    found_assignments, index_of = [], {}
    for position, name in enumerate(header[columns:], columns):
        if NON_ASSIGNMENT.search(name):
            continue
        title_id = re.fullmatch(r"(.*)\s\((\d+)\)", name, re.DOTALL)
        known = by_number.get(int(title_id[2])) if title_id else None
        how = "id" if known else None
        if known is None:
            known = next(((number, title) for number, title, _ in assignments if title == name), None)
            how = "title" if known else "new"
        key = known[0] if known else f"new: {title_id[1] if title_id else name}"
        found_assignments.append((how, key))
        index_of[key] = position
    read = {"rows": [], "grades": {}, "assignments": found_assignments, "points_possible": {}}
    for row in rows[1:]:
        if "Points Possible" in row[0]:
            read["points_possible"] = {key: row[position] for key, position in index_of.items() if row[position]}
            continue
        if all(re.fullmatch(r"\s*(Muted|Manual Posting.*)?\s*", cell, re.IGNORECASE) for cell in row):
            continue
        student, how = None, None
        if row[1].strip() and any(number == ruby_to_i(row[1]) for number, *_ in students):
            student, how = ruby_to_i(row[1]), "id"
        if student is None and sis_user is not None and row[sis_user]:
            student = next((number for number, _, _, user, _, _ in students if user == row[sis_user]), None)
            how = "sis user id" if student else None
        if student is None and sis_login is not None and row[sis_login]:
            student = next((number for number, _, _, _, login, _ in students if login == row[sis_login]), None)
            how = "sis login id" if student else None
        if student is None:
            student = next((number for number, name, sortable, *_ in students if row[0] in (name, sortable)), None)
            how = "name" if student else "new"
        read["rows"].append((how, student))
        read["grades"][student if student else row[0]] = {key: row[position].strip() for key, position in index_of.items()}
    return read


def test_the_importer_model_reads_canvas_s_own_export_back_unchanged():
    """The model is Canvas's: its own export, read back, matches every row by ID, adds nothing."""
    for include_sis_id, separator, bom in ((True, ",", False), (False, ";", True)):
        read = canvas_reads(canvas_export(include_sis_id=include_sis_id, separator=separator, bom=bom))
        assert read["rows"] == [("id", number) for number, *_ in STUDENTS]
        assert read["assignments"] == [("id", number) for number, _, _ in ASSIGNMENTS]
        assert read["points_possible"] == {number: points(most) for number, _, most in ASSIGNMENTS}


def test_the_importer_model_sees_what_the_old_import_did_a_new_assignment_and_no_canvas_id():
    """The kit's import before --roster: the submission's id as Student and SIS Login ID, ID blank, a
    bare title. The model finds what Canvas would: a new assignment, rows matched by login or not at
    all (jsmith1 is a login only as an e-mail address), so this check can fail."""
    results = [StudentResult("ajdoe", "graded", result(30)), StudentResult("jsmith1", "graded", result(20))]
    read = canvas_reads(canvas.canvas_import(results).text)
    assert read["assignments"] == [("new", "new: Homework 1 (automatic points)")]
    assert read["rows"] == [("sis login id", 1001), ("new", None)]


# --------------------------------------------------------------------------------------------
# The kit's import, with the roster
# --------------------------------------------------------------------------------------------


def result(total):
    return {"total": {"auto_earned": total}, "todos": []}


SUBMISSIONS = {  # submission id -> (status, automatic total), and whom each is
    "ajdoe": ("graded", 31.5),  # Jane Doe: the bare login
    "JSMITH1": ("graded", 12.5),  # the first John Smith: his e-mail's local part, in capitals
    "smithjohn_LATE_1003_77001_jsmith2": ("graded", 12.0),  # the second: Canvas's "Download Submissions" name
    "zlukasz": ("timed out: 2.2.1", 25.0),  # Zoë
    "sobrien": ("empty", None),  # Seán: handed in nothing; 0 as in the gradebook
    "eve": ("graded", 3.0),  # the student whose name starts with "="
    "ACRUZ": ("graded", 38.0),  # Ana María: her SIS User ID (her login is a gmail address)
    "stranger": ("graded", 7.0),  # not on the roster
    "grader-broke": ("grader error: RuntimeError: boom", None),  # not on the roster either
}
EXPECTED = {1001: "31.5", 1002: "12.5", 1003: "12", 1004: "25", 1005: "0", 1006: "3", 1007: "38", 1008: "", 1009: ""}


def student_results(submissions=SUBMISSIONS):
    return [StudentResult(student, status, None if total is None else result(total))
            for student, (status, total) in submissions.items()]


@pytest.fixture
def roster(tmp_path):
    path = tmp_path / "2026-12-07T0400_Grades-16-662.csv"
    path.write_text(canvas_export(), encoding="utf-8", newline="")
    return canvas.read_roster(path)


@pytest.mark.quick
@pytest.mark.parametrize("include_sis_id,separator,bom", [(True, ",", False), (False, ";", True)])
def test_every_row_is_matched_by_canvas_id_and_nothing_new_is_made(tmp_path, include_sis_id, separator, bom):
    path = tmp_path / "export.csv"
    path.write_text(canvas_export(include_sis_id=include_sis_id, separator=separator, bom=bom), encoding="utf-8",
                    newline="")
    submissions = dict(SUBMISSIONS)
    if not include_sis_id:  # no SIS User ID column: Ana María's only name is her gmail login's local part
        submissions["acruz"] = submissions.pop("ACRUZ")
    made = canvas.canvas_import(student_results(submissions), canvas.read_roster(path), assignment="502")
    read = canvas_reads(made.text)
    assert read["rows"] == [("id", number) for number, *_ in STUDENTS], "every row by Canvas ID, none new"
    assert read["assignments"] == [("id", 502)], "the existing assignment, none new"
    assert read["points_possible"] == {502: points(AUTO_POINTS)}, "Canvas's own maximum, unchanged"
    assert {number: grades[502] for number, grades in read["grades"].items()} == EXPECTED
    assert made.assignment == ASSIGNMENT and made.rows == len(STUDENTS)
    assert made.blank == ["Handedin, Nobody", "Student, Test"]
    assert made.not_written == {"stranger": "not on the roster", "grader-broke": "not on the roster"}
    assert "stranger" not in made.text and "grader-broke" not in made.text
    rows = list(csv.reader(io.StringIO(made.text)))
    assert rows[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", ASSIGNMENT]
    by_id = {row[1]: row for row in rows[2:]}
    assert by_id["1005"][:5] == ["O'Brien, Seán \"Shane\"", "1005", "900005" if include_sis_id else "", "sobrien",
                                 "Section A"], "Canvas's own values, quotes and accents kept"
    assert by_id["1006"][0] == "'=\"=cmd|' /C calc'!A0\"", "a name that starts with = is shown as text"
    assert [row[0] for row in rows[2:]].count("Smith, John") == 2


def test_the_assignment_is_found_by_its_whole_header_its_id_or_its_title(roster):
    for given in ("Homework 1 (code) (502)", "502", "homework 1 (code)", None):
        if given is None:
            with pytest.raises(canvas.RosterError, match="3 assignments; name the one to fill with --assignment"):
                canvas.choose_assignment(roster, given)
            continue
        assert canvas.choose_assignment(roster, given) == (ASSIGNMENT, points(AUTO_POINTS))
    assert canvas.choose_assignment(roster, "Homework 2 (777)") == ("Homework 2 (777)", "")  # given, used as given
    with pytest.raises(canvas.RosterError, match="no assignment of .* has that title or id"):
        canvas.choose_assignment(roster, "Homework 2")
    with pytest.raises(ValueError, match="does not read as an assignment"):
        canvas.choose_assignment(roster, "Current Score")
    made = canvas.canvas_import(student_results(), roster, "Homework 1, report")
    assert made.notes == [f"Homework 1, report (503) is worth {points(MANUAL_POINTS)} points in Canvas; the automatic points are out of "
                          f"{points(AUTO_POINTS)} (the import leaves Canvas's maximum as it is)"]


def test_a_name_that_fits_two_students_or_a_student_named_twice_writes_nothing(tmp_path):
    twins = [STUDENTS[0], (1010, "Jane Doe", "Doe, Jane", "900010", "ajdoe@gmail.com", "Section B"), STUDENTS[1]]
    path = tmp_path / "export.csv"
    path.write_text(canvas_export(students=twins), encoding="utf-8")
    roster = canvas.read_roster(path)
    matched, unmatched = canvas.roster_match(roster, ["ajdoe", "jsmith1", "jsmith1@andrew.cmu.edu"])
    assert matched == {"1001": "ajdoe"}, "the whole login wins over another student's e-mail local part"
    assert set(unmatched) == {"jsmith1", "jsmith1@andrew.cmu.edu"}
    assert "also handed in jsmith1@andrew.cmu.edu; neither is written" in unmatched["jsmith1"]
    both = [(1011, "A", "A", "", "kim@andrew.cmu.edu", "S"), (1012, "B", "B", "", "kim@cs.cmu.edu", "S")]
    path.write_text(canvas_export(students=both), encoding="utf-8")
    assert canvas.roster_match(canvas.read_roster(path), ["kim"])[1] == {
        "kim": "names more than one student of the roster: A (ID 1011), B (ID 1012)"}


@pytest.mark.parametrize("text,message", [
    ("", "empty"),
    ("student,status\nada,graded\n", "not the header of Canvas's gradebook export"),
    ("Student,ID,Section,HW (1)\nA,12,S,1\n", "no SIS Login ID or SIS User ID column"),
    ("Student,ID,SIS Login ID,Section,HW (1)\nA,,a,S,1\n", "row 2 \\(A\\): its ID is '', not Canvas's number"),
    ("Student,ID,SIS Login ID,Section,HW (1)\nA,12,a,S,1\nB,12,b,S,1\n", "rows 2 and 3 are both the student with ID 12"),
    ("Student,ID,SIS Login ID,Section,HW (1)\n    Points Possible,,,,10\n", "no student rows"),
])
def test_a_roster_that_is_not_canvas_s_export_is_refused_with_the_reason(tmp_path, text, message):
    path = tmp_path / "roster.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(canvas.RosterError, match=message):
        canvas.read_roster(path)
    path.write_bytes(b"Student,ID\n\xff\xfe")
    with pytest.raises(canvas.RosterError, match="not UTF-8 text"):
        canvas.read_roster(path)


def test_the_class_run_takes_the_roster_and_refuses_a_bad_one_before_grading(tmp_path):
    """``--roster``: a bad roster stops the command before anything is graded or written; a good one
    gives the import a row per roster student (here the class's submissions are empty: no student
    code runs), the roster file itself is not read as a submission."""
    folder = tmp_path / "submissions"
    for student in ("ajdoe", "stranger"):
        (folder / student).mkdir(parents=True)
    bad = tmp_path / "bad.csv"
    bad.write_text("student,status\n", encoding="utf-8")
    run = subprocess.run([sys.executable, "-m", "hwtools.grade", str(folder), "--gradebook", str(tmp_path / "g.csv"),
                          "--feedback", str(tmp_path / "fb"), "--roster", str(bad)],
                         capture_output=True, text=True, cwd=KIT, timeout=60)
    assert run.returncode == 2 and "error: --roster" in run.stderr and "not the header" in run.stderr, run.stderr
    assert not (tmp_path / "g.csv").exists() and not (tmp_path / "fb").exists()
    export = folder / "grades-export.csv"  # where a TA may well leave it
    export.write_text(canvas_export(), encoding="utf-8")
    report = classroom.grade_class(folder, tmp_path / "g.csv", tmp_path / "fb", grader=Grader(KIT, time_limit=5, jobs=1),
                                   jobs=1, roster=canvas.read_roster(export), assignment="Homework 1 (code)")
    assert [item.student for item in report.students] == ["ajdoe", "stranger"]
    read = canvas_reads(classroom.canvas_file(tmp_path / "g.csv").read_text(encoding="utf-8"))
    assert read["rows"] == [("id", number) for number, *_ in STUDENTS] and read["assignments"] == [("id", 502)]
    assert read["grades"][1001] == {502: "0"} and report.canvas.not_written == {"stranger": "not on the roster"}
