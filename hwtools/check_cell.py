"""The check cell under each TODO: ``check("1.2.1")`` runs that TODO's visible checks through the kit's grader.

A notebook's check cell is one line, ``check("1.2.1")`` (the convention of otter-grader's
``grader.check("q1")``). It runs ``python -m hwtools.grade KIT --todo 1.2.1`` in a subprocess, the
same command and the same verdicts a student gets in a terminal. A passing TODO prints one line per
check. A failing one says what is wrong in its first two lines (``feedback.first_lines``: expected
against actual where they differ most, then the TODO at fault, the known mistake the answers match,
or the check that fails), then one line per check and the Python that rebuilds the failing input
(``hwtools.cases``), 12 lines at most; ``check("1.2.1", details=True)`` adds each failing check's
values, where they differ, the tolerance, the check in full and the input (the same fields as every
report, ``feedback.FAILURE_FIELDS``). No line is wider than WIDTH where it has a space to break at:
JupyterLab breaks a wider one at any character. An untouched TODO (its stub raises ``TodoNotDone``) prints
"TODO 1.2.1 is not done yet"; a check whose failure another TODO probably caused says so first
("probably caused by TODO 1.2.1, which fails its own check": ``hwtools/grade/blame.py``); a kit
that raises while imported (a NameError at module level, sys.exit) says that error and its line first.

* In the student edition the grader compares with the answer key the release build wrote,
  runs the student's own code for the other TODOs, and only has visible checks.
* In the instructor's edition (its ``hwlib/`` holds the solutions) it grades the kit against
  itself, hidden inputs included; a check cell shows the visible part only: the solutions' checks
  read the same in both editions, and the stored outputs are stable for nbval.

On the visible inputs its verdicts are the instructor's grade's whenever the other TODOs a check
runs are right (``tests/grader/test_check.py`` compares them on wrong solutions); where one is wrong, the
check names it and keeps the points the grade would give.

The grader reads the files on disk, so a check sees the code as last saved, even when the
notebook's kernel still runs older code (``hwtools.notebook`` says so). Standard library only:
this module runs nothing of the homework in the notebook's kernel.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from hwtools.files import scratch_folder
from hwtools.grade.feedback import FAILURE_FIELDS, field_lines, first_lines
from hwtools.grade.in_sandbox.probes import IMPORT_FAILED
from hwtools.grade.judging import visible_view
from hwtools.grade.processes import kill_tree
from hwtools.not_done import KIT_ROOT, not_done_in_text, where
from hwtools.todos import TODO_BY_ID

WIDTH = 100  # characters per printed line
TIMEOUT = 1800.0  # seconds for one check in all; the grader's own limit (60 s per run) applies inside
POLL_SECONDS = 0.05  # the longest wait an interrupt may have to end
STOP_SECONDS = 0.5  # for the grader to end its runs when told to stop, before it is killed


class CheckError(RuntimeError):
    """The check itself could not run (not a verdict on the student's code)."""

    def _render_traceback_(self):  # IPython shows these lines instead of a traceback
        return [f"The check could not run: {self}"]


def grade_todo(todo, kit=KIT_ROOT, python=None, timeout=TIMEOUT):
    """The grader's result entry for TODO ``todo`` of the kit at ``kit`` (see ``hwtools.grade``),
    from ``python -m hwtools.grade KIT --todo TODO --json FILE`` run in a subprocess. An interrupt
    (Kernel > Interrupt, Ctrl+C) ends that subprocess and its children at once."""
    if todo not in TODO_BY_ID:
        raise CheckError(f"{todo!r} is not a TODO of the handout; they are {', '.join(TODO_BY_ID)}")
    kit = Path(kit).resolve()
    with scratch_folder("hwcheck-") as scratch:
        out = scratch / "result.json"
        command = [python or sys.executable, "-m", "hwtools.grade", str(kit), "--todo", todo, "--json", str(out), "--brief"]
        code, _, stderr = run_polled(command, kit, scratch, timeout)
        if code != 0 or not out.is_file():
            last = [line for line in stderr.strip().splitlines() if line.strip()][-1:] or [f"exit code {code}"]
            raise CheckError(f"python -m hwtools.grade --todo {todo}: {last[0].removeprefix('error: ')}")
        result = json.loads(out.read_text(encoding="utf-8"))
    entries = [entry for entry in result["todos"] if entry["id"] == todo]
    if len(entries) != 1:
        raise CheckError(f"the grader's result has no entry for TODO {todo}")
    return entries[0]


def child_env(**extra):
    """The environment of a Python the kit starts: this one's, with UTF-8 mode on (PEP 540), so that its
    pipes, its files and what it prints are UTF-8 whatever the system's code page (Windows' cp1252, cp936)."""
    return {**os.environ, "PYTHONUTF8": "1", "PYTHONIOENCODING": "utf-8", **extra}


def run_polled(command, cwd, scratch, timeout):
    """Run ``command`` in ``cwd`` with its output in files of the folder ``scratch`` (no pipe to fill or to
    decode), waiting in short steps, so that an interrupt (Windows wakes no long wait: cpython gh-74157)
    ends it and every process it started within a second; (exit code, its output, its error stream), as text."""
    with open(scratch / "stdout", "w+b") as stdout, open(scratch / "stderr", "w+b") as stderr:
        process = subprocess.Popen(command, cwd=cwd, env=child_env(MPLBACKEND="Agg"), stdin=subprocess.DEVNULL,
                                   stdout=stdout, stderr=stderr, start_new_session=True)
        ends = time.monotonic() + timeout
        try:
            while process.poll() is None:
                if time.monotonic() > ends:
                    raise CheckError(f"it took more than {timeout:.0f} s and was stopped")
                time.sleep(POLL_SECONDS)
        except BaseException:  # KeyboardInterrupt (Kernel > Interrupt), the time-out: end the grader now
            _kill(process)
            raise
        stdout.seek(0)
        stderr.seek(0)
        return process.returncode, stdout.read().decode("utf-8", "replace"), stderr.read().decode("utf-8", "replace")


def _kill(process):
    """End the grader and every process it started: on macOS and Linux it ends its runs itself when told
    (SIGTERM; each run has a session of its own), then its own session goes; on Windows its tree goes."""
    if hasattr(os, "killpg"):
        process.terminate()
        ends = time.monotonic() + STOP_SECONDS
        while process.poll() is None and time.monotonic() < ends:
            time.sleep(POLL_SECONDS)
    kill_tree(process)
    while process.poll() is None:
        time.sleep(POLL_SECONDS)


def _visible_failure(entry, check):
    """The first visible input ``check`` fails on ({input, expected, actual}), or None. (A grader
    that gives only the TODO's first failure gives it for that check only.)"""
    if check.get("visible_failure"):
        return check["visible_failure"]
    first = entry.get("first_failure")
    if first and not first["hidden"] and first["check"] == check["check"]:
        return {name: first[name] for name in FAILURE_FIELDS if first.get(name)}
    return None


def _not_done(entry):
    """(the TODOs that the failing visible checks of ``entry`` say are not done yet, in order;
    True when no failing check failed otherwise). Checks the grader gives no details for count
    as neither."""
    todos, other = [], False
    for check in entry["checks"]:
        if check["passed"] or check["failed_on"] != "visible":
            continue
        failure = _visible_failure(entry, check)
        if failure is None:
            continue
        todo = not_done_in_text(failure["actual"])
        if todo is None:
            other = True
        elif todo not in todos:
            todos.append(todo)
    return todos, bool(todos) and not other


def _wrap(text, indent, hang=4):
    """``text`` in lines of at most WIDTH characters, broken between words only: JupyterLab shows a
    line wider than its output area broken at any character (``word-break: break-all``)."""
    return textwrap.wrap(text, width=WIDTH, initial_indent=indent, subsequent_indent=indent + " " * hang,
                         break_long_words=False, break_on_hyphens=False) or [indent]


MAX_LINES = 12  # what a failing TODO prints unless asked for details


def _cut(text):
    """``text`` in one line of at most WIDTH characters, cut at a word ("...") where it is longer."""
    return text if len(text) <= WIDTH else text[:WIDTH - 4].rsplit(" ", 1)[0] + " ..."


def check_lines(entry, details=False):
    """The lines a check cell prints for the grader's result ``entry`` of one TODO: its visible
    checks only (``judging.visible_view``: a check that fails only on hidden inputs passes on the visible
    ones, and nothing a hidden input shaped is shown). A failing TODO says what is wrong in its first
    two lines (``feedback.first_lines``), then one line per check and the line that rebuilds the
    failing input, in at most MAX_LINES lines; ``details``: every failing check's values, tolerance,
    description and input too."""
    entry = entry if entry.get("visible_only") else visible_view(entry)
    todo, title = entry["id"], entry["title"]
    checks = entry["checks"]
    if not checks and entry["manual_possible"]:
        return _wrap(f"TODO {todo} ({title}) has no automatic checks; it is graded by hand: {entry['manual']}.", "")
    if entry["status"] not in ("graded", "not done yet") or not checks:
        note, *rest = entry["notes"] or [""]
        lines = _wrap(f"TODO {todo} ({title}): not checked ({entry['status']})" + (f": {note}" if note else ""), "")
        for note in rest:
            lines += _wrap(note, "  ")
        return lines
    not_done, only_not_done = _not_done(entry)
    if entry["status"] == "not done yet":  # a grader that says so itself
        not_done, only_not_done = [todo], True
    if only_not_done and todo in not_done:
        lines = [f"TODO {todo} is not done yet: {where(todo)}",
                 f"  Write it between ### BEGIN TODO {todo} and ### END TODO {todo}, save the file, and run this check again."]
        others = [other for other in not_done if other != todo]
        if others:
            lines += _wrap(f"Its checks also run your {' and '.join(f'TODO {o} ({where(o)})' for o in others)}, "
                           f"not done yet either.", "  ")
        return lines
    if only_not_done:
        others = " and ".join(f"TODO {other} ({where(other)})" for other in not_done)
        return _wrap(f"TODO {todo} ({title}): its checks run your {others}, which "
                     f"{'is' if len(not_done) == 1 else 'are'} not done yet; do {'it' if len(not_done) == 1 else 'them'} "
                     "first, then run this check again.", "")
    visible_pass = [check["passed"] or check["failed_on"] == "hidden" for check in checks]
    passed = sum(visible_pass)
    if passed == len(checks):
        return _passing(entry, checks, details)
    counted = f"{passed} of {len(checks)} visible checks pass" if len(checks) > 1 else "the visible check fails"
    failing = [(check, _visible_failure(entry, check)) for check, ok in zip(checks, visible_pass) if not ok]
    first = next((failure for _, failure in failing if failure), None)
    if first is not None and entry.get("first_failure") is None:
        entry = {**entry, "first_failure": {"check": failing[0][0]["check"], "hidden": False, **first}}
    raised = [failure["actual"] for _, failure in failing if failure and IMPORT_FAILED in failure["actual"]]
    if raised and not entry.get("mistake"):  # the kit stops while imported: every check fails the same way
        error, _, where_raised = raised[0].partition(f" ({IMPORT_FAILED}")  # line 2 says where: never cut off
        head = [f"TODO {todo} fails: {error}"] + ([f"({IMPORT_FAILED}{where_raised}"] if where_raised else [])
    else:
        head = first_lines(entry, "fails")
    # Line 1 in one line (said in full with details=True), so that line 2 is the reason; the rest wrapped at words.
    lines = [_cut(head[0])] + [line for text in head[1:] for line in _wrap(text, "  ")]
    lines.append("")
    lines.append(f"{title}: {counted}")
    for check, ok in zip(checks, visible_pass):
        lines += _wrap(f"{'pass' if ok else 'FAIL'}  {check['check'] if details else check.get('short') or check['check']}",
                       "  ", hang=6)
        failure = None if ok or not details else _visible_failure(entry, check)
        for name in FAILURE_FIELDS if failure else ():
            if failure.get(name) and name != "check":  # the words of every report (feedback.failure_words)
                lines += field_lines(name, failure[name], "        ", WIDTH)
    notes = [note for note in entry["notes"] if not note.startswith("not a failure, but your code")]
    if details:
        lines += [line for note in notes for line in _wrap(f"note: {note}", "  ")]
        return lines
    if first and first.get("reproduce"):
        lines += field_lines("reproduce", first["reproduce"], "  ", WIDTH)
    more = f"check(\"{todo}\", details=True) shows the inputs, the values in full, the tolerances" + \
        (f" and {len(notes)} note(s)" if notes else "")
    return lines[:MAX_LINES - 1] + [more]  # the first lines and the checks first; the rest is one call away


def _passing(entry, checks, details):
    """A passing TODO's lines: the count, each check, a note that costs nothing first, then the others."""
    todo, title = entry["id"], entry["title"]
    summary = "the visible check passes" if len(checks) == 1 else f"all {len(checks)} visible checks pass"
    if entry.get("blame"):
        summary = f"{entry['blame']}; {summary}"
    lines = _wrap(f"TODO {todo} ({title}): {summary}", "")
    free = [note for note in entry["notes"] if note.startswith("not a failure, but your code")]
    lines += [line for note in free for line in _wrap(f"note: {note}", "  ")]
    for check in checks:
        lines += _wrap(f"pass  {check['check']}", "  ", hang=6)
    for note in entry["notes"]:
        if note not in free:
            lines += _wrap(f"note: {note}", "  ")
    return lines
