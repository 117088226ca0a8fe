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


OPENBLAS_THREADS = """
import ctypes, os, sys
{imports}
libraries = sorted({{line.split()[-1] for line in open("/proc/self/maps") if "openblas" in line.lower()}})
functions = [getattr(ctypes.CDLL(path), name, None) for path in libraries
             for name in ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_", "openblas_get_num_threads")]
print(next((function() for function in functions if function is not None), "unknown"))
"""


def openblas_threads(imports, **env):
    import os
    import subprocess
    import sys

    environment = {key: value for key, value in os.environ.items() if key not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    done = subprocess.run([sys.executable, "-c", OPENBLAS_THREADS.format(imports=imports)], env={**environment, **env},
                          capture_output=True, text=True, check=True)
    return done.stdout.strip()


def test_importing_hwlib_first_keeps_blas_to_one_thread_unless_it_is_set():
    import pytest

    if openblas_threads("import numpy") == "unknown":
        pytest.skip("this numpy's BLAS is not OpenBLAS")
    assert openblas_threads("import hwlib\nimport numpy") == "1"
    assert openblas_threads("import hwlib\nimport numpy", OPENBLAS_NUM_THREADS="2") == "2"  # a setting of the user's wins
    assert openblas_threads("import numpy\nimport hwlib", OPENBLAS_NUM_THREADS="2") == "2"
