"""The release tool: the student edition of this kit, and the rules on a small made-up kit.
"""

from __future__ import annotations

import ast
import json
import os
import pkgutil
import re
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import nbformat
import pytest

import editions
from doc_mentions import Kit, missing
from day_one import versions_tested
from instructor.release import (
    ANSWER_KEY,
    INSTRUCTOR_ONLY,
    STUDENT_README,
    STUDENT_TESTS,
    ReleaseError,
    build_student_edition,
    file_blocks,
    is_instructor_only,
    kit_files,
    student_files,
    transform_notebook,
    transform_python,
)
from instructor.stubs import HINT_WIDTH

pytestmark = pytest.mark.quick  # the quick tier (pyproject.toml)

REPO = Path(__file__).resolve().parents[2]
MARKER = re.compile(r"(BEGIN|END) SOLUTION|### HINT:|### STUB:")


@pytest.fixture(scope="module")
def edition(tmp_path_factory):
    """The student edition, with the test run's answer key (written once per test process)."""
    return editions.build(tmp_path_factory.mktemp("edition") / "student", tmp_path_factory)


def _tree(root):
    return {
        path.relative_to(root).as_posix(): (path.read_bytes(), path.stat().st_mode & 0o777)
        for path in sorted(root.rglob("*"))
        if path.is_file()
    }


def _source_blocks(path):
    """(todo, body lines, style) of every solution block of a source file."""
    return [(block.todo, lines[block.body_start:block.end], style) for block, lines, style in file_blocks(path)]


# --------------------------------------------------------------------------------------------
# The student edition of this kit
# --------------------------------------------------------------------------------------------


def test_building_twice_gives_byte_identical_output(edition, tmp_path):
    build_student_edition(REPO, tmp_path / "again")  # the release command's own way, its answer key included
    assert _tree(tmp_path / "again") == _tree(edition)


def test_instructor_files_are_left_out_and_the_rest_is_there(edition):
    names = set(_tree(edition))
    for name in names:
        assert not is_instructor_only(name), name
    assert "instructor/release.py" not in names and "tests/instructor/test_release.py" not in names and "tests/grader/test_grading.py" not in names
    expected = {name for name in kit_files(REPO) if not is_instructor_only(name)}
    assert names == expected | {ANSWER_KEY}
    assert not any(name.startswith("instructor/") for name in names)
    for needed in ("hwtools/grade/__init__.py", ANSWER_KEY, "hwlib/__init__.py", "pyproject.toml", "requirements.txt", "README.md", "conftest.py"):
        assert needed in names
    assert any(name.startswith("notebooks/") and name.endswith(".ipynb") for name in names)
    assert not any(name.endswith(".npz") or name.startswith("data/audio/") for name in names)
    if (REPO / ".ci" / "run").exists():
        assert (edition / ".ci" / "run").stat().st_mode & 0o111


def test_the_editions_requirements_are_the_kits_without_the_instructors_own(edition):
    """Issue 32.3: the edition installs what the student's side runs; a requirement whose comment
    says "Instructor's kit only:" (the test command's -n 3, the similarity report's copydetect, the browser
    tests' axe-core) stays with the instructor."""
    def requirements(text):
        return [line.split(">")[0].split("=")[0] for line in text.splitlines() if line.strip() and not line.startswith("#")]

    kit = requirements((REPO / "requirements.txt").read_text())
    students = requirements((edition / "requirements.txt").read_text())
    instructors = ("pytest-xdist", "copydetect", "axe-playwright-python")
    assert set(instructors) <= set(kit) and not set(instructors) & set(students)
    assert students == [name for name in kit if name not in instructors]
    assert "Instructor's kit only" not in (edition / "requirements.txt").read_text()


def test_no_marker_and_no_solution_line_reaches_the_students(edition):
    for name in _tree(edition):
        if name.endswith((".py", ".ipynb")):
            text = (edition / name).read_text(encoding="utf-8")
            assert not MARKER.search(text), name
            source = REPO / name
            outside = _lines_outside_blocks(source)
            for todo, body, _ in _source_blocks(source):
                for line in body:
                    stripped = line.strip()
                    if len(stripped) > 12 and not stripped.startswith("#") and stripped not in outside:
                        assert stripped not in text, f"{name}: solution line of TODO {todo} leaked: {stripped}"


def _lines_outside_blocks(path):
    inside = {line.strip() for _, body, _ in _source_blocks(path) for line in body}
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".ipynb":
        text = "\n".join("".join(cell["source"]) for cell in json.loads(text)["cells"])
    return {line.strip() for line in text.split("\n")} - inside


