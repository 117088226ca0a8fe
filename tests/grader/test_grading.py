"""The grader's proof: the instructor's kit earns every point, an untouched student edition none;
no TODO's kit holds another TODO's code, so a mistake costs points in its own TODO and nowhere else
(the wrong and natural solutions are graded beside their preview in test_checks.py); correct
solutions that call another TODO's function earn every point; cheating submissions earn nothing,
and the report names what it saw.

One ``Grader`` serves the whole module: the reference's answers are computed once, and a kit the
grader has already run (the same TODO with the same code) is not run again.
"""

from __future__ import annotations

import base64
import json
import os
import re
import secrets
import shutil
import subprocess
import sys
import tempfile
import zlib
from pathlib import Path

import numpy as np
import pytest

from hwtools.grade import AUTO_POINTS, MANUAL_POINTS, TODO_BY_ID, Grader, blocks, checks, kits, mistakes
from hwtools.grade.checks.verdicts import show
from hwtools.grade.in_sandbox import served
from hwtools import check_cell
from hwtools.check_cell import check_lines
from hwtools.grade.feedback import render
import editions
from cheats import leak_search
from process_watch import live_processes

KIT = Path(__file__).resolve().parents[2]
CHEATS = Path(__file__).resolve().parent / "cheats"
# The name of this test run's own channel in the cheats that talk between runs (cheats/README.md): another test
# run grading the same cheat at the same time (two gradings side by side) uses another.
CHANNEL = secrets.randbelow(1 << 20)
NATURAL = Path(__file__).resolve().parent / "natural_solutions"
WRONG = KIT / "instructor" / "wrong_solutions"
UNSEEN = Path(__file__).resolve().parent / "unseen_mistakes"
TIME_LIMIT = 20.0  # per TODO's run: room for every natural solution however slowly written
# A cheat whose own TODO's run lasts until its limit: graded with a short one (the limit is what stops
# it, whatever its size), so that it costs seconds, not TIME_LIMIT.
SHORT_TIME_LIMIT, RUN_TO_THE_LIMIT = 3.0, {"endless_loop"}
AUTO_TODOS = [todo.id for todo in TODO_BY_ID.values() if todo.auto]

pytestmark = pytest.mark.timeout(900)


@pytest.fixture(scope="module")
def grader():
    with Grader(KIT, time_limit=TIME_LIMIT, jobs=2) as shared:
        yield shared


@pytest.fixture(scope="module")
def short_grader():  # the limit stops the cheat's run, never the budget, whatever else runs on the machine
    with Grader(KIT, time_limit=SHORT_TIME_LIMIT, jobs=2, budget=40 * SHORT_TIME_LIMIT) as shared:
        yield shared


@pytest.fixture(scope="module")
def layout():
    return blocks.load_layout(KIT)


def points(result):
    return {entry["id"]: entry["auto_earned"] for entry in result["todos"] if entry["auto_possible"]}


def full_points():
    return {todo: TODO_BY_ID[todo].auto for todo in AUTO_TODOS}


def shortfall(result):
    """What the grader said of every TODO that earned less than all its points (for a failing assert)."""
    full = full_points()
    short = [entry for entry in result["todos"] if entry["auto_possible"] and entry["auto_earned"] < full[entry["id"]]]
    return "\n".join(json.dumps({key: entry.get(key) for key in ("id", "status", "auto_earned", "first_failure", "notes",
                                                                   "checks")}, default=str)[:4000] for entry in short)


def text_of(result):
    return render(result) + json.dumps(result)


# --------------------------------------------------------------------------------------------
# The reference and the untouched student edition
# --------------------------------------------------------------------------------------------


@pytest.mark.quick  # one grade of each TODO
def test_instructor_kit_earns_every_point(grader):
    result = grader.grade(KIT)
    assert points(result) == full_points(), shortfall(result)
    assert result["total"]["auto_earned"] == AUTO_POINTS
    assert result["total"]["manual_possible"] == MANUAL_POINTS
    assert all(check["passed"] for entry in result["todos"] for check in entry["checks"])
    assert result["isolated"] == grader.sandbox.isolated


def test_untouched_student_edition_earns_nothing(grader, layout, tmp_path):
    kits.write_submission(layout, tmp_path, others="stub")
    result = grader.grade(tmp_path)
    assert result["total"]["auto_earned"] == 0
    for entry in result["todos"]:
        if entry["auto_possible"]:
            assert entry["status"] == "graded" and entry["first_failure"] is not None, entry


def test_release_student_edition_earns_nothing_and_keeping_solutions_earns_all(grader, tmp_path, tmp_path_factory):
    editions.build(tmp_path / "student", tmp_path_factory)
    assert grader.grade(tmp_path / "student")["total"]["auto_earned"] == 0
    editions.build(tmp_path / "kept", tmp_path_factory, keep=frozenset(TODO_BY_ID))
    kept = grader.grade(tmp_path / "kept")
    assert points(kept) == full_points(), shortfall(kept)


# --------------------------------------------------------------------------------------------
# Wrong solutions: points lost in their own TODO, nowhere else (each graded, beside its preview, in
# test_checks.py: on its own TODO, since the others run the reference kit's kits)
# --------------------------------------------------------------------------------------------


def parse_wrong_solution(path):
    text = path.read_text(encoding="utf-8")
    todo = re.search(r"^# todo:\s*(\S+)", text, re.M)[1]
    mistake = re.search(r"^# mistake:\s*(.+)$", text, re.M)[1]
    bodies = [part.strip("\n") for part in re.split(r"^# --- block.*$", text, flags=re.M)[1:]]
    return todo, mistake, bodies


