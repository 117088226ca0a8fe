"""Grades into Canvas with no hand edits: the class's automatic totals as the CSV that Canvas's
gradebook import (Grades → Import) takes on the first try.

Canvas's importer (canvas-lms, ``app/models/gradebook_importer.rb``) reads a header row whose first
columns are ``Student``, ``ID`` and, in this order, ``SIS User ID`` and ``SIS Login ID`` (optional),
then ``Section``; every later column named ``Title (id)`` fills the existing assignment ``id`` (any
other name makes a new assignment); a row whose first cell holds "Points Possible" sets the maxima.
It matches each row to a student by Canvas's ``ID`` first, then by SIS User ID, then by SIS Login
ID, then by exact name; a row it cannot match becomes a new student. A blank grade changes nothing.

With the roster (``read_roster``: the CSV Canvas itself exports, Grades → Export), each student on
it gets a row with Canvas's own Student, ID, SIS User ID, SIS Login ID and Section, so every row
matches by ID; a submission is matched to its student by its name (``roster_match``): the Andrew ID
in any of its usual places (the SIS Login ID, the SIS User ID, the local part of a login that is an
e-mail address), or the Canvas user id in the name Canvas gives a downloaded submission
(``doejane_12345_678901_ajdoe.zip``, ``doejane_LATE_12345_...``). A roster student without a
submission gets a blank cell (Canvas keeps what it has); a submission not on the roster is reported,
not written. Without a roster, each submission's id stands in the SIS Login ID (the Andrew ID is the
login at CMU) and in Student, ID left blank. Every cell goes through ``safe_text.csv_text``.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path

from hwtools.grade.feedback import points
from hwtools.grade.safe_text import csv_text, printable
from hwtools.todos import AUTO_POINTS

COLUMNS = ("Student", "ID", "SIS User ID", "SIS Login ID", "Section")
POINTS_POSSIBLE = "Points Possible"
DEFAULT_ASSIGNMENT = "Homework 1 (automatic points)"
ASSIGNMENT_HEADER = re.compile(r"\A(.*)\s\((\d+)\)\Z", re.DOTALL)  # Canvas's Assignment.title_and_id
# Columns the importer never reads as an assignment (GradebookImporter's NON_ASSIGNMENT_COLUMN_HEADERS,
# matched anywhere in the header, and its reserved names).
NOT_ASSIGNMENTS = re.compile("Current Score|Current Points|Current Grade|Final Score|Final Points|Final Grade|"
                             "Override Score|Override Grade|Override Status")
RESERVED = {"Student", "LastName", "FirstName", "ID", "SIS User ID", "SIS Login ID", "Section", "Integration ID",
            "Root Account"}
# The name Canvas gives each file of "Download Submissions": sortable name, LATE when late, user id,
# attachment id, the student's own file name.
CANVAS_DOWNLOAD = re.compile(r"\A[^_]+_(?:LATE_)?(\d+)_\d+_.+\Z")
MAX_ROSTER_BYTES = 20_000_000


class RosterError(ValueError):
    """A roster file that is not Canvas's gradebook export, with the reason."""


@dataclass(frozen=True)
class RosterStudent:
    """One student of Canvas's export, with Canvas's own values."""

    name: str
    canvas_id: str
    sis_user_id: str
    sis_login_id: str
    section: str


@dataclass
class Roster:
    """Canvas's export: its students (in its order) and its assignments (``Title (id)`` header -> the
    Points Possible cell, "" when the export has none)."""

    path: Path
    students: list
    assignments: dict


def _delimiter(lines):
    """"," or ";" (Canvas exports with ";" in locales whose decimal mark is a comma), chosen as
    Canvas's importer chooses: the one that splits the first lines into the same, larger, count."""
    counts = {}
    for separator in (",", ";"):
        try:
            sizes = {len(row) for row in csv.reader(lines[:3], delimiter=separator)}
        except csv.Error:
            sizes = set()
        counts[separator] = sizes.pop() if len(sizes) == 1 else 0
    return ";" if counts[";"] > counts[","] else ","


