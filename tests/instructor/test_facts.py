"""An offering's facts are written once (issue 31.1, 31.6): the TODO table and ``hwlib/settings.py``.
Every number the README, the docs, the notebooks' prose and the settings' own table state about them
is derived from there (``python -m instructor.facts``), and the kit's code reads them there."""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from hwtools import facts
from hwtools.todos import TODO_BY_ID
from instructor import facts as facts_tool
from instructor.kit import kit_files

KIT = Path(__file__).resolve().parents[2]
DOCS = ["README.md", *sorted(str(path.relative_to(KIT)) for path in (KIT / "docs").glob("*.md"))]
pytestmark = pytest.mark.timeout(300)
offering = pytest.mark.offering  # also run on the variant offering (test_variant.py)
NOW = facts_tool.Facts(KIT)  # this offering's facts: the variant below moves each of them
EQUATION_3 = TODO_BY_ID["1.2.1"].checks[0][0]


def _prose(kit, relative):
    """The text of a README/doc, or of a notebook's Markdown cells."""
    text = (kit / relative).read_text(encoding="utf-8")
    if relative.endswith(".ipynb"):
        return "\n".join("".join(cell["source"]) for cell in json.loads(text)["cells"] if cell["cell_type"] == "markdown")
    return text


def _moved():
    """This offering's settings, each moved to another value; 1.2.1 three points more (on its first check)."""
    settings = NOW.settings
    return {"MAX_EPISODE_STEPS": settings.MAX_EPISODE_STEPS + 117, "CONVERGENCE_DEADLINE": settings.CONVERGENCE_DEADLINE + 1,
            "NUM_RANDOM_POLICIES": settings.NUM_RANDOM_POLICIES + 223, "NUM_ROLLOUTS": settings.NUM_ROLLOUTS + 3,
            "FD_STEP": round(settings.FD_STEP + 0.1, 6), "LANDSCAPE_GRID_SIZE": settings.LANDSCAPE_GRID_SIZE + 10,
            "LANDSCAPE_NUM_EPISODES": settings.LANDSCAPE_NUM_EPISODES + 1}


def _variant(tmp_path):
    """A copy of the kit's texts and facts with other facts, written into the one place only: every
    setting ``_moved`` names, and 1.2.1 worth 3 points more (its first check too)."""
    kit = tmp_path / "kit"
    for relative in {*facts_tool.texts(KIT), *DOCS}:
        (kit / relative).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(KIT / relative, kit / relative)
    settings = kit / "hwlib/settings.py"
    text = settings.read_text(encoding="utf-8")
    for name, value in _moved().items():
        text, count = re.subn(rf"^{name} = .*$", f"{name} = {value}", text, flags=re.M)
        assert count == 1, name
    settings.write_text(text, encoding="utf-8")
    table = kit / "hwlib/machinery/todos.py"
    text = table.read_text(encoding="utf-8")
    todo = TODO_BY_ID["1.2.1"]
    text, count = re.subn(r'(Todo\("1\.2\.1", "[^"]*", )[\d.]+,', lambda m: f"{m[1]}{todo.auto + 3:g},", text)
    text, more = re.subn(rf'\("{EQUATION_3}", [\d.]+\)', f'("{EQUATION_3}", {todo.checks[0][1] + 3:g})', text)
    assert count == more == 1
    table.write_text(text, encoding="utf-8")
    return kit


