"""hwlib never imports the tools (hwtools, instructor): the homework stands on its own. (That no
package of the kit has an import cycle is tests/test_release.py::test_the_kit_has_no_import_cycles.)"""

import ast
from pathlib import Path

KIT = Path(__file__).resolve().parents[1]


def test_hwlib_never_imports_the_tools():
    for path in (KIT / "hwlib").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = [alias.name for alias in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            assert not any(name.split(".")[0] in {"hwtools", "instructor"} for name in names), path
