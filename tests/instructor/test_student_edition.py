"""The student edition is the handout's homework (issue: the student edition reads true).

* it states no answer outside a TODO block: no line of a solution block, no learning rate that
  converges, no parameter vector that balances, anywhere in the files a student gets;
* with one natural solution per TODO (``tests/grader/natural_solutions/``, written from the handout and the
  docstring alone, as a student would) the student edition passes its own unit tests and hands in
  (``python -m hwtools.handin``: the visible checks pass and the zip is one the grader's reader opens and
  grades in full; the report it builds runs in a student edition in tests/notebooks/test_report.py);
* day one, untouched (``tests/instructor/day_one.py``): Run All stops at the first cell that needs a TODO,
  with two lines naming it; stepping through every cell, each one that needs a TODO names it in
  its first line (the check cells too), the others run; ``pytest`` names a TODO first in every
  failure, in a few lines each;
* the commands its README gives start in it.

Every command a student types runs with a Python that has the kit's packages but cannot import the
instructor's tools (``day_one.student_python``). The reference solutions' path, editor leftovers
included, is ``tests/instructor/test_student_path.py``.
"""

import ast
import json
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import editions
import hwlib
from hwlib.machinery.episodes import run_episodes
from hwlib.machinery.todos import TODO_BY_ID
from hwlib.settings import MAX_EPISODE_STEPS
from instructor.release import HOMEWORK_FOLDERS, build_student_edition, file_blocks, kit_files

KIT = Path(__file__).resolve().parents[2]
NATURAL = KIT / "tests" / "grader" / "natural_solutions"

pytestmark = pytest.mark.timeout(1800)  # whole runs of the edition's tests, notebooks and report
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
    return editions.build(tmp_path_factory.mktemp("student") / "kit", tmp_path_factory)


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
    balancing = [f"{tuple(p)} in {candidates[tuple(p)]}" for p, row in zip(params, rewards) if np.all(row == MAX_EPISODE_STEPS)]
    assert not balancing, f"parameters that balance (an answer to 1.1.2): {balancing}"
    assert len(candidates) >= 2  # the search sees the presets, so it does look


def test_the_leak_search_finds_a_leak(tmp_path):
    """The checks above can fail: a solution line copied into a given file is found."""
    build_student_edition(KIT, tmp_path / "kit", answer_key=False)  # the key holds no line of a solution
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


@pytest.fixture(scope="module")
def python(tmp_path_factory):
    """A Python like a student's: the kit's packages, not the instructor's tools (``day_one.student_python``)."""
    from day_one import student_python

    return student_python(tmp_path_factory.mktemp("venv") / "venv")


def run_in(python, kit, *args, timeout=900):
    from day_one import kit_env

    return subprocess.run([str(python), *args], cwd=kit, env=kit_env(kit), capture_output=True, text=True, timeout=timeout)


def natural_edition(out, tmp_path_factory, **chosen):
    """A student edition at ``out`` with one natural solution per TODO: the first of each, or ``chosen[todo]``
    (with the test run's answer key: ``editions.build``)."""
    for path in natural_solutions():
        chosen.setdefault(path.name.split("_")[0], path)
    replace = {(todo, block_file(todo)): path.read_text() for todo, path in chosen.items()}
    return editions.build(out, tmp_path_factory, replace=replace)


@pytest.fixture(scope="module")
def natural_kit(tmp_path_factory):
    """A student edition with one natural solution per TODO."""
    return natural_edition(tmp_path_factory.mktemp("natural") / "kit", tmp_path_factory)