def test_library_blocks_become_todo_stubs(edition):
    """Each block becomes the student's start between kept TODO markers: the hint, then its STUB
    lines or ``pass``; the skeleton around it is the source's, line for line."""
    seen = set()
    for path in sorted((REPO / "hwlib").rglob("*.py")):
        name = path.relative_to(REPO).as_posix()
        student = (edition / name).read_text(encoding="utf-8")
        for todo, body, _ in _source_blocks(path):
            seen.add(todo)
            stub = re.compile(rf"^([ \t]*)### BEGIN TODO {re.escape(todo)}\n\1# TODO {re.escape(todo)}: .+\n"
                              rf"(\1.*\n)*?\1### END TODO {re.escape(todo)}$", re.M)
            assert stub.search(student), f"{name}: no stub for TODO {todo}"
        outside = [line for line in path.read_text().split("\n") if line not in {l for _, b, _ in _source_blocks(path) for l in b}
                   and not MARKER.search(line)]
        student_lines = student.split("\n")
        assert all(line in student_lines for line in outside), name
    assert {"1.1.1", "1.2.1", "1.3.1", "1.3.2", "1.3.3", "2.1.1", "2.2.1", "2.2.2", "2.2.3", "2.3.1"} <= seen


def test_no_answer_reaches_the_students_another_way(edition):
    """The gradient of 2.1.1 and the labels of 2.3.1 appear nowhere: not in docstrings, tests,
    benchmarks or notebooks."""
    leaks = re.compile(r"\.T *@|== *class_index|y_i - p_i|y - \\sigma|targets - |labels - sigmoid")
    for name in _tree(edition):
        if name.endswith((".py", ".ipynb", ".md", ".txt")):
            text = (edition / name).read_text(encoding="utf-8")
            assert not leaks.search(text), f"{name}: {leaks.search(text)[0]!r}"
    student_tests = (edition / "tests" / "unit" / "test_logreg.py").read_text()
    assert "def test_gradient_check_passes_for_the_analytic_gradient" in student_tests
    solution_tests = (REPO / "tests" / "instructor" / "test_solutions.py").read_text()
    assert "def test_gradient_matches_the_closed_form" in solution_tests and leaks.search(solution_tests)  # it can fail
    assert not (edition / "tests" / "instructor").exists()


def test_module_level_block_becomes_none_and_the_module_still_imports(edition):
    text = (edition / "hwlib" / "settings.py").read_text()
    assert re.search(r"^### BEGIN TODO 1\.3\.3\n(# .+\n)+LEARNING_RATE = None\n### END TODO 1\.3\.3$", text, re.M)


def test_every_line_of_a_module_level_or_notebook_stub_fits_an_editors_view(edition):
    """Their hint comments are wrapped (issue 32.5: ``LEARNING_RATE = None  # TODO ...`` was 160
    characters); a function stub's hint stays one line, the notebooks' links count the lines below it."""
    texts = [(edition / name).read_text(encoding="utf-8") for name in _tree(edition) if name.startswith("hwlib/")
             and name.endswith(".py")]
    texts += ["".join(cell["source"]) for path in (edition / "notebooks").glob("*.ipynb")
              for cell in json.loads(path.read_text(encoding="utf-8"))["cells"] if cell["cell_type"] == "code"]
    stubs = [stub for text in texts for stub in re.findall(r"^### BEGIN TODO .*?### END TODO", text, re.M | re.S)]
    assert sorted(re.match(r"### BEGIN TODO (\S+)", stub)[1] for stub in stubs) == ["1.1.2", "1.3.3", "2.3.2"]
    long = [line for stub in stubs for line in stub.split("\n") if len(line) > HINT_WIDTH]
    assert not long, long