def read_roster(path):
    """Canvas's gradebook export at ``path`` as a ``Roster``; ``RosterError`` naming what is wrong."""
    path = Path(path)
    try:
        data = path.read_bytes()[:MAX_ROSTER_BYTES + 1]
    except OSError as error:
        raise RosterError(f"{path}: cannot be read ({error.strerror or error})") from None
    if len(data) > MAX_ROSTER_BYTES:
        raise RosterError(f"{path}: more than {MAX_ROSTER_BYTES // 1_000_000} MB; Canvas's gradebook export of a "
                          "class is far smaller")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise RosterError(f"{path}: not UTF-8 text (byte {error.start}); give the CSV Canvas exports "
                          "(Grades → Export), not a copy saved by a spreadsheet in another encoding") from None
    lines = text.splitlines(keepends=True)
    try:
        rows = list(csv.reader(lines, delimiter=_delimiter(lines)))
    except csv.Error as error:
        raise RosterError(f"{path}: not a CSV file ({error})") from None
    rows = [row for row in rows if any(cell.strip() for cell in row)]  # cells kept as Canvas wrote them
    if not rows:
        raise RosterError(f"{path}: empty; give the CSV Canvas exports (Grades → Export)")
    header = [name.strip() for name in rows[0]]
    where = {name: header.index(name) for name in RESERVED if name in header}
    if not (("Student" in where or {"LastName", "FirstName"} <= set(where)) and "ID" in where and "Section" in where):
        raise RosterError(f"{path}: its first row is not the header of Canvas's gradebook export (Student, ID, "
                          f"SIS User ID, SIS Login ID, Section, ...): {printable(', '.join(header[:6]))[:200]}")
    if "SIS Login ID" not in where and "SIS User ID" not in where:
        raise RosterError(f"{path}: no SIS Login ID or SIS User ID column, so no submission can be matched to a "
                          "student; export the gradebook as someone allowed to see them")
    first_assignment = max(where.values()) + 1
    assignments = {name: "" for name in header[first_assignment:]
                   if ASSIGNMENT_HEADER.match(name) and not NOT_ASSIGNMENTS.search(name)}

    def cell(row, name):
        return row[where[name]] if name in where and where[name] < len(row) else ""

    students, seen = [], {}
    for number, row in enumerate(rows[1:], 2):
        if POINTS_POSSIBLE in row[0]:
            for index, name in enumerate(header):
                if name in assignments and index < len(row):
                    assignments[name] = row[index]
            continue
        if all(re.fullmatch(r"\s*(Muted|Manual Posting.*)?\s*", value, re.IGNORECASE) for value in row):
            continue  # the row that marks muted or manually posted assignments
        name = cell(row, "Student") or f"{cell(row, 'FirstName')} {cell(row, 'LastName')}".strip()
        canvas_id = cell(row, "ID").strip()
        if not re.fullmatch(r"[0-9]+", canvas_id):
            raise RosterError(f"{path}: row {number} ({printable(name)[:60]}): its ID is {printable(canvas_id)[:30]!r}, "
                              "not Canvas's number for the student")
        if canvas_id in seen:
            raise RosterError(f"{path}: rows {seen[canvas_id]} and {number} are both the student with ID {canvas_id}")
        seen[canvas_id] = number
        students.append(RosterStudent(name, canvas_id, cell(row, "SIS User ID"), cell(row, "SIS Login ID"),
                                      cell(row, "Section")))
    if not students:
        raise RosterError(f"{path}: no student rows under the header")
    return Roster(path, students, assignments)


def check_assignment(assignment):
    """``assignment`` as an assignment column's name, or ValueError naming what is wrong."""
    if not isinstance(assignment, str) or not assignment.strip() or printable(assignment) != assignment:
        raise ValueError(f"assignment: expected a non-empty one-line column name, got {assignment!r}")
    if assignment.strip() in RESERVED or NOT_ASSIGNMENTS.search(assignment) or POINTS_POSSIBLE in assignment:
        raise ValueError(f"assignment: {assignment!r} names a column Canvas's import does not read as an assignment")
    return assignment.strip()


def choose_assignment(roster, given=None):
    """The assignment column (``Title (id)``) and its Points Possible cell for the import: the export's
    one whose whole header, id or title (any letter case) is ``given``, or, without ``given``, its only
    assignment; a ``given`` name of the form ``Title (id)`` is used as it is. RosterError otherwise."""
    columns = list(roster.assignments)
    listed = "; ".join(columns[:20]) + (f"; ... ({len(columns)} in all)" if len(columns) > 20 else "")
    if given is None:
        if len(columns) == 1:
            return columns[0], roster.assignments[columns[0]]
        raise RosterError(f"{roster.path}: {'no assignment column' if not columns else f'{len(columns)} assignments'}; "
                          f"name the one to fill with --assignment (one of: {listed or 'none'}; or 'Title (id)')")
    given = check_assignment(given)
    found = [name for name in columns if given.casefold() in
             (name.casefold(), ASSIGNMENT_HEADER.match(name)[2], ASSIGNMENT_HEADER.match(name)[1].strip().casefold())]
    if len(found) == 1:
        return found[0], roster.assignments[found[0]]
    if len(found) > 1:
        raise RosterError(f"--assignment {given!r}: {len(found)} assignments of {roster.path} match: "
                          f"{'; '.join(found)}; give the whole 'Title (id)'")
    if ASSIGNMENT_HEADER.match(given):
        return given, ""
    raise RosterError(f"--assignment {given!r}: no assignment of {roster.path} has that title or id (its "
                      f"assignments: {listed or 'none'}); give one of them, or 'Title (id)'")


