"""A next offering keeps the kit green (issues 31.3, 41.1), proven on a variant: a copy of the kit changed
in the one place only (``make_variant``: the TODO table gives 1.2.1 two points more, on its first check;
the hidden checks one more hidden input for it and another seed; the settings cap episodes at 200), its
facts written by ``python -m instructor.facts``, as docs/instructor.md's term steps say. Then:

* the release re-runs every known mistake under the new facts and refuses, naming each that no longer
  loses points (from this kit's cap to 200 steps: ``learning_rate_too_large``, whose rate then
  converges), before writing anything; each it names earns every point of its TODO in the variant's
  grade; the instructor deletes them, and the student edition is built;
* the variant's reference earns every point, a known mistake of 1.2.1 keeps <= 30%;
* the kit's offering-dependent tests (``-m offering``: the tests that read the facts, chosen cheap)
  pass in the variant as they pass here. The README's test command runs this file, so CI proves a
  next offering every time.
"""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from hwtools.grade import checks
from hwtools.grade.grader import load_hidden_checks
from hwtools.todos import TODO_BY_ID
from instructor.facts import Facts
from instructor.kit import kit_files

KIT = Path(__file__).resolve().parents[2]
NOW = Facts(KIT)
pytestmark = pytest.mark.timeout(900)


def _edit(path, pattern, make):
    """Replace the one match of ``pattern`` (a regular expression, multi-line) in ``path`` by ``make(match)``."""
    text, count = re.subn(pattern, make, path.read_text(encoding="utf-8"), flags=re.M)
    assert count == 1, f"{path}: {pattern!r} found {count} times"
    path.write_text(text, encoding="utf-8")


