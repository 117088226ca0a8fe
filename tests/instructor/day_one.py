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
import tempfile
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
EDITION_TESTS_SECONDS = 1500  # the edition's whole pytest: about 2.5 min at load 3-6 on 2 cores


def assert_edition_tests_pass(python, kit, encoding, only=()):
    """The edition's own test command, ``python -m pytest`` in ``kit`` with the student's ``python``, passes within
    its time limits, its notebooks among its tests (its output read in ``encoding``, the system's pipes'); ``only``:
    the command run on these of its tests alone (``("tests",)``: its unit tests), its notebooks still collected."""
    def pytest(*options, timeout):
        return subprocess.run([str(python), "-m", "pytest", "-q", "-p", "no:cacheprovider", *options], cwd=kit,
                              env=kit_env(kit, python), capture_output=True, encoding=encoding, errors="replace",
                              timeout=timeout)

    assert re.search(r"^timeout = \d+$", (Path(kit) / "pyproject.toml").read_text(), re.M)  # a limit for every test
    done = pytest(*only, timeout=EDITION_TESTS_SECONDS)
    summary = done.stdout.strip().splitlines()[-1] if done.stdout.strip() else ""
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert re.fullmatch(r"=* ?\d+ passed(, \d+ skipped)? in .*", summary.strip("= ")), summary
    assert "notebooks/p2_food_cutting_logistic_regression.ipynb" in pytest("--collect-only", timeout=300).stdout


