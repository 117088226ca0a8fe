"""Which TODO lost the points: in the student edition's preview, a failing check names the TODO at fault.

The grade runs each TODO with the reference for every other TODO, so a mistake costs points only
where it was made. The preview (the student edition: no reference) runs the student's own code
for the other TODOs a check calls (``checks.PREVIEW_NEEDS``: 1.3.2 calls 1.1.1, 1.2.1 and 1.3.1;
1.3.3's training run all four), so a wrong 1.2.1 fails the checks of 1.3.2 and 1.3.3 too.
``apply`` finds, for each TODO whose visible checks fail there, the TODOs it calls that fail their
own visible checks and are not themselves explained by another (the TODOs *at fault*), and then:

* the entry says so first: ``blamed_on`` and ``blame`` ("probably caused by TODO 1.2.1, which
  fails its own check"), which the check cell prints as its first line; a TODO that passes its
  checks but returns what breaks the code calling it (``breaks_callers``: 1.2.1's gradient as a
  list, where 1.3.2 computes learning_rate * gradient) is at fault the same way ("which returns a
  list where ...");
* its points count as earned in the preview, as the grade (which runs it with the reference's
  1.2.1) would give them to a right TODO: the preview's total is the grade's on the visible part
  wherever the blamed TODO is right. A TODO whose own code is still the stub is never credited.

``training_note`` says whose training code 1.3.3's check ran. Standard library only.
"""

from __future__ import annotations

import re

from hwtools.grade import checks
from hwtools.todos import TODO_BY_ID

TRAINING = ("1.1.1", "1.2.1", "1.3.1", "1.3.2")  # the code of 1.3.3's training run, besides LEARNING_RATE

_STUB_CODE = re.compile(r"(pass|raise ([\w.]+\.)?(TodoNotDone|NotImplementedError)\b.*"
                        r"|from hwlib(\.machinery\.todos)? import TodoNotDone|import hwlib(\.machinery\.todos)?|[A-Za-z_]\w* = None)")


def untouched(body):
    """True if a block's lines are still the student edition's stub: comments, ``pass``,
    ``raise TodoNotDone(...)`` or ``NAME = None``."""
    code = [line.split("  #")[0].strip() for line in body if line.strip() and not line.strip().startswith("#")]
    return all(_STUB_CODE.fullmatch(line) for line in code)


def fails_visible(entry):
    return any(check["failed_on"] == "visible" for check in entry["checks"])


def needed(entries):
    """The TODOs whose own visible verdicts decide the blame of ``entries`` (those calls reach)."""
    return {need for entry in entries if fails_visible(entry) for need in checks.PREVIEW_NEEDS.get(entry["id"], ())}


def _in_words(todos, judged):
    why = [judged[todo].get("breaks_callers") if not fails_visible(judged[todo]) else "" for todo in todos]
    if not any(why):
        names = " and ".join(f"TODO {todo}" for todo in todos)
        return f"probably caused by {names}, which {'fails its own check' if len(todos) == 1 else 'fail their own checks'}"
    return "probably caused by " + " and ".join(f"TODO {todo}, which {reason or 'fails its own check'}"
                                                for todo, reason in zip(todos, why))


def apply(entries, judged, stubs, preview):
    """Blame the TODOs at fault in ``entries`` (see the module docstring). ``judged``: {todo: entry}
    of every TODO ``needed`` names (and of ``entries``); ``stubs``: the TODOs whose code is still
    the stub; ``preview``: without a reference (else only the training note is added)."""
    at_fault = {}

    def faults(todo):  # the TODOs at fault for ``todo``'s failing visible checks (itself if none other)
        if todo not in at_fault:
            entry = judged.get(todo)
            at_fault[todo] = []
            if entry is not None and fails_visible(entry):
                others = [root for need in checks.PREVIEW_NEEDS.get(todo, ()) for root in faults(need)]
                at_fault[todo] = list(dict.fromkeys(others)) or [todo]
            elif entry is not None and entry.get("breaks_callers"):  # it passes, but breaks the code calling it
                at_fault[todo] = [todo]
        return at_fault[todo]

    for entry in entries:
        training_note(entry, preview)
        todo = entry["id"]
        if not preview or todo in stubs or not fails_visible(entry) or faults(todo) == [todo]:
            continue
        blamed = faults(todo)
        entry["blamed_on"], entry["blame"] = blamed, _in_words(blamed, judged)
        entry["auto_earned"] = TODO_BY_ID[todo].auto
        _unname_mistake(entry)  # the mistake it matches is most likely the TODO at fault's
        entry["notes"].append(f"its checks ran your {' and '.join(f'TODO {t}' for t in blamed)}; its points count as "
                              f"earned in this preview, as the grade (which runs it with the reference's "
                              f"{' and '.join(blamed)}) gives them if it is right: fix {' and '.join(blamed)} first, "
                              "then run this check again")
        entry.setdefault("visible_notes", []).append(entry["notes"][-1])  # the preview's: visible checks only


def _unname_mistake(entry):
    entry.pop("mistake", None)
    for failure in [check["visible_failure"] for check in entry["checks"]] + [entry["first_failure"]]:
        if failure:
            failure.pop("mistake", None)


def training_note(entry, preview):
    if entry["id"] != "1.3.3" or not entry["checks"]:
        return
    whose = "your own code" if preview else "the reference's code"
    why = " (the student edition has no reference: a mistake there fails this check too)" if preview else ""
    entry["notes"].append(f"this check's training run used {whose} for TODOs {', '.join(TRAINING)}{why}, with your "
                          "LEARNING_RATE")
    entry.setdefault("visible_notes", []).append(entry["notes"][-1])  # fixed words: no hidden verdict in them
