"""What the report's tests share: notebook values as the notebooks' kernels export them, for the report's pieces
without a notebook run (``hwtools.report.problem_one``, ``problem_two``; an earlier report's answers.tex in
test_other_systems.py), and readers of the executed notebooks' pages the report writes."""

import html
import json
import re
import subprocess
from pathlib import Path

import nbformat

from day_one import kit_env, student_python
from hwlib import settings
from hwtools.check_cell import check_lines
from hwtools.report import NOTEBOOKS

KIT = Path(__file__).resolve().parents[2]

TOP = float(settings.MAX_EPISODE_STEPS)  # the best episode reward
DERIVATION = "Write $z_i = \\tilde w^\\top \\tilde x_i$.\n\n$$\\nabla l = X^\\top (y - p)$$"


def p1_values(**changes):
    values = {
        "tried": {"my first guess": [0.1, -0.2, -1.0, -0.3], "pole angle only": [0, 0, -1, 0]},
        "random_rewards": [9.0, 11.0, TOP, 30.0],
        "learning_rate": 0.0007,
        "run": {"rewards": [9.4, 136.55, TOP, TOP], "policy.params": [0.0081, -0.5874, 0.8861, -1.0]},
        "sweep": {"learning_rates": [1e-4, 1e-3], "converged_fraction": [0.0, 0.95], "seeds": list(range(20)),
                  "deadline": settings.CONVERGENCE_DEADLINE},
    }
    values.update(changes)
    return values


def p2_values():
    return {
        "data": {"names": ["Apple", "Carrot"], "source": "synthetic stand-in", "path": None, "labels.shape": [10]},
        "train_accuracies": [0.5, 0.8, 0.995],
        "test_accuracy": 0.75,
        "test_predictions": [0, 1, 1, 0],
        "y_test": [0, 1, 0, 0],
        "first_above_99": 2,
    }


# --- what the executed notebooks' pages show ------------------------------------------------------------------------


def rendered_texts(page):
    """The texts of an executed notebook's output areas, in order (printed text and plain-text results)."""
    blocks = re.findall(r'<div class="jp-RenderedText[^"]*"[^>]*>\s*<pre>(.*?)</pre>', page, flags=re.DOTALL)
    return [html.unescape(re.sub(r"<[^>]+>", "", block)) for block in blocks]


def output_text(page):
    """What the executed notebook printed: the text of its output areas."""
    return "\n".join(rendered_texts(page))


def printed_by_cell(page):
    """{code cell id: the text its outputs show, a print the kernel sent in pieces joined} of an executed notebook's
    page."""
    cells = {}
    for block in re.split(r'(?=<div class="jp-Cell )', page):
        found = re.match(r'<div class="jp-Cell jp-CodeCell[^"]*" id="cell-id=([^"]+)"', block)
        if found:
            cells[found.group(1)] = "".join(rendered_texts(block))
    return cells


def linux_check_texts(kit, folder):
    """{TODO id: what its check cell prints on Linux} in the student edition at ``kit``: ``check_lines`` of each
    entry of its preview, run with a student's Python of this Linux box (made in the new ``folder``)."""
    python, out = student_python(Path(folder) / "venv"), Path(folder) / "preview.json"
    done = subprocess.run([str(python), "-m", "hwtools.grade", "--json", str(out)], cwd=kit, env=kit_env(kit, python),
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return {entry["id"]: "\n".join(check_lines(entry)) + "\n" for entry in json.loads(out.read_text())["todos"]}


def expected_printed(notebook, check_texts):
    """{code cell id: the text it shows on Linux} for the cells of this kit's ``notebook`` whose outputs nbval compares:
    a check cell's, ``check_texts`` (the student edition's words: ``linux_check_texts``); the others' as stored (on
    Linux, and compared there by this kit's own nbval)."""
    cells = {}
    for cell in nbformat.read(KIT / "notebooks" / notebook, as_version=4).cells:
        if cell.cell_type == "code" and "NBVAL_IGNORE_OUTPUT" not in cell.source:
            check = re.fullmatch(r'check\("([\d.]+)"\)', cell.source.strip())
            cells[cell.id] = check_texts[check.group(1)] if check else "".join(
                output.text if output.output_type == "stream" else output.data["text/plain"] for output in cell.outputs
                if output.output_type == "stream" or set(output.get("data", {})) == {"text/plain"})
    return cells


def assert_printed_as_on_linux(out_dir, check_texts):
    """Every cell nbval compares, in the pages of the report in ``out_dir``, shows what it shows on Linux."""
    for name in NOTEBOOKS:
        expected = expected_printed(name, check_texts)
        got = printed_by_cell((Path(out_dir) / name.replace(".ipynb", ".html")).read_text(encoding="utf-8"))
        differ = {cell: {"shown": got.get(cell), "on Linux": text} for cell, text in expected.items() if got.get(cell) != text}
        assert not differ, f"{name}: {differ}"
