"""Dependencies point one way. hwlib never imports the tools (hwtools, instructor): the homework
stands on its own. What runs inside the grader's sandbox (``hwtools/grade/in_sandbox/``, copied
whole into every kit) imports nothing outside its folder. Importing hwlib keeps numpy's BLAS to one
thread unless the user set it. (That no package of the kit has an import cycle is
tests/test_release.py::test_the_kit_has_no_import_cycles.)"""

import ast
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

KIT = Path(__file__).resolve().parents[1]
IN_SANDBOX = KIT / "hwtools" / "grade" / "in_sandbox"


def imports(path):
    """(line, level, module name) of every import statement of the file at ``path``, at any depth."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, 0, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            found.append((node.lineno, node.level, node.module or ""))
    return found


def test_hwlib_never_imports_the_tools():
    for path in (KIT / "hwlib").rglob("*.py"):
        assert not any(name.split(".")[0] in {"hwtools", "instructor"} for _, _, name in imports(path)), path


def test_what_runs_in_the_sandbox_imports_nothing_outside_its_folder(tmp_path):
    """Read: every import of in_sandbox/ is relative to the folder itself, of the standard library,
    or of numpy and gymnasium (the kit's own dependencies, there in the sandbox). Run: the folder,
    copied alone as a kit's ``_hwgrade/`` is, imports in a Python that sees only it and the
    installed packages (not the kit's hwtools or hwlib)."""
    allowed = set(sys.stdlib_module_names) | {"numpy", "gymnasium"}
    for path in sorted(IN_SANDBOX.rglob("*.py")):
        for line, level, name in imports(path):
            where = f"{path.relative_to(KIT)}:{line}"
            assert level <= len(path.relative_to(IN_SANDBOX).parts), f"{where}: imports from outside in_sandbox/ ({'.' * level}{name})"
            assert level > 0 or name.split(".")[0] in allowed, f"{where}: imports {name}, outside in_sandbox/"
    shutil.copytree(IN_SANDBOX, tmp_path / "_hwgrade", ignore=shutil.ignore_patterns("__pycache__"))
    names = sorted(".".join(path.relative_to(IN_SANDBOX).with_suffix("").parts) for path in IN_SANDBOX.rglob("*.py")
                   if path.name != "__init__.py")
    code = (f"import sys; sys.path[:] = [{str(tmp_path)!r}, {sysconfig.get_paths()['purelib']!r}] + "
            "[p for p in sys.path if 'site-packages' not in p]; "
            f"import {', '.join(f'_hwgrade.{name}' for name in names)}")
    # -I: no current folder, no user site; -S: no .pth files, so the kit's editable install is not found
    result = subprocess.run([sys.executable, "-I", "-S", "-c", code], capture_output=True, text=True, timeout=120,
                            cwd=tmp_path)
    assert result.returncode == 0, result.stderr


OPENBLAS_THREADS = """
import ctypes, os, sys
{imports}
libraries = sorted({{line.split()[-1] for line in open("/proc/self/maps") if "openblas" in line.lower()}})
functions = [getattr(ctypes.CDLL(path), name, None) for path in libraries
             for name in ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_", "openblas_get_num_threads")]
print(next((function() for function in functions if function is not None), "unknown"))
"""


def openblas_threads(imports, **env):
    environment = {key: value for key, value in os.environ.items() if key not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    done = subprocess.run([sys.executable, "-c", OPENBLAS_THREADS.format(imports=imports)], env={**environment, **env},
                          capture_output=True, text=True, check=True)
    return done.stdout.strip()


def test_importing_hwlib_first_keeps_blas_to_one_thread_unless_it_is_set():
    if openblas_threads("import numpy") == "unknown":
        pytest.skip("this numpy's BLAS is not OpenBLAS")
    assert openblas_threads("import hwlib\nimport numpy") == "1"
    assert openblas_threads("import hwlib\nimport numpy", OPENBLAS_NUM_THREADS="2") == "2"  # a setting of the user's wins
    assert openblas_threads("import numpy\nimport hwlib", OPENBLAS_NUM_THREADS="2") == "2"
