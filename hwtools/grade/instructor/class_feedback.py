"""Markdown feedback for students (a class's files, Gradescope's tests): status, points per TODO,
what was checked, the first failing visible check with its input, expected and actual value;
never a hidden input. Everything a submission may have shaped is escaped for Markdown and shown
without control characters."""

from __future__ import annotations

import re

from hwtools.grade import blocks
from hwtools.grade.feedback import failure_words, points
from hwtools.grade.instructor.gradebook import status_of
from hwtools.grade.judging import visible_view
from hwtools.grade.safe_text import printable
from hwtools.grade.submissions import KIT_DEPTH, MAX_PY_BYTES, size_text




def _fence(text):
    """``text`` in a fenced code block whose fence no backtick run inside it can close."""
    text = printable(text, keep_newlines=True)
    longest = max((len(run) for run in re.findall(r"`+", text)), default=0)
    fence = "`" * max(3, longest + 1)
    return f"{fence}text\n{text.rstrip()}\n{fence}"


def md_escape(text):
    """Text a student's files may have shaped (notes, file names, statuses), safe inside a Markdown
    line: no emphasis, links, code, table cells or HTML."""
    text = printable(str(text).replace("\n", " ")).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return re.sub(r"([\\`*_\[\]|~])", r"\\\1", text)


def todo_markdown(entry, visible_only=False):
    """One TODO of a result as Markdown: the points, what was checked, the first failing visible
    check with its input, expected and actual value, the notes. ``visible_only``: what the visible
    inputs alone show (``judging.visible_view``: a check that fails only on hidden inputs reads as
    passing, nothing a hidden input shaped) and no points, for feedback given before the grades
    are published."""
    if visible_only:
        entry = entry if entry.get("visible_only") else visible_view(entry)
    lines = []
    verdict = "fails" if visible_only else (f"earns {points(entry['auto_earned'])} of {points(entry['auto_possible'])} points"
                                            if entry["auto_possible"] else "(graded by hand; this check is for the grader) fails")
    first, fields = failure_words(entry, verdict)  # the same words as every other report: what is wrong, first
    if first:
        lines += [_fence("\n".join(first)), ""]
    if not visible_only and entry["auto_possible"]:
        lines.append(f"**{points(entry['auto_earned'])} of {points(entry['auto_possible'])} automatic point(s)** "
                     f"({entry['status']})")
    elif not entry["auto_possible"]:
        lines.append("Graded by hand" + ("; the check below is for the grader, it gives no points." if entry["checks"]
                                         else "."))
    if lines and entry["checks"]:
        lines.append("")
    for check in entry["checks"]:
        if visible_only:
            where = f"{check['visible_inputs']} visible input(s)"
            lines.append(f"- {'pass' if check['passed'] else '**FAIL**'}: {check['check']} ({where})")
            continue
        inputs = f"{check['visible_inputs']} visible"
        inputs += f", {check['hidden_inputs']} hidden" if check["hidden_inputs"] else ""
        where = f"; failed on a {check['failed_on']} input" if check["failed_on"] else ""
        lines.append(f"- {'pass' if check['passed'] else '**FAIL**'}, {points(check['points'])} pt: "
                     f"{check['check']} ({inputs} input(s){where})")
    if fields:
        lines += ["", "First failing check:"]
    for name, text in fields:
        lines += ["", f"{name}:", "", _fence(text)]
    if entry["notes"]:
        lines.append("")
        lines += [f"- note: {md_escape(note)}" for note in entry["notes"]]
    if entry["manual_possible"] and not visible_only:
        lines.append("")
        lines.append(f"By hand ({points(entry['manual_possible'])} pt): {md_escape(entry['manual'])}")
    return "\n".join(lines)


def summary_table(result):
    lines = ["| TODO | what | automatic | by hand | status |", "|---|---|---|---|---|"]
    for entry in result["todos"]:
        auto = "–"
        if entry["auto_possible"]:
            auto = f"{points(entry['auto_earned'])} / {points(entry['auto_possible'])}"
        manual = points(entry["manual_possible"]) if entry["manual_possible"] else "–"
        lines.append(f"| {entry['id']} | {entry['title']} | {auto} | {manual} | {entry['status']} |")
    total = result["total"]
    lines.append(f"| **total** | | **{points(total['auto_earned'])} / {points(total['auto_possible'])}** | "
                 f"{points(total['manual_possible'])} | |")
    return "\n".join(lines)


UNGRADED_HELP = (f"What the grader reads: your `{blocks.PACKAGE}/` folder (with the code between the "
                 "`### BEGIN TODO` and `### END TODO` markers), in a folder or a .zip, at the top or up to "
                 f"{KIT_DEPTH} folders down; plain files only (no links), each Python file under "
                 f"{size_text(MAX_PY_BYTES)}.")


def feedback_markdown(student_result):
    """The feedback file of one student (Markdown): status, points per TODO, what was checked and
    the first failing visible check per TODO; never a hidden input. Its status line, like
    results.json's, reads the visible runs alone (``status_of(..., visible=True)``); the points and
    what the hidden inputs did (a check failed on one, a run stopped in its hidden phase) come
    under them: the file gives the grade, so it goes to the student with the grades."""
    lines = [f"# Homework 1, automatic grading: {md_escape(student_result.student)}", ""]
    result = student_result.result
    lines.append(f"Status: **{md_escape(status_of(result, visible=True) if result else student_result.status)}**")
    if result is None:
        lines += ["", "Automatic points: **0**. Nothing of this submission was run.", "", UNGRADED_HELP]
        return "\n".join(lines) + "\n"
    total = result["total"]
    lines += ["", f"Automatic points: **{points(total['auto_earned'])} of {points(total['auto_possible'])}**; "
                  f"{points(total['manual_possible'])} more points are graded by hand."]
    lines += ["", "Each TODO is checked with your code for that TODO and the reference solution for every other "
                  "one, so a mistake costs points only where it was made."]
    for note in student_result.notes + result["notes"]:
        lines += ["", f"- note: {md_escape(note)}"]
    lines += ["", summary_table(result)]
    for entry in result["todos"]:
        if not entry["checks"] and not entry["notes"] and not entry["manual_possible"]:
            continue
        lines += ["", f"## {entry['id']} {entry['title']}", "", todo_markdown(entry)]
    return "\n".join(lines) + "\n"
