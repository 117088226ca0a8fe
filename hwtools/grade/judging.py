"""Points and feedback for one TODO: each behaviour's verdicts on its cases, in the grader's own words.

``judge_todo`` turns what a run answered (``broker.run_cases``) into the TODO's entry of the
result dict: points per behaviour (every input, visible and hidden, must pass; at most 30% of the
TODO while one of its value checks fails on any input), the first failing visible check with the known mistake the
answers match (``mistakes.py``), its input and the line that rebuilds it
(``checks.rebuild_line``), expected and actual value, and notes. What a student may read is built
from the grader's words and the student's own values on visible inputs only; a hidden input's
failure shows only the check's description. Text that holds a line of the reference solution is
replaced (``Scrubber``).
"""

from __future__ import annotations

from hwtools.grade import broker, checks, mistakes, suspects
from hwtools.grade.checks.behaviour import MOST_KEPT
from hwtools.grade.checks.verdicts import Verdict, show
from hwtools.grade.in_sandbox.channel import fingerprint, text
from hwtools.todos import TODO_BY_ID

_STATUS = {"timeout": "time limit", "ended": "crashed", "garbled": "crashed", "violation": "crashed", "lost": "crashed"}


def service_key(probe, args):
    return f"{probe}:{fingerprint({'args': args})}"


class Scrubber:
    """Keeps the reference's solution lines out of anything shown to a student."""

    def __init__(self, reference_bodies):
        lines = set()
        for bodies in (reference_bodies or {}).values():
            for body in bodies:
                for line in body:
                    stripped = line.strip()
                    if len(stripped) >= 12 and not stripped.startswith("#"):
                        lines.add(stripped)
        self.lines = tuple(sorted(lines))

    def __call__(self, text):
        text = str(text)
        if any(line in text for line in self.lines):
            return "(not shown: it contains the reference solution's code)"
        return text