def assert_the_other_todos_run_the_reference_kits(grader, layout, kit, todo):
    """Every TODO of ``kit`` but ``todo`` runs on the very kit it runs on in the reference kit (graded
    in full: test_instructor_kit_earns_every_point; no TODO's kit holds another TODO's code:
    test_no_kit_a_student_run_gets_holds_reference_code...), so a test of ``todo``'s code grades
    ``todo`` alone: what the others would earn is already proven. Read and built, not run."""
    with tempfile.TemporaryDirectory(prefix="hwgrade-test-reference-") as scratch:
        kits.write_submission(layout, scratch, others="reference")
        reference = blocks.read_submission(Path(scratch), layout)
    read = blocks.read_submission(Path(kit), layout)
    for other in checks.GRADED_TODOS:
        if other != todo:
            assert grader._composite(other, read, layout) == grader._composite(other, reference, layout), other


def assert_first_two_lines_say_what_is_wrong(entry, diagnosis):
    """Issue 40.4: the check cell's line 1 is the TODO, its verdict and expected against actual; line 2
    (wrapped at words, so it may go on below) the known mistake."""
    lines = check_lines(entry)
    assert lines[0].startswith(f"TODO {entry['id']} fails: ") and "expected" in lines[0] and "actual" in lines[0], lines
    assert lines[1].startswith("  ") and diagnosis.startswith(lines[1].strip()), lines
    assert len(lines) <= check_cell.MAX_LINES, lines


# A known mistake written with another constant than its wrong solution's (issue 32.5: 5 rollouts
# instead of 1, a step of 1e-3 instead of 0.5, the last episode instead of the first) is named as
# that mistake, by the rule its judge sees in the grader's records, and keeps at most 30% of its TODO.
@pytest.mark.parametrize("path", sorted(UNSEEN.glob("*.txt")), ids=lambda path: path.stem)
def test_a_known_mistake_with_another_constant_is_named_as_that_mistake(grader, layout, tmp_path, path):
    todo, mistake, bodies = parse_wrong_solution(path)
    expected = mistakes.read_wrong_solution(WRONG / (re.search(r"^# expect:\s*(\S+)", path.read_text(encoding="utf-8"), re.M)[1] + ".txt"))
    kits.write_submission(layout, tmp_path, {todo: bodies}, others="reference")
    result = grader.grade(tmp_path, todos=[todo])
    entry = next(entry for entry in result["todos"] if entry["id"] == todo)
    assert (entry.get("mistake") or {}).get("diagnosis") == expected.diagnosis, (path.name, mistake, entry.get("mistake"))
    assert points(result)[todo] <= 0.3 * TODO_BY_ID[todo].auto, (path.name, points(result)[todo])
    assert_first_two_lines_say_what_is_wrong(entry, expected.diagnosis)


def test_a_known_mistake_that_returns_a_list_is_named_as_that_mistake(grader, layout, tmp_path):
    """The answer's form (a list, where the wrong solution returns an array: probes.FORMS) tells no
    mistake apart; the values do, and the note says what the list breaks."""
    body = ("gradient = []\nfor i in range(len(x)):\n    step = np.zeros_like(x)\n    step[i] = h[i]\n"
            "    gradient.append((f(x - step) - f(x + step)) / (2.0 * h[i]))\nreturn gradient")
    kits.write_submission(layout, tmp_path, {"1.2.1": body}, others="reference")
    entry = next(entry for entry in grader.grade(tmp_path, todos=["1.2.1"])["todos"])
    expected = mistakes.read_wrong_solution(WRONG / "finite_diff_flipped_sign.txt")
    assert (entry.get("mistake") or {}).get("diagnosis") == expected.diagnosis, entry.get("mistake")
    assert entry["breaks_callers"].startswith("returns a list where the training code does arithmetic")


# Mistakes the issue names, with the points they keep: the credit follows what is right.
MISTAKES = {
    "score <= 0 gives action 1 (the tie)": ("1.1.1", "action = int(np.dot(self.params, obs) <= 0)", 0),
    "central difference over h, not 2h": ("1.2.1", "for i in range(len(x)):\n    step = np.zeros_like(x)\n"
                                          "    step[i] = h[i]\n    gradient[i] = (f(x + step) - f(x - step)) / h[i]", 0),
    "perturbs a vector filled with x_i, not x": ("1.2.1", "for i in range(len(x)):\n    point = np.full_like(x, x[i])\n"
                                                 "    step = np.zeros_like(x)\n    step[i] = h[i]\n"
                                                 "    gradient[i] = (f(point + step) - f(point - step)) / (2 * h[i])", 0),
    "one step h[0] for every coordinate": ("1.2.1", "for i in range(len(x)):\n    step = np.zeros_like(x)\n"
                                           "    step[i] = h[0]\n    gradient[i] = (f(x + step) - f(x - step)) / (2 * h[0])", 3),
    "one rollout only": ("1.3.1", "mean_reward = run_policy(policy, seed=seed)", 1),
    "unseeded episodes": ("1.3.1", "mean_reward = np.mean([run_policy(policy) for k in range(num_rollouts)])", 4),
    "records the reward before the update": ("1.3.2", "g = lambda p: eval_params(p, num_rollouts_per_eval, seed=eval_seed)\n"
                                             "rewards.append(g(params))\n"
                                             "params = params + learning_rate * scalar_finite_diff(g, params, fd_step)", 0),
    "a learning rate that does not converge in 7": ("1.3.3", "LEARNING_RATE = 1e-4", 0),
    "sigmoid that gives NaN far out": ("2.2.1", "values = np.exp(z) / (1 + np.exp(z))", 0.5),
    "predict_prob without the sigmoid": ("2.2.2", "X_aug = np.hstack([X, np.ones((len(X), 1))])\n"
                                         "probabilities = X_aug @ self.weights", 0),
    "mean gradient instead of the sum": ("2.2.3", "self.weights = self.weights + learning_rate * "
                                         "X_aug.T @ (y - sigmoid(X_aug @ self.weights)) / len(y)", 0),
    "two steps per class per iteration": ("2.3.1", "labels_c = (y == c).astype(int)\n"
                                          "self.classifiers[c].gradient_ascent_step(X, labels_c, learning_rate)\n"
                                          "self.classifiers[c].gradient_ascent_step(X, labels_c, learning_rate)", 0),
}


