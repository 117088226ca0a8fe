"""The class's gradebook: one CSV row per student (``StudentResult``): status, automatic points per
TODO, their total, empty columns for the points graded by hand (maxima in the headers), notes; and
the same automatic totals for Canvas are written by ``canvas.py``. No time stamps: the same results
give the same bytes. Every cell is written by ``safe_text.csv_text``: shown as text (no formula from a
student's file name) and without control characters."""

from __future__ import annotations

from dataclasses import dataclass, field

from hwtools.grade.feedback import points
from hwtools.grade.safe_text import csv_text
from hwtools.todos import AUTO_POINTS, TODOS

GRADED, NOT_ISOLATED = "graded", "not isolated"


@dataclass
class StudentResult:
    """One student's row: ``status`` (graded, not isolated, timed out: ..., empty, unreadable: ...,
    rejected: ...), ``result`` (the grader's dict, or None when nothing was graded), ``notes``
    (what the reader did), ``reused`` (taken from the saved state)."""

    student: str
    status: str
    result: dict | None = None
    notes: list = field(default_factory=list)
    reused: bool = False
    seconds: float = 0.0

    @property
    def auto_total(self):
        return self.result["total"]["auto_earned"] if self.result else 0.0

    def auto_points(self, todo):
        if not self.result:
            return 0.0
        return next((entry["auto_earned"] for entry in self.result["todos"] if entry["id"] == todo), 0.0)


def status_of(result, visible=False):
    """The gradebook's status of a graded result: TODOs that timed out, TODOs the grader failed on
    (``grader_error``: not saved, a rerun tries again), and whether it ran unsandboxed. ``visible``:
    as the visible runs alone show it (``visible_status``: a run stopped in its hidden phase is not
    named), for what a student reads before the grades are published."""
    key = "visible_status" if visible else "status"
    timed_out = [entry["id"] for entry in result["todos"] if entry.get(key, entry["status"]) == "time limit"]
    failed = [entry["id"] for entry in result["todos"] if entry.get("grader_error")]
    parts = [f"timed out: {', '.join(timed_out)}"] if timed_out else []
    parts += [f"grader error: {', '.join(failed)}"] if failed else []
    if not result["isolated"]:
        parts.append(NOT_ISOLATED)
    return "; ".join(parts) or GRADED



def gradebook_header():
    """The gradebook's columns: student, status, one per TODO's automatic points, the automatic
    total, one (empty) per TODO's points graded by hand, notes; maxima in the headers."""
    header = ["student", "status"]
    header += [f"{todo.id} {todo.title} (/{points(todo.auto)})" for todo in TODOS if todo.auto]
    header.append(f"auto total (/{points(AUTO_POINTS)})")
    header += [f"{todo.id} by hand: {todo.manual_what if todo.auto else todo.title} (/{points(todo.manual)})"
               for todo in TODOS if todo.manual]
    header.append("notes")
    return header


def row_notes(student_result):
    notes = []
    if student_result.result:
        notes += [f"{entry['id']} {entry['status']}" for entry in student_result.result["todos"]
                  if entry["status"] in ("time limit", "crashed", "not graded")]
    return "; ".join(notes)


def gradebook_row(student_result):
    row = [student_result.student, student_result.status]
    row += [points(student_result.auto_points(todo.id)) for todo in TODOS if todo.auto]
    row.append(points(student_result.auto_total))
    row += ["" for todo in TODOS if todo.manual]
    row.append(row_notes(student_result))
    return row


def gradebook_text(student_results):
    rows = [gradebook_row(student_result) for student_result in sorted(student_results, key=lambda item: item.student)]
    return csv_text([gradebook_header(), *rows])
