"""A variant offering, proven (issue 31.3): a copy of the kit changed in the one place only (the TODO
table: 1.2.1 worth 12; the hidden checks: one more hidden input for 1.2.1 and another seed; the
settings: episodes capped at 200), its facts written by ``python -m instructor.facts``, its student
edition built, and the variant's reference graded at full points and a known mistake at <= 30%.
These are the steps of docs/instructor.md's checklist for a new offering."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from instructor.kit import kit_files

KIT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.timeout(900)


def _edit(path, old, new):
    text = path.read_text(encoding="utf-8")
    assert old in text, f"{path}: {old!r} not found"
    path.write_text(text.replace(old, new), encoding="utf-8")


def _run(args, kit, timeout):
    """``python args`` in ``kit`` with ``kit`` first on the path (its own hwlib, hwtools, instructor)."""
    done = subprocess.run([sys.executable, *args], cwd=kit, capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "PYTHONPATH": str(kit), "MPLBACKEND": "Agg"})
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done.stdout


GRADE = r"""
import json, sys
from pathlib import Path
from hwtools.grade import Grader, blocks, kits, mistakes
import hwtools
assert hwtools.__file__.startswith(sys.argv[1]), hwtools.__file__
kit, out = Path(sys.argv[1]), Path(sys.argv[2])
wrong = mistakes.read_wrong_solution(kit / "instructor/wrong_solutions/finite_diff_half_steps.txt")
mistake = out / "mistake"
kits.write_submission(blocks.load_layout(kit), mistake, {"1.2.1": list(wrong.bodies)}, others="reference")
with Grader(kit, jobs=2) as grader:
    cases = grader.cases["1.2.1"]
    hidden = sum(1 for case_id, *_ in cases.hidden if case_id.startswith("1.2.1/equation-3/"))
    reference = grader.grade(kit)
    wrong = grader.grade(mistake, todos=["1.2.1"])
print(json.dumps({"hidden": hidden, "reference": reference, "mistake": wrong}))
"""


def test_a_variant_offering_changed_in_the_one_place(tmp_path):
    kit = tmp_path / "variant"
    for name in kit_files(KIT):
        (kit / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(KIT / name, kit / name)
    # The one place: the TODO table, the hidden checks, the settings.
    _edit(kit / "hwlib/machinery/todos.py", 'eq. (3)", 10,', 'eq. (3)", 12,')
    _edit(kit / "hwlib/machinery/todos.py", '("equation-3", 7)', '("equation-3", 9)')
    _edit(kit / "instructor/hidden_checks/__init__.py", '"1.2.1/equation-3": 3,', '"1.2.1/equation-3": 4,')
    _edit(kit / "instructor/hidden_checks/__init__.py", "HIDDEN_SEED = 0x6F3A_91C2_57D4_0B1E", "HIDDEN_SEED = 0x1234_5678_9ABC_DEF0")
    _edit(kit / "hwlib/settings.py", "\nMAX_EPISODE_STEPS = 500\n", "\nMAX_EPISODE_STEPS = 200\n")

    # Its facts, written where the notebooks and docs state them.
    assert "rewrote: notebooks/p1_cartpole_finite_difference.ipynb" in _run(["-m", "instructor.facts"], kit, 120)
    _run(["-m", "instructor.facts", "--check"], kit, 120)

    # Its student edition (with its answer key: the variant reference's values on the visible checks).
    edition = tmp_path / "student"
    _run(["-m", "instructor.release", "student", str(edition), "--source", str(kit)], kit, 600)
    notebook = (edition / "notebooks/p1_cartpole_finite_difference.ipynb").read_text(encoding="utf-8")
    assert "(12 pts)" in notebook and "or 200 steps pass" in notebook and "(10 pts)" not in notebook
    assert "\nMAX_EPISODE_STEPS = 200\n" in (edition / "hwlib/settings.py").read_text(encoding="utf-8")
    assert not (edition / "instructor").exists()

    # The variant's reference earns every point (41: 1.2.1's 12 included); a known mistake keeps <= 30%.
    (tmp_path / "out").mkdir()
    result = json.loads(_run(["-c", GRADE, str(kit), str(tmp_path / "out")], kit, 800))
    original = subprocess.run([sys.executable, "-c", "from hwtools.grade import Grader; "
                               "print(sum(1 for case_id, *_ in Grader(%r).cases['1.2.1'].hidden "
                               "if case_id.startswith('1.2.1/equation-3/')))" % str(KIT)],
                              cwd=KIT, capture_output=True, text=True, timeout=120, check=True)
    assert result["hidden"] == int(original.stdout) + 1  # one more hidden input
    reference = result["reference"]
    assert reference["total"]["auto_possible"] == 41 and reference["total"]["auto_earned"] == 41, \
        [(todo["id"], todo["auto_earned"], todo["auto_possible"], todo["first_failure"]) for todo in reference["todos"]]
    finite_diff = next(todo for todo in reference["todos"] if todo["id"] == "1.2.1")
    assert finite_diff["auto_possible"] == 12 and finite_diff["auto_earned"] == 12
    mistake = next(todo for todo in result["mistake"]["todos"] if todo["id"] == "1.2.1")
    assert mistake["auto_possible"] == 12 and mistake["auto_earned"] <= 0.3 * 12, mistake
    assert (mistake.get("mistake") or {}).get("id") == "finite_diff_half_steps"
