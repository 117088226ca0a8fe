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
    """The 0-based line JupyterLab's ``#line=`` fragment puts the cursor on: the last line inside the
    TODO's block in the student edition (the stub's line the student replaces). JupyterLab scrolls that
    line just into view, at the editor's bottom edge, so the whole stub shows with the function above it."""
    lines = student_edition_text(relative).split("\n")
    return next(index for index, line in enumerate(lines) if line.strip() == f"### END TODO {todo}") - 1


def todo_links(todo, relative):
    """A TODO's two links to its code, both of a form JupyterLab opens in its own editor (never a second
    JupyterLab in a new browser tab, by mouse or by Enter). The first puts JupyterLab's editor at the TODO
    (``#line=``, 0-based). The second names the line and takes VS Code there (``#L<line>``, 1-based: VS Code
    1.83 and later keep a relative link's fragment and read its leading ``L<digits>``); JupyterLab opens
    the file at its top. Notebook 7 shows either link's file read-only (its ``/tree/`` page sends a file
    to ``/files/``): its students open the file from its file browser (docs/student-README.md)."""
    line = todo_link_line(todo, relative)
    return f"[`{relative}`](../{relative}#line={line}) (VS Code: [line {line + 1}](../{relative}#L{line + 1}))"


def test_every_todo_links_to_its_code_at_its_todo():
    """Every library TODO's code is linked from the notebooks with the two links of ``todo_links``
    (where the heading cell is the student's own answer, as 2.1.1's, they sit just above), and every
    link into hwlib with a fragment is one of them."""
    import json

    from hwlib.machinery.todos import TODO_BY_ID

    want = {todo: todo_links(todo, entry.where[0]) for todo, entry in TODO_BY_ID.items() if entry.where[0].endswith(".py")}
    text = "\n".join("".join(cell["source"]) for path in NOTEBOOKS
                     for cell in json.loads(path.read_text(encoding="utf-8"))["cells"] if cell["cell_type"] == "markdown")
    missing = {todo: links for todo, links in want.items() if links not in text}
    assert not missing, f"TODOs whose code the notebooks do not link at its line: {missing}"
    wanted = "".join(want.values())
    for link in re.findall(r"\]\(\.\./hwlib/[^)]*#[^)]*\)", text):
        assert link in wanted, f"a link {link} that lands on no TODO; the TODOs' links: {want}"
    files = {entry.where[0] for entry in TODO_BY_ID.values()}
    assert not files & set(re.findall(r"\]\(\.\./(hwlib/[\w/]+\.py)\)", text)), "a link to a TODO's file without its line"
