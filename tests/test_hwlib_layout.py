"""How hwlib reads: the files a student edits hold plain homework code, and every module reads in one sitting."""

import ast
import re
from pathlib import Path

KIT = Path(__file__).resolve().parents[1]
HWLIB = KIT / "hwlib"
TODO_BLOCK = re.compile(r"^[ \t]*### BEGIN (?:SOLUTION|TODO) \d\.\d\.\d", re.M)
MAX_LINES = 400  # issue 16.3: "no module over about 400 lines"

# What a student may meet above a function of theirs: the plain Python they know.
PLAIN_DECORATORS = {"property", "staticmethod", "classmethod", "dataclass"}
# Kit machinery that belongs in hwlib's underscore modules, not in the files students edit.
MACHINERY = ("weakref", "the door", "_batch", "_replay", "threading", "ctypes", "functools", "lru_cache",
             "plays_rollouts_together")


def student_files():
    files = [path for path in sorted(HWLIB.rglob("*.py"))
             if not path.name.startswith("_") and TODO_BLOCK.search(path.read_text(encoding="utf-8"))]
    assert {path.name for path in files} >= {"cartpole.py", "finite_diff.py", "policy_search.py", "settings.py",
                                             "logreg.py"}
    return files


def test_the_files_a_student_edits_hold_no_kit_machinery():
    for path in student_files():
        text = path.read_text(encoding="utf-8")
        for word in MACHINERY:
            assert not re.search(rf"\b{word}\b", text, re.I), f"{path.relative_to(KIT)} mentions {word!r}"
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                for decorator in node.decorator_list:
                    name = ast.unparse(decorator.func if isinstance(decorator, ast.Call) else decorator)
                    assert name in PLAIN_DECORATORS, f"{path.relative_to(KIT)}: @{name} above {node.name}"


def test_every_hwlib_module_reads_in_one_sitting():
    long = {path.relative_to(KIT).as_posix(): count for path in sorted(HWLIB.rglob("*.py"))
            if (count := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"


def test_every_hwlib_module_opens_with_what_it_holds():
    for path in sorted(HWLIB.rglob("*.py")):
        docstring = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
        assert docstring and len(docstring.split()) >= 4, path.relative_to(KIT)
