"""The text report of a grading result (the dict ``Grader.grade`` returns)."""

from __future__ import annotations

import textwrap


def points(value):
    """Points as the reports write them: 7, 1.5, 0.3."""
    return f"{value:g}"


def render(result, details=True):
    """The report as text. Its first line says what it is: in the student edition (no reference) a
    preview of the visible checks, run on this computer; with a reference, "NOT ISOLATED: ..." when
    the student's code ran without a sandbox."""
    lines = []
    preview = not result["one_mistake_one_place"]
    if preview:
        lines.append("Preview of the visible checks, running your code on this computer: not a grade. Each TODO runs "
                     "with your own code for the others; the grade runs it with the reference's, and hidden inputs too.")
    elif not result["isolated"]:
        lines.append(f"NOT ISOLATED: {result['isolation']}")
    lines.append(f"Grading {result['submission']}" if not preview else f"Your kit: {result['submission']}")
    lines.append(f"against {result['reference']}" if not preview else "compared with the answer key of the visible checks")
    if result["isolated"]:
        lines.append(f"sandbox: {result['isolation']}")
    lines.append("")
    width = max(len(entry["title"]) for entry in result["todos"]) + 2
    lines.append(f"{'TODO':<7}{'what':<{width}}{'automatic':>12}  {'by hand':>8}  status")
    for entry in result["todos"]:
        auto = f"{points(entry['auto_earned'])} / {points(entry['auto_possible'])}" if entry["auto_possible"] else "-"
        manual = points(entry["manual_possible"]) if entry["manual_possible"] else "-"
        status = entry["status"] + (f" (depends on {', '.join(entry['blamed_on'])})" if entry.get("blamed_on") else "")
        lines.append(f"{entry['id']:<7}{entry['title']:<{width}}{auto:>12}  {manual:>8}  {status}")
    total = result["total"]
    lines.append(f"{'total':<7}{'':<{width}}{points(total['auto_earned']) + ' / ' + points(total['auto_possible']):>12}"
                 f"  {points(total['manual_possible']):>8}")
    for note in result["notes"]:
        lines.extend(_wrapped(f"note: {note}", ""))
    if details:
        for entry in result["todos"]:
            if not entry["checks"] and not entry["notes"]:
                continue
            lines.append("")
            if entry["auto_possible"]:
                earned = f"{points(entry['auto_earned'])} of {points(entry['auto_possible'])} automatic point(s)"
                lines.append(f"{entry['id']} {entry['title']}: {earned}")
                earned = f"earns {points(entry['auto_earned'])} of {points(entry['auto_possible'])} points"
            else:
                earned = "(graded by hand; this check is for the grader) fails"
                lines.append(f"{entry['id']} {entry['title']}: graded by hand; the check below is for the grader")
            first, fields = failure_words(entry, earned)
            for line in first:
                lines.extend(_wrapped(line, "  "))
            for check in entry["checks"]:
                mark = "pass" if check["passed"] else "FAIL"
                inputs = f"{check['visible_inputs']} visible" + (f", {check['hidden_inputs']} hidden" if check["hidden_inputs"] else "")
                where = f"; failed on a {check['failed_on']} input" if check["failed_on"] else ""
                lines.extend(_wrapped(f"[{mark}] {points(check['points'])} pt: {check['check']} ({inputs} input(s){where})",
                                      "  "))
            if fields:
                lines.append("  First failing check:")
            for name, text in fields:
                lines.extend(field_lines(name, text, "    ", 110))
            for note in entry["notes"]:
                lines.extend(_wrapped(f"note: {note}", "  "))
            if entry["manual_possible"]:
                lines.extend(_wrapped(f"by hand ({points(entry['manual_possible'])} pt): {entry['manual']}", "  "))
    return "\n".join(lines) + "\n"


# After a failure's first two lines (``first_lines``): the values and where they differ, then the check in
# full, the input and the line that rebuilds it. (The known mistake is line 2.)
FAILURE_FIELDS = ("expected", "actual", "difference", "tolerance", "check", "input", "reproduce")
UNWRAPPED = ("reproduce",)  # Python to copy: one statement a line, never wrapped


def field_lines(name, text, indent, width):
    """The lines of one failure field ``name: text``, wrapped at ``width`` between words; ``reproduce``
    (Python to copy) one statement a line instead, so that nothing breaks it mid-word."""
    if name in UNWRAPPED:
        code, _, then = text.partition("  # then ")
        statements = [part.strip() for part in code.split("; ")] + ([f"# then {then}"] if then else [])
        return [f"{indent}{name + ':':<12}{statements[0]}"] + [f"{indent}{'':<12}{part}" for part in statements[1:]]
    return textwrap.wrap(f"{indent}{name + ':':<12}{text}", width=width, subsequent_indent=indent + " " * 4,
                         break_long_words=False, break_on_hyphens=False) or [indent]


def first_lines(entry, verdict):
    """The first lines of a TODO's report, the same in every report (issue 40.4): line 1 the TODO, the
    ``verdict`` (the caller's words: "fails", "earns 0 of 10 points") and what is wrong, expected
    against actual where they differ most (``Verdict.summary``); line 2 the TODO at fault (the
    preview's blame), else the known mistake the answers match, else the check that fails in one line;
    then a note that costs nothing but breaks the code calling it (a list where an array is expected).
    Empty when nothing fails and there is no such note. Never a hidden input: a hidden failure says
    only which check."""
    todo, failure = entry["id"], entry.get("first_failure")
    lines = []
    if failure is not None and failure.get("hidden"):
        lines = [f"TODO {todo} {verdict}: a check fails on a hidden input (hidden inputs are not shown; its visible "
                 "inputs pass)", f"the check: {failure.get('short') or failure['check']}"]
    elif failure is not None:
        what = failure.get("summary") or f"expected {failure['expected']}, actual {failure['actual']}"
        why = entry.get("blame") or failure.get("mistake") or f"the check: {failure.get('short') or failure['check']}"
        lines = [f"TODO {todo} {verdict}: {what}", why]
    elif entry.get("status") not in (None, "graded", "graded by hand", "no checks") and entry.get("notes"):
        lines = [f"TODO {todo} {verdict}: not checked ({entry['status']}): {entry['notes'][0]}"]
    if entry.get("breaks_callers"):
        lines.append(f"note: not a failure, but your code {entry['breaks_callers']}")
    return lines


def failure_words(entry, verdict):
    """(first lines, [(name, text)]): the words of a TODO's report, the same in every report (this text
    report: the student's preview and the instructor's grade; the class's Markdown feedback and
    Gradescope): ``first_lines``, then for a visible input, in FAILURE_FIELDS' order, the expected and
    actual value, where they differ most (index, both values with digits enough to tell them apart,
    the relative difference), the tolerance, the check in full, the input and the line of Python
    that rebuilds it; for a hidden input nothing more."""
    failure = entry.get("first_failure")
    fields = []
    if failure is not None and not failure.get("hidden"):
        fields = [(name, str(failure[name])) for name in FAILURE_FIELDS if failure.get(name)]
    return first_lines(entry, verdict), fields


def _wrapped(text, indent):
    return textwrap.wrap(text, width=110, initial_indent=indent, subsequent_indent=indent + "    ",
                         break_long_words=False, break_on_hyphens=False) or [indent]