def versions_tested():
    """The Python versions the student edition is tested on, oldest first: pyproject.toml's classifiers."""
    import tomllib  # noqa: PLC0415 - 3.11+, as the instructor's kit's Python

    classifiers = tomllib.loads((KIT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["classifiers"]
    found = [re.fullmatch(r"Programming Language :: Python :: (3\.\d+)", line) for line in classifiers]
    return sorted((match.group(1) for match in found if match), key=lambda version: tuple(map(int, version.split("."))))


def find_python(version):
    """A CPython ``version`` ("3.10") on this machine, or None: ``python3.10`` on PATH, else one pyenv built
    (``~/.pyenv/versions/3.10.*``); this Python for its own version."""
    if sysconfig.get_python_version() == version:
        return Path(sys.executable)
    for candidate in [*sorted(Path.home().glob(f".pyenv/versions/{version}.*/bin/python{version}"), reverse=True),
                      shutil.which(f"python{version}")]:  # pyenv's shims on PATH only run the version pyenv selects
        if candidate and subprocess.run([str(candidate), "-c", "pass"], capture_output=True, timeout=60).returncode == 0:
            return Path(candidate)
    return None


PACKAGES_CACHE = Path.home() / ".cache" / "hwkit-test-pythons"  # outside the clone: shared by every test run here


def packages_of(python):
    """The site-packages folder of a virtual environment of ``python`` (another version than this one) with the
    kit's requirements installed: built once per machine and requirements (``PACKAGES_CACHE``, under a lock, in
    place only once complete), then shared by every test run, as this environment's own packages are."""
    import fcntl  # noqa: PLC0415 - the instructor's kit runs on Linux
    import hashlib  # noqa: PLC0415

    requirements = [line for line in (KIT / "requirements.txt").read_text().splitlines()
                    if line.strip() and not line.startswith(("#", "-e"))]
    version = subprocess.run([str(python), "-c", "import sys; print('%d.%d.%d' % sys.version_info[:3])"],
                             capture_output=True, text=True, check=True, timeout=60).stdout.strip()
    key = hashlib.sha256("\n".join([version, *requirements]).encode()).hexdigest()[:16]
    venv = PACKAGES_CACHE / f"cpython-{version}-{key}"
    PACKAGES_CACHE.mkdir(parents=True, exist_ok=True)
    with open(PACKAGES_CACHE / ".lock", "w") as lock:  # noqa: PTH123
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not venv.is_dir():
            building = Path(tempfile.mkdtemp(prefix=f".{venv.name}-", dir=PACKAGES_CACHE))
            subprocess.run([str(python), "-m", "venv", str(building)], check=True, timeout=300)
            subprocess.run([str(building / "bin" / "python"), "-m", "pip", "install", "-q", *requirements], check=True,
                           timeout=1800, env={**os.environ, "PIP_DISABLE_PIP_VERSION_CHECK": "1"})
            building.rename(venv)  # its site-packages and share/ are all the tests use of it: they move with it
    purelib = subprocess.run([str(venv / "bin" / "python"), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True, timeout=60).stdout.strip()
    return Path(purelib)


def student_python(folder, foreign=False, system=None, home=None, base=None):
    """A Python like a student's, in the new folder ``folder``: a virtual environment with this
    environment's packages (those of requirements.txt) but not this kit's own (its editable install
    is not read), so ``instructor`` cannot be imported. Run it with ``kit_env(edition, python)``: the
    edition is then on its path, as the edition's own ``pip install -e .`` puts it. ``system``
    ("macos", "windows", "hub"; ``foreign``: "windows"): every process of it behaves as on that system
    (``foreign_os.py``; ``home``: the user's home there, a hub's read-only). ``base``: another Python to make it of (then
    with packages of its own version, ``packages_of``)."""
    base = Path(base or sys.executable)
    subprocess.run([str(base), "-m", "venv", "--without-pip", str(folder)], check=True, timeout=300)
    python = Path(folder) / "bin" / "python"
    purelib = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    same = base == Path(sys.executable)
    packages = sysconfig.get_paths()["purelib"] if same else packages_of(base)
    Path(purelib, "kit-packages.pth").write_text(f"{packages}\n")
    (Path(folder) / "share").symlink_to(Path(sys.prefix if same else Path(packages).parents[2]) / "share")  # Jupyter's data files
    system = system or ("windows" if foreign else None)
    if system:
        import foreign_os  # noqa: PLC0415 - not installed by importing it

        shutil.copyfile(foreign_os.__file__, Path(purelib, "foreign_os.py"))
        Path(purelib, "foreign-os.pth").write_text(
            f"import foreign_os; foreign_os.install({system!r}, home={None if home is None else str(home)!r})\n")
        foreign_os.stripped_path(Path(folder) / FOREIGN_PROGRAMS, system)
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


INTERRUPT = r'''
import json, os, sys, time
from jupyter_client import KernelManager

kit, todo, token = sys.argv[1:4]

def runs():
    """The grader and its workers of this kit: processes whose command line names it (the grader), or whose
    environment carries the token (the workers, started with a clean environment, carry the kit's path)."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == os.getpid():
            continue
        try:
            with open(f"/proc/{entry}/cmdline", "rb") as handle:
                line = handle.read().replace(b"\0", b" ").decode("utf-8", "replace")
        except OSError:
            continue
        if ("hwtools.grade" in line or "worker.py" in line) and token in line:
            found.append(line)
    return found

manager = KernelManager(kernel_name="python3")
manager.start_kernel(cwd=kit)
client = manager.client()
client.start_channels()
client.wait_for_ready(timeout=300)
request = client.execute(f"from hwtools.notebook import check\ncheck({todo!r})")
begun = time.monotonic()
while not any("worker.py" in line for line in runs()):
    if time.monotonic() - begun > 600:
        raise SystemExit("no worker started within 600 s")
    time.sleep(0.05)
time.sleep(1.0)  # the worker is in the student's loop
interrupted = time.monotonic()
manager.interrupt_kernel()
reply = client.get_shell_msg(timeout=600)
while reply["parent_header"].get("msg_id") != request:
    reply = client.get_shell_msg(timeout=600)
ended = time.monotonic() - interrupted
time.sleep(0.2)
left = runs()
client.stop_channels()
manager.shutdown_kernel(now=True)
json.dump({"status": reply["content"]["status"], "error": reply["content"].get("ename"),
           "seconds": round(ended, 2), "left": left}, sys.stdout)
'''


def interrupt_a_check(python, kit, todo):
    """Run ``check(todo)`` in a kernel of ``python`` on the kit at ``kit``, press Kernel > Interrupt once the
    grader's worker runs, and say what happened: {"status", "error" (the cell's), "seconds" (from the interrupt
    to the cell's end), "left" (the command lines of the kit's grader and workers still alive then)}."""
    done = subprocess.run([str(python), "-c", INTERRUPT, str(kit), todo, str(kit)], capture_output=True,
                          env=kit_env(kit, python), cwd=kit, timeout=1800)
    assert done.returncode == 0, done.stderr[-3000:].decode("utf-8", "replace")
    return json.loads(done.stdout)