def _keys(student):
    """The names a submission of ``student`` may carry, best first: the SIS Login ID and SIS User ID
    whole, then the local part of a login that is an e-mail address."""
    whole = {value.casefold() for value in (student.sis_login_id, student.sis_user_id) if value}
    local = {value.split("@")[0].casefold() for value in (student.sis_login_id, student.sis_user_id)
             if value.count("@") == 1 and value.split("@")[0]}
    return whole, local - whole


def roster_match(roster, submission_ids):
    """({canvas id: submission id}, {submission id: why it is not written}): each submission matched
    to the one roster student it names (``CANVAS_DOWNLOAD``'s user id, else a whole SIS Login ID or SIS
    User ID, else an e-mail's local part, letter case ignored). A name that fits two students, or a
    student two submissions name, is reported and writes nothing."""
    by_id = {student.canvas_id: student for student in roster.students}
    tiers = ({}, {})
    for student in roster.students:
        for tier, keys in zip(tiers, _keys(student)):
            for key in keys:
                tier.setdefault(key, set()).add(student.canvas_id)
    claims, unmatched = {}, {}
    for submission in submission_ids:
        download = CANVAS_DOWNLOAD.match(submission)
        found = {download[1]} & set(by_id) if download else set()
        key = submission.casefold()
        for tier in tiers:
            found = found or tier.get(key, set())
        if not found:
            unmatched[submission] = "not on the roster"
        elif len(found) > 1:
            names = ", ".join(f"{by_id[canvas_id].name} (ID {canvas_id})" for canvas_id in sorted(found))
            unmatched[submission] = f"names more than one student of the roster: {names}"
        else:
            claims.setdefault(found.pop(), []).append(submission)
    matched = {}
    for canvas_id, submissions in claims.items():
        if len(submissions) == 1:
            matched[canvas_id] = submissions[0]
            continue
        for submission in submissions:
            others = ", ".join(other for other in submissions if other != submission)
            unmatched[submission] = (f"{by_id[canvas_id].name} (ID {canvas_id}) also handed in {others}; "
                                     "neither is written")
    return matched, unmatched


@dataclass
class CanvasImport:
    """The import's text and what it left out: ``blank`` (roster students without a submission),
    ``not_written`` ({submission id: why}), ``notes`` (for the instructor)."""

    text: str
    assignment: str
    rows: int = 0
    blank: list = field(default_factory=list)
    not_written: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)


def _grade(student_result):
    """The cell of one submission: its automatic total, as in the gradebook; None when the grader
    itself failed on it (written blank, reported: a rerun grades it)."""
    if "grader error" in student_result.status:
        return None
    return points(student_result.auto_total)


def canvas_import(student_results, roster=None, assignment=None):
    """The ``CanvasImport`` of ``student_results`` (``gradebook.StudentResult``): the header
    (``COLUMNS``, the assignment column), the Points Possible row, one row per roster student (in
    the roster's order), or, without a roster, one per submission (sorted by id)."""
    results = sorted(student_results, key=lambda item: item.student)
    if roster is None:
        assignment = check_assignment(DEFAULT_ASSIGNMENT if assignment is None else assignment)
        maximum = points(AUTO_POINTS)
    else:
        assignment, maximum = choose_assignment(roster, assignment)
        maximum = maximum or points(AUTO_POINTS)
    out = CanvasImport("", assignment)
    rows = [[*COLUMNS, assignment], [POINTS_POSSIBLE, "", "", "", "", maximum]]
    if roster is None:
        for item in results:
            grade = _grade(item)
            if grade is None:
                out.not_written[item.student] = item.status
            else:
                rows.append([item.student, "", "", item.student, "", grade])
    else:
        by_student = {item.student: item for item in results}
        matched, out.not_written = roster_match(roster, list(by_student))
        for student in roster.students:
            item = by_student.get(matched.get(student.canvas_id))
            grade = _grade(item) if item is not None else None
            if item is None:
                out.blank.append(student.name)
            elif grade is None:
                out.not_written[item.student] = item.status
            rows.append([student.name, student.canvas_id, student.sis_user_id, student.sis_login_id, student.section,
                         "" if grade is None else grade])
        try:
            if float(maximum) != AUTO_POINTS:
                out.notes.append(f"{assignment} is worth {maximum} points in Canvas; the automatic points are out of "
                                 f"{points(AUTO_POINTS)} (the import leaves Canvas's maximum as it is)")
        except ValueError:
            pass
    out.rows = len(rows) - 2
    out.text = csv_text(rows)
    return out
