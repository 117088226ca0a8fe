"""The student edition is the handout's homework (issue: the student edition reads true).

* it states no answer outside a TODO block: no line of a solution block, no learning rate that
  converges, no parameter vector that balances, anywhere in the files a student gets;
* every natural solution in tests/natural_solutions/ (written from the handout and the docstring
  alone, as a student would) runs in a freshly built student edition, and with one natural
  solution per TODO the student edition runs both notebooks, the learning-rate sweep included.

Instructor-only: this file is left out of the student edition.
"""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hwlib.cartpole import run_episodes
from instructor.release import HOMEWORK_FOLDERS, build_student_edition, file_blocks, kit_files

KIT = Path(__file__).resolve().parents[1]
NATURAL = KIT / "tests" / "natural_solutions"
TEXT_SUFFIXES = (".py", ".md", ".ipynb", ".toml", ".txt", ".cfg")


def solution_blocks():
    """(todo, file, body lines) of every solution block of the instructor's kit, its STUB lines left out."""
    found = []
    for name in kit_files(KIT):
        if not name.startswith(HOMEWORK_FOLDERS):
            continue
        for block, lines, _ in file_blocks(KIT / name, name):
            given = {line.strip() for line in block.stub}  # the STUB lines are the student's start, not an answer
            found.append((block.todo, name, [line for line in lines[block.body_start:block.end] if line.strip() not in given]))
    return found


def distinctive(line):
    """A solution line long and specific enough that finding it elsewhere would hand the answer over."""
    stripped = line.strip()
    if len(stripped) < 20 or stripped.startswith(("#", "<!--")):
        return False
    return not re.fullmatch(r"(return|def|for|if|else|elif)\b.{0,12}", stripped)


def student_texts(root):
    """{relative path: text} of the student edition's text files (notebook cell sources only)."""
    texts = {}
    for path in sorted(root.rglob("*")):
        if not path.is_file() or path.suffix not in TEXT_SUFFIXES:
            continue
        text = path.read_text(encoding="utf-8")
        if path.suffix == ".ipynb":
            text = "\n".join("".join(cell["source"]) for cell in json.loads(text)["cells"])
        texts[path.relative_to(root).as_posix()] = text
    return texts


@pytest.fixture(scope="module")
def student_edition(tmp_path_factory):
    out = tmp_path_factory.mktemp("student") / "kit"
    build_student_edition(KIT, out)
    return out


def test_no_solution_line_appears_in_the_student_edition(student_edition):
    texts = student_texts(student_edition)
    leaks = []
    for todo, name, body in solution_blocks():
        for line in filter(distinctive, body):
            leaks += [f"TODO {todo} ({name}): {line.strip()!r} in {path}" for path, text in texts.items() if line.strip() in text]
    assert not leaks, "\n".join(leaks)


def test_no_converging_learning_rate_appears_in_the_student_edition(student_edition):
    from hwlib import settings

    rate = settings.LEARNING_RATE
    pattern = re.compile(rf"(?<![\d.]){re.escape(repr(rate))}(?![\d])")
    found = [path for path, text in student_texts(student_edition).items() if pattern.search(text)]
    assert not found, f"the answer to 1.3.3 ({rate}) appears in {found}"


def test_no_balancing_parameters_appear_in_the_student_edition(student_edition):
    """Every 4-number vector written in the student edition that balances on seeds 0-4 is an answer to 1.1.2."""
    number = r"-?\d+(?:\.\d+)?(?:e-?\d+)?"
    vector = re.compile(rf"[\[(]\s*({number})\s*,\s*({number})\s*,\s*({number})\s*,\s*({number})\s*,?\s*[\])]")
    candidates = {}
    for path, text in student_texts(student_edition).items():
        for match in vector.finditer(text):
            candidates.setdefault(tuple(float(value) for value in match.groups()), path)
    params = np.array(list(candidates))
    seeds = np.arange(5)
    rewards = run_episodes(np.repeat(params, len(seeds), axis=0), np.tile(seeds, len(params))).reshape(len(params), -1)
    balancing = [f"{tuple(p)} in {candidates[tuple(p)]}" for p, row in zip(params, rewards) if np.all(row == 500)]
    assert not balancing, f"parameters that balance (an answer to 1.1.2): {balancing}"
    assert len(candidates) >= 2  # the search sees the presets, so it does look


def test_the_leak_search_finds_a_leak(tmp_path):
    """The checks above can fail: a solution line copied into a given file is found."""
    build_student_edition(KIT, tmp_path / "kit")
    todo, name, body = next(block for block in solution_blocks() if block[0] == "1.2.1")
    line = next(filter(distinctive, body)).strip()
    readme = tmp_path / "kit" / "README.md"
    readme.write_text(readme.read_text() + f"\n    {line}\n")
    assert any(line in text for text in student_texts(tmp_path / "kit").values())


def natural_solutions():
    return sorted(path for path in NATURAL.glob("*.py"))


def block_file(todo):
    """The file of the kit whose code block (library or notebook code cell) is TODO ``todo``."""
    files = {name for block_todo, name, body in solution_blocks() if block_todo == todo}
    code_files = sorted(name for name in files if name.endswith(".py")) or sorted(files)
    return code_files[0]


def test_every_library_todo_has_natural_solutions():
    todos = {path.name.split("_")[0] for path in natural_solutions()}
    library_todos = {todo for todo, name, body in solution_blocks() if name.endswith(".py")}
    assert library_todos <= todos, f"no natural solution for {sorted(library_todos - todos)}"
    for todo in ("1.2.1", "1.3.2", "2.3.1"):
        assert sum(path.name.startswith(todo + "_") for path in natural_solutions()) >= 2, todo


def run_in(kit, *args, timeout=900):
    env = {**os.environ, "PYTHONPATH": str(kit), "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, *args], cwd=kit, env=env, capture_output=True, text=True, timeout=timeout)


def test_a_student_edition_with_natural_solutions_runs_its_notebooks_and_the_sweep(tmp_path):
    chosen = {}
    for path in natural_solutions():
        chosen.setdefault(path.name.split("_")[0], path)
    replace = {(todo, block_file(todo)): path.read_text() for todo, path in chosen.items()}
    kit = tmp_path / "kit"
    build_student_edition(KIT, kit, replace=replace)
    result = run_in(kit, "-m", "pytest", "-q", "-p", "no:cacheprovider", "notebooks", "tests/test_policy_search.py",
                    "tests/test_finite_diff.py", "tests/test_cartpole.py", "tests/test_logreg.py")
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    assert re.search(r"\d+ passed", result.stdout)