def test_every_module_of_the_student_edition_imports(edition):
    modules = sorted(
        name for _, name, _ in pkgutil.walk_packages([str(edition / "hwlib")], prefix="hwlib.")
    )
    assert "hwlib.settings" in modules and not (edition / "instructor").exists()
    code = "import importlib, sys\nfor name in sys.argv[1:]:\n    importlib.import_module(name)\nimport hwlib\nprint(hwlib.__file__)"
    env = dict(os.environ, PYTHONPATH=str(edition), MPLBACKEND="Agg")
    tools = sorted(".".join(path.relative_to(edition).with_suffix("").parts).removesuffix(".__init__")
                   for path in (edition / "hwtools").rglob("*.py")  # its own files (walk_packages imports this kit's)
                   if path.name != "__main__.py")  # a command's module runs the command
    assert "hwtools.grade.sandbox" in tools and not any(".instructor" in name for name in tools)  # issue 32.3
    result = subprocess.run([sys.executable, "-c", code, "hwlib", *modules, "hwtools", *tools], cwd=edition, env=env,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert Path(result.stdout.strip()).resolve().is_relative_to(edition.resolve())


def test_notebooks_are_valid_without_outputs_and_with_stubs(edition):
    notebooks = sorted((REPO / "notebooks").glob("*.ipynb"))
    assert notebooks
    for source in notebooks:
        student_path = edition / "notebooks" / source.name
        notebook = nbformat.read(student_path, as_version=4)
        nbformat.validate(notebook)
        assert "widgets" not in notebook.metadata
        original = json.loads(source.read_text(encoding="utf-8"))["cells"]
        assert len(notebook.cells) == len(original)
        for cell, before in zip(notebook.cells, original):
            assert cell.get("id") == before.get("id")
            if cell.cell_type == "code":
                assert cell.outputs == [] and cell.execution_count is None
                assert "execution" not in cell.metadata
            source_text = "".join(before["source"])
            if "BEGIN SOLUTION" not in source_text:
                assert cell.source == source_text
            elif cell.cell_type == "code":
                assert re.search(r"^### BEGIN TODO \d+(\.\d+)+\n# TODO \d+(\.\d+)+: .+$", cell.source, re.M)
                assert re.search(r"^### END TODO \d+(\.\d+)+$", cell.source, re.M)
            else:
                assert "YOUR ANSWER HERE" in cell.source
        stored = student_path.read_text(encoding="utf-8")
        assert stored == nbformat.writes(notebook) + "\n"  # the layout Jupyter itself writes


def test_pyproject_runs_the_notebooks_lax(edition):
    source = (REPO / "pyproject.toml").read_text()
    student = (edition / "pyproject.toml").read_text()
    assert re.search(r'^addopts = ".*--nbval-lax', student, re.M)
    assert not re.search(r"--nbval(?![-\w])", student)
    assert student.replace("--nbval-lax", "--nbval") == source


def test_the_student_readme_is_one_page_and_names_only_what_the_edition_has(edition):
    """The edition's README is docs/student-README.md, at most 8 KB, and every file, module, name and
    link it mentions is in the edition (doc_mentions.py; test_docs.py shows the check can fail)."""
    readme = (edition / "README.md").read_bytes()
    assert readme == (REPO / STUDENT_README).read_bytes()
    assert len(readme) <= 8 * 1024, f"the student README is {len(readme)} bytes: more than one page"
    names = [path.relative_to(edition).as_posix() for path in edition.rglob("*") if path.is_file()]
    lacking = missing(readme.decode("utf-8"), Kit(edition, names), "README.md")
    assert not lacking, f"the student README names what the edition lacks: {lacking}"


def _install_variants(readme):
    """{first word of its bold label: the words of its code block, line by line} of the README's "Install and open"."""
    section = readme.split("## Install and open", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"\*\*(\w+)[^*]*\*\*[^\n]*\n\n```\w*\n(.*?)```", section, flags=re.DOTALL)
    return {label: [line.split() for line in block.splitlines()] for label, block in blocks}


def test_the_student_readme_installs_with_the_editions_files_on_macos_linux_windows_and_conda(edition):
    """Each install variant makes its environment, installs requirements.txt and opens problem 1 in this folder;
    every file or folder it names is the edition's or the environment's programs, in the folder Python's own
    install schemes give (``bin`` on macOS and Linux, ``Scripts`` on Windows) with the system's separator; the
    Windows lines run in PowerShell 5 (no ``&&``). Elsewhere, a ``.venv/bin/`` command has its Windows spelling."""
    readme = (edition / "README.md").read_text(encoding="utf-8")
    variants = _install_variants(readme)
    assert set(variants) == {"macOS", "Windows", "conda"}, variants
    scripts = {label: sysconfig.get_paths(scheme, vars={"base": ".venv", "platbase": ".venv"})["scripts"] + "/"
               for label, scheme in (("macOS", "posix_prefix"), ("Windows", "nt"))}
    scripts["Windows"] = scripts["Windows"].replace("/", "\\")
    tested = versions_tested()  # the Windows line picks one of them (py -3.12): py alone takes the newest installed
    first = {"macOS": ["python3", "-m", "venv", ".venv"], "Windows": ["py", f"-{variants['Windows'][0][1][1:]}", "-m",
                                                                    "venv", ".venv"], "conda": ["conda", "create"]}
    assert variants["Windows"][0][1][1:] in tested, variants["Windows"][0]
    assert f"Python {tested[0]} to {tested[-1]}" in readme  # the tested versions, as pyproject.toml states them
    for label, lines in variants.items():
        words = [word for line in lines for word in line]
        assert lines[0][:len(first[label])] == first[label], (label, lines[0])
        assert "requirements.txt" in words and "--notebook-dir=." in words, (label, lines)
        assert lines[-1][0].endswith("jupyter") and lines[-1][1] == "lab", (label, lines[-1])  # opens JupyterLab
        other_separator = "/" if label == "Windows" else "\\"
        assert not any(other_separator in word for word in words), (label, lines)
        named = [word for word in words if "/" in word or "\\" in word or word.endswith((".txt", ".ipynb"))]
        for word in named:
            if word.startswith(".venv"):
                assert label in scripts and word in (scripts[label] + "python", scripts[label] + "jupyter"), (label, word)
            else:
                assert (edition / word.replace("\\", "/")).exists(), f"{label}: {word} is not in the edition"
        assert any(word.endswith("p1_cartpole_finite_difference.ipynb") for word in named), label
        if label == "Windows":
            assert "&&" not in " ".join(words), lines
    outside = re.sub(r"```.*?```", "", readme.split("## Install and open", 1)[1].split("\n## ", 1)[1], flags=re.DOTALL)
    for program in re.findall(r"\.venv/bin/(\w+)", outside):
        assert f"{scripts['Windows']}{program}" in outside, f".venv/bin/{program} without its Windows spelling"


def test_the_student_edition_ships_the_tests_of_the_homework_only(edition):
    """The student's tests are tests/unit/ (with the fixture they share, tests/conftest.py), shipped as they
    are; every other folder of tests/ stays with the instructor, a new one too (instructor/kit.py)."""
    tests = [name for name in kit_files(REPO) if name.startswith("tests/")]
    shipped = {name for name in _tree(edition) if name.startswith("tests/")}
    assert shipped == {name for name in tests if name == "tests/conftest.py" or name.startswith("tests/unit/")}
    assert all((edition / name).read_bytes() == (REPO / name).read_bytes() for name in shipped)
    for module in ("cartpole", "finite_diff", "policy_search", "logreg", "todo"):  # a test file per homework module
        assert f"tests/unit/test_{module}.py" in shipped, module
    left_out = {"instructor"} | {Path(name).stem for name in tests if name.endswith(".py") and name not in shipped}
    assert {"day_one", "process_watch", "containers", "lab_under_test", "test_grading"} <= left_out
    for name in shipped:  # none imports or runs what the edition leaves out (tests/instructor/test_student_path.py runs them)
        text = (edition / name).read_text()
        imported = {alias.name.split(".")[0] for node in ast.walk(ast.parse(text)) if isinstance(node, ast.Import)
                    for alias in node.names}
        imported |= {(node.module or "").split(".")[0] for node in ast.walk(ast.parse(text)) if isinstance(node, ast.ImportFrom)}
        assert not imported & left_out and '"instructor.' not in text, name
    pyproject = (edition / "pyproject.toml").read_text()
    assert re.search(r"^timeout = \d+$", pyproject, re.M)  # every test of the edition has a time limit


def test_a_failed_build_leaves_nothing_half_built(tmp_path, monkeypatch):
    import hwtools.grade

    source = make_kit(tmp_path / "src")
    out = tmp_path / "out"

    def fails(*args, **kwargs):
        raise RuntimeError("the reference fails a visible check")

    monkeypatch.setattr(hwtools.grade, "write_answer_key", fails)
    with pytest.raises(RuntimeError, match="the reference fails"):
        build_student_edition(source, out)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["src"]  # no out/, no temporary folder beside it
    build_student_edition(source, out, answer_key=False)
    before = _tree(out)
    with pytest.raises(RuntimeError, match="the reference fails"):
        build_student_edition(source, out, force=True)
    assert _tree(out) == before and sorted(path.name for path in tmp_path.iterdir()) == ["out", "src"]
    (source / "hwlib" / "extra.py").write_text("x = 1\n")
    build_student_edition(source, out, force=True, answer_key=False)  # replaced once the new one is complete
    assert "hwlib/extra.py" in _tree(out) and sorted(path.name for path in tmp_path.iterdir()) == ["out", "src"]


def test_keep_puts_solutions_back_and_everything_kept_equals_the_source(tmp_path):
    everything = frozenset({"1.1.1", "1.1.2", "1.1.3", "1.2.1", "1.3.1", "1.3.2", "1.3.3",
                            "2.1.1", "2.2.1", "2.2.2", "2.2.3", "2.3.1", "2.3.2"})
    files = student_files(REPO, keep=everything)
    for name in ("hwlib/cartpole.py", "hwlib/finite_diff.py", "hwlib/policy_search.py", "hwlib/logreg.py"):
        source_lines = [re.sub(r"SOLUTION", "TODO", line) for line in (REPO / name).read_text().split("\n")
                        if not re.search(r"### (HINT|STUB):", line)]
        assert files[name][0].decode().split("\n") == source_lines
    partial = student_files(REPO, keep=frozenset({"1.2.1"}))
    finite_diff = partial["hwlib/finite_diff.py"][0].decode()
    assert "(2.0 * h[i])" in finite_diff and "### BEGIN TODO 1.2.1" in finite_diff
    assert "# TODO 1.1.1: " in partial["hwlib/cartpole.py"][0].decode()


# --------------------------------------------------------------------------------------------
# Rules, on a made-up kit
# --------------------------------------------------------------------------------------------

PYPROJECT = """\
[tool.pytest.ini_options]
testpaths = ["tests", "notebooks"]
addopts = "--nbval --nbval-current-env -p no:cacheprovider"
"""

MODULE = '''\
"""A module with two TODOs."""

import numpy as np

### BEGIN SOLUTION 1.3.3
RATE = 0.5
### END SOLUTION 1.3.3


def double(x):
    """Twice x."""
    x = np.asarray(x)
    ### BEGIN SOLUTION 1.1.1
    ### HINT: multiply by two
    result = 2 * x
    return result
    ### END SOLUTION 1.1.1


class Thing:
    def value(self):
        if True:
            ### BEGIN SOLUTION 1.2.1
            return 3
            ### END SOLUTION 1.2.1
        return 0
'''


def _notebook(cells):
    notebook = nbformat.v4.new_notebook()
    for index, (kind, source) in enumerate(cells):
        cell = nbformat.v4.new_code_cell(source) if kind == "code" else nbformat.v4.new_markdown_cell(source)
        cell["id"] = f"cell{index}"
        if kind == "code":
            cell["execution_count"] = index + 1
            cell["outputs"] = [nbformat.v4.new_output("stream", name="stdout", text="hello\n")]
            cell["metadata"]["execution"] = {"iopub.execute_input": "2026-01-01T00:00:00Z"}
        notebook.cells.append(cell)
    notebook.metadata["widgets"] = {"application/vnd.jupyter.widget-state+json": {"state": {}}}
    return nbformat.writes(notebook) + "\n"


NOTEBOOK_CELLS = [
    ("markdown", "# Title"),
    ("code", "import numpy as np"),
    ("code", "### BEGIN SOLUTION 1.1.2\nanswer = 42\nprint(answer)\n### END SOLUTION 1.1.2\nprint('after')"),
    ("markdown", "Derive it.\n<!-- BEGIN SOLUTION 2.1.1 -->\n$$x^2$$\n<!-- END SOLUTION 2.1.1 -->\nDone."),
]


def make_kit(root, module=MODULE, notebook_cells=NOTEBOOK_CELLS):
    files = {
        "pyproject.toml": PYPROJECT,
        "README.md": "# The kit\n\nFor instructors: secret.\n",
        "docs/student-README.md": "# The kit\n\nFor students.\n",
        "docs/grading.md": "secret\n",
        "hwlib/__init__.py": "",
        "hwlib/mod.py": module,
        "instructor/release.py": "# the tool\n",
        "notebooks/nb.ipynb": _notebook(notebook_cells),
        "tests/conftest.py": "import pytest\n",
        "tests/unit/test_mod.py": "def test_x():\n    pass\n",
        "tests/test_loose.py": "def test_y():\n    pass\n",
        "tests/newkind/test_new.py": "def test_z():\n    pass\n",
        "instructor/hidden_checks/__init__.py": "HIDDEN_SEED = 1\n",
        "instructor/wrong_solutions/mistake.txt": "# todo: 1.1.1\n",
        "tests/instructor/test_release.py": "def test_release():\n    pass\n",
        "data/README.md": "where the data goes\n",
        "data/data.npz": "not really\n",
        "data/audio/0_apple.wav": "not really\n",
        ".venv/lib/site.py": "x\n",
        "hwlib/__pycache__/mod.cpython-311.pyc": "x\n",
        "build/lib/hwlib/mod.py": "x\n",
        "hwlib.egg-info/PKG-INFO": "x\n",
        "test-artifacts/shot.png": "x\n",
        # What JupyterLab and editors leave beside the files: never part of the edition.
        "hwlib/.ipynb_checkpoints/mod-checkpoint.py": MODULE,
        "notebooks/.ipynb_checkpoints/nb-checkpoint.ipynb": "{}\n",
        "hwlib/mod.py~": MODULE,
        "hwlib/.mod.py.swp": "b0VIM\n",
        "README.md~": "# The kit\nsecret\n",
    }
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def test_made_up_kit_student_edition(tmp_path):
    source = make_kit(tmp_path / "src")
    build_student_edition(source, tmp_path / "out", answer_key=False)
    names = sorted(_tree(tmp_path / "out"))
    assert names == ["README.md", "data/README.md", "hwlib/__init__.py", "hwlib/mod.py", "notebooks/nb.ipynb", "pyproject.toml",
                     "tests/conftest.py", "tests/unit/test_mod.py"]  # of tests/, the student's folder only
    module = (tmp_path / "out" / "hwlib" / "mod.py").read_text()
    assert re.search(r"^# TODO 1\.3\.3: .+\nRATE = None$", module, re.M)
    assert ("    x = np.asarray(x)\n    ### BEGIN TODO 1.1.1\n    # TODO 1.1.1: multiply by two\n    pass\n"
            "    ### END TODO 1.1.1\n\n") in module
    assert "        if True:\n            ### BEGIN TODO 1.2.1\n            # TODO 1.2.1: " in module
    assert "result = 2 * x" not in module and "return 3" not in module
    compile(module, "mod.py", "exec")
    notebook = nbformat.read(tmp_path / "out" / "notebooks" / "nb.ipynb", as_version=4)
    hint = notebook.cells[2].source.split(": ", 1)[1].split("\n")[0]
    assert notebook.cells[2].source == (f"### BEGIN TODO 1.1.2\n# TODO 1.1.2: {hint}\n# YOUR CODE HERE\nraise NotImplementedError()\n"
                                        "### END TODO 1.1.2\nprint('after')")
    assert notebook.cells[3].source == "Derive it.\nYOUR ANSWER HERE\nDone."
    assert all(cell.get("outputs", []) == [] for cell in notebook.cells)
    assert (tmp_path / "out" / "README.md").read_text() == "# The kit\n\nFor students.\n"  # docs/student-README.md


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_files_come_from_git_when_the_kit_is_a_repository(tmp_path):
    source = make_kit(tmp_path / "src")
    (source / ".gitignore").write_text("ignored.txt\n")
    (source / "ignored.txt").write_text("x\n")
    (source / "untracked.txt").write_text("x\n")
    git = ["git", "-C", str(source), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "hwlib/mod.py", "README.md"], check=True)
    names = kit_files(source)
    assert "untracked.txt" in names and "hwlib/mod.py" in names and ".gitignore" in names
    assert "ignored.txt" not in names
    assert not any(name.startswith((".git/", ".venv/", "build/", "test-artifacts/")) or ".egg-info" in name or name.endswith(".npz") for name in names)


