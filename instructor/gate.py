"""The release gate: what the student edition, the Gradescope bundle and the class run check before
they write anything, and refuse with one message naming each problem.

* **The offering's facts** (``instructor.facts.problems``): a file that states a fact other than the
  one place gives it (run ``python -m instructor.facts``), the episode cap or the automatic total
  written as a literal in code or a template, a points table that disagrees with itself or with the
  grader's checks (a check renamed or missing, points that do not add up).
* **An answer key older than the known mistakes** (``stale_keys``): the kit's own
  ``hwtools/grade/answer_key.json`` and that of every student edition built inside the kit
  (``build/*/``, where docs/instructor.md builds it) must hold every file of
  ``instructor/wrong_solutions/`` as it is now, and the grader's visible checks: a student previewing
  with an older one is not told a mistake the class run and Gradescope name.
* **A known mistake that no longer loses points** under these facts (``mistakes_losing_nothing``):
  each is run on the visible checks like a student's code (the answer key's table); one that fails
  no check with points would earn them all. The student edition's build makes that table anyway and
  refuses there; ``python -m instructor.release check`` runs everything, for the bundle and the class run.
"""

from __future__ import annotations

import json
from pathlib import Path

from hwtools import facts as fact_files
from instructor import facts

ANSWER_KEY = Path("hwtools/grade/answer_key.json")
EDITIONS = "build/*/"  # where docs/instructor.md builds the student edition (git ignores build/)


class Refused(Exception):
    """The kit is not ready: ``problems`` is the list of what is wrong, each in one line."""

    def __init__(self, what, problems):
        self.problems = list(problems)
        lines = "\n".join(f"  - {problem}" for problem in self.problems)
        super().__init__(f"{what} refused: {len(self.problems)} problem(s) in the kit, nothing was written:\n{lines}\n"
                         "Fix each (python -m instructor.facts writes the facts; python -m instructor.release check "
                         "checks everything) and run it again.")


def answer_keys(kit, skip=None):
    """The answer keys students of this kit may preview with: the kit's own and those of the editions
    built inside it (``EDITIONS``), but the edition at ``skip`` (the one a build is about to replace)."""
    kit = Path(kit)
    keys = [kit / ANSWER_KEY, *sorted(folder / ANSWER_KEY for folder in kit.glob(EDITIONS))]
    skip = Path(skip).resolve() if skip is not None else None
    return [key for key in keys if key.is_file() and (skip is None or not key.resolve().is_relative_to(skip))]


def stale_keys(kit, keys):
    """What makes each answer key of ``keys`` older than the kit's known mistakes or visible checks."""
    from hwtools.grade import answer_key, checks, mistakes  # noqa: PLC0415 - numpy, only for the check

    kit = Path(kit)
    if not keys:
        return []
    try:
        current = {wrong.id: answer_key.mistake_digest(wrong)
                   for wrong in mistakes.read_wrong_solutions(kit / mistakes.WRONG_SOLUTIONS)}
    except ValueError as error:  # a known mistake's file the grader cannot read either
        return [f"{mistakes.WRONG_SOLUTIONS}/{error}"]
    visible = answer_key.visible_digest({todo: checks.case_set(todo) for todo in checks.GRADED_TODOS})
    found = []
    for key in keys:
        where = key.relative_to(kit) if key.is_relative_to(kit) else key
        try:
            data = json.loads(key.read_text(encoding="utf-8"))
        except (OSError, ValueError) as error:
            found.append(f"{where}: not an answer key ({error})")
            continue
        recorded = data.get("known_mistakes")
        rebuild = "rebuild that student edition (python -m instructor.release student OUT --force) and publish it"
        if recorded is None:
            found.append(f"{where}: an answer key older than the known mistakes (it records none of them): {rebuild}")
            continue
        new = sorted(set(current) - set(recorded))
        changed = sorted(name for name in set(current) & set(recorded) if current[name] != recorded[name])
        gone = sorted(set(recorded) - set(current))
        for names, how in ((new, "newer than the answer key"), (changed, "changed since it"), (gone, "gone since it")):
            if names:
                found.append(f"{where}: known mistake(s) {', '.join(names)} {how} (instructor/wrong_solutions/): "
                             f"its students' preview would not name them as the grade does; {rebuild}")
        if data.get("visible_cases") != visible:
            found.append(f"{where}: written for other visible checks than the grader's: {rebuild}")
    return found


def mistakes_losing_nothing(table):
    """The known mistakes of ``table`` (the grader's: ``Grader.known_mistakes``, or an answer key's)
    that fail no visible check carrying points: under these facts they would earn their TODO's points."""
    from hwtools.todos import TODO_BY_ID  # noqa: PLC0415

    found = []
    for known in table:
        points = TODO_BY_ID[known["todo"]].check_points
        if not any(points.get(check, 0) > 0 for check in known["failing"]):
            found.append(f"known mistake {known['id']} (TODO {known['todo']}, instructor/wrong_solutions/{known['id']}.txt) "
                         "no longer loses points under these facts: it fails no visible check that carries points; "
                         "change its code so it is a mistake again, or delete it")
    return found


def problems(kit, skip=None):
    """The gate's cheap part, for every release and class run: the facts, the answer keys. A kit
    without the facts' one place (a test's miniature kit: no TODO table, no settings) states none."""
    kit = Path(kit)
    if not all((kit / place).is_file() for place in (fact_files.TABLE, fact_files.SETTINGS)):
        return stale_keys(kit, answer_keys(kit, skip))
    return facts.problems(kit) + stale_keys(kit, answer_keys(kit, skip))


def check(kit, what, skip=None):
    """Raise ``Refused`` (for ``what``: "the student edition", ...) if the kit has a problem."""
    found = problems(kit, skip)
    if found:
        raise Refused(what, found)