def judge_todo(todo, run, services, cases, expected_of, scrub, limits, seen_notes, known=None):
    """The result entry of ``todo``. ``run``: None (no checks), or {"student": (Outcome, results) or
    a reason string, "reference": {case id: values} or None}; ``services``: {service_key: result};
    ``cases``: its CaseSet; ``expected_of(case_id, behaviour, reference)``: the values an exact
    check compares with; ``limits``: (time limit s, memory limit MiB); ``seen_notes``: notes on
    the code itself; ``known(todo)``: the known mistakes' table (``mistakes.py``), asked only when
    a visible check fails, whose matching mistake the first visible failure names."""
    info = TODO_BY_ID[todo]
    entry = {"id": todo, "title": info.title, "auto_earned": 0.0, "auto_possible": info.auto,
             "manual_possible": info.manual, "manual": info.manual_what, "code": info.code,
             "status": "graded", "checks": [], "first_failure": None, "notes": []}
    if run is None:
        entry["status"] = "graded by hand" if info.manual else "no checks"
        entry["visible_status"], entry["visible_notes"] = entry["status"], []
        return entry
    student = run["student"]
    visible_notes = []  # what the visible-only view may show: nothing a hidden input shaped
    entry["visible_status"] = "graded"
    if isinstance(student, str):
        entry["status"] = entry["visible_status"] = "not graded"
        entry["notes"].append(student)
        visible_notes.append(student)
        outcome, results = None, {}
    else:
        outcome, results = student
        if outcome.status != "ok":
            entry["status"] = _STATUS[outcome.status]
            where = "" if outcome.phase == "hidden" else f" (after {outcome.seconds:.1f} s)"
            entry["notes"].append(f"the run of your code stopped: {outcome.detail}{where}; time limit "
                                  f"{limits[0]:.0f} s, memory limit {limits[1]:.0f} MiB")
            if outcome.phase != "hidden":
                entry["visible_status"] = entry["status"]
                visible_notes.append(entry["notes"][-1])
        entry["notes"].extend(outcome.notes)
        visible_notes.extend(outcome.visible_notes)  # those given before any hidden input was sent
    reference = run["reference"] or {}
    earned, warnings, passed_by_key = 0.0, [], {}
    for behaviour in checks.BEHAVIOURS_BY_TODO[todo]:
        verdicts, source = [], checks.cases_of(behaviour)
        for visible, phase in ((True, cases.visible), (False, cases.hidden)):
            for case_id, case_behaviour, args in phase:
                if case_behaviour is not source:
                    continue
                result = results.get(case_id) or broker.missing(outcome, isinstance(student, str) and student)
                if visible:
                    warnings.extend(result.get("warnings", []))
                    if behaviour.breaks_callers and result["status"] == "ok":
                        entry["breaks_callers"] = entry.get("breaks_callers") or behaviour.breaks_callers(result)
                expected = expected_of(case_id, behaviour, reference)
                if behaviour.exact and expected is None:
                    continue  # a hidden case with only an answer key: not checked here
                wanted = behaviour.services(args, result) if behaviour.services else []
                answers = [services.get(service_key(probe, a)) for probe, a in wanted]
                try:
                    verdict = behaviour.judge(args, result, expected, answers)
                except Exception as error:  # noqa: BLE001 - malformed values from the worker
                    verdict = Verdict(False, "", text(f"unexpected values ({type(error).__name__}: {error})"))
                verdicts.append((visible, case_id, args, verdict))
        passed = bool(verdicts) and all(verdict.passed for _, _, _, verdict in verdicts)
        failed_on = None if passed else ("visible" if any(v and not d.passed for v, _, _, d in verdicts) else "hidden")
        earned += behaviour.points if passed else 0.0
        passed_by_key[behaviour.key] = passed
        # The first visible input this check fails on, shown in full (the notebook's check cells show it per check).
        first = next(((case_id, args, verdict) for v, case_id, args, verdict in verdicts if v and not verdict.passed), None)
        visible_failure = None if first is None else _visible_failure(behaviour, *first, scrub)
        check = {"id": behaviour.id, "check": behaviour.description, "short": behaviour.short, "points": behaviour.points,
                 "passed": passed,
                 "failed_on": failed_on, "visible_inputs": sum(v for v, _, _, _ in verdicts),
                 "hidden_inputs": sum(not v for v, _, _, _ in verdicts), "visible_failure": visible_failure}
        if first is not None and first[2].rule:
            check["rule"] = first[2].rule
        entry["checks"].append(check)
        if entry["first_failure"] is None and not passed:
            if visible_failure is not None:
                entry["first_failure"] = {"check": behaviour.description, "hidden": False, **visible_failure}
            else:
                entry["first_failure"] = {"check": behaviour.description, "short": behaviour.short, "hidden": True,
                                          "input": "a hidden input (not shown)"}
    entry["auto_earned"] = round(min(_capped(todo, earned, passed_by_key, entry["notes"]), info.auto), 2)
    entry["notes"].extend(seen_notes)
    visible_notes.extend(seen_notes)
    for warning in dict.fromkeys(warnings):  # warnings of visible inputs only
        entry["notes"].append(f"warning (not a failure): {scrub(warning)}")
        visible_notes.append(entry["notes"][-1])
    if entry.get("breaks_callers"):  # right or not, what breaks the code calling it (blame.py)
        entry["notes"].append(f"not a failure, but your code {entry['breaks_callers']}")
        visible_notes.append(entry["notes"][-1])
    entry["visible_notes"] = visible_notes
    if known is not None and any(check["failed_on"] == "visible" for check in entry["checks"]):
        mine = mistakes.signature(cases.visible, results, entry)
        if not mistakes.stopped_at_stubs(mine):  # a stub matches no mistake: the table is not even made
            name_mistake(entry, mistakes.name(todo, mine, known(todo)), scrub)
    return entry


