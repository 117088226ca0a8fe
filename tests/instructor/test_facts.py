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
from instructor import facts as facts_tool

KIT = Path(__file__).resolve().parents[2]
DOCS = ["README.md", *sorted(str(path.relative_to(KIT)) for path in (KIT / "docs").glob("*.md"))]
pytestmark = pytest.mark.timeout(300)


def _prose(kit, relative):
    """The text of a README/doc, or of a notebook's Markdown cells."""
    text = (kit / relative).read_text(encoding="utf-8")
    if relative.endswith(".ipynb"):
        return "\n".join("".join(cell["source"]) for cell in json.loads(text)["cells"] if cell["cell_type"] == "markdown")
    return text


def _variant(tmp_path):
    """A copy of the kit's texts and facts with other facts, written into the one place only: the
    episode cap 317, the deadline 6 iterations, 777 random policies, 23 rollouts, h = 0.6, a
    31 x 31 landscape of 4 episodes a cell, 1.2.1 worth 13 (its equation-3 check 10)."""
    kit = tmp_path / "kit"
    for relative in [*facts_tool.NOTEBOOKS, *facts_tool.TEXTS, *DOCS]:
        (kit / relative).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(KIT / relative, kit / relative)
    settings = kit / "hwlib/settings.py"
    text = settings.read_text(encoding="utf-8")
    for old, new in [("MAX_EPISODE_STEPS = 500", "MAX_EPISODE_STEPS = 317"), ("CONVERGENCE_DEADLINE = 7", "CONVERGENCE_DEADLINE = 6"),
                     ("NUM_RANDOM_POLICIES = 1000", "NUM_RANDOM_POLICIES = 777"), ("NUM_ROLLOUTS = 20", "NUM_ROLLOUTS = 23"),
                     ("FD_STEP = 0.5", "FD_STEP = 0.6"), ("LANDSCAPE_GRID_SIZE = 41", "LANDSCAPE_GRID_SIZE = 31"),
                     ("LANDSCAPE_NUM_EPISODES = 5", "LANDSCAPE_NUM_EPISODES = 4")]:
        assert f"\n{old}\n" in text, old
        text = text.replace(f"\n{old}\n", f"\n{new}\n")
    settings.write_text(text, encoding="utf-8")
    table = kit / "hwlib/machinery/todos.py"
    text = table.read_text(encoding="utf-8")
    assert 'eq. (3)", 10,' in text and '("equation-3", 7)' in text
    table.write_text(text.replace('eq. (3)", 10,', 'eq. (3)", 13,').replace('("equation-3", 7)', '("equation-3", 10)'),
                     encoding="utf-8")
    return kit


def test_the_kit_states_its_facts_as_written():
    """``python -m instructor.facts --check`` finds every file as the facts give it."""
    done = subprocess.run([sys.executable, "-m", "instructor.facts", "--check"], cwd=KIT, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr


def test_a_changed_fact_reaches_every_place_that_states_it(tmp_path):
    kit = _variant(tmp_path)
    assert facts_tool.run(kit, check=True)  # out of date until rewritten
    changed = facts_tool.run(kit)
    assert {"README.md", "docs/grading.md", facts_tool.NOTEBOOKS[0]} <= set(changed)
    assert facts_tool.run(kit, check=True) == []  # idempotent
    stale = []
    for relative in DOCS + list(facts_tool.NOTEBOOKS) + ["hwlib/settings.py"]:
        for line in _prose(kit, relative).splitlines():
            # The old cap, the old deadline, the old totals: none may be left where a fact is stated.
            if re.search(r"(?<![\d.±+-])500(?![\d.])|within 7 iterations|\b39\b|\(10 pts\)|problem 1, 30 points|\b1000 (rew|par|\s*ran)"
                         r"|\b20 (start states|episodes per|fresh)|h = 0\.5|\b41 ×|× 41|8,405|\b5 (episodes|start|fixed)", line):
                if "2.1.1" not in line and "gymnasium registers CartPole-v1 with 500" not in line:
                    stale.append(f"{relative}: {line.strip()[:150]}")
    assert not stale, "stated but not derived from the one place:\n" + "\n".join(stale)
    notebook = _prose(kit, facts_tool.NOTEBOOKS[0])
    assert "### 1.2.1 Todo: implement `scalar_finite_diff` (13 pts)" in notebook
    assert "## Rubric (problem 1, 33 points)" in notebook and "| 1.2.1 finite differences | 13 | automatically |" in notebook
    assert "the best possible total reward is **317**" in notebook and "converges within 6 iterations" in notebook
    for said in ("Draw 777 parameter vectors", "*same* 23 start states", "**23 episodes per evaluation.**", "$h = 0.6$",
                 "The 31 × 31 cells", "(3,844 episodes)", "mean reward of 4 episodes", "on 23 fresh episodes, the picture on 4"):
        assert said in notebook, said
    grading = _prose(kit, "docs/grading.md")
    assert "42 points are automatic, 21 are graded by hand" in grading
    assert "| 1.2.1 finite differences | 13 | 10: eq. (3)" in grading and "(42/42" in _prose(kit, "README.md")
    assert "| ``MAX_EPISODE_STEPS``        | 317 " in _prose(kit, "hwlib/settings.py")


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
