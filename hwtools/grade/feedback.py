"""The text report of a grading result (the dict ``Grader.grade`` returns)."""

from __future__ import annotations

import textwrap


def points(value):
    """Points as the reports write them: 7, 1.5, 0.3."""
    return f"{value:g}"


def render(result, details=True):
    """The report as text. Its first line says "NOT ISOLATED: ..." when the student's code ran
    without a sandbox."""
    lines = []
    if not result["isolated"]:
        lines.append(f"NOT ISOLATED: {result['isolation']}")
    lines.append(f"Grading {result['submission']}")
    lines.append(f"against {result['reference']}")
    if result["isolated"]:
        lines.append(f"sandbox: {result['isolation']}")
    if not result["one_mistake_one_place"]:
        lines.append("Without the instructor's reference, each TODO runs with your own code for the others, and "
                     "only the visible checks run: the points below are a preview.")
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
                lines.append(f"{entry['id']} {entry['title']}: {points(entry['auto_earned'])} of "
                             f"{points(entry['auto_possible'])} automatic point(s)")
            else:
                lines.append(f"{entry['id']} {entry['title']}: graded by hand; the check below is for the grader")
            if entry.get("blame"):
                lines.extend(_wrapped(entry["blame"], "  "))
            for check in entry["checks"]:
                mark = "pass" if check["passed"] else "FAIL"
                inputs = f"{check['visible_inputs']} visible" + (f", {check['hidden_inputs']} hidden" if check["hidden_inputs"] else "")
                where = f"; failed on a {check['failed_on']} input" if check["failed_on"] else ""
                lines.extend(_wrapped(f"[{mark}] {points(check['points'])} pt: {check['check']} ({inputs} input(s){where})",
                                      "  "))
            failure = entry["first_failure"]
            if failure:
                headline, fields = failure_words(failure)
                lines.extend(_wrapped(headline, "  "))
                for name, text in fields:
                    lines.extend(field_lines(name, text, "    ", 110))
            for note in entry["notes"]:
                lines.extend(_wrapped(f"note: {note}", "  "))
            if entry["manual_possible"]:
                lines.extend(_wrapped(f"by hand ({points(entry['manual_possible'])} pt): {entry['manual']}", "  "))
    return "\n".join(lines) + "\n"


# What is wrong first (the known mistake, the values and where they differ), then the input and the line that rebuilds it.
FAILURE_FIELDS = ("mistake", "expected", "actual", "difference", "tolerance", "input", "reproduce")
UNWRAPPED = ("reproduce",)  # one line of Python, to copy: never wrapped


def field_lines(name, text, indent, width):
    """The lines of one failure field ``name: text`` (wrapped at ``width``, but for ``UNWRAPPED``)."""
    line = f"{indent}{name + ':':<12}{text}"
    if name in UNWRAPPED:
        return [line]
    return textwrap.wrap(line, width=width, subsequent_indent=indent + " " * 4, break_long_words=True,
                         break_on_hyphens=False) or [indent]


def failure_words(failure):
    """(headline, [(name, text)]): the words of a TODO's first failing check, the same in every
    report (this text report: the student's preview and the instructor's grade; the class's
    Markdown feedback and Gradescope). A visible input gives, in FAILURE_FIELDS' order, the known
    mistake the answers match (if one does), the expected and actual value, where they first differ
    (index, both values with digits enough to tell them apart, the relative difference), the
    tolerance, then the input and the line of Python that rebuilds it; a hidden one only the
    check's description."""
    if failure["hidden"]:
        return (f"First failing check: {failure['check']}, on a hidden input (hidden inputs are not shown; the "
                "visible ones of this check pass)."), []
    return (f"First failing check: {failure['check']}",
            [(name, str(failure[name])) for name in FAILURE_FIELDS if failure.get(name)])


def _wrapped(text, indent):
    return textwrap.wrap(text, width=110, initial_indent=indent, subsequent_indent=indent + "    ",
                         break_long_words=True, break_on_hyphens=False) or [indent]
