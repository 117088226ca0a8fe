"""Running the two notebooks and reading back what the report needs: the variables of ``NOTEBOOK_VARIABLES``
from each notebook's kernel (written as JSON by one extra cell, no pickle) and the 2.1.1 derivation (Markdown).

Every result is computed once, by the notebooks: ``execute_notebook`` runs a notebook from a fresh kernel
and, in the same kernel after the last cell, the cell of ``export_cell_source``; ``read_exported`` reads
its JSON back, naming what is missing and the cell that makes it.
"""

from __future__ import annotations

import inspect
import json
import os
import re
import sys
from pathlib import Path

KIT_ROOT = Path(__file__).resolve().parent.parent.parent
NOTEBOOK_DIR = KIT_ROOT / "notebooks"
P1_NOTEBOOK = "p1_cartpole_finite_difference.ipynb"
P2_NOTEBOOK = "p2_food_cutting_logistic_regression.ipynb"
NOTEBOOKS = (P1_NOTEBOOK, P2_NOTEBOOK)
CELL_TIMEOUT = 600  # seconds one notebook cell may take

# What the report reads from each notebook's kernel: variable -> the attributes read (() = the value itself).
NOTEBOOK_VARIABLES = {
    P1_NOTEBOOK: {
        "tried": (),
        "random_rewards": (),
        "learning_rate": (),
        "run": ("rewards", "policy.params"),
        "sweep": ("learning_rates", "converged_fraction", "seeds", "deadline"),
    },
    P2_NOTEBOOK: {
        "data": ("names", "source", "path", "labels.shape"),
        "train_accuracies": (),
        "test_accuracy": (),
        "test_predictions": (),
        "y_test": (),
        "first_above_99": (),
    },
}
# Where each variable is made, for the error messages.
VARIABLE_ORIGIN = {
    "tried": "TODO 1.1.2: a dict, name -> the 4 parameters you tried",
    "random_rewards": "1.1.3: the rewards of the random policies",
    "learning_rate": "1.3.3: the learning rate the notebook trains with",
    "run": "1.3.3: the TrainingRun of the notebook's training",
    "sweep": "1.3.3: the learning-rate sweep",
    "data": "the cell that loads the food-cutting data",
    "train_accuracies": "2.3.2: the training accuracy per iteration",
    "test_accuracy": "2.3.2: the test accuracy",
    "test_predictions": "2.3.2: the predictions on the test set",
    "y_test": "the train/test split",
    "first_above_99": "2.3.2: the first iteration above 99%",
}
DERIVATION_TODO = "2.1.1"


class ReportError(Exception):
    """A problem the user can fix: a bad OUT_DIR, a missing notebook, a failing cell, a TODO left."""


def _report_export_variables(namespace, wanted, path):
    """Write the variables ``wanted`` ({name: attribute paths}) of ``namespace`` to ``path`` as JSON.

    Runs INSIDE the notebook's kernel: the report sends this function's source as one extra cell
    after the notebook's last, so it may use nothing from its module. Arrays become nested lists;
    whatever cannot be written is listed under "problems" for the report to explain.
    """
    import json
    from pathlib import Path

    import numpy as np

    def plain(value):
        if value is None or isinstance(value, (bool, str, int, float)):
            return value
        if isinstance(value, np.generic):
            return value.item()
        if isinstance(value, np.ndarray):
            return plain(value.tolist()) if value.dtype == object else value.tolist()
        if isinstance(value, Path):
            return str(value)
        if isinstance(value, dict):
            return {str(key): plain(item) for key, item in value.items()}
        if isinstance(value, (list, tuple)):
            return [plain(item) for item in value]
        raise TypeError(f"a {type(value).__name__}")

    values, problems = {}, []
    for name, attributes in wanted.items():
        if name not in namespace:
            problems.append(f"`{name}` is not defined")
            continue
        entry = {}
        for attribute in attributes or [None]:
            target, label = namespace[name], name
            try:
                for part in attribute.split(".") if attribute else []:
                    label = f"{label}.{part}"
                    target = getattr(target, part)
                entry[attribute] = plain(target)
            except AttributeError:
                problems.append(f"`{name}` has no attribute `{label}` (it is a {type(namespace[name]).__name__})")
            except TypeError as error:
                problems.append(f"`{label}` holds {error}, which the report cannot read")
        if len(entry) == len(attributes or [None]):
            values[name] = entry[None] if not attributes else entry
    Path(path).write_text(json.dumps({"values": values, "problems": problems}), encoding="utf-8")


def export_cell_source(wanted, path):
    """The extra cell run after a notebook's last: ``_report_export_variables`` and one call of it."""
    function = inspect.getsource(_report_export_variables)
    call = f"_report_export_variables(globals(), {dict(wanted)!r}, {str(path)!r})"
    return f"{function}\n\n{call}\ndel _report_export_variables\n"


