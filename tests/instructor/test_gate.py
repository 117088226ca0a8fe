"""The release gate (issue 41.2, ``instructor/gate.py``): the student edition, the Gradescope bundle and
the class run refuse a kit that is not ready, with one message naming each problem and before they write
anything; a known mistake that no longer loses points and an answer key older than the known mistakes
are found. The variant offering of ``test_variant.py`` meets the known-mistake refusal for real."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from hwtools.grade import answer_key, checks, mistakes
from hwtools.todos import TODO_BY_ID
from instructor import gate
from instructor.kit import kit_files

KIT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def kit(tmp_path_factory):
    """A copy of this kit (its files as the release sees them)."""
    kit = tmp_path_factory.mktemp("gate") / "kit"
    for name in kit_files(KIT):
        (kit / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(KIT / name, kit / name)
    return kit


def _run(kit, *args):
    env = {name: value for name, value in os.environ.items() if not name.startswith("PYTEST_")}
    return subprocess.run([sys.executable, *args], cwd=kit, capture_output=True, text=True, timeout=240,
                          env={**env, "PYTHONPATH": str(kit), "MPLBACKEND": "Agg"})


@pytest.mark.quick
@pytest.mark.offering
def test_a_known_mistake_that_fails_no_check_with_points_is_named():
    todo = TODO_BY_ID["1.2.1"]
    (first, _), (second, _) = todo.checks[:2]
    table = [{"id": "fails_first", "todo": "1.2.1", "failing": [first]},
             {"id": "fails_nothing", "todo": "1.2.1", "failing": []},
             {"id": "fails_a_check_without_points", "todo": "2.1.1", "failing": [TODO_BY_ID["2.1.1"].checks[0][0]]},
             {"id": "fails_second", "todo": "1.2.1", "failing": [second]}]
    found = gate.mistakes_losing_nothing(table)
    assert [problem.split()[2] for problem in found] == ["fails_nothing", "fails_a_check_without_points"]
    assert "instructor/wrong_solutions/fails_nothing.txt" in found[0] and "no longer loses points" in found[0]


@pytest.mark.quick
@pytest.mark.offering
def test_an_answer_key_older_than_the_known_mistakes_is_found(tmp_path):
    kit = KIT
    wrong = mistakes.read_wrong_solutions(kit / mistakes.WRONG_SOLUTIONS)
    cases = {todo: checks.case_set(todo) for todo in checks.GRADED_TODOS}
    key = tmp_path / "answer_key.json"
    answer_key.write({}, cases, key, sources=wrong)
    assert gate.stale_keys(kit, [key]) == []
    answer_key.write({}, cases, key, sources=wrong[1:])  # written before the first known mistake was added
    (stale,) = gate.stale_keys(kit, [key])
    assert f"known mistake(s) {wrong[0].id} newer than the answer key" in stale and "rebuild" in stale
    data = json.loads(key.read_text(encoding="utf-8"))
    data["known_mistakes"][wrong[0].id] = "0" * 16  # ... or with another text of it
    data["visible_cases"] = "other"
    key.write_text(json.dumps(data), encoding="utf-8")
    changed, other_checks = gate.stale_keys(kit, [key])
    assert f"{wrong[0].id} changed since it" in changed and "other visible checks" in other_checks
    del data["known_mistakes"]  # a key from before the keys recorded them
    key.write_text(json.dumps(data), encoding="utf-8")
    assert "older than the known mistakes" in gate.stale_keys(kit, [key])[0]


def test_the_keys_looked_at_are_the_kits_and_its_built_editions_but_the_one_being_replaced(kit):
    built = kit / "build" / "student" / gate.ANSWER_KEY
    built.parent.mkdir(parents=True)
    built.write_text("{}", encoding="utf-8")
    try:
        assert gate.answer_keys(kit) == [built]
        assert gate.answer_keys(kit, skip=kit / "build" / "student") == []
    finally:
        shutil.rmtree(kit / "build")


def test_every_release_and_the_class_run_refuse_a_stale_fact_with_one_message_and_write_nothing(kit, tmp_path):
    settings = kit / "hwlib/settings.py"
    kept = settings.read_text(encoding="utf-8")
    settings.write_text(kept.replace("\nMAX_EPISODE_STEPS = ", "\nMAX_EPISODE_STEPS = 1 + "), encoding="utf-8")
    (tmp_path / "submissions").mkdir()
    try:
        for what, args, out in (
                ("the student edition", ["-m", "instructor.release", "student", str(tmp_path / "edition")], tmp_path / "edition"),
                ("the Gradescope bundle", ["-m", "instructor.release", "gradescope", str(tmp_path / "b.zip")], tmp_path / "b.zip"),
                ("the class run", ["-m", "hwtools.grade", str(tmp_path / "submissions"), "--gradebook",
                                   str(tmp_path / "grades.csv"), "--feedback", str(tmp_path / "feedback")], tmp_path / "grades.csv")):
            done = _run(kit, *args)
            assert done.returncode in (1, 2) and "Traceback" not in done.stderr, done.stderr
            assert done.stderr.startswith(f"error: {what} refused: ") and "hwlib/settings.py: out of date" in done.stderr
            assert not out.exists() and not (tmp_path / "feedback").exists()
    finally:
        settings.write_text(kept, encoding="utf-8")


def test_the_release_check_names_every_problem_it_finds(kit):
    """``python -m instructor.release check``: here a points table off by one point (the grader, which
    would run every known mistake, refuses such a table: it is not started) and a stale fact."""
    table = kit / "hwlib/machinery/todos.py"
    kept = table.read_text(encoding="utf-8")
    check, points = TODO_BY_ID["1.2.1"].checks[0]
    table.write_text(kept.replace(f'("{check}", {points:g})', f'("{check}", {points + 1:g})'), encoding="utf-8")
    try:
        done = _run(kit, "-m", "instructor.release", "check")
    finally:
        table.write_text(kept, encoding="utf-8")
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.startswith("error: the release refused: 2 problem(s)")
    assert "docs/grading.md: out of date" in done.stderr and "points table: TODO 1.2.1: its checks add up to" in done.stderr
