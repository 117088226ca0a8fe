"""What the grader checks, TODO by TODO: the behaviours each TODO's points ride on, their inputs and judges.

To read or change the checks of one TODO, open its problem's module and go to its section:

* ``p1_cartpole.py``: 1.1.1, 1.2.1, 1.3.1, 1.3.2, 1.3.3;
* ``p2_logreg.py``: 2.1.1, 2.2.1, 2.2.2, 2.2.3, 2.3.1.

A section holds the TODO's input makers, judges and tolerances and, last, its behaviours
(``behaviour.Behaviour``: key, what is checked in words, the probe the worker runs, the
maker and the judge). The probes themselves run in the sandbox (``in_sandbox/probes.py``, under
the same names); how an answer is compared and shown is ``verdicts.py``; the hidden inputs come
from ``instructor/hidden_checks``; each behaviour's points and a TODO's total from the TODO table
(``Todo.checks``, ``Todo.auto`` in ``hwlib/machinery/todos.py``, through ``hwtools/todos.py``),
which must agree (``points_table_problems``: the grader refuses to start otherwise).

A behaviour earns its points only when every one of its inputs passes, visible and hidden, so an
answer written for the visible inputs earns nothing. Two kinds of judging:

* **exact**, where the handout fixes the computation (eq. (1), eq. (3), the sigmoid, eq. (8), ...):
  the student's values must equal the reference solution's on the same input, within the
  behaviour's tolerance (``verdicts.exact``);
* **by property**, where it does not (which start states ``eval_params`` plays, how the training
  loop is written): the property the handout asks for is checked on the grader's own records,
  with the reference re-scoring what the student's code produced (``Behaviour.services``).

Checks that any code passes (the door checks, shapes made by given code) carry no points.
This module gathers the table (``BEHAVIOURS``) and makes each TODO's cases. Standard library and
numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hwtools.grade.checks import p1_cartpole, p2_logreg
from hwtools.todos import TODOS

BEHAVIOURS = p1_cartpole.BEHAVIOURS + p2_logreg.BEHAVIOURS
BEHAVIOURS_BY_TODO = {}
for _behaviour in BEHAVIOURS:
    BEHAVIOURS_BY_TODO.setdefault(_behaviour.todo, []).append(_behaviour)
GRADED_TODOS = tuple(BEHAVIOURS_BY_TODO)
REBUILT = p1_cartpole.REBUILT | p2_logreg.REBUILT

# The other TODOs whose functions each TODO's check calls. No kit a student's code runs in holds
# their code: the worker's copies are proxies that the reference server answers (``in_sandbox/served.py``).
NEEDS = {
    "1.1.1": (),
    "1.2.1": (),
    "1.3.1": ("1.1.1",),
    "1.3.2": ("1.1.1", "1.2.1", "1.3.1"),
    "1.3.3": (),  # only hwlib/settings.py is run with the student's block; the reference server trains
    "2.1.1": ("2.2.1",),
    "2.2.1": (),
    "2.2.2": ("2.2.1",),
    "2.2.3": ("2.1.1", "2.2.1"),
    "2.3.1": ("2.1.1", "2.2.1", "2.2.2", "2.2.3"),
}
SETTINGS_ONLY = {"1.3.3": ("hwlib/settings.py",)}  # TODOs whose kit holds only these files
# The other TODOs whose code a check runs in the student edition's preview, which has no reference:
# its server is the student's own kit, and 1.3.3's training run is the student's 1.1.1-1.3.2 (blame.py).
PREVIEW_NEEDS = NEEDS | {"1.3.3": ("1.1.1", "1.2.1", "1.3.1", "1.3.2")}


@dataclass
class CaseSet:
    """The cases of one TODO: ``visible`` and ``hidden`` lists of (case id, behaviour, args)."""

    todo: str
    visible: list = field(default_factory=list)
    hidden: list = field(default_factory=list)
    draw: str = ""  # what the hidden inputs were drawn from besides the instructor's seed: a grading's secret


def cases_of(behaviour):
    """The behaviour whose cases ``behaviour`` is judged on (itself, or the one it names)."""
    if not behaviour.judged_on:
        return behaviour
    return next(other for other in BEHAVIOURS_BY_TODO[behaviour.todo] if other.key == behaviour.judged_on)


def case_set(todo, hidden_module=None, draw=""):
    """The cases of ``todo``: ids "TODO/key/vN" (visible) and "TODO/key/hN" (hidden, from ``hidden_module``,
    drawn for ``draw``: the grader passes the secret of one grading, ``Grader.case_set``)."""
    cases = CaseSet(todo, draw=draw)
    for behaviour in BEHAVIOURS_BY_TODO[todo]:
        if behaviour.judged_on:
            continue  # judged on the cases of another behaviour
        for number, args in enumerate(behaviour.visible_cases()):
            cases.visible.append((f"{behaviour.id}/v{number}", behaviour, args))
        if hidden_module is not None:
            drawn = hidden_module.hidden_cases(behaviour, draw) if draw else hidden_module.hidden_cases(behaviour)
            for number, args in enumerate(drawn):
                cases.hidden.append((f"{behaviour.id}/h{number}", behaviour, args))
    return cases


def points_table_problems(case_sets, todos=None, behaviours=None):
    """What makes the points table disagree with itself, in words (empty: nothing); the grader
    refuses to start on any. ``case_sets``: {TODO: ``CaseSet``} with its hidden cases. A TODO's
    checks (``Todo.checks``) must be exactly its behaviours here and add up to its automatic
    points; a behaviour tried on hidden inputs must be tried on visible ones too (its visible
    twin: what the preview and the feedback show)."""
    problems, by_todo = [], {}
    for behaviour in BEHAVIOURS if behaviours is None else behaviours:
        by_todo.setdefault(behaviour.todo, []).append(behaviour.key)
    for todo in TODOS if todos is None else todos:
        table = [key for key, _ in todo.checks]
        total = round(sum(points for _, points in todo.checks), 9)
        if total != todo.auto:
            problems.append(f"TODO {todo.id}: its checks add up to {total:g} points, its total is {todo.auto:g} "
                            "(hwlib/machinery/todos.py)")
        if sorted(table) != sorted(by_todo.get(todo.id, [])):
            problems.append(f"TODO {todo.id}: the TODO table lists the checks {', '.join(table) or 'none'}, the grader "
                            f"has {', '.join(by_todo.get(todo.id, [])) or 'none'}")
    for todo, cases in case_sets.items():
        visible = {cases_of(behaviour).id for _, behaviour, _ in cases.visible}
        for twinless in sorted({cases_of(behaviour).id for _, behaviour, _ in cases.hidden} - visible):
            problems.append(f"{twinless}: hidden inputs but no visible one (every hidden behaviour needs a visible twin)")
    return problems


def rebuild_line(case_id, probe):
    """The one line of Python that rebuilds visible case ``case_id`` of ``probe`` in a student's
    kernel (``hwtools.cases.visible_case``), or "" (a setting: nothing to rebuild)."""
    rebuilt = REBUILT.get(probe)
    if rebuilt is None:
        return ""
    names, then = rebuilt
    return f'from hwtools.cases import visible_case; {names} = visible_case("{case_id}")  # then {then}'