def test_a_student_edition_with_natural_solutions_passes_its_own_unit_tests(python, natural_kit):
    """Its notebooks, the learning-rate sweep included, run in the report of the hand-in below (and the
    edition's whole test command, notebooks included, in tests/instructor/test_student_path.py)."""
    result = run_in(python, natural_kit, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests")
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    assert re.search(r"\d+ passed", result.stdout)


def test_one_command_checks_and_hands_in_the_zip(python, natural_kit):
    """The hand-in's zip, after its checks. (The report it builds too, ``python -m hwtools.report``, runs in a
    student edition in tests/notebooks/test_report.py, and the hand-in's handling of it in test_student_path;
    the instructor's grader grades a hand-in's zip in full in test_student_path; the natural solutions earn
    their points in test_grading.)"""
    result = run_in(python, natural_kit, "-m", "hwtools.handin", "alovelac", "--no-report")
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    zip_path = natural_kit / "handin" / "alovelac.zip"
    assert "finds the code of every TODO" in result.stdout and "every visible check passes" in result.stdout
    assert "training with your LEARNING_RATE converges" in result.stdout and "not done yet" not in result.stdout
    assert "Hand in handin/alovelac.zip on Canvas." in result.stdout
    with zipfile.ZipFile(zip_path) as archive:
        names = archive.namelist()
    assert names == sorted(names) and all(name.startswith(("hwlib/", "notebooks/")) for name in names)
    assert {"hwlib/cartpole.py", "hwlib/logreg.py", "notebooks/p1_cartpole_finite_difference.ipynb"} <= set(names)
    from hwtools.handin import checked_zip

    assert checked_zip(natural_kit, "alovelac")[0] == zip_path.read_bytes()  # no time stamps: the same files give the same zip


def test_run_all_of_p1_works_with_an_eval_params_that_plays_in_its_own_environment(tmp_path, tmp_path_factory):
    """Issue 25.1: an eval_params with its own gym.make("CartPole-v1") loop is correct, and the kit's runs
    replay it in their batches; played step by step, the notebook's sweep would take an hour, and the
    kit would stop it (TooSlow) and Run All with it. (test_batch plays each way of writing it: an
    environment per episode, one seeded once, one passed to run_policy.)"""
    from day_one import run_all

    kit = natural_edition(tmp_path / "kit", tmp_path_factory, **{"1.3.1": NATURAL / "1.3.1_own_env_loop.py"})
    assert "gym.make" in (kit / "hwlib" / "policy_search.py").read_text()
    run = run_all(kit / "notebooks" / P1, kit)
    assert run["stopped"] is None, [line for outputs in run["outputs"].values() for output in outputs
                                    for line in output.get("traceback", [])][-6:]
    sweep = [text for outputs in run["outputs"].values() for output in outputs
             for text in [output.get("text", "")] if "seeds converge within" in text]
    assert sweep and "100%" in sweep[0], sweep  # the sweep ran, and rates converge


def test_the_hand_in_refuses_what_the_grader_cannot_read(python, tmp_path):
    kit = tmp_path / "kit"
    build_student_edition(KIT, kit, answer_key=False)
    logreg = kit / "hwlib" / "logreg.py"
    logreg.write_text(logreg.read_text().replace("### END TODO 2.2.1", "", 1))  # a marker deleted by mistake
    result = run_in(python, kit, "-m", "hwtools.handin", "alovelac", "--no-report")
    assert result.returncode == 1
    assert "2.2.1" in result.stderr and "hwlib/logreg.py" in result.stderr and "Traceback" not in result.stderr, result.stderr
    assert not (kit / "handin").exists()  # nothing written before the checks pass
    bad = run_in(python, kit, "-m", "hwtools.handin", "../alovelac", "--no-report")
    assert bad.returncode == 1 and "not an Andrew ID" in bad.stderr


# --------------------------------------------------------------------------------------------
# Day one: the untouched student edition
# --------------------------------------------------------------------------------------------

P1, P2 = "p1_cartpole_finite_difference.ipynb", "p2_food_cutting_logistic_regression.ipynb"
FIRST_STOP = {P1: ("p1-05", "1.1.1"), P2: ("13197592", "2.1.1")}  # Run All stops here on day one
# Cells that need no TODO: they run on day one. Every other code cell must name the TODO it needs.
NEEDS_NO_TODO = {
    "p1-01", "p1-03",  # the imports; the environment's reset and step
    "p1-09",  # the 1.1.2 table: its starting rows are the student's to change
    "4d5ea793", "84a85dd5", "eac8480e",  # the imports; the data; the recordings (skipped without them)
}
NOT_DONE = re.compile(r"^TODO (\d+\.\d+\.\d+) is not done yet: ")


@pytest.fixture(scope="module")
def day_one_kit(tmp_path_factory):
    from day_one import day_one_edition

    return day_one_edition(tmp_path_factory.mktemp("day-one") / "kit", tmp_path_factory)


@pytest.mark.parametrize("notebook", [P1, P2])
def test_day_one_run_all_stops_at_the_first_todo_and_names_it_in_two_lines(day_one_kit, notebook):
    from day_one import first_lines, run_all

    run = run_all(day_one_kit / "notebooks" / notebook, day_one_kit)
    cell, todo = FIRST_STOP[notebook]
    assert run["stopped"] == cell, f"Run All stopped at {run['stopped']}, not at the first cell that needs a TODO ({cell})"
    shown = first_lines(run["outputs"][cell])
    assert len(shown) == 2 and shown[0].startswith(f"TODO {todo} is not done yet: "), shown
    assert run["ran"][-1] == cell  # nothing ran after it


def code_cells(notebook):
    return [cell["id"] for cell in json.loads((KIT / "notebooks" / notebook).read_text())["cells"] if cell["cell_type"] == "code"]


@pytest.fixture(scope="module")
def stepped(day_one_kit):
    """Every code cell of both notebooks run in turn on day one, as Shift-Enter through them does."""
    from day_one import step_through

    return {notebook: {cell["id"]: cell for cell in step_through(day_one_kit / "notebooks" / notebook, day_one_kit)}
            for notebook in (P1, P2)}


@pytest.mark.parametrize(("notebook", "cell_id"), [
    (notebook, cell_id) for notebook in (P1, P2) for cell_id in code_cells(notebook)])
def test_day_one_every_cell_that_needs_a_todo_names_it_first(stepped, notebook, cell_id):
    from day_one import error_of, first_lines

    cell = stepped[notebook][cell_id]
    shown, error = first_lines(cell["outputs"]), error_of(cell["outputs"])
    if cell_id in NEEDS_NO_TODO:
        assert error is None, f"{cell_id} needs no TODO but failed: {shown[:6]}"
        return
    assert shown and NOT_DONE.match(shown[0]), f"{cell_id} ({cell['source'][:60]!r}) does not name a TODO first: {shown[:6]}"
    if error is not None:
        assert len(shown) == 2, f"{cell_id}: {len(shown)} lines, not two: {shown[:8]}"
    if cell["source"].startswith("check("):
        assert error is None and len(shown) <= 3  # a check prints its verdict; it does not stop Run All


def test_day_one_pytest_names_a_todo_first_in_every_failure(python, day_one_kit):
    """The untouched edition's whole test suite, as the student runs it (with a Python that cannot
    import the instructor's tools): every failure and error starts with the TODO to do, in a few lines."""
    result = run_in(python, day_one_kit, "-m", "pytest", "-p", "no:cacheprovider", "-rfEs", timeout=1800)
    out = result.stdout
    assert result.returncode == 1, out[-3000:]
    reports = re.split(r"(?m)^=+ (?:ERRORS|FAILURES) =+$", out.split(" short test summary info ")[0], maxsplit=1)[-1]
    sections = re.split(r"(?m)^_+ (.+?) _+$", re.sub(r"(?m)^=+ (?:ERRORS|FAILURES) =+$", "", reports))
    bodies = {sections[i]: [line for line in sections[i + 1].strip().splitlines()
                            if not line.startswith(("=", "TODOs not done yet"))] for i in range(1, len(sections) - 1, 2)}
    assert len(bodies) >= 50, out[-2000:]
    unnamed = {name: body[:3] for name, body in bodies.items() if not body or not body[0].startswith("TODO ")}
    assert not unnamed, f"failures that do not name their TODO first: {unnamed}"
    long = {name: len(body) for name, body in bodies.items() if len(body) > 3}
    assert not long, f"failures longer than 3 lines on day one: {long}"


def test_every_command_of_the_student_readme_starts_in_the_edition(python, student_edition):
    """Its install command is the kit's quick start (which tests/browser/test_quick_start.py runs), and each
    ``python -m`` command it gives starts in the edition with a student's Python. (What files it names:
    tests/instructor/test_release.py.)"""
    readme = (student_edition / "README.md").read_text()
    commands = [block.strip() for block in re.findall(r"```bash\n(.*?)```", readme, re.S)]
    quick_start = re.findall(r"```bash\n(.*?)```", (KIT / "README.md").read_text().split("## Quick start", 1)[1], re.S)[0]
    kit_line = quick_start.strip().split(" && ")  # the student's lines (issue 32.6) do the quick start's steps
    assert commands and [step.strip() for step in commands[0].replace("\n", " && ").split(" && ")] == \
        [step.replace(".venv/bin/pip ", ".venv/bin/python -m pip ") for step in kit_line]
    modules = sorted(set(re.findall(r"python -m ([\w.]+)", readme)))
    assert {"hwtools.handin", "hwtools.grade", "pytest"} <= set(modules), modules
    for module in modules:
        result = run_in(python, student_edition, "-m", module, "--help", timeout=120)
        assert result.returncode == 0 and "usage" in result.stdout.lower(), (module, result.stderr[-2000:])


TODO_BLOCK = re.compile(r"^[ \t]*### BEGIN TODO (\d\.\d\.\d)", re.M)
STUDENT_CALLS = """
import json, numpy as np
from hwlib import *
from hwlib import TodoNotDone
from hwlib.landscape import reward_slice
from hwlib.training import learning_rate_sweep, run_training
X, y = np.ones((4, 2)), np.array([0, 1, 0, 1])
two = TwoClassLogisticRegressionClassifier(2)
calls = {
    "policy": lambda: CartPoleLinearPolicy([0.0] * 4)(np.zeros(4)),
    "run_policy": lambda: run_policy(CartPoleLinearPolicy([0.0] * 4), seed=0),
    "random policies": lambda: random_policy_rewards(10, seed=0),
    "landscape": lambda: reward_slice(np.zeros(4), grid_size=3, num_episodes=1),
    "finite differences": lambda: scalar_finite_diff(lambda v: 0.0, [1.0], 0.1),
    "eval_params": lambda: eval_params([0.0] * 4, 2, seed=0),
    "training": lambda: train_cartpole_policy(1, learning_rate=0.001),
    "training with the settings": lambda: run_training(1),
    "sweep": lambda: learning_rate_sweep([0.001], num_seeds=2, num_training_iterations=1),
    "sigmoid": lambda: sigmoid(0.0),
    "predict_prob": lambda: two.predict_prob(X),
    "gradient step": lambda: two.gradient_ascent_step(X, y, 0.1),
    "one-vs-rest": lambda: MultiClassLogisticRegressionClassifier(2, 2).fit(X, y, 0.1, 1),
    "gradient": lambda: log_likelihood_gradient(np.zeros(3), X, y),
}
raised = {}
for name, call in calls.items():
    try:
        call()
        raised[name] = "nothing"
    except TodoNotDone as error:
        raised[name] = [error.todo, type(error).__name__, str(error).splitlines()[0]]
    except Exception as error:
        raised[name] = repr(error)
print(json.dumps(raised))
"""


class TestTheStudentEditionsStubs:
    """What the release writes in place of each solution: stubs that raise TodoNotDone, naming their TODO."""

    @pytest.fixture(scope="class")
    @classmethod
    def student_edition(cls, tmp_path_factory):
        out = tmp_path_factory.mktemp("student") / "kit"
        subprocess.run([sys.executable, "-m", "instructor.release", "student", str(out), "--no-answer-key"],
                       cwd=KIT, check=True, capture_output=True)
        return out

    def test_every_stub_in_the_student_edition_raises_todo_not_done(self, student_edition):
        for path in (student_edition / "hwlib").rglob("*.py"):
            text = path.read_text(encoding="utf-8")
            for todo in TODO_BLOCK.findall(text):
                if path.name == "settings.py":
                    assert re.search(rf"^# TODO {todo}: .+\n(# .+\n)*LEARNING_RATE = None$", text, re.M)
                else:
                    assert f'raise TodoNotDone("{todo}")' in text, (path.name, todo)
            ast.parse(text)
        for path in (student_edition / "notebooks").glob("*.ipynb"):  # a code cell's too, but where it starts with values
            for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]:
                source = "".join(cell["source"]) if cell["cell_type"] == "code" else ""
                for todo in TODO_BLOCK.findall(source):
                    assert f'raise TodoNotDone("{todo}")' in source or cell["id"] in NEEDS_NO_TODO, (path.name, todo, source)

    def test_on_day_one_every_entry_point_names_the_first_todo_it_needs(self, student_edition):
        done = subprocess.run([sys.executable, "-c", STUDENT_CALLS], cwd=student_edition, capture_output=True, text=True,
                              env={"PYTHONPATH": str(student_edition), "MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"})
        assert done.returncode == 0, done.stderr
        raised = json.loads(done.stdout.strip().splitlines()[-1])
        expected = {
            "policy": "1.1.1", "run_policy": "1.1.1", "random policies": "1.1.1", "landscape": "1.1.1",
            "finite differences": "1.2.1", "eval_params": "1.3.1", "training": "1.3.1",
            "training with the settings": "1.3.3", "sweep": "1.1.1", "sigmoid": "2.2.1", "predict_prob": "2.2.2",
            "gradient step": "2.2.3", "one-vs-rest": "2.3.1", "gradient": "2.1.1",
        }
        for name, todo in expected.items():
            assert raised[name][:2] == [todo, "TodoNotDone"], (name, raised[name])
            where, what = TODO_BY_ID[todo].where
            assert raised[name][2].startswith(f"TODO {todo} is not done yet: {what} in {where}")
        assert hwlib.__file__.startswith(str(KIT))  # the kit under test here is the instructor's, untouched
