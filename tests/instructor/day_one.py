"""The student edition as a student opens it on day one, for the tests that look at it.

``day_one_edition(out[, tmp_path_factory])`` builds the untouched student edition (``instructor.release``),
whose every stub raises ``TodoNotDone`` when it runs, a notebook cell's too: the tests look at the stubs
the release writes.

``student_python(folder)`` makes a Python like a student's, which has the kit's packages but not the
instructor's tools; ``student_python(folder, foreign=True)`` one whose kit code runs as on Windows
(``foreign_os.py``), to be run with ``kit_env(kit, python)``.

``step_through(path)`` runs every code cell of a notebook in one kernel, on past errors, as a
student pressing Shift-Enter through it does, and gives each cell's outputs.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

KIT = Path(__file__).resolve().parents[2]


def day_one_edition(out, tmp_path_factory=None, **options):
    """The untouched student edition in ``out``: in a test run with the run's one answer key
    (``editions.build``), else (``benchmarks/bench_dayone.py``) as the release builds it."""
    if tmp_path_factory is None:
        from instructor.release import build_student_edition  # noqa: PLC0415 - the instructor's tool

        build_student_edition(KIT, out, **options)
    else:
        from editions import build  # noqa: PLC0415

        build(out, tmp_path_factory, **options)
    return Path(out)


def kit_env(kit, python=None):
    """The environment in which the kit at ``kit`` (not this one) is what Python imports; with the
    ``python`` of ``student_python(..., foreign=True)``, its ``PATH`` has no bubblewrap, ``prlimit``
    or Chromium. The instructor's own pytest options (``PYTEST_ADDOPTS``) are not the student's."""
    env = {key: value for key, value in os.environ.items() if key != "PYTEST_ADDOPTS"}
    env |= {"PYTHONPATH": str(kit), "MPLBACKEND": "Agg"}
    if python is not None and (Path(python).parent.parent / FOREIGN_PROGRAMS).is_dir():
        env["PATH"] = os.pathsep.join((str(Path(python).parent), str(Path(python).parent.parent / FOREIGN_PROGRAMS)))
    return env


FOREIGN_PROGRAMS = "foreign-programs"  # beside a foreign student Python's bin/: the programs its PATH holds


def student_python(folder, foreign=False):
    """A Python like a student's, in the new folder ``folder``: a virtual environment with this
    environment's packages (those of requirements.txt) but not this kit's own (its editable install
    is not read), so ``instructor`` cannot be imported. Run it with ``kit_env(edition, python)``: the
    edition is then on its path, as the edition's own ``pip install -e .`` puts it. ``foreign``: every
    process of it takes Windows's gaps away from the kit's code (``foreign_os.py``)."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(folder)], check=True, timeout=300)
    python = Path(folder) / "bin" / "python"
    purelib = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    Path(purelib, "kit-packages.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    (Path(folder) / "share").symlink_to(Path(sys.prefix) / "share")  # Jupyter's data files (nbconvert's templates)
    if foreign:
        import foreign_os  # noqa: PLC0415 - not installed by importing it

        shutil.copyfile(foreign_os.__file__, Path(purelib, "foreign_os.py"))
        Path(purelib, "foreign-os.pth").write_text("import foreign_os; foreign_os.install()\n")
        foreign_os.stripped_path(Path(folder) / FOREIGN_PROGRAMS)
    return python


STEP_THROUGH = r'''
import json, sys
import nbformat
from nbclient import NotebookClient

path = sys.argv[1]
notebook = nbformat.read(path, as_version=4)
client = NotebookClient(notebook, timeout=900, allow_errors=True, kernel_name="python3",
                        resources={"metadata": {"path": str(__import__("pathlib").Path(path).parent)}})
cells = []
with client.setup_kernel():
    for index, cell in enumerate(notebook.cells):
        if cell.cell_type == "code":
            client.execute_cell(cell, index)
            cells.append({"id": cell.id, "source": cell.source, "outputs": cell.outputs})
json.dump(cells, sys.stdout)
'''


def step_through(notebook, kit):
    """[{"id", "source", "outputs"}] of every code cell of ``notebook``, each run in turn in one
    kernel that imports the kit at ``kit``, whatever the cells before it did."""
    done = subprocess.run([sys.executable, "-c", STEP_THROUGH, str(notebook)], capture_output=True, text=True,
                          env=kit_env(kit), cwd=kit, timeout=1800)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout)


ANSI = re.compile(r"\x1b\[[0-9;]*m")


def first_lines(outputs):
    """The lines a student reads first in a cell's output: an error's traceback as shown, else the printed text."""
    lines = []
    for output in outputs:
        if output["output_type"] == "error":
            lines += ANSI.sub("", "\n".join(output["traceback"])).splitlines()
        elif output["output_type"] == "stream":
            lines += output["text"].splitlines()
    return lines


def error_of(outputs):
    return next((output for output in outputs if output["output_type"] == "error"), None)


RUN_ALL = r'''
import json, sys
import nbformat
from nbclient import NotebookClient
from nbclient.exceptions import CellExecutionError

path = sys.argv[1]
notebook = nbformat.read(path, as_version=4)
client = NotebookClient(notebook, timeout=900, kernel_name="python3",
                        resources={"metadata": {"path": str(__import__("pathlib").Path(path).parent)}})
try:
    client.execute()
    stopped = None
except CellExecutionError:
    stopped = next((cell.id for cell in notebook.cells if cell.cell_type == "code"
                    and any(out.output_type == "error" for out in cell.get("outputs", []))), "?")
ran = [cell.id for cell in notebook.cells if cell.cell_type == "code" and cell.get("execution_count")]
cells = {cell.id: cell.get("outputs", []) for cell in notebook.cells if cell.cell_type == "code"}
json.dump({"stopped": stopped, "ran": ran, "outputs": cells}, sys.stdout)
'''


def run_all(notebook, kit):
    """Run > Run All Cells in a fresh kernel: {"stopped": the id of the cell it stopped at (None if
    none), "ran": ids of the cells that ran, "outputs": {id: outputs}}."""
    done = subprocess.run([sys.executable, "-c", RUN_ALL, str(notebook)], capture_output=True, text=True,
                          env=kit_env(kit), cwd=kit, timeout=1800)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout)
