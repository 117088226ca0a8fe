"""How hwlib reads: its top level is the homework, the files a student edits hold plain homework code,
and the machinery that makes that code fast or checks it is one subpackage a student never needs to open."""

import ast
import re
from pathlib import Path

KIT = Path(__file__).resolve().parents[2]
HWLIB = KIT / "hwlib"
TODO_BLOCK = re.compile(r"^[ \t]*### BEGIN (?:SOLUTION|TODO) \d\.\d\.\d", re.M)

# What a student opens or calls: the files with TODOs, the settings, the given modules the
# notebooks call, the figures, and the one folder of machinery.
TOP_LEVEL = {"__init__.py", "cartpole.py", "finite_diff.py", "policy_search.py", "logreg.py", "settings.py",
             "training.py", "landscape.py", "widgets.py", "food_data.py", "plots", "machinery"}
STUDENT_FILES = {"cartpole.py", "finite_diff.py", "policy_search.py", "settings.py", "logreg.py"}
# What the files a student edits may take from the machinery: the error a TODO's stub raises and the
# checks at their functions' doors. Nothing that routes, batches or times their code.
STUDENT_MACHINERY = {"hwlib.machinery.todos", "hwlib.machinery.validation"}
# What a student may meet above a function of theirs: the plain Python they know.
PLAIN_DECORATORS = {"property", "staticmethod", "classmethod", "dataclass"}
MACHINERY_WORDS = ("weakref", "threading", "ctypes", "functools", "lru_cache", "route", "session")


def imported_modules(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            yield node.module
            yield from (f"{node.module}.{alias.name}" for alias in node.names)


def test_the_top_level_holds_only_what_a_student_opens_or_calls():
    entries = {path.name for path in HWLIB.iterdir()
               if not path.name.startswith(".") and path.name != "__pycache__"}  # editors' and Python's leftovers
    assert entries == TOP_LEVEL


def test_the_files_a_student_edits_are_the_ones_with_todos():
    with_todos = {path.name for path in HWLIB.rglob("*.py") if TODO_BLOCK.search(path.read_text(encoding="utf-8"))}
    assert with_todos == STUDENT_FILES


def test_the_files_a_student_edits_hold_no_kit_machinery():
    for name in sorted(STUDENT_FILES):
        text = (HWLIB / name).read_text(encoding="utf-8")
        tree = ast.parse(text)
        machinery = {module for module in imported_modules(tree) if module.startswith("hwlib.machinery")}
        allowed = STUDENT_MACHINERY | {f"{module}.{name}" for module in STUDENT_MACHINERY for name in dir(__import__(module, fromlist=["x"]))}
        assert machinery <= allowed, f"hwlib/{name} imports {sorted(machinery - allowed)}"
        for word in MACHINERY_WORDS:
            assert not re.search(rf"\b{word}\b", text, re.I), f"hwlib/{name} mentions {word!r}"
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                for decorator in node.decorator_list:
                    name_of = ast.unparse(decorator.func if isinstance(decorator, ast.Call) else decorator)
                    assert name_of in PLAIN_DECORATORS, f"hwlib/{name}: @{name_of} above {node.name}"


def test_the_machinery_says_students_need_not_read_it_and_names_each_module():
    docstring = ast.get_docstring(ast.parse((HWLIB / "machinery" / "__init__.py").read_text(encoding="utf-8")))
    assert "students need not read this" in docstring
    for path in sorted((HWLIB / "machinery").glob("*.py")):
        if path.name != "__init__.py":
            assert f"``{path.stem}``" in docstring, f"hwlib/machinery/__init__.py does not say what {path.name} does"


def test_every_hwlib_module_opens_with_what_it_holds():
    for path in sorted(HWLIB.rglob("*.py")):
        docstring = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
        assert docstring and len(docstring.split()) >= 4, path.relative_to(KIT)


# --- each TODO heading's link opens its file at the TODO ----------------------------------------

NOTEBOOKS = sorted((KIT / "notebooks").glob("*.ipynb"))


def student_edition_text(relative):
    """The file as the student edition has it: its own text there; here, the instructor's release
    of it (a TODO's stub is shorter or longer than its solution, which moves the lines below it)."""
    text = (KIT / relative).read_text(encoding="utf-8")
    try:
        from instructor.stubs import transform_python  # noqa: PLC0415 - the instructor's edition only
    except ImportError:  # the student edition: the file is its own
        return text
    return transform_python(text, relative, require_not_done=True)


def todo_link_line(todo, relative):
    """The 0-based line JupyterLab's ``#line=`` fragment puts the cursor on: the first line inside
    the TODO's block in the student edition (its hint)."""
    lines = student_edition_text(relative).split("\n")
    return 1 + next(index for index, line in enumerate(lines) if line.strip() == f"### BEGIN TODO {todo}")


def test_every_todo_links_to_its_code_at_its_todo():
    """Every library TODO's code is linked from the notebooks with a #line= fragment that lands on its
    block (where the heading cell is the student's own answer, as 2.1.1's, the link sits just above),
    and every such link lands on a TODO."""
    import json

    from hwlib.machinery.todos import TODO_BY_ID

    want = {(entry.where[0], f"#line={todo_link_line(todo, entry.where[0])}"): todo
            for todo, entry in TODO_BY_ID.items() if entry.where[0].endswith(".py")}
    found = set()
    for path in NOTEBOOKS:
        cells = [cell for cell in json.loads(path.read_text(encoding="utf-8"))["cells"] if cell["cell_type"] == "markdown"]
        for cell in cells:
            for file, fragment in re.findall(r"\]\(\.\./(hwlib/[\w/]+\.py)(#line=\d+)?\)", "".join(cell["source"])):
                if (file, fragment) in want:
                    found.add((file, fragment))
                else:
                    assert not fragment and all(key[0] != file for key in want), \
                        f"{path.name}: a link to {file}{fragment} that lands on no TODO; the TODOs there: " + \
                        ", ".join(f"{todo} {key[1]}" for key, todo in want.items() if key[0] == file)
    missing = {todo: key for key, todo in want.items() if key not in found}
    assert not missing, f"TODOs whose code no notebook links at its line: {missing}"
