"""The points table cannot disagree with itself (issue 31.2): a TODO's checks add up to its total,
the grader's checks are the table's, and every behaviour tried on hidden inputs has visible ones too.
The grader refuses to start otherwise; each of these tests makes one of those fail."""

import dataclasses
import re
from pathlib import Path

import pytest

from hwtools.grade import checks
from hwtools.grade.grader import Grader, GradingError
from hwtools.todos import AUTO_POINTS, TODO_BY_ID, TODOS

KIT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.offering  # also run on the variant offering (test_variant.py)


def _cases():
    return {todo: checks.case_set(todo, None) for todo in checks.GRADED_TODOS}


def _with(todo_id, **changes):
    """TODOS with TODO ``todo_id`` changed."""
    return tuple(dataclasses.replace(todo, **changes) if todo.id == todo_id else todo for todo in TODOS)


def test_the_kits_table_agrees_with_itself():
    assert checks.points_table_problems(_cases()) == []
    assert AUTO_POINTS == sum(points for todo in TODOS for _, points in todo.checks)
    for behaviour in checks.BEHAVIOURS:  # the checks' points are the table's
        assert behaviour.points == TODO_BY_ID[behaviour.todo].check_points[behaviour.key]


def _raised(todo_id, more):
    """TODO ``todo_id``'s checks with ``more`` points on its first one."""
    (first, points), *rest = TODO_BY_ID[todo_id].checks
    return ((first, points + more), *rest)


def test_checks_that_do_not_add_up_to_the_total_are_found():
    total = TODO_BY_ID["1.2.1"].auto
    problems = checks.points_table_problems(_cases(), _with("1.2.1", checks=_raised("1.2.1", 2)))  # total unchanged
    assert len(problems) == 1 and "1.2.1" in problems[0] and f"add up to {total + 2:g} points, its total is {total:g}" in problems[0]
    assert checks.points_table_problems(_cases(), _with("1.2.1", auto=total + 2, checks=_raised("1.2.1", 2))) == []


def test_a_check_missing_from_the_table_is_found():
    todo = TODO_BY_ID["2.2.2"]
    problems = checks.points_table_problems(_cases(), _with("2.2.2", checks=((todo.checks[0][0], todo.auto),)))
    assert len(problems) == 1 and todo.checks[1][0] in problems[0]


def test_a_hidden_behaviour_without_a_visible_twin_is_found():
    cases = _cases()
    twinless = next(behaviour for behaviour in checks.BEHAVIOURS_BY_TODO["1.2.1"] if behaviour.key == "one-step")
    cases["1.2.1"].visible = [case for case in cases["1.2.1"].visible if case[1] is not twinless]
    cases["1.2.1"].hidden.append(("1.2.1/one-step/h0", twinless, {}))
    problems = checks.points_table_problems(cases)
    assert problems == ["1.2.1/one-step: hidden inputs but no visible one (every hidden behaviour needs a visible twin)"]


def test_the_grader_refuses_to_start_on_a_table_that_disagrees(monkeypatch):
    monkeypatch.setattr(checks, "TODOS", _with("1.2.1", checks=_raised("1.2.1", 2)))
    said = f"points table disagrees with itself:\n  TODO 1.2.1: its checks add up to {TODO_BY_ID['1.2.1'].auto + 2:g} "
    with pytest.raises(GradingError, match=re.escape(said)):
        Grader(KIT)