@pytest.mark.parametrize("mistake", list(MISTAKES))
def test_a_mistake_keeps_the_points_of_what_is_right_and_costs_nothing_elsewhere(grader, layout, tmp_path, mistake):
    todo, body, kept = MISTAKES[mistake]
    kits.write_submission(layout, tmp_path, {todo: body}, others="reference")
    result = grader.grade(tmp_path)
    assert points(result) == full_points() | {todo: kept}, render(result)


def test_the_class_sees_its_mistakes_beside_the_gradebook(grader, layout, tmp_path):
    """A class of three: one right, two with a forward difference in 1.2.1. Beside the gradebook:
    each check's pass rate and each named mistake's count, as a table and a bar chart."""
    from hwtools.grade.instructor import classroom

    forward = mistakes.read_wrong_solution(WRONG / "forward_difference.txt")
    for student, bodies in (("ada", {}), ("bob", {"1.2.1": list(forward.bodies)}), ("cy", {"1.2.1": list(forward.bodies)})):
        kits.write_submission(layout, tmp_path / "class" / student, bodies, others="reference")
    report = classroom.grade_class(tmp_path / "class", tmp_path / "out" / "grades.csv", tmp_path / "out" / "feedback",
                                   grader=grader, jobs=2)
    assert len(report.students) == 3
    import csv

    with open(tmp_path / "out" / "grades-checks.csv", newline="", encoding="utf-8") as handle:
        rows = {(row["kind"], row["id"]): row for row in csv.DictReader(handle)}
    equation3 = rows["check", "1.2.1/equation-3"]
    assert (equation3["students"], equation3["count"], equation3["share"]) == ("3", "1", "0.3333")
    assert rows["check", "2.2.1/values"]["count"] == "3"
    named = rows["mistake", "forward_difference"]
    assert (named["todo"], named["count"], named["what"]) == ("1.2.1", "2", forward.diagnosis)
    assert [key for key in rows if key[0] == "mistake"] == [("mistake", "forward_difference")]
    assert (tmp_path / "out" / "grades-checks.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# --------------------------------------------------------------------------------------------
# Correct solutions written another way: every point
# --------------------------------------------------------------------------------------------


# A correct solution of each TODO that calls another TODO's function (each one it could use): the
# call is answered by the reference server, and the solution earns every point.
CALLS_ANOTHER_TODO = {
    ("1.3.1", "1.1.1"): "first_action = policy(np.zeros(4))  # the policy acts: 1.1.1's __call__\n"
                        "mean_reward = np.mean([run_policy(policy, seed=seed + k) for k in range(num_rollouts)])",
    ("1.3.2", "1.1.1"): "g = lambda p: eval_params(p, num_rollouts_per_eval, seed=eval_seed)\n"
                        "params = params + learning_rate * scalar_finite_diff(g, params, fd_step)\n"
                        "assert CartPoleLinearPolicy(params)(np.zeros(4)) in (0, 1)\n"
                        "rewards.append(g(params))",
    ("1.3.2", "1.2.1"): "from hwlib.finite_diff import scalar_finite_diff as central\n"
                        "g = lambda p: eval_params(p, num_rollouts_per_eval, seed=eval_seed)\n"
                        "params = params + learning_rate * central(g, params, np.full(4, fd_step))\n"
                        "rewards.append(g(params))",
    ("1.3.2", "1.3.1"): "import hwlib\n"
                        "g = lambda p: hwlib.eval_params(p, num_rollouts=num_rollouts_per_eval, seed=eval_seed)\n"
                        "params = params + learning_rate * scalar_finite_diff(g, params, fd_step)\n"
                        "rewards.append(g(params))",
    ("2.1.1", "2.2.1"): "gradient = features_aug.T @ (labels - sigmoid(features_aug @ weights))",
    ("2.1.1", "2.2.2"): "model = TwoClassLogisticRegressionClassifier(features_aug.shape[1] - 1)\n"
                        "model.weights = weights\n"
                        "gradient = features_aug.T @ (labels - model.predict_prob(features_aug[:, :-1]))",
    ("2.2.2", "2.2.1"): "probabilities = sigmoid(np.hstack([X, np.ones((len(X), 1))]) @ self.weights)",
    ("2.2.3", "2.1.1"): "self.weights = self.weights + learning_rate * log_likelihood_gradient(self.weights, X, y)",
    ("2.2.3", "2.2.1"): "self.weights = self.weights + learning_rate * X_aug.T @ (y - sigmoid(X_aug @ self.weights))",
    ("2.2.3", "2.2.2"): "self.weights = self.weights + learning_rate * X_aug.T @ (y - self.predict_prob(X))",
    ("2.3.1", "2.1.1"): "w = self.classifiers[c].weights\n"
                        "self.classifiers[c].weights = w + learning_rate * log_likelihood_gradient(w, X, (y == c) * 1)",
    ("2.3.1", "2.2.1"): "labels = (y == c).astype(float)\nw = self.classifiers[c].weights\n"
                        "X1 = np.hstack([X, np.ones((len(X), 1))])\n"
                        "self.classifiers[c].weights = w + learning_rate * X1.T @ (labels - sigmoid(X1 @ w))",
    ("2.3.1", "2.2.2"): "labels = (y == c).astype(float)\nmodel = self.classifiers[c]\n"
                        "X1 = np.hstack([X, np.ones((len(X), 1))])\n"
                        "model.weights = model.weights + learning_rate * X1.T @ (labels - model.predict_prob(X))",
    ("2.3.1", "2.2.3"): "self.classifiers[c].fit(X, (y == c).astype(int), learning_rate, 1)",
}


@pytest.mark.parametrize("todo, other", list(CALLS_ANOTHER_TODO), ids=lambda value: str(value))
def test_a_correct_solution_that_calls_another_todos_function_earns_every_point(grader, layout, tmp_path, todo, other):
    kits.write_submission(layout, tmp_path, {todo: CALLS_ANOTHER_TODO[todo, other]}, others="reference")
    assert_the_other_todos_run_the_reference_kits(grader, layout, tmp_path, todo)
    result = grader.grade(tmp_path, todos=[todo])
    assert points(result) == {t: full for t, full in full_points().items() if t == todo}, render(result)
    entry = next(entry for entry in result["todos"] if entry["id"] == todo)
    assert all(check["passed"] for check in entry["checks"]), render(result)


def test_every_todo_has_a_solution_calling_each_earlier_todos_function_it_could_use():
    """The table above covers, for every graded TODO, each function of an earlier TODO its code
    could call (a served function whose result is not the TODO's own)."""
    usable = {"1.3.1": {"1.1.1"}, "1.3.2": {"1.1.1", "1.2.1", "1.3.1"}, "2.1.1": {"2.2.1", "2.2.2"},
              "2.2.2": {"2.2.1"}, "2.2.3": {"2.1.1", "2.2.1", "2.2.2"}, "2.3.1": {"2.1.1", "2.2.1", "2.2.2", "2.2.3"}}
    for todo, others in usable.items():
        assert {other for (t, other) in CALLS_ANOTHER_TODO if t == todo} == others, todo
        for other in others:  # and each of them is served to that TODO's run
            assert any(entry.todo == other for entry in served.plan(todo)[0].values()), (todo, other)


# --------------------------------------------------------------------------------------------
# Cheats: nothing earned, and the report names what it saw
# --------------------------------------------------------------------------------------------


def parse_cheat(path):
    text = path.read_text(encoding="utf-8").replace("CHANNEL", str(CHANNEL))
    header, *sections = re.split(r"^(# --- .*)$", text, flags=re.M)
    cheat = {"others": "stub", "expect": [], "bodies": {}, "files": {}, "prepend": {}, "links": [], "hardcode": [],
             "keeps": []}
    for key, value in re.findall(r"^# (\w+):[ \t]*(.*)$", header, flags=re.M):
        if key == "points":
            raise ValueError(f"{path.name}: '# points:' states an absolute score; say what it keeps of its TODO (# keeps:)")
        if key == "keeps":
            cheat["keeps"] = value.split()
        elif key == "others":
            cheat["others"] = value.strip()
        elif key == "expect":
            cheat["expect"].append(value.strip())
        elif key == "cheat":
            cheat["what"] = value.strip()
        elif key == "loses":
            cheat["loses"] = value.split()
    for marker, content in zip(sections[::2], sections[1::2]):
        kind, _, target = marker[len("# --- "):].partition(" ")
        content = content.strip("\n")
        if kind == "todo":
            cheat["bodies"][target.strip()] = content
        elif kind == "file":
            cheat["files"][target.strip()] = content + "\n"
        elif kind == "prepend":
            cheat["prepend"][target.strip()] = content + "\n"
        elif kind == "link":
            cheat["links"].append(target.strip())
        elif kind == "hardcode":
            cheat["hardcode"].append(target.strip())
    cheat.setdefault("loses", list(cheat["bodies"]))  # the TODOs whose points it may cost (default: its own)
    cheat["points"] = cheat_points(cheat, path.name)
    return cheat


def cheat_points(cheat, name):
    """What a cheat must earn, from the TODO table: with ``others: reference`` every TODO it may not
    cost keeps its points; each TODO it may cost keeps only its checks named in ``# keeps:``."""
    costly = {f"{todo}/{key}": points for todo in cheat["loses"] for key, points in TODO_BY_ID[todo].checks}
    unknown = sorted(set(cheat["keeps"]) - set(costly))
    if unknown:
        raise ValueError(f"{name}: keeps {', '.join(unknown)}, not a check of a TODO it may cost ({', '.join(costly)})")
    others = sum(todo.auto for todo in TODO_BY_ID.values() if todo.id not in cheat["loses"]) if cheat["others"] == "reference" else 0
    return others + sum(costly[check] for check in cheat["keeps"])


def hardcoded_body(todo, key):
    """Code that answers the visible inputs of ``todo`` from their expected values, and nothing else."""
    table = {}
    for case_id, behaviour, args in checks.case_set(todo).visible:
        if case_id not in key["expected"]:
            continue
        values = key["expected"][case_id]
        if todo == "2.2.1":
            table[np.asarray(args["z"], dtype=np.float64).tobytes()] = values["values"].tolist()
        elif todo == "1.2.1":
            table[np.atleast_1d(np.asarray(args["x"], dtype=np.float64)).tobytes()] = \
                np.atleast_1d(values["gradient"]).tolist()
        elif todo == "1.1.1":
            for params, obs, act in zip(args["params"], args["obs"], values["actions"]):
                table[np.concatenate([params, obs]).tobytes()] = int(act)
    if todo == "2.2.1":
        return (f"answers = {table!r}\nkey = np.asarray(z, dtype=np.float64).tobytes()\n"
                "values = np.array(answers[key]).reshape(z.shape) if key in answers else np.zeros_like(z)")
    if todo == "1.2.1":
        return (f"answers = {table!r}\nkey = x.tobytes()\n"
                "if key in answers:\n    gradient = np.array(answers[key])")
    return f"answers = {table!r}\naction = answers.get(np.concatenate([self.params, obs]).tobytes(), 0)"


@pytest.fixture(scope="module")
def answer_key(tmp_path_factory):
    from hwtools.grade.grader import read_answer_key

    return read_answer_key(editions.answer_key_file(tmp_path_factory))


def build_cheat(layout, cheat, folder, answer_key):
    bodies = dict(cheat["bodies"])
    for todo in cheat["hardcode"]:
        bodies[todo] = hardcoded_body(todo, answer_key)
    kits.write_submission(layout, folder, bodies, others=cheat["others"])
    for relative, content in cheat["prepend"].items():
        target = folder / relative
        target.write_text(content + target.read_text(encoding="utf-8"), encoding="utf-8")
    for relative, content in cheat["files"].items():
        target = folder / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(content, encoding="utf-8")
    for relative in cheat["links"]:
        target = folder / relative
        target.unlink()
        target.symlink_to(KIT / relative)


CHEAT_FILES = sorted(CHEATS.glob("*.txt"))


@pytest.mark.offering
def test_a_cheat_states_what_it_keeps_of_its_todo_not_a_score(tmp_path):
    """What a cheat must earn follows from the TODO table, so a next offering's points change it too."""
    points = {path.stem: parse_cheat(path)["points"] for path in CHEATS.rglob("*.txt")}
    assert points["unseeded_flags"] == AUTO_POINTS - TODO_BY_ID["1.3.1"].check_points["repeatable"]
    assert points["tmp_relay"] == AUTO_POINTS and points["endless_loop"] == AUTO_POINTS - TODO_BY_ID["2.2.1"].auto
    assert points["holdback_hidden"] == 0  # others: stub
    for header, said in (("# points: 37\n# others: reference\n", "absolute score"), ("# keeps: 2.2.2/with-bias\n", "not a check")):
        (tmp_path / "cheat.txt").write_text(f"# cheat: x\n{header}# --- todo 2.2.1\nvalues = z\n", encoding="utf-8")
        with pytest.raises(ValueError, match=said):
            parse_cheat(tmp_path / "cheat.txt")


def test_there_are_at_least_ten_cheats():
    assert len(CHEAT_FILES) >= 10


def descendants(roots):
    """``roots`` and every process below them."""
    parents = {}
    for entry in Path("/proc").iterdir():
        try:
            parents[int(entry.name)] = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (ValueError, OSError, IndexError):
            continue
    found, grown = set(roots), True
    while grown:
        grown = {pid for pid, parent in parents.items() if parent in found} - found
        found |= grown
    return found


def worker_processes(settle=3.0):
    """The processes of this test run running the grader's worker (a student's run, a reference
    server, or a grading's zygote with the runs it forks) that are still alive (zombies excluded), after giving killed ones up to ``settle``
    seconds to go. Only this process's own tree counts (other test runs and graders may share the
    machine; in bubblewrap a process that leaves its session stays in the sandbox's tree)."""
    alive = live_processes(lambda cmdline: (b"worker.py" in cmdline or b"zygote.py" in cmdline) and
                           (b"/grader/" in cmdline or b"hwgrade-" in cmdline), settle)
    return alive & descendants({os.getpid()})


@pytest.mark.parametrize("path", CHEAT_FILES, ids=lambda path: path.stem)
def test_cheat_earns_nothing_it_should_not(request, layout, tmp_path, path, answer_key, secrets):
    cheat = parse_cheat(path)
    build_cheat(layout, cheat, tmp_path, answer_key)
    grader = request.getfixturevalue("short_grader" if path.stem in RUN_TO_THE_LIMIT else "grader")
    before = worker_processes(settle=0)
    result = grader.grade(tmp_path)
    grader.close()  # its reference servers live on between submissions until then
    assert result["total"]["auto_earned"] == cheat["points"], render(result)
    report = text_of(result)
    for expected in cheat["expect"]:
        assert expected in report, f"the report does not say {expected!r}:\n{render(result)}"
    assert worker_processes() <= before, "a process of the run (or a reference server) outlived it"
    if cheat["others"] == "reference":  # the cheat may cost only its own TODO
        lost = [todo for todo, value in points(result).items() if value < TODO_BY_ID[todo].auto]
        assert lost == cheat["loses"], render(result)
    for entry in result["todos"]:
        if entry["first_failure"] and entry["first_failure"]["hidden"]:
            assert set(entry["first_failure"]) == {"check", "short", "hidden", "input"}  # the check in full and in one line: its public words
        if entry["id"] in cheat["hardcode"]:  # right on every visible input, wrong on the hidden ones
            assert all(check["failed_on"] == "hidden" for check in entry["checks"]), entry
    leak_search.assert_nothing_leaks(result, secrets)
    # and its own hidden inputs (drawn from its grading's secret)
    leak_search.assert_nothing_leaks(result, leak_search.secrets_of(grader, layout, grader.case_sets(result["secret"])))


def test_an_answer_that_would_inflate_is_refused_unread(layout, tmp_path, answer_key):
    """The zip-bomb cheat, graded in a fresh process: its peak memory stays far below the 300 MB
    the answer would inflate to (nothing is decompressed, no array is made from a header's shape)."""
    build_cheat(layout, parse_cheat(CHEATS / "zip_bomb.txt"), tmp_path / "kit", answer_key)
    code = ("import json, sys; from hwtools.grade import Grader; "
            f"result = Grader({str(KIT)!r}, time_limit={TIME_LIMIT}).grade({str(tmp_path / 'kit')!r}, todos=['2.2.1']); "
            "peak = [line.split()[1] for line in open('/proc/self/status') if line.startswith('VmHWM:')][0]; "
            "print(json.dumps([result['todos'][0]['status'], int(peak)]))")  # VmHWM: this image's peak (ru_maxrss keeps the parent's)
    run = subprocess.run([sys.executable, "-c", code], cwd=KIT, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    status, peak_kib = json.loads(run.stdout.strip().splitlines()[-1])
    assert status == "crashed" and peak_kib < 200 * 1024, (status, peak_kib)


# --------------------------------------------------------------------------------------------
# The leak search: every output, decoded as a cheat would encode it
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def secrets(grader, layout):
    return leak_search.secrets_of(grader, layout)


def test_the_leak_search_finds_what_it_looks_for(grader, secrets):
    """The search must be able to fail: a reference line and a hidden input, compressed and encoded."""
    line, (_, _, args) = secrets["lines"][0], grader.cases["1.2.1"].hidden[0]
    for planted in (base64.b64encode(zlib.compress(line.encode())).decode()[:60],
                    zlib.compress(repr(args).encode()).hex(),
                    base64.b64encode(np.asarray(args["x"], dtype=np.float64).tobytes()).decode()):
        entry = {"id": "2.2.1", "title": "sigmoid", "auto_earned": 0, "auto_possible": 2, "manual_possible": 0,
                 "manual": "", "code": "", "status": "graded", "checks": [], "first_failure": None,
                 "notes": [f"warning (not a failure): UserWarning: {planted}"]}
        fake = {"notes": [], "todos": [entry], "isolated": True,
                "isolation": "", "submission": "s", "reference": "r", "one_mistake_one_place": True,
                "total": {"auto_earned": 0, "auto_possible": AUTO_POINTS, "manual_possible": 21}}
        with pytest.raises(AssertionError, match="reached an output"):
            leak_search.assert_nothing_leaks(fake, secrets)


# --------------------------------------------------------------------------------------------
# Feedback: actionable, leaking nothing
# --------------------------------------------------------------------------------------------


def test_feedback_shows_visible_failures_and_never_a_hidden_input(grader, layout, tmp_path):
    forward = "for i in range(len(x)):\n    step = np.zeros_like(x)\n    step[i] = h[i]\n" \
              "    gradient[i] = (f(x + step) - f(x)) / h[i]"
    kits.write_submission(layout, tmp_path, {"1.2.1": forward}, others="reference")
    result = grader.grade(tmp_path)
    entry = next(entry for entry in result["todos"] if entry["id"] == "1.2.1")
    assert entry["auto_earned"] == 0
    assert entry["first_failure"]["hidden"] is False and "x=" in entry["first_failure"]["input"]
    report = render(result)
    for case_id, _, args in grader.case_sets(result["secret"])["1.2.1"].hidden:  # its own hidden inputs
        assert show(args["x"]) not in report, case_id
    for line in grader._scrub.lines:
        assert line not in report


def test_no_kit_a_student_run_gets_holds_reference_code_and_the_server_kit_holds_it_all(grader, layout, tmp_path):
    """Of an untouched student edition: no kit holds a line of any solution. Of a kit whose every block
    is the reference's: the kit of a TODO holds no line of another TODO's block, so no TODO's grade runs
    another TODO's code, the student's or the reference's (the other TODOs' calls go to the server)."""
    reference = layout.reference_bodies()
    solution_lines = {todo: {line.strip() for body in bodies for line in body
                             if len(line.strip()) > 12 and not line.strip().startswith("#")}
                      for todo, bodies in reference.items()}
    for others in ("stub", "reference"):
        kits.write_submission(layout, tmp_path / others, others=others)
        read = blocks.read_submission(tmp_path / others, layout)
        for todo in checks.GRADED_TODOS:
            files = grader._composite(todo, read, layout)  # what the grader writes for the student's run of todo
            assert "_hwgrade/runtime.py" in files
            text = "\n".join(files.values())
            own = solution_lines[todo] if others == "reference" else set()  # its own block: the student's code
            for other, lines in solution_lines.items():
                shown = {line for line in lines - own if line in text}
                assert not shown, f"the kit of {todo} ({others} elsewhere) shows the block of {other}: {shown}"
            if "hwlib/settings.py" in files and todo != "1.3.3":  # the learning rate (1.3.3's answer) is in no other kit
                assert "LEARNING_RATE = None" in files["hwlib/settings.py"]
    server = "\n".join(grader.pool.files.values())  # the reference server's kit: every solution but 1.3.3's
    for other, lines in solution_lines.items():
        assert (lines <= {line for line in lines if line in server}) == (other != "1.3.3"), other


def test_each_check_is_served_the_functions_it_calls_and_none_that_compute_its_own_result():
    for todo in checks.GRADED_TODOS:
        allowed, refused = served.plan(todo)
        for entry in served.SERVED:
            if entry.name in allowed:
                assert todo not in entry.uses and entry.todo != todo, (todo, entry.name)
            else:
                assert todo in entry.uses or entry.todo == todo, (todo, entry.name)
            if entry.todo is not None and entry.todo != todo and todo in entry.uses:
                assert entry.name in refused and f"TODO {todo}" in refused[entry.name]
        for need in checks.NEEDS[todo]:
            assert any(entry.todo == need for entry in allowed.values()), (todo, need)
    assert "log_likelihood_gradient" not in served.plan("2.2.1")[0]  # it computes sigmoid
    assert "one_vs_rest_fit" not in served.plan("2.2.3")[0] and "run_policy" not in served.plan("1.1.1")[0]
    assert {"predict_prob", "log_likelihood_gradient", "sigmoid"} <= set(served.plan("2.2.3")[0])


def test_report_names_an_unisolated_run_on_its_first_line(tmp_path, layout):
    unisolated = Grader(KIT, isolation="none", time_limit=TIME_LIMIT)
    kits.write_submission(layout, tmp_path, others="reference")
    result = unisolated.grade(tmp_path, todos=["2.2.1"])
    assert render(result).startswith("NOT ISOLATED: ")
    assert points(result) == {"2.2.1": 2}


def test_a_block_that_does_not_parse_costs_only_its_todo(grader, layout, tmp_path):
    swallow = 'values = 1 / (1 + np.exp(-z))\n"""'  # an open string would swallow the kit's code after the block
    kits.write_submission(layout, tmp_path, {"2.2.1": swallow}, others="reference")
    result = grader.grade(tmp_path)
    assert points(result) == full_points() | {"2.2.1": 0}
    entry = next(entry for entry in result["todos"] if entry["id"] == "2.2.1")
    assert entry["status"] == "not graded" and "does not parse" in entry["notes"][0]
    assert "(line 2 of your block) opens a string that the block never closes" in entry["notes"][0]


# Issue 40.1: a block is judged in its place in its file, as Python runs it. What is valid where it sits
# is valid (a break or continue in the loop around it, a return in its function, a nonlocal of that
# function); what does not parse there is named by its line in the student's file and in the block; a
# bracket, string or line continuation the block leaves open is named by the line that opens it.
IN_PLACE = [
    ("1.3.2", "g = lambda p: eval_params(p, num_rollouts_per_eval, seed=eval_seed)\n"
              "if not np.all(np.isfinite(params)):\n    break\nparams = params + learning_rate * "
              "scalar_finite_diff(g, params, fd_step)\nrewards.append(g(params))", None, None),
    ("1.3.2", "def update():\n    nonlocal params\n    params = params + 0.0\nupdate()\nrewards.append(0.0)", None, None),
    ("2.3.1", "if c < 0:\n    continue\nself.classifiers[c].gradient_ascent_step(X, (y == c) * 1, learning_rate)",
     None, None),
    ("1.3.1", "return float(np.mean([run_policy(policy, seed=seed + k) for k in range(num_rollouts)]))", None, None),
    ("2.2.1", "values = np.exp(-np.logaddexp(0, -z))\nbreak", 2, "'break' outside loop"),
    ("1.3.3", "return 0.001", 1, "'return' outside function"),
    ("1.3.2", "def update():\n    nonlocal theta\n    return 0\nrewards.append(update())", 2,
     "no binding for nonlocal 'theta' found"),
    ("2.2.1", "if z.ndim:", 1, "expected an indented block after 'if' statement on line 1 of your block"),
    ("1.3.2", "g = lambda p: eval_params(p,\n    num_rollouts_per_eval, seed=eval_seed\nparams = params", 1,
     "opens a bracket '(' that the block never closes"),
    ("2.2.2", "X_aug = np.hstack([X, np.ones((len(X), 1))])\nprobabilities = X_aug @ \\", 2,
     "opens a line continuation (a backslash at its end) that the block never closes"),
    ("2.2.1", "values = 1 / (1 + np.exp(-z))\nnote = \'\'\'unfinished", 2, "opens a string that the block never closes"),
    ("1.3.3", "LEARNING_RATE = float(\n    0.001", 1, "opens a bracket '(' that the block never closes"),
]


@pytest.mark.quick
@pytest.mark.parametrize("todo, body, line, said", IN_PLACE, ids=lambda value: str(value)[:30])
def test_a_block_is_judged_in_its_place_and_named_by_its_line(layout, tmp_path, todo, body, line, said):
    kits.write_submission(layout, tmp_path, {todo: body}, others="reference")
    read = blocks.read_submission(tmp_path, layout)
    problem = kits.placement_problem(layout, todo, read.bodies[todo], read.places[todo])
    if said is None:
        assert problem is None
        return
    relative, (begin,) = read.places[todo]
    assert problem.startswith(f"{relative} line {begin + 1 + line} (line {line} of your block)"), problem
    assert said in problem, problem
    file_line = (tmp_path / relative).read_text(encoding="utf-8").split("\n")[begin + line]
    assert file_line.strip() == body.split("\n")[line - 1].strip()  # the line it names is that line of the file


def test_answer_key_grades_the_visible_checks_of_a_student_edition(answer_key, layout, tmp_path, tmp_path_factory):
    key_file = tmp_path / "key.json"
    from hwtools.grade.answer_key import ANSWER_KEY_VERSION

    key_file.write_text(json.dumps({"version": ANSWER_KEY_VERSION, "visible_cases": "stale", "expected": {}}))
    with pytest.raises(Exception, match="other visible checks"):
        Grader(None, answer_key=key_file)
    good = editions.answer_key_file(tmp_path_factory)  # write_answer_key(KIT, ...), once per test run
    text = good.read_text()
    assert "/h0" not in text  # visible inputs only
    student = Grader(None, answer_key=good, time_limit=TIME_LIMIT)
    kits.write_submission(layout, tmp_path / "kit", others="reference")
    result = student.grade(tmp_path / "kit", todos=["1.1.1", "2.2.1", "2.2.3"])
    assert points(result) == {"1.1.1": 2, "2.2.1": 2, "2.2.3": 5}
    assert result["one_mistake_one_place"] is False
    # issue 40.4: the preview opens with what it is, whatever sandbox it found (never "NOT ISOLATED" and a module name)
    for isolated in (True, False):
        report = render({**result, "isolated": isolated, "isolation": "No module named 'hwtools.grade.instructor'"})
        assert report.startswith("Preview of the visible checks, running your code on this computer"), report[:200]
        assert "NOT ISOLATED" not in report and ("hwtools.grade.instructor" in report) == isolated


def test_command_line_help_needs_no_homework_packages():
    code = ("import sys; sys.modules['gymnasium'] = None; sys.modules['hwlib'] = None; "
            "sys.argv = ['hwtools.grade', '--help']; import runpy; runpy.run_module('hwtools.grade', run_name='__main__')")
    result = subprocess.run([sys.executable, "-c", code], cwd=KIT, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert "--reference" in result.stdout and "--json" in result.stdout and "--todo" in result.stdout


def test_a_grader_s_idle_zygote_ends_with_it():
    """A grading's zygote waits idle for the grader's next grading; it ends with the grader (at the
    latest when the grading process exits), its processes and control groups gone, not left to
    bubblewrap's --die-with-parent, which removes no control group."""
    import gc  # noqa: PLC0415

    grader = Grader(KIT, isolation="auto", time_limit=TIME_LIMIT)
    if grader.zygotes is None:
        pytest.skip(f"no bubblewrap here: {grader.sandbox.how}")
    budget = grader._grading(grader.budget, grader.layout)
    budget.close()  # the grading is over: its zygote waits idle
    zygote = budget.zygote
    del grader, budget
    gc.collect()
    assert zygote.process.process.poll() is not None, "an idle zygote outlived its grader"
    assert zygote.group is None or not any(folder.exists() for folder in zygote.group.folders)


def test_command_line_grades_one_todo_to_json(tmp_path):
    out = tmp_path / "result.json"
    result = subprocess.run([sys.executable, "-m", "hwtools.grade", str(KIT), "--todo", "2.2.2", "--json", str(out),
                             "--brief"], cwd=KIT, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    data = json.loads(out.read_text())
    assert [entry["id"] for entry in data["todos"]] == ["2.2.2"] and data["total"]["auto_earned"] == 3
    assert "2.2.2" in result.stdout


def test_a_kit_of_some_files_holds_the_kit_modules_they_import(tmp_path):
    """A TODO checked on some files only (1.3.3: hwlib/settings.py) gets the kit's modules those
    import, as hwlib/_todo.py once the stubs' module imports TodoNotDone."""
    shutil.copytree(KIT / "hwlib", tmp_path / "hwlib", ignore=shutil.ignore_patterns("__pycache__"))
    (tmp_path / "hwlib" / "_todo.py").write_text("class TodoNotDone(NotImplementedError):\n    pass\n")
    settings = tmp_path / "hwlib" / "settings.py"
    settings.write_text("from hwlib._todo import TodoNotDone  # noqa: F401\n" + settings.read_text())
    files = kits.composite_files(blocks.load_layout(tmp_path), {}, set(), only=checks.SETTINGS_ONLY["1.3.3"])
    assert set(files) == {"hwlib/__init__.py", "hwlib/settings.py", "hwlib/_todo.py"}
    assert files["hwlib/__init__.py"] == ""  # a package's own __init__ is left out, as before


def test_the_preview_of_a_kit_without_a_todo_s_markers_says_it_is_not_graded(answer_key, layout, tmp_path,
                                                                             tmp_path_factory):
    """The student edition's preview reads the student's own kit: a TODO whose markers were deleted
    has no block there, and is "not graded" with the reason (not a KeyError); the others are graded."""
    key = editions.answer_key_file(tmp_path_factory)
    kits.write_submission(layout, tmp_path / "kit", others="reference")
    logreg = tmp_path / "kit" / "hwlib" / "logreg.py"
    logreg.write_text("\n".join(line for line in logreg.read_text().split("\n")
                                if not re.match(r"\s*### (BEGIN|END) TODO 2\.2\.1\s*$", line)))
    result = Grader(None, answer_key=key, time_limit=TIME_LIMIT).grade(tmp_path / "kit", todos=["2.2.1", "2.2.2"])
    entry = next(entry for entry in result["todos"] if entry["id"] == "2.2.1")
    assert entry["status"] == "not graded" and "markers '### BEGIN TODO 2.2.1'" in entry["notes"][0], entry
    assert points(result) == {"2.2.1": 0, "2.2.2": 3}