@pytest.mark.parametrize(
    ("module", "message"),
    [
        ("x = 1\n### BEGIN SOLUTION 1.1.1\ny = 2\n", r"hwlib/mod\.py:2: BEGIN SOLUTION 1\.1\.1 has no END SOLUTION"),
        ("def f():\n    return 1\n    ### END SOLUTION 1.1.1\n", r"hwlib/mod\.py:3: END SOLUTION 1\.1\.1 without a BEGIN"),
        ("def f():\n    ### BEGIN SOLUTION 1.1.1\n    ### BEGIN SOLUTION 1.2.1\n    return 1\n    ### END SOLUTION 1.2.1\n    ### END SOLUTION 1.1.1\n",
         r"hwlib/mod\.py:3: nested BEGIN SOLUTION 1\.2\.1: BEGIN SOLUTION 1\.1\.1 of hwlib/mod\.py:2 is still open"),
        ("def f():\n    ### BEGIN SOLUTION 1.1.1\n    return 1\n    ### END SOLUTION 1.2.1\n",
         r"hwlib/mod\.py:4: END SOLUTION 1\.2\.1 closes BEGIN SOLUTION 1\.1\.1 of hwlib/mod\.py:2: the ids differ"),
        ("def f():\n    ### BEGIN SOLUTION\n    return 1\n    ### END SOLUTION\n", r"hwlib/mod\.py:2: solution marker without a TODO id"),
        ("def f():\n    ### BEGIN SOLUTION 9.9.9\n    return 1\n    ### END SOLUTION 9.9.9\n", r"hwlib/mod\.py:2: unknown TODO id 9\.9\.9"),
        ("def f():\n    ### BEGIN SOLUTION one\n    return 1\n", r"hwlib/mod\.py:2: 'one' is not a TODO id"),
        ("def f():\n    # BEGIN SOLUTION 1.1.1\n    return 1\n", r"hwlib/mod\.py:2: malformed solution marker"),
        ("def f():\n    ### BEGIN SOLUTION 1.1.1\n    return 1\n### END SOLUTION 1.1.1\n", r"hwlib/mod\.py:4: END SOLUTION 1\.1\.1 is not indented like its BEGIN"),
        ("### BEGIN SOLUTION 1.3.3\nprint('hi')\n### END SOLUTION 1.3.3\n", r"hwlib/mod\.py:2: a module-level solution block may only assign names"),
    ],
    ids=["begin-without-end", "end-without-begin", "nested", "mismatched-ids", "no-id", "unknown-id", "bad-id",
         "malformed", "end-indentation", "module-level-code"],
)
def test_marker_errors_name_the_file_and_line(tmp_path, module, message):
    source = make_kit(tmp_path / "src", module=module)
    with pytest.raises(ReleaseError, match=message):
        build_student_edition(source, tmp_path / "out")
    assert not (tmp_path / "out").exists()  # nothing is written on an error