def make_variant(kit):
    """Copy this kit to ``kit`` and change it in the one place: returns (its 1.2.1 points, its cap)."""
    for name in kit_files(KIT):
        (kit / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(KIT / name, kit / name)
    todo = TODO_BY_ID["1.2.1"]
    check, points = todo.checks[0]
    _edit(kit / "hwlib/machinery/todos.py", r'(Todo\("1\.2\.1", "[^"]*", )[\d.]+,', lambda m: f"{m[1]}{todo.auto + 2:g},")
    _edit(kit / "hwlib/machinery/todos.py", rf'\("{check}", [\d.]+\)', f'("{check}", {points + 2:g})')
    _edit(kit / "instructor/hidden_checks/__init__.py", rf'("1\.2\.1/{check}": )(\d+)', lambda m: f"{m[1]}{int(m[2]) + 1}")
    _edit(kit / "instructor/hidden_checks/__init__.py", r"^(HIDDEN_SEED = )(\S+)", lambda m: f"{m[1]}{int(m[2], 0) ^ 0x1234_5678:#x}")
    cap = 200 if NOW.cap != 200 else 500
    _edit(kit / "hwlib/settings.py", r"^MAX_EPISODE_STEPS = \d+$", f"MAX_EPISODE_STEPS = {cap}")
    return todo.auto + 2, cap


def _run(args, kit, timeout, ok=True):
    """``python args`` in ``kit`` with ``kit`` first on the path (its own hwlib, hwtools, instructor)."""
    env = {name: value for name, value in os.environ.items() if not name.startswith(("PYTEST_", "COV_"))}
    done = subprocess.run([sys.executable, *args], cwd=kit, capture_output=True, text=True, timeout=timeout,
                          env={**env, "PYTHONPATH": str(kit), "MPLBACKEND": "Agg"})
    if ok:
        assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done


GRADE = r"""
import json, sys
from pathlib import Path
from hwtools.grade import Grader, blocks, kits, mistakes
import hwtools
assert hwtools.__file__.startswith(sys.argv[1]), hwtools.__file__
kit, out, check, named = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3], sys.argv[4:]
layout = blocks.load_layout(kit)
with Grader(kit, jobs=2) as grader:
    cases = grader.cases["1.2.1"]
    hidden = sum(1 for case_id, *_ in cases.hidden if case_id.startswith(f"1.2.1/{check}/"))
    reference = grader.grade(kit)
    graded = {}
    for name in ["finite_diff_half_steps", *named]:
        wrong = mistakes.read_wrong_solution(out / "known" / f"{name}.txt")
        kits.write_submission(layout, out / name, {wrong.todo: list(wrong.bodies)}, others="reference")
        graded[name] = grader.grade(out / name, todos=[wrong.todo])["todos"][0]
print(json.dumps({"hidden": hidden, "reference": reference, "graded": graded}))
"""


def test_a_next_offering_changed_in_the_one_place_keeps_the_kit_green(tmp_path):
    kit = tmp_path / "variant"
    finite_diff_points, cap = make_variant(kit)
    check = TODO_BY_ID["1.2.1"].checks[0][0]
    assert "rewrote: notebooks/p1_cartpole_finite_difference.ipynb" in _run(["-m", "instructor.facts"], kit, 120).stdout
    _run(["-m", "instructor.facts", "--check"], kit, 120)

    # The release re-runs every known mistake under the new facts: one that no longer loses points stops it.
    edition = tmp_path / "student"
    refused = _run(["-m", "instructor.release", "student", str(edition)], kit, 600, ok=False)
    named = re.findall(r"known mistake (\S+) \(TODO [\d.]+, instructor/wrong_solutions/\1\.txt\) no longer loses points",
                       refused.stderr)
    assert "Traceback" not in refused.stderr and edition.exists() == (refused.returncode == 0)  # refused: nothing written
    assert (refused.returncode == 1) == bool(named), refused.stdout[-2000:] + refused.stderr[-3000:]
    shutil.rmtree(edition, ignore_errors=True)  # built where no mistake was named: built again below
    (tmp_path / "out" / "known").mkdir(parents=True)
    for name in named:  # the instructor deletes them (kept aside to be graded below)
        (kit / "instructor/wrong_solutions" / f"{name}.txt").rename(tmp_path / "out" / "known" / f"{name}.txt")
    shutil.copy(KIT / "instructor/wrong_solutions/finite_diff_half_steps.txt", tmp_path / "out" / "known")
    _run(["-m", "instructor.release", "student", str(edition), "--no-answer-key"], kit, 600)
    notebook = (edition / "notebooks/p1_cartpole_finite_difference.ipynb").read_text(encoding="utf-8")
    old = NOW.total("1.2.1")
    assert f"({finite_diff_points:g} pts)" in notebook and f"or {cap} steps pass" in notebook and f"({old:g} pts)" not in notebook
    assert f"\nMAX_EPISODE_STEPS = {cap}\n" in (edition / "hwlib/settings.py").read_text(encoding="utf-8")
    assert not (edition / "instructor").exists()

    # The variant's reference earns every point; a known mistake keeps <= 30%; each mistake the release named
    # earns every point of its TODO under the new facts (the refusal was right).
    result = json.loads(_run(["-c", GRADE, str(kit), str(tmp_path / "out"), check, *named], kit, 800).stdout)
    here = checks.case_set("1.2.1", load_hidden_checks(KIT)).hidden
    assert result["hidden"] == sum(1 for case_id, *_ in here if case_id.startswith(f"1.2.1/{check}/")) + 1  # one more
    reference, auto = result["reference"], NOW.auto + 2
    assert reference["total"]["auto_possible"] == auto and reference["total"]["auto_earned"] == auto, \
        [(todo["id"], todo["auto_earned"], todo["auto_possible"], todo["first_failure"]) for todo in reference["todos"]]
    finite_diff = next(todo for todo in reference["todos"] if todo["id"] == "1.2.1")
    assert finite_diff["auto_possible"] == finite_diff["auto_earned"] == finite_diff_points
    mistake = result["graded"].pop("finite_diff_half_steps")
    assert mistake["auto_possible"] == finite_diff_points and mistake["auto_earned"] <= 0.3 * finite_diff_points, mistake
    assert (mistake.get("mistake") or {}).get("id") == "finite_diff_half_steps"
    for name, graded in result["graded"].items():
        assert graded["auto_earned"] == graded["auto_possible"] > 0, (name, graded)

    # The kit's offering-dependent tests, in the variant.
    files = sorted(str(path.relative_to(KIT)) for path in (KIT / "tests").rglob("test_*.py")
                   if "mark.offering" in path.read_text(encoding="utf-8"))
    tests = _run(["-m", "pytest", "-m", "offering", "-q", "-p", "no:cacheprovider", "--durations=5", *files], kit, 600,
                 ok=False)
    assert tests.returncode == 0 and re.search(r"\d+ passed", tests.stdout), tests.stdout[-4000:] + tests.stderr[-2000:]
