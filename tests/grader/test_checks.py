"""The checks of issue 15 (3-8): shapes as the handout states them, checks that see each mistake,
tolerances that fit the computation, feedback that shows the difference, the same verdicts in the
student's preview and the instructor's grade.

* The words of a difference, tested on the judges directly (no sandbox): the index, digits enough
  to tell expected and actual apart, the relative difference, the tolerance; the same words in
  the text report, the class's Markdown feedback and Gradescope's.
* The tolerances on the numbers that correct and wrong formulas give (no sandbox).
* Every natural solution (``tests/grader/natural_solutions/``, CRLF copies saved as whole CRLF kits)
  earns every point; every wrong one (``instructor/wrong_solutions/``) keeps at most 30% of its
  TODO and nothing outside it; the cases the handout leaves open get docs/grading.md's verdict.
* Preview = grade: the student edition's ``python -m hwtools.grade`` (answer key) and the
  instructor's grade give every visible check the same verdict, and the same words for a first
  failure on a visible input.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hwtools.grade import TODO_BY_ID, Grader, blocks, checks, judging, kits, mistakes
from hwtools.grade.checks import p1_cartpole, p2_logreg
from hwtools.grade.checks.verdicts import show, tell_apart
from hwtools.grade.episodes import Environments, Records
from hwtools.grade.instructor.class_feedback import todo_markdown
from hwtools.check_cell import check_lines
from hwtools import check_cell
from hwtools.grade.feedback import failure_words, render
import editions
from test_grading import (assert_first_two_lines_say_what_is_wrong, assert_the_other_todos_run_the_reference_kits,
                          full_points, parse_wrong_solution, points)

KIT = Path(__file__).resolve().parents[2]
NATURAL = Path(__file__).resolve().parent / "natural_solutions"
WRONG = KIT / "instructor" / "wrong_solutions"
TIME_LIMIT = 60.0  # per TODO's run: the preview runs the student's own code for the other TODOs too

pytestmark = pytest.mark.timeout(1800)


def behaviour(behaviour_id):
    return next(b for b in checks.BEHAVIOURS if b.id == behaviour_id)


def ok(**values):
    return {"status": "ok", "error": "", "warnings": [], "values": {k: np.asarray(v) for k, v in values.items()}}


def judged(behaviour_id, args, actual, expected, records=None):
    """The verdict of ``behaviour_id``'s judge on one answer (and the grader's ``records`` of its run), without a sandbox."""
    b = behaviour(behaviour_id)
    name = {"2.2.1": "values", "1.2.1": "gradient", "2.2.2": "probabilities", "2.3.1": "weights",
            "2.2.3": "weights", "1.1.1": "actions", "2.1.1": "gradient"}[b.todo]
    return b.judge(args, {**ok(**{name: actual}), "records": dict(records or {})}, {name: np.asarray(expected)}, [])


def reference_sigmoid(z):
    decay = np.exp(-np.abs(z))
    return np.where(z >= 0, 1.0 / (1.0 + decay), decay / (1.0 + decay))


# --------------------------------------------------------------------------------------------
# The words of a difference (no sandbox)
# --------------------------------------------------------------------------------------------


def test_a_tiny_value_is_shown_as_itself_and_its_difference_relative():
    z = np.array([0.0, 1.0, -3.0, 10.0, 5.0, -24.4])
    expected = reference_sigmoid(z)
    actual = expected.copy()
    actual[5] = 0.0  # sigma(-24.4) = 2.5e-11, "rounded" to 0
    verdict = judged("2.2.1/precision", {"z": z}, actual, expected)
    assert not verdict.passed
    assert "2.53055e-11" in verdict.expected and "2.53055e-11" in show(expected[5])
    assert verdict.difference.startswith("differs most at index [5] (z[5] = -24.4): expected 2.53055e-11, actual 0")
    assert verdict.summary == "at z[5] = -24.4: expected 2.53055e-11, actual 0 (1 of 6 differ)"
    assert "relative difference 1;" in verdict.difference and "1 of 6 entries differ" in verdict.difference
    assert verdict.tolerance.startswith("|actual - expected| <= 1e-12 * |expected| + 1e-15;")
    # the values check lets |z| > 20 be 1e-8 off (a sigmoid clipped at +-20 is a shortcut), and says so
    assert judged("2.2.1/values", {"z": z}, actual, expected).passed
    assert "+ 1e-08 in place of + 1e-15 where |z| > 20" in p2_logreg.SIGMOID_TOLERANCE.words()


def test_values_off_by_2e_9_are_told_apart_with_enough_digits():
    z = np.array([-0.3, 0.4, 2.0])
    expected = reference_sigmoid(z)
    actual = expected + np.array([0.0, 2e-9, 0.0])
    verdict = judged("2.2.1/precision", {"z": z}, actual, expected)
    assert not verdict.passed
    want, got = tell_apart(expected[1], actual[1])
    assert want != got and len(want) > 8, (want, got)  # six digits would print the two alike
    assert f"expected {want}, actual {got}" in verdict.difference
    assert "index [1]" in verdict.difference and "relative difference 3.34e-09" in verdict.difference
    assert tell_apart(0.123456789, 0.123456791) == ("0.123456789", "0.123456791")
    assert tell_apart(1.0, 1.0 + 2.0**-52) == ("1", "1.0000000000000002")


def test_the_difference_names_the_entry_and_its_input():
    args = {"params": np.array([[1.0, 2.0, 0.0, 0.0], [3.0, -1.0, 1.0, 2.0]]),
            "obs": np.array([[1.0, -1.0, 0.0, 0.0], [1.0, 3.0, 0.0, 0.0]])}
    verdict = judged("1.1.1/equation-1", args, [1, 1], [1, 0])
    assert verdict.difference == ("differs most at index [1] (row 1 (params . obs = 0): params [3, -1, 1, 2], obs "
                                  "[1, 3, 0, 0]): expected 0, actual 1; 1 of 2 entries differ")
    assert verdict.summary == "at row 1 (params . obs = 0): expected 0, actual 1 (1 of 2 differ)"
    assert verdict.tolerance == "exactly equal"
    steps = {"n_features": 2, "steps": 2}
    verdict = judged("2.2.3/two-steps", steps, [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]], [[0.1, 0.2, 0.3], [0.4, 0.5, 0.7]])
    assert "index [1, 2] (weight 2 (the bias) after step 2): expected 0.7, actual 0.6" in verdict.difference
    assert "relative difference 0.143" in verdict.difference
    fd = {"x": np.array([0.5, -1.0]), "h": np.array([0.1, 0.2])}
    verdict = judged("1.2.1/equation-3", fd, [1.0, 2.5], [1.0, 2.0])
    assert "index [1] (coordinate 1: x[1] = -1, h[1] = 0.2): expected 2, actual 2.5" in verdict.difference
    # where they differ most, not where they first differ (issue 40.4): the entry farthest outside the tolerance
    verdict = judged("1.2.1/equation-3", fd, [1.01, 2.5], [1.0, 2.0])
    assert verdict.summary == "at coordinate 1: expected 2, actual 2.5 (2 of 2 differ)", verdict.summary


def test_a_real_run_update_off_equation_4_says_what_it_gives_and_where_in_numbers():
    """1.3.2's real run (issue 32.5): expected is equation (4) in the run's own numbers (its evaluations at
    theta +- h e_i), actual the entry, then where they differ (it said "actual: theta[1][0] = -0.0435898:
    evaluations there give theta[1][0] = 0.0184102")."""
    from test_protocol import real_training_records

    args, result = real_training_records(1)  # g+ = 100 + i, g- = 90 at every theta +- h e_i
    history = result["values"]["params_history"].copy()
    wanted = history[1][2]
    history[1][2] = 2 * history[0][2] - wanted  # stepped down the gradient in coordinate 2
    verdict = p1_cartpole.judge_real_rewards(args, dict(result, values=dict(result["values"], params_history=history)),
                                             None, [])
    assert not verdict.passed and verdict.actual == f"theta[1][2] = {show(history[1][2])}"
    assert verdict.expected == (f"theta[1][2] = theta[0][2] + learning_rate * (g+ - g-) / (2 h) = {show(history[0][2])} + "
                                f"{show(args['learning_rate'])} * (102 - 90) / 0.7 = {show(wanted)}, with g+ and g- your "
                                "eval_params at theta[0] + h e_2 and theta[0] - h e_2 (h = fd_step = 0.35)")
    assert verdict.difference.startswith(f"the value differs (theta[1][2] in update 1): expected {show(wanted)}, actual ")
    assert verdict.tolerance.startswith("|actual - expected| <= 1e-09 * |expected| + 1e-09")
    records = result["records"]
    kept = ~np.all(np.isclose(records["evaluation_params"], history[0] - 0.35 * np.eye(4)[1]), axis=1)  # no g- of e_1
    alone = dict(result, records=dict(records, **{key: records[key][kept] for key in
                                                  ("evaluation_params", "evaluation_seeds", "evaluation_values")}))
    verdict = p1_cartpole.judge_real_rewards(args, alone, None, [])
    assert verdict.actual == f"theta[1][1] = {show(history[1][1])}, and eval_params was not called at both with one seed"


def test_nan_and_a_zero_expected_value_are_said_plainly():
    verdict = judged("2.2.1/values", {"z": np.array([800.0, -800.0])}, [np.nan, 0.0], [1.0, 0.0])
    assert "index [0] (z[0] = 800): expected 1, actual nan" in verdict.difference
    verdict = judged("2.1.1/gradient", {"weights": np.zeros(2)}, [0.5, 1e-3], [0.5, 0.0])
    assert "relative difference undefined (the expected value is 0)" in verdict.difference


def test_an_answer_is_its_numbers_in_a_row_where_the_handout_says_so():
    # 1.2.1: "the same dimension as x": a list, an array, (1,) for a single number
    single = {"x": 0.3, "h": 0.1, "x_scalar": True}
    assert judged("1.2.1/one-step", single, np.array([2.0]), np.array(2.0)).passed
    assert judged("1.2.1/one-step", single, 2.0, np.array(2.0)).passed
    row = {"x": np.zeros(3), "h": np.ones(3)}
    assert judged("1.2.1/equation-3", row, [1.0, 2.0, 3.0], np.array([1.0, 2.0, 3.0])).passed
    column = judged("1.2.1/equation-3", row, np.array([[1.0], [2.0], [3.0]]), np.array([1.0, 2.0, 3.0]))
    assert not column.passed and column.difference == "the answer is an array of shape (3, 1), where shape (3,) is expected"
    short = judged("1.2.1/equation-3", row, [1.0, 2.0], np.array([1.0, 2.0, 3.0]))
    assert not short.passed and "2 number(s), where 3 are expected" in short.difference
    # the sigmoid keeps the shape of z: 12 numbers in a row are not a 3 x 4 array
    z = np.zeros((3, 4))
    assert not judged("2.2.1/any-shape", {"z": z}, np.full(12, 0.5), np.full((3, 4), 0.5)).passed
    assert judged("2.2.1/any-shape", {"z": np.asarray(0.0)}, [0.5], np.asarray(0.5)).passed


def test_every_failure_has_one_wording_in_every_report():
    """Issue 40.4: every report of a failure opens with the same two lines, what is wrong (the TODO, its
    verdict, expected against actual where they differ most) and why (the known mistake), then the
    values, the check in full, the input and the line that rebuilds it, never broken mid-word."""
    failure = {"check": "sigma(z) = 1 / (1 + e^(-z)) for every entry ...", "short": "sigma(z) = 1 / (1 + e^(-z))",
               "hidden": False, "mistake": "your values equal 1 / (1 + e^z), the sign of the exponent flipped",
               "summary": "at z[0] = 1: expected 0.731059, actual 0.268941", "input": "z=[1]",
               "reproduce": 'from hwtools.cases import visible_case; z = visible_case("2.2.1/values/v0")  # then sigmoid(z)',
               "expected": "[0.731059]", "actual": "[0.268941]",
               "difference": "differs at index [0] (z[0] = 1): expected 0.731059, actual 0.268941",
               "tolerance": "|actual - expected| <= 1e-12 * |expected| + 1e-15"}
    entry = {"id": "2.2.1", "title": "sigmoid", "auto_earned": 0.0, "auto_possible": 2, "manual_possible": 0,
             "manual": "", "status": "graded", "notes": [], "first_failure": failure,
             "mistake": {"id": "sigmoid_wrong_sign", "diagnosis": failure["mistake"]},
             "checks": [{"check": failure["check"], "short": failure["short"], "points": 2, "passed": False,
                         "failed_on": "visible", "visible_inputs": 1, "hidden_inputs": 1,  # as judging gives it
                         "visible_failure": {k: v for k, v in failure.items() if k not in ("check", "hidden")}}]}
    first, fields = failure_words(entry, "earns 0 of 2 points")
    assert first == ["TODO 2.2.1 earns 0 of 2 points: at z[0] = 1: expected 0.731059, actual 0.268941", failure["mistake"]]
    assert [name for name, _ in fields] == ["expected", "actual", "difference", "tolerance", "check", "input",
                                            "reproduce"]  # the values, then the check, the input and its line
    result = {"isolated": True, "isolation": "bwrap", "submission": "s", "reference": "r", "one_mistake_one_place": True,
              "todos": [entry], "notes": [], "total": {"auto_earned": 0.0, "auto_possible": 2, "manual_possible": 0}}

    def plain(text):
        return " ".join(text.split())

    statements = ['from hwtools.cases import visible_case', 'z = visible_case("2.2.1/values/v0")', "# then sigmoid(z)"]
    reports = {"text report (preview and grade)": render(result), "class feedback": todo_markdown(entry),
               "Gradescope's visible test": todo_markdown(entry, visible_only=True),
               "check cell, details": "\n".join(check_lines(entry, details=True))}
    for name, report in reports.items():
        said = first if "visible" not in name and "cell" not in name else [first[0].replace("earns 0 of 2 points", "fails"),
                                                                           first[1]]
        assert plain("\n".join(said)) in plain(report), (name, report)
        for label, words in fields:
            if label != "reproduce" and not (label == "check" and "cell" in name):
                assert plain(words) in plain(report) and f"{label}:" in report, (name, label)
        lines = [line.strip() for line in report.splitlines()]  # Python to copy: whole statements, one a line
        assert failure["reproduce"] in lines or all(any(line.endswith(s) for line in lines) for s in statements), name
    cell = check_lines(entry)  # the notebook's check cell: the first two lines say what is wrong, 12 at most
    assert cell[0] == "TODO 2.2.1 fails: at z[0] = 1: expected 0.731059, actual 0.268941"
    assert cell[1] == "  " + failure["mistake"] and len(cell) <= check_cell.MAX_LINES
    assert [line.strip()[len("reproduce:"):].strip() if "reproduce:" in line else line.strip() for line in cell
            if any(line.strip().endswith(s) for s in statements)] == statements
    assert cell[-1].startswith('check("2.2.1", details=True)')
    hidden = {"check": "sigma(z) ...", "short": "sigma(z)", "hidden": True, "input": "a hidden input (not shown)"}
    entry["first_failure"] = hidden
    first, fields = failure_words(entry, "earns 0 of 2 points")
    assert fields == [] and "on a hidden input" in first[0] and first[1] == "the check: sigma(z)"
    assert plain(first[0]) in plain(render(result)) and plain(first[0]) in plain(todo_markdown(entry))
    assert "hidden input" not in todo_markdown(entry, visible_only=True)


# --------------------------------------------------------------------------------------------
# Tolerances (no sandbox): what correct formulas give passes, what wrong ones give does not
# --------------------------------------------------------------------------------------------


def sigmoid_forms():
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        return {
            "naive": lambda z: 1 / (1 + np.exp(-z)),
            "tanh": lambda z: 0.5 * (1 + np.tanh(z / 2)),
            "clip at 500": lambda z: 1 / (1 + np.exp(-np.clip(z, -500, 500))),
            "log-sum-exp": lambda z: np.exp(-np.logaddexp(0, -z)),
        }


@pytest.mark.parametrize("form", list(sigmoid_forms()))
def test_correct_sigmoids_pass_every_tolerance(form):
    z = np.concatenate([np.linspace(-1000, 1000, 20001), np.linspace(-50, 50, 20001), [-24.4, 24.4, 0.0]])
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        actual = sigmoid_forms()[form](z)
    for key in ("values", "any-shape", "precision"):
        assert judged(f"2.2.1/{key}", {"z": z}, actual, reference_sigmoid(z)).passed, (form, key)


def test_sigmoid_tolerances_see_clipping_and_nan():
    z = np.concatenate([np.linspace(-1000, 1000, 2001), np.linspace(-50, 50, 2001)])
    expected = reference_sigmoid(z)
    with np.errstate(over="ignore", invalid="ignore"):
        clip20 = 1 / (1 + np.exp(-np.clip(z, -20, 20)))
        nan = np.exp(z) / (1 + np.exp(z))
    assert judged("2.2.1/values", {"z": z}, clip20, expected).passed  # within 2.1e-9: a shortcut, not a wrong formula
    assert not judged("2.2.1/precision", {"z": z}, clip20, expected).passed  # not float64 precision
    assert not judged("2.2.1/values", {"z": z}, nan, expected).passed
    near = np.linspace(-20, 20, 401)
    # float64 precision is the precision check's own sub-point, not the formula's
    assert not judged("2.2.1/precision", {"z": near}, reference_sigmoid(near) + 2e-15, reference_sigmoid(near)).passed
    cut = np.where(near > 10, 1.0, np.where(near < -10, 0.0, reference_sigmoid(near)))  # a cut-off, not a formula
    assert not judged("2.2.1/values", {"z": near}, cut, reference_sigmoid(near)).passed
    assert not judged("2.2.1/values", {"z": near}, reference_sigmoid(-near), reference_sigmoid(near)).passed


def test_a_sigmoid_in_float32_earns_the_formula_but_not_the_precision_point():
    z = np.concatenate([np.linspace(-1000, 1000, 2001), np.linspace(-50, 50, 2001), [-24.4, 24.4, 0.0]])
    with np.errstate(over="ignore"):
        single = reference_sigmoid(z.astype(np.float32)).astype(np.float32)
    assert judged("2.2.1/values", {"z": z}, single, reference_sigmoid(z)).passed
    assert judged("2.2.1/any-shape", {"z": z}, single, reference_sigmoid(z)).passed
    assert not judged("2.2.1/precision", {"z": z}, single, reference_sigmoid(z)).passed


def test_finite_difference_tolerance_takes_another_order_and_float32_but_no_other_formula():
    rng = np.random.default_rng(1)
    spec = p1_cartpole._coupled(rng, 5)
    from hwtools.grade.in_sandbox.probes import known_function

    f, x, h = known_function(spec), rng.uniform(-1.5, 1.5, 5), np.array([0.01, 0.05, 0.3, 0.8, 0.2])
    eye = np.eye(5)
    reference = np.array([(f(x + h[i] * eye[i]) - f(x - h[i] * eye[i])) / (2.0 * h[i]) for i in range(5)])
    reordered = np.array([f(x + h[i] * eye[i]) / (2 * h[i]) - f(x - h[i] * eye[i]) / (2 * h[i]) for i in range(5)])
    halved = np.array([0.5 * (f(x + h[i] * eye[i]) - f(x - h[i] * eye[i])) / h[i] for i in range(5)])
    half_steps = np.array([(f(x + h[i] / 2 * eye[i]) - f(x - h[i] / 2 * eye[i])) / h[i] for i in range(5)])
    forward = np.array([(f(x + h[i] * eye[i]) - f(x)) / h[i] for i in range(5)])
    first_step = np.array([(f(x + h[0] * eye[i]) - f(x - h[0] * eye[i])) / (2.0 * h[0]) for i in range(5)])
    x32, h32 = x.astype(np.float32), h.astype(np.float32)
    single = np.array([(np.float32(f(x32 + h32[i] * eye[i].astype(np.float32))) -
                        np.float32(f(x32 - h32[i] * eye[i].astype(np.float32)))) / (np.float32(2) * h32[i])
                       for i in range(5)], dtype=np.float32)  # every step of it in float32, f's values too
    args = {"x": x, "h": h}
    for right in (reordered, halved, reference.astype(np.float32), single):
        assert judged("1.2.1/equation-3", args, right, reference).passed
    for wrong in (half_steps, forward, 2 * reference, first_step):
        assert not judged("1.2.1/equation-3", args, wrong, reference).passed


def test_no_hidden_input_repeats_a_visible_one():
    """A hidden input equal to a visible one would be shown in feedback, and answered by the key."""
    from hwtools.grade.grader import load_hidden_checks
    from hwtools.grade.in_sandbox.channel import fingerprint

    hidden = load_hidden_checks(KIT)
    shown = {show(value) for b in checks.BEHAVIOURS for args in b.visible_cases() for value in args.values()}
    for b in checks.BEHAVIOURS:
        visible = {fingerprint({"args": args}) for args in b.visible_cases()}
        for args in hidden.hidden_cases(b):
            assert fingerprint({"args": args}) not in visible, (b.id, args)
            for name, value in args.items():  # nor does it read as one where feedback shows a visible input
                if isinstance(value, np.ndarray) and np.unique(value).size >= 3:
                    assert show(value) not in shown, (b.id, name, show(value))


# --------------------------------------------------------------------------------------------
# The regimes the handout names, reached by visible and hidden inputs alike (issue 40.2; no sandbox)
# --------------------------------------------------------------------------------------------


def reaches(todo, key, regime, draws=4):
    """(whether a visible input of behaviour ``key`` of ``todo`` reaches ``regime(args)``, whether a hidden
    one does for each of ``draws`` submissions)."""
    from hwtools.grade.grader import load_hidden_checks

    hidden = load_hidden_checks(KIT)
    visible = any(regime(args) for _, b, args in checks.case_set(todo).visible if b.key == key)
    drawn = [any(regime(args) for _, b, args in checks.case_set(todo, hidden, f"draw {draw}").hidden if b.key == key)
             for draw in range(draws)]
    return visible, all(drawn)


@pytest.mark.quick
def test_the_makers_cartpole_is_gymnasiums():
    """1.3.1's maker picks its seeds with its own CartPole (episode_lengths); it must play gymnasium's."""
    from hwlib.machinery.episodes import play_batch

    rng = np.random.default_rng(3)
    rows = np.vstack([np.array(p1_cartpole.ON_THE_EDGE), rng.uniform(-1, 1, size=(12, 4))])
    seeds = rng.integers(0, 10_000, size=len(rows))
    assert np.array_equal(p1_cartpole.episode_lengths(rows, seeds), play_batch(rows, seeds))


@pytest.mark.quick
def test_1_3_1_inputs_reach_the_cap_and_end_early_in_the_same_call():
    """An eval_params that stops at the first episode to reach the cap must be seen: in one call, the
    first and the last episode end early and one between them reaches the cap, visible and hidden
    (played by gymnasium), so that code stopping there plays fewer episodes than it was asked for."""
    from hwlib.machinery.episodes import play_batch
    from hwtools.facts import MAX_EPISODE_STEPS

    def mixed(args):
        seeds = args["seed"] + np.arange(args["num_rollouts"])
        lengths = play_batch(np.tile(args["params"], (len(seeds), 1)), seeds)
        return lengths[0] < MAX_EPISODE_STEPS > lengths[-1] and lengths.max() == MAX_EPISODE_STEPS

    assert reaches("1.3.1", "mean-reward", mixed) == (True, True)


@pytest.mark.quick
def test_1_3_2_inputs_reach_the_cap_and_train_on_at_it():
    """A training loop that stops once the reward reaches the cap must be seen: a known objective, capped
    where rewards are, that the reference's run reaches before its last update, visible and hidden."""
    from hwtools.facts import MAX_EPISODE_STEPS
    from hwtools.grade.in_sandbox.probes import training_objective

    def capped_early(args):
        g, theta = training_objective(args["objective"]), np.asarray(args["initial_params"], dtype=np.float64)
        rewards = [g(theta)]
        for _ in range(args["iterations"]):
            theta = theta + args["learning_rate"] * p1_cartpole.central_difference(g, theta, args["fd_step"])
            rewards.append(g(theta))
        return rewards[0] < MAX_EPISODE_STEPS and MAX_EPISODE_STEPS in rewards[:-1]

    assert reaches("1.3.2", "equation-4", capped_early) == (True, True)


@pytest.mark.quick
@pytest.mark.parametrize("decimals", p1_cartpole.ROUNDED)
def test_1_1_1_inputs_show_an_observation_rounded(decimals):
    def flips(args):
        params, obs = np.asarray(args["params"]), np.asarray(args["obs"])
        return bool(np.any((np.einsum("ij,ij->i", params, np.round(obs, decimals)) < 0) !=
                           (np.einsum("ij,ij->i", params, obs) < 0)))

    assert reaches("1.1.1", "equation-1", flips) == (True, True)


@pytest.mark.quick
def test_2_2_3_and_2_3_1_inputs_reach_a_single_class_and_an_absent_one():
    def single(args):
        return np.unique(np.asarray(args["y"])).size == 1

    def absent(args):
        return np.unique(np.asarray(args["y"])).size < int(args["n_classes"])

    assert reaches("2.2.3", "from-zero", single) == (True, True)
    assert reaches("2.2.3", "from-weights", single) == (True, True)
    assert reaches("2.3.1", "iterations", absent) == (True, True)


def visible_args(behaviour_id, number=0):
    return behaviour(behaviour_id).visible_cases()[number]


def fd_answer(args, steps=None, every=None):
    """Equation (3) on a 1.2.1 case with ``steps`` (default h), or f(x + d_i) - f(x - d_i) over 2 h_i with ``every(i)`` = d_i."""
    from hwtools.grade.in_sandbox.probes import known_function

    f, x = known_function(args["f"]), np.asarray(args["x"], dtype=np.float64)
    h = np.broadcast_to(np.asarray(args["h"], dtype=np.float64), x.shape)
    if every is not None:
        return np.array([(f(x + every(h, i)) - f(x - every(h, i))) / (2 * h[i]) for i in range(len(x))])
    return p1_cartpole._central(f, x, h if steps is None else steps(h))


def ascent(args, rate, steps=1, start=None, labels=None):
    """Weights after ``steps`` steps of equation (8) with ``rate`` (2.2.3's cases; 2.3.1's with ``labels``)."""
    w = np.asarray(args["weights"] if start is None else start, dtype=np.float64)
    X_aug = np.hstack([np.asarray(args["X"]), np.ones((len(args["X"]), 1))])
    y = np.asarray(args["y"] if labels is None else labels, dtype=np.float64)
    out = []
    for _ in range(steps):
        w = w + rate * X_aug.T @ (y - reference_sigmoid(X_aug @ w))
        out.append(w)
    return np.array(out)


def one_vs_rest(args, per_iteration):
    classes, X = int(args["n_classes"]), np.asarray(args["X"])
    start = args.get("initial_weights", np.zeros((classes, X.shape[1] + 1)))
    return np.array([ascent({"X": X, "weights": start[c]}, args["learning_rate"], per_iteration * args["n_iters"],
                            labels=(np.asarray(args["y"]) == c) * 1.0)[-1] for c in range(classes)])


def steps_asked(args, per_iteration):
    """2.3.1's records of a fit that asked the grader for ``per_iteration`` steps per classifier and iteration."""
    return {"served": np.array(["gradient_ascent_step"] * (per_iteration * int(args["n_classes"]) * int(args["n_iters"])))}


def rounded_actions(args, decimals):
    return (np.einsum("ij,ij->i", args["params"], np.round(args["obs"], decimals)) < 0) * 1


# (behaviour, its visible case, the right answer, [(the rule a wrong answer shows whatever its constant, that answer)]),
# and answers that are right in another way (float32, a clip far out): no rule, and they pass.
RULES = {
    "1.1.1": ("1.1.1/equation-1", 0, lambda a: rounded_actions(a, 17),
              [("rounds_observation", lambda a: rounded_actions(a, d)) for d in (2, 3, 4)], []),
    "1.2.1": ("1.2.1/equation-3", 0, fd_answer,
              [("scaled_steps", lambda a: fd_answer(a, lambda h: h / 2)), ("scaled_steps", lambda a: fd_answer(a, lambda h: 10 * h)),
               ("one_step", lambda a: fd_answer(a, lambda h: np.full(len(h), h[0]))),
               ("one_step", lambda a: fd_answer(a, lambda h: np.full(len(h), 1e-3))),
               ("moves_every_coordinate", lambda a: fd_answer(a, every=lambda h, i: h)),
               ("moves_every_coordinate", lambda a: fd_answer(a, every=lambda h, i: np.full(len(h), h[i])))],
              [lambda a: fd_answer(a).astype(np.float32)]),
    "2.2.1": ("2.2.1/values", 0, lambda a: reference_sigmoid(a["z"]),
              [("cuts_off", lambda a, c=c: np.where(np.abs(a["z"]) > c, (a["z"] > 0) * 1.0, reference_sigmoid(a["z"])))
               for c in (6, 10, 15)],
              [lambda a: reference_sigmoid(np.clip(a["z"], -20, 20)), lambda a: reference_sigmoid(a["z"]).astype(np.float32)]),
    "2.2.3": ("2.2.3/from-weights", 0, lambda a: ascent(a, a["learning_rate"]),
              [("other_rate", lambda a, r=r: ascent(a, r)) for r in (1.0, 0.2, 0.003)], [lambda a: ascent(a, a["learning_rate"]).astype(np.float32)]),
    "2.3.1": ("2.3.1/iterations", 0, lambda a: one_vs_rest(a, 1),
              [("other_steps", lambda a, k=k: one_vs_rest(a, k)) for k in (2, 4)], []),
}
RECORDS = {"2.3.1": steps_asked}  # rules read from the grader's records: what the wrong answer's run asked for


@pytest.mark.quick
@pytest.mark.parametrize("todo", list(RULES))
def test_a_rule_names_a_mistake_whatever_its_constant_and_never_a_right_answer(todo):
    behaviour_id, number, right, wrongs, also_right = RULES[todo]
    args = visible_args(behaviour_id, number)
    assert judged(behaviour_id, args, right(args), right(args)).passed
    for answer in also_right:
        verdict = judged(behaviour_id, args, answer(args), right(args))
        assert verdict.passed and not verdict.rule, verdict
    for k, (rule, answer) in enumerate(wrongs):
        records = RECORDS[todo](args, (2, 4)[k]) if todo in RECORDS else {}
        verdict = judged(behaviour_id, args, answer(args), right(args), records)
        assert not verdict.passed and verdict.rule == rule, (rule, verdict.rule, verdict.summary)
    other = judged(behaviour_id, args, right(args) * -1.0 + 0.5, right(args),  # another mistake: no rule of these
                   RECORDS[todo](args, 1) if todo in RECORDS else {})
    assert not other.passed and other.rule == "", other.rule


# --------------------------------------------------------------------------------------------
# 1.3.1 on the grader's records, whatever door the episodes came through (no sandbox)
# --------------------------------------------------------------------------------------------


def eval_result(episodes, value, again=None):
    """A result of the eval_params probe whose records hold ``episodes`` (episodes.Episode)."""
    records = Records()
    records.episodes = list(episodes)
    return {"status": "ok", "error": "", "warnings": [], "records": records.arrays(),
            "values": {"value": np.asarray(value), "value_again": np.asarray(value if again is None else again)}}


def own_loop(params, start, steps, seed=None, finished=True, actions=None):
    """An own-loop episode of ``steps`` steps from ``start``, with the actions of CartPoleLinearPolicy(params)."""
    envs, rng = Environments(), np.random.default_rng(steps)
    env = envs.get(envs.make()[0])
    episode = envs.reset(env, seed, start)
    for t in range(steps):
        obs = env.last_obs
        action = int(np.dot(params, obs) < 0) if actions is None else actions
        envs.step(env, action, [rng.normal(size=4), 1.0, finished and t == steps - 1, False])
    return episode


def test_own_loop_episodes_count_when_their_actions_are_the_policys():
    params, count = np.array([0.1, -0.4, 0.9, 0.3]), 2
    args = {"params": params, "num_rollouts": count, "seed": 3}
    starts = [np.array([0.01 * k, 0.02, -0.01, 0.0]) for k in range(count)]
    episodes = [own_loop(params, start, 10 + k, seed=3 + k) for k, start in enumerate(starts)] * 2
    result = eval_result(episodes, 10.5)
    assert behaviour("1.3.1/mean-reward").judge(args, result, None, []).passed
    assert behaviour("1.3.1/different-starts").judge(args, result, None, []).passed
    assert behaviour("1.3.1/repeatable").judge(args, result, None, []).passed
    pushed_left = [own_loop(params, start, 10 + k, seed=3 + k, actions=0) for k, start in enumerate(starts)] * 2
    verdict = behaviour("1.3.1/mean-reward").judge(args, eval_result(pushed_left, 10.5), None, [])
    assert not verdict.passed and "not those of CartPoleLinearPolicy(params)" in verdict.actual
    stopped = [own_loop(params, start, 10 + k, seed=3 + k, finished=False) for k, start in enumerate(starts)] * 2
    verdict = behaviour("1.3.1/mean-reward").judge(args, eval_result(stopped, 10.5), None, [])
    assert not verdict.passed and "stopped before it ended" in verdict.actual


def test_repeatable_means_the_same_start_states_and_the_same_number():
    params, args = np.zeros(4), {"params": np.zeros(4), "num_rollouts": 2, "seed": 3}
    first = [own_loop(params, np.array([0.01, 0.0, 0.0, k]), 9) for k in (0.01, 0.02)]
    continued = [own_loop(params, np.array([0.01, 0.0, 0.0, k]), 9) for k in (0.03, 0.04)]
    assert behaviour("1.3.1/repeatable").judge(args, eval_result(first + first[::-1], 9.0), None, []).passed
    verdict = behaviour("1.3.1/repeatable").judge(args, eval_result(first + continued, 9.0), None, [])
    assert not verdict.passed and "started from other states" in verdict.actual
    assert not behaviour("1.3.1/repeatable").judge(args, eval_result(first + first, 9.0, 9.5), None, []).passed


def test_a_reset_that_no_step_follows_is_no_episode():
    envs = Environments()
    env = envs.get(envs.make()[0])
    records = Records()
    records.episodes = [envs.reset(env, 7, np.zeros(4))]  # env.reset(seed=seed) to seed it, then reset() per episode
    episode = envs.reset(env, None, np.full(4, 0.01))
    envs.step(env, 1, [np.zeros(4), 1.0, True, False])
    records.episodes.append(episode)
    arrays = records.arrays()
    assert arrays["episode_seeds"].tolist() == [-1] and arrays["episode_determined"].tolist() == [True]
    assert arrays["step_episode"].tolist() == [0] and arrays["episode_rewards"].tolist() == [1.0]


@pytest.mark.parametrize("todo", [todo for todo in checks.GRADED_TODOS if TODO_BY_ID[todo].auto])
def test_no_wrong_value_keeps_more_than_30_percent_whichever_check_it_passes(todo):
    behaviours = checks.BEHAVIOURS_BY_TODO[todo]
    values = [b for b in behaviours if b.value]
    assert values, f"TODO {todo} has no value check"
    most = 0.3 * TODO_BY_ID[todo].auto
    for wrong in values:  # one value check fails (on any input), every other check passes
        passed = {b.key: b is not wrong for b in behaviours}
        notes = []
        earned = sum(b.points for b in behaviours if passed[b.key])
        assert judging._capped(todo, earned, passed, notes) <= most + 1e-9, wrong.id
        assert not notes or "30%" in notes[0]
    every = {b.key: True for b in behaviours}
    assert judging._capped(todo, TODO_BY_ID[todo].auto, every, []) == TODO_BY_ID[todo].auto


# --------------------------------------------------------------------------------------------
# Grading the solutions (sandbox)
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def grader():
    return Grader(KIT, time_limit=TIME_LIMIT, jobs=2)


@pytest.fixture(scope="module")
def layout():
    return blocks.load_layout(KIT)


def is_crlf(path):
    return b"\r\n" in path.read_bytes()


def write_kit(layout, folder, bodies, crlf=False):
    """A student's kit with ``bodies`` ({todo: code}) in their blocks and the reference elsewhere;
    with ``crlf`` every file saved with Windows line endings, as Git for Windows checks it out."""
    kits.write_submission(layout, folder, bodies, others="reference")
    if crlf:
        for path in Path(folder).rglob("*.py"):
            path.write_bytes(path.read_bytes().replace(b"\r\n", b"\n").replace(b"\n", b"\r\n"))
    return Path(folder)


def natural_solutions():
    return [path for path in sorted(NATURAL.glob("*.py"))
            if TODO_BY_ID[path.name.split("_")[0]].auto or path.name.startswith("2.1.1_")]


def natural_body(path):
    return path.read_bytes().decode("utf-8").replace("\r\n", "\n")


def test_crlf_copies_are_byte_for_byte_crlf_and_cover_every_graded_todo():
    copies = [path for path in natural_solutions() if path.stem.endswith("_crlf")]
    assert {path.name.split("_")[0] for path in copies} == set(checks.GRADED_TODOS)
    for path in copies:
        data = path.read_bytes()
        assert data.count(b"\r\n") == data.count(b"\n") > 0, path.name
        assert (NATURAL / (path.stem[: -len("_crlf")] + ".py")).read_bytes() == data.replace(b"\r\n", b"\n")


def test_the_whole_reference_kit_saved_with_crlf_earns_every_point(grader, layout, tmp_path):
    result = grader.grade(write_kit(layout, tmp_path / "kit", {}, crlf=True))
    assert points(result) == full_points(), render(result)


WRONG_FILES = sorted(WRONG.glob("*.txt"))


# The cases the handout leaves open, with the verdict docs/grading.md's table gives and why.
VERDICTS = {
    "a sigmoid clipped at +-20 (off by up to 2.1e-9)": (
        "2.2.1", "values = 1.0 / (1.0 + np.exp(-np.clip(z, -20, 20)))", 1.5),
    "a numpy bool as action (env.step refuses it)": ("1.1.1", "action = np.dot(self.params, obs) < 0", 1.5),
    "a Python bool as action (env.step takes it)": ("1.1.1", "action = float(np.dot(self.params, obs)) < 0", 2),
    "a float as action (env.step refuses it)": ("1.1.1", "action = float(np.dot(self.params, obs) < 0)", 1.5),
    "the gradient as a column (N, 1): not the dimension of x": (
        "1.2.1", "column = np.zeros((len(x), 1))\nfor i in range(len(x)):\n    e = np.zeros(len(x))\n    e[i] = h[i]\n"
                 "    column[i, 0] = (f(x + e) - f(x - e)) / (2 * h[i])\nreturn column", 0),
    "a sigmoid that breaks on a single number (iterates over z)": (
        "2.2.1", "values = np.array([1 / (1 + np.exp(-v)) for v in z])", 1.7),
    "a sigmoid in float32 (the formula right, float32 precision)": (
        "2.2.1", "values = (1 / (1 + np.exp(-np.clip(z, -80, 80).astype(np.float32)))).astype(np.float32)", 1.5),
}


@pytest.mark.parametrize("case", list(VERDICTS))
def test_open_cases_get_the_readme_verdict(grader, layout, tmp_path, case):
    todo, body, kept = VERDICTS[case]
    kit = write_kit(layout, tmp_path / "kit", {todo: body})
    assert_the_other_todos_run_the_reference_kits(grader, layout, kit, todo)
    result = grader.grade(kit, todos=[todo])
    assert points(result) == {todo: kept}, render(result)


# --------------------------------------------------------------------------------------------
# Preview = grade on the visible part
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def student_edition(tmp_path_factory):
    """The student edition with its answer key (the test run's one: ``editions.build``; the release's command
    is run by tests/instructor/test_student_path.py), and the environment that runs its own ``hwtools``."""
    out = editions.build(tmp_path_factory.mktemp("edition") / "student", tmp_path_factory)
    assert (out / "hwtools" / "grade" / "answer_key.json").is_file() and not (out / "instructor").exists()
    env = {**os.environ, "PYTHONPATH": str(out), "MPLBACKEND": "Agg"}
    where = subprocess.run([sys.executable, "-c", "import hwtools.grade; print(hwtools.grade.__file__)"], cwd=out,
                           env=env, capture_output=True, text=True, timeout=60)
    assert Path(where.stdout.strip()).resolve().is_relative_to(out.resolve()), where.stdout + where.stderr
    return out, env


def preview(student_edition, kit, todos, out):
    edition, env = student_edition
    command = [sys.executable, "-m", "hwtools.grade", str(kit), "--json", str(out), "--time-limit", str(TIME_LIMIT)]
    for todo in todos:
        command += ["--todo", todo]
    run = subprocess.run(command, cwd=edition, env=env, capture_output=True, text=True, timeout=1200)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return json.loads(Path(out).read_text(encoding="utf-8"))


def visible_verdicts(result, todos):
    """{(todo, check): passed on its visible inputs}."""
    return {(entry["id"], check["check"]): check["passed"] or check["failed_on"] == "hidden"
            for entry in result["todos"] if entry["id"] in todos for check in entry["checks"]}


def assert_same_visible_verdicts(grade, shown, todos):
    assert shown["one_mistake_one_place"] is False and grade["one_mistake_one_place"] is True
    assert visible_verdicts(shown, todos) == visible_verdicts(grade, todos)
    for todo in todos:
        graded = next(entry for entry in grade["todos"] if entry["id"] == todo)["first_failure"]
        previewed = next(entry for entry in shown["todos"] if entry["id"] == todo)["first_failure"]
        if graded is not None and not graded["hidden"]:  # the same words for the same visible failure
            assert previewed == graded, (todo, previewed, graded)


def test_the_line_a_failing_check_prints_rebuilds_its_input_in_the_student_edition(student_edition):
    """Each visible case's line of Python, run in the student edition (its own hwtools and hwlib),
    gives the input the check gave the student's function."""
    from hwtools.cases import visible_case
    from hwtools.grade.checks import rebuild_line
    from hwtools.grade.in_sandbox.probes import known_function

    edition, env = student_edition
    lines = {case_id: rebuild_line(case_id, b.probe) for todo in checks.GRADED_TODOS
             for case_id, b, _ in checks.case_set(todo).visible}
    assert lines["1.3.3/converges/v0"] == "" and all(line for case_id, line in lines.items() if "1.3.3" not in case_id)
    script = "import json, numpy as np\nout = {}\n"
    for case_id, line in lines.items():
        if line:
            names = line.split("; ", 1)[1].split(" = ", 1)[0]
            script += f"{line}\nout[{case_id!r}] = digest([{names}])\n"
    script = DIGEST + script + "print(json.dumps(out))\n"
    run = subprocess.run([sys.executable, "-c", script], cwd=edition, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    shown = json.loads(run.stdout)
    namespace = {}
    exec(DIGEST, namespace)
    for case_id, line in lines.items():
        if line:
            value, single = visible_case(case_id), "," not in line.split("; ", 1)[1].split(" = ", 1)[0]
            assert shown[case_id] == json.loads(json.dumps(namespace["digest"]([value] if single else list(value)))), case_id
    # and what the grader gave: the finite-difference case itself
    case_id, _, args = checks.case_set("1.2.1").visible[0]
    f, x, h = visible_case(case_id)
    assert np.array_equal(x, args["x"]) and np.array_equal(h, args["h"]) and f(x) == known_function(args["f"])(x)


DIGEST = """
def digest(values):
    import numpy as np
    out = []
    for value in values:
        if callable(value):
            out.append("a function")
        elif isinstance(value, dict):
            out.append({key: np.asarray(item).tolist() for key, item in sorted(value.items())})
        elif hasattr(value, "classifiers"):
            out.append([np.asarray(c.weights).tolist() for c in value.classifiers])
        elif hasattr(value, "weights"):
            out.append(np.asarray(value.weights).tolist())
        else:
            out.append(np.asarray(value).tolist())
    return out
"""


@pytest.mark.parametrize("path", natural_solutions(), ids=lambda path: path.stem)
def test_natural_solution_earns_every_point_and_the_preview_gives_its_grade(grader, layout, student_edition, tmp_path,
                                                                           path):
    """One solution at a time, the reference elsewhere (a CRLF copy in a kit saved whole with CRLF, as
    Git for Windows checks it out), graded on its own TODO: every other TODO runs on the reference
    kit's own kits (graded in full once, with LF in test_grading.py and with CRLF here). The preview
    runs the student's own code for the other TODOs, so a correct 1.2.1 that returns a list fails the
    student's own 1.3.2 there (params + learning_rate * list), where the grade runs 1.3.2 with the
    reference's 1.2.1."""
    todo = path.name.split("_")[0]
    kit = write_kit(layout, tmp_path / "kit", {todo: natural_body(path)}, crlf=is_crlf(path))
    assert_the_other_todos_run_the_reference_kits(grader, layout, kit, todo)
    grade = grader.grade(kit, todos=[todo])
    assert points(grade) == {t: full for t, full in full_points().items() if t == todo}, render(grade)
    entry = next(entry for entry in grade["todos"] if entry["id"] == todo)
    assert all(check["passed"] for check in entry["checks"]), render(grade)
    assert not any(other.get("mistake") for other in grade["todos"])  # no correct solution is named a mistake
    shown = preview(student_edition, kit, [todo], tmp_path / "preview.json")
    assert_same_visible_verdicts(grade, shown, [todo])
    assert all(visible_verdicts(shown, [todo]).values()), render(shown)


def test_a_1_2_1_that_returns_a_list_is_named_where_the_students_1_3_2_fails_on_it(grader, layout, student_edition,
                                                                                  tmp_path):
    """Issue 32.5: a right 1.2.1 that returns a list keeps its points, and its check says that the
    training code does arithmetic on the gradient; the preview runs the student's own 1.2.1 in 1.3.2's
    check and 1.3.3's training run, where learning_rate * list fails: their checks name 1.2.1 and keep
    the grade's points."""
    body = natural_body(NATURAL / "1.2.1_returns_list.py")
    kit = write_kit(layout, tmp_path / "kit", {"1.2.1": body})  # the reference's 1.3.2 and LEARNING_RATE
    todos = ["1.2.1", "1.3.2", "1.3.3"]
    graded = {entry["id"]: entry for entry in grader.grade(kit, todos=todos)["todos"]}
    shown = {entry["id"]: entry for entry in preview(student_edition, kit, todos, tmp_path / "p.json")["todos"]}
    for todo in todos:  # preview = grade: the points, whichever 1.2.1 ran
        assert shown[todo]["auto_earned"] == graded[todo]["auto_earned"] == TODO_BY_ID[todo].auto, \
            (todo, check_lines(shown[todo]))
    assert "return an array (np.array(...))" in " ".join(check_lines(shown["1.2.1"])), check_lines(shown["1.2.1"])
    for todo in ("1.3.2", "1.3.3"):
        assert shown[todo]["blamed_on"] == ["1.2.1"] and "blamed_on" not in graded[todo]
        first = " ".join(" ".join(check_lines(shown[todo])[0:2]).split())
        assert "probably caused by TODO 1.2.1, which returns a list" in first, check_lines(shown[todo])


# A wrong formula keeps at most 30% of its TODO's points (issue 15.4), in every TODO: every wrong
# solution loses at least 70% of its own TODO and nothing elsewhere, and the preview gives its grade.
@pytest.mark.parametrize("path", WRONG_FILES, ids=lambda path: path.stem)
def test_wrong_solution_loses_points_only_in_its_todo_and_the_preview_gives_its_grade(grader, layout, student_edition,
                                                                                      tmp_path, path):
    """Graded on its own TODO (and 2.1.1, whose check must not blame the derivation for another TODO's
    mistake): every other TODO runs on the reference kit's own kits (graded in full once)."""
    todo, mistake, bodies = parse_wrong_solution(path)
    kit = write_kit(layout, tmp_path / "kit", {todo: bodies})
    assert_the_other_todos_run_the_reference_kits(grader, layout, kit, todo)
    result = grader.grade(kit, todos=[todo, "2.1.1"])
    earned = points(result)
    assert earned[todo] < TODO_BY_ID[todo].auto, f"{path.name} ({mistake}) kept every point of {todo}"
    assert earned[todo] <= 0.3 * TODO_BY_ID[todo].auto, f"{path.name} ({mistake}) kept {earned[todo]} of {todo}"
    entry = next(entry for entry in result["todos"] if entry["id"] == todo)
    failure = entry["first_failure"]
    assert failure is not None and failure["check"]
    assert "NameError" not in failure.get("actual", ""), f"{path.name} no longer fits the kit's code: {failure}"
    if not failure["hidden"]:
        assert failure["input"] and failure["expected"] and failure["actual"]
    # 2.1.1 is graded by hand; the check shown for its grader must not blame the derivation for another TODO's mistake
    derivation = next(entry for entry in result["todos"] if entry["id"] == "2.1.1")
    assert todo == "2.1.1" or all(check["passed"] for check in derivation["checks"])
    # the feedback names the mistake, in the file's own words, first in the first visible failure
    diagnosis = mistakes.read_wrong_solution(path).diagnosis
    assert (entry.get("mistake") or {}).get("diagnosis") == diagnosis, (path.name, entry.get("mistake"))
    assert entry["mistake"]["id"] in {w.id for w in mistakes.read_wrong_solutions(WRONG) if w.diagnosis == diagnosis}
    named = next(check["visible_failure"] for check in entry["checks"] if check["failed_on"] == "visible")
    assert list(named)[0] == "mistake" and named["mistake"] == diagnosis
    if todo != "1.3.3":  # and the one line of Python that rebuilds the visible input (1.3.3's is a setting)
        assert named["reproduce"].startswith("from hwtools.cases import visible_case; ") and "\n" not in named["reproduce"]
    assert all(other.get("mistake") is None for other in result["todos"] if other["id"] != todo)
    assert_first_two_lines_say_what_is_wrong(entry, diagnosis)
    assert_same_visible_verdicts(result, preview(student_edition, kit, [todo], tmp_path / "preview.json"), [todo])