def test_notebook_marker_errors_name_the_file_line_and_cell(tmp_path):
    cells = [("code", "x = 1"), ("code", "y = 2\n### BEGIN SOLUTION 1.1.2\nanswer = 42")]
    source = make_kit(tmp_path / "src", notebook_cells=cells)
    raw_lines = (source / "notebooks" / "nb.ipynb").read_text().split("\n")
    file_line = next(number for number, line in enumerate(raw_lines, 1) if "BEGIN SOLUTION 1.1.2" in line)
    with pytest.raises(ReleaseError, match=rf"notebooks/nb\.ipynb:{file_line} \(cell 2, line 2 of the cell\): BEGIN SOLUTION 1\.1\.2 has no END"):
        build_student_edition(source, tmp_path / "out")
    markdown = [("markdown", "<!-- BEGIN SOLUTION 2.1.1 -->\nx\n<!-- END SOLUTION 2.3.2 -->")]
    source2 = make_kit(tmp_path / "src2", notebook_cells=markdown)
    with pytest.raises(ReleaseError, match=r"nb\.ipynb:\d+ \(cell 1, line 3 of the cell\): END SOLUTION 2\.3\.2 closes BEGIN SOLUTION 2\.1\.1"):
        build_student_edition(source2, tmp_path / "out2")