def visible_view(entry):
    """The entry of a TODO as its visible inputs alone show it (the preview's check cells,
    Gradescope's visible test, feedback before grades are out): each check passes unless a visible
    input fails it, the first failure is the first visible one (whatever hidden inputs did before
    it), status and notes are those no hidden input shaped (``visible_status``, ``visible_notes``),
    and no points. Built from visible verdicts and notes only, so it carries no bit of a hidden one."""
    checks_ = [dict(check, passed=check["failed_on"] != "visible" and bool(check["visible_inputs"]),
                    failed_on="visible" if check["failed_on"] == "visible" else None, hidden_inputs=0)
               for check in entry["checks"]]
    failing = next((check for check in checks_ if check.get("visible_failure")), None)
    view = {key: value for key, value in entry.items() if key not in ("auto_earned", "first_failure", "rule")}
    view.update(checks=checks_, status=entry.get("visible_status", entry["status"]),
                notes=list(entry.get("visible_notes", entry["notes"])), visible_only=True,
                first_failure=None if failing is None else {"check": failing["check"], "hidden": False,
                                                            **failing["visible_failure"]})
    return view


def _visible_failure(behaviour, case_id, args, verdict, scrub):
    """What a failing visible input shows: the input, the line that rebuilds it in the student's
    kernel, expected and actual, where they differ and the tolerance (``feedback.FAILURE_FIELDS``)."""
    failure = {"summary": scrub(_summary(verdict)), "short": behaviour.short, "input": scrub(show(args)),
               "reproduce": checks.rebuild_line(case_id, behaviour.probe),
               "expected": scrub(verdict.expected), "actual": scrub(verdict.actual)}
    failure.update({name: scrub(getattr(verdict, name)) for name in ("difference", "tolerance") if getattr(verdict, name)})
    return {name: value for name, value in failure.items() if value or name in ("expected", "actual", "input")}


SHORT = 60  # characters: an expected value this short is said in full in a failure's first line


def _summary(verdict):
    """What is wrong in one clause: the judge's ``summary``, else expected against actual, each cut at a
    word to a line's room (both are said in full below)."""
    if verdict.summary:
        return verdict.summary

    def cut(text, room):
        return text if len(text) <= room else text[:room].rsplit(" ", 1)[0] + " ..."

    return f"expected {cut(verdict.expected, SHORT)}, actual {cut(verdict.actual, 2 * SHORT)}"


def name_mistake(entry, named, scrub=str):
    """Put the known mistake ``named`` ({"id", "diagnosis"} or None) in ``entry``: its id, and its
    one line first in the first visible failure (the TODO's and that check's)."""
    if named is None:
        return
    diagnosis = scrub(named["diagnosis"])
    entry["mistake"] = {"id": named["id"], "diagnosis": diagnosis}
    check = next(check for check in entry["checks"] if check["failed_on"] == "visible")
    check["visible_failure"] = {"mistake": diagnosis, **check["visible_failure"]}
    first = entry["first_failure"]
    if first is not None and not first["hidden"] and first["check"] == check["check"]:
        entry["first_failure"] = {"check": first["check"], "hidden": False, "mistake": diagnosis,
                                  **{key: value for key, value in first.items() if key not in ("check", "hidden")}}


def _capped(todo, earned, passed, notes):
    """``earned``, at most ``MOST_KEPT`` of the TODO while any of its value checks (``Behaviour.value``)
    fails on any input, visible or hidden: no wrong value keeps more, whichever other check it passes.
    The note says so in the full feedback only (``visible_view`` leaves it out: a hidden failure may cause it)."""
    wrong = [b.key for b in checks.BEHAVIOURS_BY_TODO[todo] if b.value and not passed[b.key]]
    most = MOST_KEPT * TODO_BY_ID[todo].auto
    if not wrong or earned <= most:
        return earned
    notes.append(f"its other checks count only up to {MOST_KEPT:.0%} of TODO {todo} while a value is wrong "
                 f"({', '.join(wrong)})")
    return most


def seen(todo, read, layout):
    """A note naming what the student's code for ``todo`` reaches for that a solution does not need."""
    if todo not in read.bodies or layout is None:
        return []
    module_level = any(block.module_level for file_blocks in layout.blocks_by_file.values()
                       for block in file_blocks if block.todo == todo)
    names = sorted({name for body in read.bodies[todo] for name in suspects.scan_body(body, module_level)})
    if not names:
        return []
    return [f"seen in your code for {todo}: {', '.join(names)}. None of it can change a grade: your code runs "
            "in a sandbox and only the values it returns are compared, by the grader, with the reference's"]