def test_the_kit_states_its_facts_as_written():
    """``python -m instructor.facts --check`` finds every file as the facts give it (in the variant offering,
    test_variant.py runs it itself: not marked ``offering``)."""
    done = subprocess.run([sys.executable, "-m", "instructor.facts", "--check"], cwd=KIT, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr


@offering
def test_a_changed_fact_reaches_every_place_that_states_it(tmp_path):
    kit = _variant(tmp_path)
    assert facts_tool.run(kit, check=True)  # out of date until rewritten
    changed = facts_tool.run(kit)
    known = [name for name in facts_tool.texts(KIT) if name.startswith("instructor/wrong_solutions/")]  # their diagnoses
    assert {"README.md", "docs/grading.md", facts_tool.NOTEBOOKS[0]} <= set(changed) and set(known) & set(changed)
    assert facts_tool.run(kit, check=True) == []  # idempotent
    settings, new, todo = NOW.settings, _moved(), TODO_BY_ID["1.2.1"]
    grid, episodes = settings.LANDSCAPE_GRID_SIZE, settings.LANDSCAPE_NUM_EPISODES
    problem_1 = sum(NOW.total(other) for other in NOW.todos if other.startswith("1."))
    # The old cap (on a line about episodes: a count of forks may equal it), the old total (on a line about
    # points: a time may equal it), the old deadline, the old points: none may be left where a fact is stated.
    cap = rf"(?<![\d.±+-]){NOW.cap}(?![\d.])"
    total, points = rf"(?<![\d.]){NOW.auto:g}(?![\d.])", r"\b(?:points?|pts|total|score)\b|/"
    old = (rf"within {NOW.deadline} iterations|\({NOW.total('1.2.1'):g} pts\)"
           rf"|problem 1, {problem_1:g} points|\b{settings.NUM_RANDOM_POLICIES} (rew|par|\s*ran)"
           rf"|\b{settings.NUM_ROLLOUTS} (start states|episodes per|fresh)|h = {settings.FD_STEP:g}\b|\b{grid} ×|× {grid}\b"
           rf"|{grid * grid * episodes:,}|\b{episodes} (episodes|start|fixed)")
    stale = []
    for relative in DOCS + list(facts_tool.NOTEBOOKS) + ["hwlib/settings.py"] + known:
        stale += [f"{relative}: {line.strip()[:150]}" for line in _prose(kit, relative).splitlines() if "2.1.1" not in line
                  and (re.search(old, line) or re.search(cap, line) and re.search(facts_tool.CAP_WORDS, line, re.I)
                       or re.search(total, line) and re.search(points, line))]
    assert not stale, "stated but not derived from the one place:\n" + "\n".join(stale)
    notebook = _prose(kit, facts_tool.NOTEBOOKS[0])
    cap, deadline, auto = new["MAX_EPISODE_STEPS"], new["CONVERGENCE_DEADLINE"], NOW.auto + 3
    assert f"### 1.2.1 Todo: implement `scalar_finite_diff` ({NOW.total('1.2.1') + 3:g} pts)" in notebook
    assert f"## Rubric (problem 1, {problem_1 + 3:g} points)" in notebook
    assert f"| 1.2.1 finite differences | {NOW.total('1.2.1') + 3:g} | automatically |" in notebook
    assert f"the best possible total reward is **{cap}**" in notebook and f"converges within {deadline} iterations" in notebook
    grid, episodes, rollouts = new["LANDSCAPE_GRID_SIZE"], new["LANDSCAPE_NUM_EPISODES"], new["NUM_ROLLOUTS"]
    for said in (f"Draw {new['NUM_RANDOM_POLICIES']} parameter vectors", f"*same* {rollouts} start states",
                 f"**{rollouts} episodes per evaluation.**", f"$h = {new['FD_STEP']:g}$", f"The {grid} × {grid} cells",
                 f"({grid * grid * episodes:,} episodes)", f"mean reward of {episodes} episodes",
                 f"on {rollouts} fresh episodes, the picture on {episodes}"):
        assert said in notebook, said
    grading = _prose(kit, "docs/grading.md")
    assert f"{auto:g} points are automatic, {NOW.manual:g} are graded by hand" in grading
    assert f"| 1.2.1 finite differences | {todo.auto + 3:g} | {todo.checks[0][1] + 3:g}: eq. (3)" in grading
    assert f"({auto:g}/{auto:g}" in _prose(kit, "README.md")
    assert f"| ``MAX_EPISODE_STEPS``        | {cap} " in _prose(kit, "hwlib/settings.py")
    diagnoses = "\n".join(_prose(kit, name) for name in known)
    assert re.search(rf"reach(es|ed) {cap}\b", diagnoses) and f"within {deadline} iterations" in diagnoses


@offering
def test_the_check_rejects_a_literal_cap_or_total_and_a_renamed_check(tmp_path):
    """``--check`` finds the cap or the automatic total written as a literal in code or a template, and
    a check renamed in the TODO table, in a copy of the kit; this kit has none of them (above)."""
    kit = tmp_path / "kit"
    for relative in kit_files(KIT):
        if relative.startswith(("hwlib/", "hwtools/", "instructor/")) or relative in facts_tool.NOTEBOOKS:
            (kit / relative).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(KIT / relative, kit / relative)
    template = kit / "hwtools/report/templates/answers.tex.j2"
    template.write_text(template.read_text(encoding="utf-8") + f"\nthe maximum reward is {NOW.cap}\n", encoding="utf-8")
    code = kit / "hwlib/plots/training.py"
    code.write_text(code.read_text(encoding="utf-8") + f"\nFULL_SCORE = {NOW.auto:g}  # points\n", encoding="utf-8")
    table = kit / "hwlib/machinery/todos.py"
    table.write_text(table.read_text(encoding="utf-8").replace(f'("{EQUATION_3}", ', '("equation-three", '), encoding="utf-8")
    found = facts_tool.problems(kit)
    assert [problem.split(": ")[0] for problem in found] == [
        "hwlib/plots/training.py:" + str(len(code.read_text(encoding="utf-8").splitlines())),
        "hwtools/report/templates/answers.tex.j2:" + str(len(template.read_text(encoding="utf-8").splitlines())),
        "points table"], found
    assert f"the automatic points' total {NOW.auto:g} written as a literal" in found[0]
    assert f"the episode cap {NOW.cap} written as a literal" in found[1]
    assert "equation-three" in found[2] and EQUATION_3 in found[2]


@offering
def test_numbers_said_next_to_a_setting_are_the_setting():
    """Wherever the README, a doc or a notebook writes a setting's name with a number beside it
    (``NAME`` = 7, ``NAME`` (7), 7 (``NAME``)), and in the settings' own table, the number is the setting's."""
    names = {name: value for name, value in vars(facts.settings).items()
             if name.isupper() and isinstance(value, (int, float)) and name != "LEARNING_RATE"}
    wrong, seen = [], 0
    sources = [(relative, _prose(KIT, relative)) for relative in DOCS + list(facts_tool.NOTEBOOKS)]
    for relative in ("hwlib/settings.py", "hwlib/policy_search.py"):  # their docstrings' tables
        sources.append((relative, (KIT / relative).read_text(encoding="utf-8").split('"""')[1]))
    for relative, text in sources:
        for name, value in names.items():
            for said in re.findall(rf"`+{name}`+(?: +\| +| = | \()(\d[\d_.e+-]*)|(\d[\d_.e+-]*) \(`+{name}`+\)", text):
                number = float((said[0] or said[1]).replace("_", ""))
                seen += 1
                if number != value:
                    wrong.append(f"{relative}: {name} said to be {said[0] or said[1]}, it is {value}")
    assert seen >= 10  # the settings' own table at least
    assert not wrong, "\n".join(wrong)


@offering
def test_the_code_reads_the_episode_cap_from_the_settings(tmp_path):
    """The one episode cap: what gym.make registers, what the kit's engine plays and what the plots,
    report and checks say all come from ``settings.MAX_EPISODE_STEPS`` (here changed to 200 in a
    copy of ``hwlib``, as a variant offering would)."""
    shutil.copytree(KIT / "hwlib", tmp_path / "hwlib", ignore=shutil.ignore_patterns("__pycache__"))
    settings = tmp_path / "hwlib/settings.py"
    settings.write_text(settings.read_text(encoding="utf-8").replace("\nMAX_EPISODE_STEPS = 500\n", "\nMAX_EPISODE_STEPS = 200\n"),
                        encoding="utf-8")
    program = (
        "import hwlib; assert hwlib.__file__.startswith(%r), hwlib.__file__\n"
        "import gymnasium as gym, numpy as np\n"
        "from hwlib import cartpole\n"
        "from hwlib.machinery import episodes\n"
        "env = gym.make('CartPole-v1'); print(env.spec.max_episode_steps, cartpole.MAX_EPISODE_REWARD)\n"
        "print(episodes.constants().max_episode_steps)\n"
        "good = np.array([[0.0, -0.5, -5.0, -1.0]])\n"
        "print(int(episodes.run_episodes(good, np.array([0]))[0]))\n"
        "print(int(cartpole.run_policy(cartpole.CartPoleLinearPolicy(good[0]), 0)))\n"
    )
    done = subprocess.run([sys.executable, "-c", program % str(tmp_path)], cwd=tmp_path, capture_output=True, text=True,
                          timeout=120, env={**os.environ, "PYTHONPATH": str(tmp_path)})
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["200", "200", "200", "200", "200"], done.stdout