def native_kernel_dir(tmp_dir):
    """A kernelspec folder whose 'python3' is this very Python, whatever other kernels are installed."""
    from ipykernel.kernelspec import get_kernel_dict

    spec_dir = Path(tmp_dir) / "kernels" / "python3"
    spec_dir.mkdir(parents=True)
    spec = get_kernel_dict()  # ipykernel's own spec, with argv[0] = sys.executable
    spec["argv"][0] = sys.executable
    (spec_dir / "kernel.json").write_text(json.dumps(spec))
    return spec_dir.parent


def execute_notebook(path, kernel_dir, export=None):
    """Run every cell of the notebook at ``path`` in a fresh kernel started in its folder.

    ``export=(wanted, json_path)`` runs one more cell in the same kernel after the last, which
    writes the variables ``wanted`` to ``json_path`` (see ``_report_export_variables``); that cell
    is not part of the notebook returned. The kernel is this environment's Python and sees no
    MPLBACKEND, so figures come out inline as a student sees them. Raises
    ``nbclient.exceptions.CellExecutionError`` if a cell fails.
    """
    import nbformat
    import zmq
    from jupyter_client import KernelManager
    from jupyter_client.kernelspec import KernelSpecManager
    from nbclient import NotebookClient

    notebook = nbformat.read(path, as_version=4)
    if export is not None:
        notebook.cells.append(nbformat.v4.new_code_cell(export_cell_source(*export)))
    env = {key: value for key, value in os.environ.items() if key != "MPLBACKEND"}
    kernel_manager = KernelManager(
        kernel_name="python3", kernel_spec_manager=KernelSpecManager(kernel_dirs=[str(kernel_dir)])
    )
    if zmq.has("curve") and "transport_encryption" in kernel_manager.trait_names():
        kernel_manager.transport_encryption = "auto"  # encrypt the kernel's local sockets where it can
    client = NotebookClient(  # one output per stream, as Jupyter shows it, however the kernel sent it in pieces
        notebook, km=kernel_manager, timeout=CELL_TIMEOUT, kernel_name="python3", coalesce_streams=True,
        resources={"metadata": {"path": str(Path(path).parent)}},
    )
    try:
        client.execute(env=env)
    finally:
        if kernel_manager.has_kernel:
            kernel_manager.shutdown_kernel(now=False)
        if export is not None:
            notebook.cells.pop()
    return notebook


def read_exported(json_path, notebook_name):
    """The values one notebook's extra cell wrote, or a ReportError naming what is missing and where it is made."""
    try:
        exported = json.loads(Path(json_path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise ReportError(f"{notebook_name}: the notebook's values could not be read back: {error}") from None
    if exported["problems"]:
        lines = []
        for problem in exported["problems"]:
            name = re.match(r"`([^`.]+)", problem).group(1)
            lines.append(f"  - {problem} (made in {VARIABLE_ORIGIN.get(name, 'the notebook')})")
        raise ReportError(
            f"{notebook_name}: the report reads these variables after the last cell, and some are missing or "
            "unreadable; keep the notebook's variable names:\n" + "\n".join(lines)
        )
    return exported["values"]


# --- what the report reads from the notebook files themselves -----------------------------------

HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
MARKER_COMMENT = re.compile(r"^\s*<!--.*?-->\s*$")


def derivation_markdown(notebook, todo=DERIVATION_TODO):
    """The Markdown under the notebook's ``todo`` heading (e.g. "### 2.1.1 ..."): the rest of that cell and the
    Markdown cells after it, up to the next heading of the same or a higher level or the next code cell.
    The solution/TODO marker comments are left out; None if the notebook has no such heading."""
    collected, level = [], None
    for cell in notebook.cells:
        if level is not None and cell.cell_type != "markdown":
            break
        if cell.cell_type != "markdown":
            continue
        for line in cell.source.split("\n"):
            heading = HEADING.match(line)
            if level is None:
                if heading and re.match(rf"{re.escape(todo)}\b", heading.group(2)):
                    level = len(heading.group(1))
                continue
            if heading and len(heading.group(1)) <= level:
                return _tidy_markdown(collected)
            if not MARKER_COMMENT.match(line):
                collected.append(line)
        if level is not None:
            collected.append("")
    return None if level is None else _tidy_markdown(collected)


def _tidy_markdown(lines):
    return "\n".join(lines).strip()


def notebook_title(path):
    """The first Markdown heading of the notebook at ``path``."""
    import nbformat

    for cell in nbformat.read(path, as_version=4).cells:
        if cell.cell_type == "markdown":
            match = re.search(r"^#+\s+(.+)$", cell.source, flags=re.MULTILINE)
            if match:
                return match.group(1).strip()
    return Path(path).stem