def test_replacement_must_match_the_blocks(tmp_path):
    text = "def f():\n    ### BEGIN SOLUTION 1.1.1\n    return 1\n    ### END SOLUTION 1.1.1\n"
    assert transform_python(text, "m.py", replace={"1.1.1": "return 2"}) == (
        "def f():\n    ### BEGIN TODO 1.1.1\n    return 2\n    ### END TODO 1.1.1\n")
    with pytest.raises(ReleaseError, match="TODO 1.2.1 has 0 solution block"):
        transform_python(text, "m.py", replace={"1.2.1": "return 2"})
    with pytest.raises(ReleaseError, match="TODO 1.1.1 has 1 solution block.*but 2 replacement"):
        transform_python(text, "m.py", replace={"1.1.1": ["return 2", "return 3"]})
    notebook = _notebook([("code", "### BEGIN SOLUTION 1.1.2\nx = 1\n### END SOLUTION 1.1.2")])
    replaced = json.loads(transform_notebook(notebook, "nb.ipynb", replace={"1.1.2": "x = 2"}))
    assert "".join(replaced["cells"][0]["source"]) == "x = 2"


def test_command_line_refuses_to_overwrite_and_replaces_an_earlier_edition_with_force(tmp_path):
    source = make_kit(tmp_path / "src")
    command = [sys.executable, "-m", "instructor.release", "student", "--no-answer-key"]
    env = dict(os.environ, PYTHONPATH=str(REPO))

    def run(*args):
        return subprocess.run([*command, *args, "--source", str(source)], cwd=tmp_path, env=env, capture_output=True, text=True)

    first = run(str(tmp_path / "out"))
    assert first.returncode == 0 and "student edition: 8 files" in first.stdout
    again = run(str(tmp_path / "out"))
    assert again.returncode == 1 and "not empty (pass --force" in again.stderr
    (tmp_path / "out" / "stale.txt").write_text("from an earlier build\n")
    forced = run(str(tmp_path / "out"), "--force")
    assert forced.returncode == 0 and not (tmp_path / "out" / "stale.txt").exists()
    (tmp_path / "precious").mkdir()
    (tmp_path / "precious" / "thesis.tex").write_text("x\n")
    refused = run(str(tmp_path / "precious"), "--force")
    assert refused.returncode == 1 and "not a kit; refusing to delete it" in refused.stderr
    assert (tmp_path / "precious" / "thesis.tex").exists()
    inside = run(str(source))
    assert inside.returncode == 1 and "must not be the kit" in inside.stderr
    broken = make_kit(tmp_path / "broken", module="### BEGIN SOLUTION 1.1.1\nx = 1\n")
    result = subprocess.run([*command, str(tmp_path / "out3"), "--source", str(broken)], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert result.returncode == 1 and "hwlib/mod.py:1: BEGIN SOLUTION 1.1.1 has no END SOLUTION" in result.stderr


# --------------------------------------------------------------------------------------------
# "Not done yet": an untouched function stub raises TodoNotDone, naming its TODO
# --------------------------------------------------------------------------------------------

TODO_MODULE = '''"""The kit's "not done yet" (a stand-in for hwlib/machinery/todos.py)."""


class TodoNotDone(NotImplementedError):
    def __init__(self, todo):
        super().__init__(f"TODO {todo} is not done yet")
        self.todo = todo
'''


def _with_not_done(module):
    return module.replace("import numpy as np\n", "import numpy as np\n\nfrom hwlib.machinery.todos import TodoNotDone\n", 1)


def _write_todo_module(source):
    (source / "hwlib" / "machinery").mkdir(exist_ok=True)
    (source / "hwlib" / "machinery" / "todos.py").write_text(TODO_MODULE)


def test_function_stubs_raise_todo_not_done_where_the_kit_defines_it(tmp_path):
    source = make_kit(tmp_path / "src", module=_with_not_done(MODULE))
    _write_todo_module(source)
    build_student_edition(source, tmp_path / "out", answer_key=False)
    module = (tmp_path / "out" / "hwlib" / "mod.py").read_text()
    assert ("    x = np.asarray(x)\n    ### BEGIN TODO 1.1.1\n    # TODO 1.1.1: multiply by two\n"
            '    raise TodoNotDone("1.1.1")\n    ### END TODO 1.1.1\n') in module
    assert re.search(r'^            # TODO 1\.2\.1: .+\n            raise TodoNotDone\("1\.2\.1"\)\n            ### END TODO 1\.2\.1$',
                     module, re.M)
    assert re.search(r"^RATE = None$", module, re.M) and "pass" not in module  # module level: still None
    code = ("import hwlib.mod as m\nfrom hwlib.machinery.todos import TodoNotDone\nfor call in (lambda: m.double(1), lambda: m.Thing().value()):\n"
            "    try:\n        call()\n    except TodoNotDone as error:\n        print(error.todo)\nprint(m.RATE)")
    result = subprocess.run([sys.executable, "-c", code], cwd=tmp_path / "out", capture_output=True, text=True,
                            env=dict(os.environ, PYTHONPATH=str(tmp_path / "out")))
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["1.1.1", "1.2.1", "None"]


def test_a_module_with_a_function_stub_must_import_todo_not_done(tmp_path):
    source = make_kit(tmp_path / "src")  # MODULE does not import it
    _write_todo_module(source)
    with pytest.raises(ReleaseError, match=r"hwlib/mod\.py:\d+: the stub of TODO 1\.1\.1 raises TodoNotDone; import it"):
        build_student_edition(source, tmp_path / "out", answer_key=False)


def test_stub_lines_come_before_the_raise_and_a_stub_that_raises_keeps_its_own():
    given = ("from hwlib.machinery.todos import TodoNotDone\n\n\ndef f(x):\n    ### BEGIN SOLUTION 1.1.1\n    ### HINT: h\n"
             "    ### STUB: y = x\n    y = x\n    return 2 * y\n    ### END SOLUTION 1.1.1\n\n\n"
             "def g(x):\n    ### BEGIN SOLUTION 1.2.1\n    ### HINT: h\n    ### STUB: raise ValueError('mine')\n"
             "    return 3\n    ### END SOLUTION 1.2.1\n")
    student = transform_python(given, "m.py")
    assert '    # TODO 1.1.1: h\n    y = x\n    raise TodoNotDone("1.1.1")\n    ### END TODO 1.1.1' in student
    assert "    # TODO 1.2.1: h\n    raise ValueError('mine')\n    ### END TODO 1.2.1" in student
    assert student.count("raise TodoNotDone") == 1


def test_every_function_stub_of_this_kit_raises_todo_not_done(tmp_path):
    """This kit's student edition, with ``hwlib/machinery/todos.py`` and its imports (added here where the kit
    does not have them yet): every block in a function is its hint and ``raise TodoNotDone("id")``,
    every module imports, and an untouched ``scalar_finite_diff`` raises TodoNotDone("1.2.1")."""
    source = tmp_path / "src"
    for name in kit_files(REPO):
        (source / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / name, source / name)
    if not (source / "hwlib" / "machinery" / "todos.py").exists():
        _write_todo_module(source)
    function_todos = {}
    for path in sorted((source / "hwlib").rglob("*.py")):
        found = [block for block, _, _ in file_blocks(path)]
        function_todos.update({block.todo: path for block in found if block.indent})
        text = path.read_text()
        if any(block.indent for block in found) and not re.search(r"^from \S+ import .*\bTodoNotDone\b", text, re.M):
            last_import = max(node.end_lineno for node in ast.parse(text).body if isinstance(node, (ast.Import, ast.ImportFrom)))
            lines = text.split("\n")
            path.write_text("\n".join(lines[:last_import] + ["from hwlib.machinery.todos import TodoNotDone"] + lines[last_import:]))
    assert {"1.1.1", "1.2.1", "1.3.1", "1.3.2", "2.1.1", "2.2.1", "2.2.2", "2.2.3", "2.3.1"} <= set(function_todos)
    out = tmp_path / "student"
    build_student_edition(source, out, answer_key=False)
    for todo, path in function_todos.items():
        student = (out / path.relative_to(source)).read_text()
        assert re.search(rf'^([ \t]+)### BEGIN TODO {re.escape(todo)}\n\1# TODO {re.escape(todo)}: .+\n'
                         rf'\1raise TodoNotDone\("{re.escape(todo)}"\)\n\1### END TODO {re.escape(todo)}$', student, re.M), todo
    assert re.search(r"^LEARNING_RATE = None$", (out / "hwlib" / "settings.py").read_text(), re.M)
    code = ("import hwlib\nfrom hwlib.machinery.todos import TodoNotDone\nfrom hwlib.finite_diff import scalar_finite_diff\n"
            "try:\n    scalar_finite_diff(lambda x: float(x.sum()), [1.0, 2.0], 0.1)\nexcept TodoNotDone as error:\n"
            "    print('raised', *error.args)")
    result = subprocess.run([sys.executable, "-c", code], cwd=out, capture_output=True, text=True,
                            env=dict(os.environ, PYTHONPATH=str(out), MPLBACKEND="Agg"))
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("raised") and "1.2.1" in result.stdout, result.stdout


# --------------------------------------------------------------------------------------------
# Dependencies point one way
# --------------------------------------------------------------------------------------------

ACYCLIC = ("instructor", "hwtools", "hwlib")  # every package of the kit (issue 16.2)


def _imports(package_root):
    """{module: the kit's modules it imports (at any depth of its code)} for the packages in ACYCLIC."""
    modules = {}
    for path in sorted(package_root.rglob("*.py")):
        parts = path.relative_to(package_root).with_suffix("").parts
        if parts[0] in ACYCLIC and "__pycache__" not in parts:
            modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        found = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join([*package.split(".")[:len(package.split(".")) - node.level + 1], *([base] if base else [])])
                targets = [base] + [f"{base}.{alias.name}" for alias in node.names]
            else:
                continue
            for target in targets:
                while target and target not in modules:
                    target = target.rpartition(".")[0]
                if target and target != name and not name.startswith(target + "."):  # a package's own parents
                    found.add(target)
        graph[name] = found
    return graph


def _cycles(graph):
    """The import cycles of ``graph``, each as the list of modules on it."""
    cycles, state = [], {}

    def visit(name, path):
        state[name] = "open"
        for target in sorted(graph[name]):
            if state.get(target) == "open":
                cycles.append(path[path.index(target):] + [target])
            elif target not in state:
                visit(target, [*path, target])
        state[name] = "done"

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])
    return cycles


def test_every_instructor_only_entry_is_a_file_or_folder_of_the_kit():
    """INSTRUCTOR_ONLY and STUDENT_TESTS name what exists: a stale entry would hide that a file it meant moved."""
    names = kit_files(REPO)
    stale = [entry for entry in INSTRUCTOR_ONLY + STUDENT_TESTS
             if not any(name == entry or (entry.endswith("/") and name.startswith(entry)) for name in names)]
    assert stale == []


def test_the_kit_has_no_import_cycles():
    graph = _imports(REPO)
    assert "instructor.kit" in graph["instructor.gradescope_bundle"] and "instructor.release" not in graph["instructor.gradescope_bundle"]
    assert graph["hwtools.markers"] == set()  # the shared reader stands on nothing of the kit
    assert _cycles(graph) == []
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == [["a", "b", "c", "a"]]  # the search does find one
