"""Known mistakes: which one a failing answer matches, told in one line a student understands.

The kit's wrong solutions (``instructor/wrong_solutions/*.txt``) are the known mistakes. Each
file says, besides its code, what a student is told when their answers look like it::

    # mistake: forward differences (...) instead of the central ones of equation (3)   <- for the instructor
    # diagnosis: your values equal a forward difference ...; equation (3) uses ...   <- for the student
    # rule: overshoots        (optional: a judge names it by this rule instead of by its values)

A mistake's *signature* is what it gives on the visible inputs of its TODO: per visible case the
values it answered (or its error's text) and the episodes the grader recorded (how many, from how
many start states), and which visible checks it fails. A student's failing answer is matched
against every known mistake of its TODO (``name``): all visible cases alike (within the check's
tolerance, the same error's text) and the same visible checks failed, or the rule a judge gave
(``Verdict.rule``).
Where the matches disagree, nothing is named. Only visible inputs are compared, and the words
come from the files: no hidden input, no reference line.

The instructor's grader computes the signatures by running each file's code on the visible
inputs, sandboxed like a student's (``Grader.known_mistakes``); the release build stores them in
the student edition's answer key (data, no code), where the preview reads them.
Standard library and numpy only.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hwtools.grade import checks
from hwtools.grade.checks.verdicts import Tolerance, same_numbers
from hwtools.grade.in_sandbox import probes

WRONG_SOLUTIONS = Path("instructor") / "wrong_solutions"
PROPERTY_TOLERANCE = Tolerance(1e-9, 1e-9)  # values of checks judged by property (1.3.x): the judges' own


@dataclass(frozen=True)
class WrongSolution:
    """One file of ``instructor/wrong_solutions/``."""

    id: str  # the file's stem
    todo: str
    file: str
    mistake: str  # for the instructor
    diagnosis: str  # for the student
    rule: str
    bodies: tuple  # the code of each block of the TODO in ``file``


def read_wrong_solution(path):
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    header = text.split("# --- block", 1)[0]
    fields = dict(re.findall(r"^# (mistake|diagnosis|todo|file|rule):[ \t]*(.*?)[ \t]*$", header, flags=re.M))
    bodies = tuple(part.strip("\n") for part in re.split(r"^# --- block.*$", text, flags=re.M)[1:])
    missing = [name for name in ("mistake", "diagnosis", "todo", "file") if not fields.get(name)]
    if missing or not bodies:
        raise ValueError(f"{path.name}: a wrong solution needs # {', # '.join(missing) or '--- block'}")
    return WrongSolution(path.stem, fields["todo"], fields["file"], fields["mistake"], fields["diagnosis"],
                         fields.get("rule", ""), bodies)


def read_wrong_solutions(folder):
    """Every wrong solution in ``folder``, sorted by file name (none if there is no such folder)."""
    folder = Path(folder)
    return [read_wrong_solution(path) for path in sorted(folder.glob("*.txt"))] if folder.is_dir() else []


# --------------------------------------------------------------------------------------------
# Signatures
# --------------------------------------------------------------------------------------------


@dataclass
class Signature:
    """What one answer gives on the visible inputs of one TODO (see the module docstring)."""

    cases: dict = field(default_factory=dict)  # case id -> {"values": {name: array}} or {"error": text}, + episodes
    failing: tuple = ()  # keys of the visible checks it fails
    rules: tuple = ()  # the rules its failing visible verdicts gave


def _episodes(result):
    records = result.get("records") or {}
    direct = records.get("episode_direct")
    if direct is None or not len(direct):
        return [0, 0]
    starts = records["episode_starts"][direct]
    return [int(direct.sum()), int(len(np.unique(starts, axis=0)))]


def signature(visible, results, entry):
    """The signature of an answer: ``visible`` the TODO's visible cases [(case id, behaviour,
    args)], ``results`` {case id: result} of its run, ``entry`` its judged result entry."""
    cases = {}
    for case_id, _, _ in visible:
        result = results.get(case_id) or {"status": "error", "error": "not answered"}
        if result["status"] == "ok":
            case = {"values": {name: np.asarray(value) for name, value in result["values"].items()
                               if name not in probes.FORMS}}  # a list or an array: the same mistake
        else:
            case = {"error": str(result.get("error", ""))[:200]}  # its whole text: the same mistake, the same words
        case["episodes"] = _episodes(result)
        cases[case_id] = case
    failing = tuple(sorted(check["id"].split("/", 1)[1] for check in entry["checks"] if check["failed_on"] == "visible"))
    rules = tuple(sorted({check["rule"] for check in entry["checks"] if check.get("rule")}))
    return Signature(cases, failing, rules)


def stopped_at_stubs(mine):
    """True if every visible case of signature ``mine`` stopped at a TODO not done yet (a stub)."""
    return all("is not done yet" in case.get("error", "") for case in mine.cases.values())


def _tolerance(case_id):
    behaviour = next(b for b in checks.BEHAVIOURS if case_id.startswith(b.id + "/"))
    judge = behaviour.judge
    return getattr(judge, "tolerance", None) or PROPERTY_TOLERANCE


def _same_case(case_id, mine, theirs):
    if mine.get("episodes") != theirs.get("episodes"):
        return False
    if "error" in theirs or "error" in mine:
        return mine.get("error") == theirs.get("error")
    if set(mine["values"]) != set(theirs["values"]):
        return False
    tolerance = _tolerance(case_id)
    for name, wanted in theirs["values"].items():
        arranged, wrong_shape = same_numbers(mine["values"][name], wanted)
        if wrong_shape:
            return False
        actual, wanted = np.asarray(arranged, dtype=np.float64), np.asarray(wanted, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            close = np.abs(actual - wanted) <= tolerance.limits(wanted, None) if tolerance.loose is None else \
                np.abs(actual - wanted) <= tolerance.rtol * np.abs(wanted) + max(tolerance.atol, tolerance.loose_atol)
        if not np.all(close | (np.isnan(actual) & np.isnan(wanted))):
            return False
    return True


def matches(mine, known):
    """True if the answer of signature ``mine`` looks like the known mistake ``known`` (a dict of
    the table: its rule, or its visible failures and every visible case)."""
    if known["rule"]:
        return known["rule"] in mine.rules
    if not known["failing"] or tuple(known["failing"]) != tuple(mine.failing):
        return False
    return set(known["cases"]) == set(mine.cases) and \
        all(_same_case(case_id, mine.cases[case_id], theirs) for case_id, theirs in known["cases"].items())


def name(todo, mine, table):
    """{"id", "diagnosis"} of the known mistake of ``todo`` in ``table`` that signature ``mine``
    matches, or None (none matches, or matches that say different things)."""
    found = [known for known in table if known["todo"] == todo and matches(mine, known)]
    diagnoses = {known["diagnosis"] for known in found}
    if len(diagnoses) != 1:
        return None
    return {"id": found[0]["id"], "diagnosis": found[0]["diagnosis"]}


def table_entry(wrong, mine):
    """The table's entry of wrong solution ``wrong`` (a WrongSolution) whose signature is ``mine``."""
    return {"id": wrong.id, "todo": wrong.todo, "diagnosis": wrong.diagnosis, "rule": wrong.rule,
            "failing": list(mine.failing), "cases": mine.cases}


# --------------------------------------------------------------------------------------------
# In the answer key: JSON
# --------------------------------------------------------------------------------------------


def encode(table, encode_array):
    return [dict(known, cases={case_id: {key: ({name: encode_array(v) for name, v in value.items()}
                                               if key == "values" else value) for key, value in case.items()}
                               for case_id, case in known["cases"].items()}) for known in table]


def decode(data, decode_array):
    return [dict(known, cases={case_id: {key: ({name: decode_array(v) for name, v in value.items()}
                                               if key == "values" else value) for key, value in case.items()}
                               for case_id, case in known["cases"].items()}) for known in data]
