"""What a class got wrong: each check's pass rate and each named mistake's count, as a table and a chart.

``write(results, gradebook)`` writes, beside the gradebook ``grades.csv``:

* ``grades-checks.csv``: one row per check (``kind`` check: how many graded students passed it,
  on every input) and per known mistake the feedback named (``kind`` mistake: how many students'
  answers matched it, with its one-line diagnosis), so an instructor reads "14 students used a
  forward difference" before the next lecture;
* ``grades-checks.png``: the same as two bar charts (matplotlib, imported only here).

Only graded submissions count (a row of the gradebook without a result is left out). The same
results give the same bytes. ``classroom.grade_class`` calls it last.
"""

from __future__ import annotations

from pathlib import Path

from hwtools.grade import checks
from hwtools.grade.safe_text import csv_text

HEADER = ("kind", "todo", "id", "what", "students", "count", "share")


def rows(results):
    """The table's rows (tuples in ``HEADER``'s order) of ``results`` (``gradebook.StudentResult``)."""
    graded = [item.result for item in results if item.result is not None]
    entries = [entry for result in graded for entry in result["todos"]]
    table = []
    for behaviour in checks.BEHAVIOURS:
        seen = [check for entry in entries if entry["id"] == behaviour.todo for check in entry["checks"]
                if check.get("id") == behaviour.id]
        passed = sum(check["passed"] for check in seen)
        table.append(("check", behaviour.todo, behaviour.id, behaviour.description, len(seen), passed,
                      round(passed / len(seen), 4) if seen else 0.0))
    named = {}
    for entry in entries:
        mistake = entry.get("mistake")
        if mistake:
            key = (entry["id"], mistake["id"])
            named[key] = (mistake["diagnosis"], named.get(key, ("", 0))[1] + 1)
    for (todo, mistake), (diagnosis, count) in sorted(named.items(), key=lambda item: (-item[1][1], item[0])):
        table.append(("mistake", todo, mistake, diagnosis, len(graded), count, round(count / len(graded), 4)))
    return table


def table_text(table):
    return csv_text([HEADER, *table])  # every text shown as text: no formula from a student's file


def chart(table, path):
    """The two bar charts of ``table``: each check's pass rate, each named mistake's count."""
    import matplotlib  # noqa: PLC0415 - only the class run draws

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure  # noqa: PLC0415

    check_rows = [row for row in table if row[0] == "check" and row[4]]
    mistake_rows = [row for row in table if row[0] == "mistake"]
    height = 1.5 + 0.28 * max(len(check_rows), len(mistake_rows), 4)
    figure = Figure(figsize=(13, height), layout="constrained")
    left, right = figure.subplots(1, 2, width_ratios=(1, 1))
    bars = left.barh([row[2] for row in check_rows], [100 * row[6] for row in check_rows], color="tab:green")
    left.bar_label(bars, fmt="%.0f%%", padding=2, fontsize=8)
    left.set_xlim(0, 112)
    left.set_xlabel("students who pass the check (%)")
    left.set_title(f"checks ({check_rows[0][4] if check_rows else 0} students graded)")
    left.invert_yaxis()
    if mistake_rows:
        bars = right.barh([row[2] for row in mistake_rows], [row[5] for row in mistake_rows], color="tab:red")
        right.bar_label(bars, padding=2, fontsize=8)
        right.set_xlabel("students whose answers match the mistake")
        right.xaxis.get_major_locator().set_params(integer=True)
        right.invert_yaxis()
    else:
        right.text(0.5, 0.5, "no known mistake named", ha="center", va="center", transform=right.transAxes)
        right.set_axis_off()
    right.set_title("known mistakes named in the feedback")
    figure.savefig(path, dpi=100, metadata={"Software": None})


def paths(gradebook):
    gradebook = Path(gradebook)
    return gradebook.with_name(f"{gradebook.stem}-checks.csv"), gradebook.with_name(f"{gradebook.stem}-checks.png")


def write(results, gradebook):
    """Write the table and the chart beside ``gradebook``; returns their paths."""
    table = rows(results)
    table_path, chart_path = paths(gradebook)
    table_path.write_text(table_text(table), encoding="utf-8")
    chart(table, chart_path)
    return table_path, chart_path
