"""The one marker reader (``hwtools/markers.py``): a file is read as Python reads it, a notebook as
any Jupyter front end saves it, and the grader and the release tool see the same blocks.

* unit rules: line ends (``\\r\\n``, ``\\r``), a BOM, a coding line, trailing white space after a
  marker, tabs, the error messages, HINT and STUB lines, notebooks of JupyterLab, VS Code and Colab;
* the grader: the instructor's kit saved with CRLF, CR, a BOM, or tabs and trailing white space
  scores 39/39 with ``python -m hwtools.grade``; the student edition's preview gives a CRLF copy
  the same verdicts as the LF one;
* the release tool: the student edition built from a checkout with Windows line ends (or with
  BOMs) is byte-identical to the one built from LF files.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

from hwtools import markers
from hwtools.grade import AUTO_POINTS, TODO_BY_ID, blocks, kits
from instructor.release import ANSWER_KEY, build_student_edition, kit_files, transform_notebook
import editions

KIT = Path(__file__).resolve().parents[2]
AUTO_TODOS = sorted(todo.id for todo in TODO_BY_ID.values() if todo.auto)

pytestmark = [pytest.mark.timeout(900), pytest.mark.quick]  # quick: the quick tier (pyproject.toml)

MODULE = (
    '"""A module."""\n'
    "\n"
    "### BEGIN SOLUTION 1.3.3\n"
    "RATE = 0.5\n"
    "### END SOLUTION 1.3.3\n"
    "\n"
    "\n"
    "def double(x):\n"
    "    ### BEGIN SOLUTION 1.1.1\n"
    "    ### HINT: multiply by two\n"
    "    ### STUB: result = None\n"
    "    result = 2 * x\n"
    "    ### END SOLUTION 1.1.1\n"
    "    return result\n"
)


def summary(found):
    """What a caller uses of each block: id, indentation, the lines between the markers, the code."""
    return [(block.todo, block.indent, block.style, block.body, block.code, block.hint, block.stub) for block in found]


def saved(text, how):
    """``text`` (LF) as an editor or a checkout might save it, as bytes."""
    if how == "crlf":
        return text.replace("\n", "\r\n").encode()
    if how == "cr":
        return text.replace("\n", "\r").encode()
    if how == "bom":
        return b"\xef\xbb\xbf" + text.encode()
    if how == "bom-crlf":
        return b"\xef\xbb\xbf" + text.replace("\n", "\r\n").encode()
    if how == "tabs-trailing":  # indentation as tabs, white space after every marker
        lines = []
        for line in text.split("\n"):
            width = len(line) - len(line.lstrip(" "))
            line = "\t" * (width // 4) + " " * (width % 4) + line[width:]
            lines.append(line + " \t " if markers.match_marker(line) else line)
        return "\n".join(lines).encode()
    assert how == "lf"
    return text.encode()


SAVED = ["lf", "crlf", "cr", "bom", "bom-crlf", "tabs-trailing"]


# --------------------------------------------------------------------------------------------
# The rules
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("how", SAVED)
def test_a_python_file_has_the_same_blocks_however_it_is_saved(how):
    expected = summary(markers.find_blocks(MODULE.split("\n")))
    assert [todo for todo, *_ in expected] == ["1.3.3", "1.1.1"]
    assert expected[1][4:] == (("    result = 2 * x",), "multiply by two", ("result = None",))
    text = markers.decode_python(saved(MODULE, how))
    found = summary(markers.find_blocks(markers.split_lines(text)))
    if how == "tabs-trailing":  # the same blocks, indented by a tab
        expected = [(todo, indent.replace("    ", "\t"), style, tuple(line.replace("    ", "\t", 1) for line in body),
                     tuple(line.replace("    ", "\t", 1) for line in code), hint, stub)
                    for todo, indent, style, body, code, hint, stub in expected]
    assert found == expected
    compile(text, "module.py", "exec", dont_inherit=True)  # and Python reads the same text


def test_line_ends_are_python_s_not_str_splitlines():
    assert markers.split_lines("a\r\nb\rc\nd") == ["a", "b", "c", "d"]
    assert markers.split_lines("a\fb\x1cc\u2028d\x85e") == ["a\fb\x1cc\u2028d\x85e"]  # no line end for Python
    assert markers.match_marker(markers.split_lines("    ### END TODO 1.2.1\r\n")[0])


def test_a_coding_line_is_honoured_and_bad_bytes_are_named():
    latin = "# -*- coding: latin-1 -*-\ndef f():\n    ### BEGIN SOLUTION 1.1.1\n    return 'é'\n    ### END SOLUTION 1.1.1\n"
    text = markers.decode_python(latin.encode("latin-1"), "m.py")
    assert markers.find_blocks(markers.split_lines(text))[0].body == ("    return 'é'",)
    with pytest.raises(markers.MarkerError, match=r"^m\.py: not UTF-8 text$"):
        markers.decode_python(b"x = '\xff'\n", "m.py")
    with pytest.raises(markers.MarkerError, match=r"^m\.py: .*encoding"):
        markers.decode_python(b"# coding: no-such-codec\nx = 1\n", "m.py")


@pytest.mark.parametrize(
    ("line", "is_marker"),
    [
        ("### BEGIN TODO 1.2.1", True),
        ("###BEGIN TODO 1.2.1", True),
        ("\t\t### END SOLUTION 1.2.1 \t ", True),
        ("    ###   BEGIN\tTODO   1.2.1", True),
        ("### BEGIN TODO 1.2.1 \u00a0", True),  # a no-break space some editors leave at the end
        ("# BEGIN TODO 1.2.1", False),
        ("### begin todo 1.2.1", False),
        ("### BEGIN TODOS 1.2.1", False),
        ("x = 1  ### BEGIN TODO 1.2.1", False),
    ],
)
def test_what_a_marker_line_is(line, is_marker):
    assert bool(markers.match_marker(line)) is is_marker


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("### BEGIN TODO 1.1.1\nx = 1\n", r"^f:1: BEGIN TODO 1\.1\.1 has no END TODO 1\.1\.1$"),
        ("x = 1\n### END TODO 1.1.1\n", r"^f:2: END TODO 1\.1\.1 without a BEGIN TODO$"),
        ("### BEGIN TODO 1.1.1\n### BEGIN TODO 1.2.1\n", r"^f:2: nested BEGIN TODO 1\.2\.1: BEGIN TODO 1\.1\.1 of f:1 is still open"),
        ("### BEGIN TODO 1.1.1\n### END TODO 1.2.1\n", r"^f:2: END TODO 1\.2\.1 closes BEGIN TODO 1\.1\.1 of f:1: the ids differ"),
        ("### BEGIN TODO\n", r"^f:1: todo marker without a TODO id"),
        ("### BEGIN TODO one\n", r"^f:1: 'one' is not a TODO id"),
    ],
)
def test_broken_markers_are_named_by_line(text, message):
    with pytest.raises(markers.MarkerError, match=message):
        markers.find_blocks(markers.split_lines(text), lambda index: f"f:{index + 1}")


def test_strict_adds_the_instructor_s_rules_and_the_grader_reads_without_them():
    dedented_end = ["def f():", "    ### BEGIN TODO 1.1.1", "    return 1", "### END TODO 1.1.1"]
    assert markers.find_blocks(dedented_end)[0].body == ("    return 1",)  # a comment's indentation changes no Python
    with pytest.raises(markers.MarkerError, match="is not indented like its BEGIN"):
        markers.find_blocks(dedented_end, strict=True)
    near = ["def f():", "    # BEGIN TODO 1.1.1", "    return 1"]
    assert markers.find_blocks(near) == []
    with pytest.raises(markers.MarkerError, match=r"^line 2: malformed todo marker '# BEGIN TODO 1\.1\.1'"):
        markers.find_blocks(near, strict=True)
    with pytest.raises(markers.MarkerError, match="unknown TODO id 9.9.9"):
        markers.find_blocks(["### BEGIN TODO 9.9.9", "### END TODO 9.9.9"], known=TODO_BY_ID)
    assert markers.find_blocks(["### BEGIN TODO 1.1.1", "### END TODO 1.1.1"], styles=("SOLUTION",)) == []


def test_the_grader_names_a_marker_an_editor_broke(tmp_path):
    layout = blocks.load_layout(KIT)
    kits.write_submission(layout, tmp_path, others="reference")
    path = tmp_path / "hwlib" / "finite_diff.py"
    path.write_text(path.read_text().replace("### BEGIN TODO 1.2.1", "# BEGIN TODO 1.2.1").replace("### END TODO 1.2.1", "# END TODO 1.2.1"))
    read = blocks.read_submission(tmp_path, layout)
    assert re.search(r"found 0; line \d+ looks like a marker but is not one: '# BEGIN TODO 1\.2\.1'", read.problems["1.2.1"])


# --------------------------------------------------------------------------------------------
# Notebooks as JupyterLab, VS Code and Colab save them
# --------------------------------------------------------------------------------------------

CELLS = [
    ("markdown", "# Title\n\nDerive it.\n<!-- BEGIN SOLUTION 2.1.1 -->\n$$x^2$$\n<!-- END SOLUTION 2.1.1 -->\nDone."),
    ("code", "import numpy as np"),
    ("code", "### BEGIN SOLUTION 1.1.2\n### HINT: name them\ntried = {'a': 1}\n### END SOLUTION 1.1.2\nprint(tried)"),
]


def jupyterlab_notebook():
    """nbformat 4.5 as JupyterLab 4 writes it: cell ids, sources as lists of lines."""
    notebook = nbformat.v4.new_notebook()
    for index, (kind, source) in enumerate(CELLS):
        cell = nbformat.v4.new_code_cell(source) if kind == "code" else nbformat.v4.new_markdown_cell(source)
        cell["id"] = f"cell-{index}"
        notebook.cells.append(cell)
    return nbformat.writes(notebook) + "\n"


def vscode_notebook():
    """As VS Code writes one: nbformat 4.2, no cell ids, CRLF inside the sources, its own metadata."""
    cells = [{"cell_type": kind, "metadata": {"vscode": {"languageId": "python"}},
              "source": [line + "\r\n" for line in source.split("\n")[:-1]] + [source.split("\n")[-1]],
              **({"execution_count": None, "outputs": []} if kind == "code" else {})} for kind, source in CELLS]
    notebook = {"cells": cells, "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3"},
                                             "orig_nbformat": 4}, "nbformat": 4, "nbformat_minor": 2}
    return json.dumps(notebook, indent=1).replace("\n", "\r\n")  # and the JSON saved with CRLF


def colab_notebook():
    """As Colab writes one: nbformat 4.0, the cell id in the cell's metadata, sources as one string
    per cell, a BOM before the JSON (some downloads add one)."""
    cells = [{"cell_type": kind, "metadata": {"id": f"c{index}", "colab": {"base_uri": "https://localhost:8080/"}},
              "source": source, **({"execution_count": 3, "outputs": []} if kind == "code" else {})}
             for index, (kind, source) in enumerate(CELLS)]
    notebook = {"nbformat": 4, "nbformat_minor": 0, "metadata": {"colab": {"provenance": []}, "accelerator": "GPU"},
                "cells": cells}
    return "\ufeff" + json.dumps(notebook, indent=2)


@pytest.mark.parametrize("make", [jupyterlab_notebook, vscode_notebook, colab_notebook], ids=["jupyterlab", "vscode", "colab"])
def test_a_notebook_has_the_same_blocks_whichever_front_end_saved_it(make, tmp_path):
    expected = summary(block for block, _, _ in markers.file_blocks("nb.ipynb", jupyterlab_notebook().encode()))
    assert [todo for todo, *_ in expected] == ["2.1.1", "1.1.2"]
    found = markers.file_blocks("nb.ipynb", make().encode("utf-8"))
    assert summary(block for block, _, _ in found) == expected
    assert [dialect for _, _, dialect in found] == ["markdown", "code"]
    # The release tool gives it the same student cells.
    student = json.loads(transform_notebook(make(), "nb.ipynb"))
    reference = json.loads(transform_notebook(jupyterlab_notebook(), "nb.ipynb"))
    assert [markers.cell_text(cell) for cell in student["cells"]] == [markers.cell_text(cell) for cell in reference["cells"]]
    assert "\\r" not in json.dumps(student)
    assert all(cell.get("outputs", []) == [] for cell in student["cells"])


def test_a_notebook_that_is_not_nbformat_4_is_named():
    with pytest.raises(markers.MarkerError, match=r"nb\.ipynb: nbformat 3 notebook"):
        markers.read_notebook('{"nbformat": 3, "worksheets": []}', "nb.ipynb")
    with pytest.raises(markers.MarkerError, match=r"nb\.ipynb:1: not a notebook"):
        markers.read_notebook("{", "nb.ipynb")


# --------------------------------------------------------------------------------------------
# The grader reads a kit saved any of these ways
# --------------------------------------------------------------------------------------------


def saved_copy(root, out, how, prefix="hwlib/"):
    """The kit's files under ``prefix`` copied into ``out``, text files saved ``how``."""
    for name in kit_files(root):
        if not name.startswith(prefix) or "__pycache__" in name:
            continue
        target = out / name
        target.parent.mkdir(parents=True, exist_ok=True)
        data = (root / name).read_bytes()
        target.write_bytes(saved(data.decode("utf-8"), how) if name.endswith((".py", ".ipynb", ".md", ".txt", ".toml", ".json"))
                           and b"\0" not in data else data)
        shutil.copymode(root / name, target)
    return out


def grade_cli(kit, out, cwd=KIT):
    env = {**os.environ, "PYTHONPATH": str(cwd), "MPLBACKEND": "Agg"}
    result = subprocess.run([sys.executable, "-m", "hwtools.grade", str(kit), "--json", str(out), "--brief"],
                            cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return json.loads(out.read_text()), result.stdout


# Each way an editor saves a file, on a file with TODOs: one kit, one grade (the kit's other files LF).
SAVED_EACH_ITS_WAY = {"hwlib/cartpole.py": "cr", "hwlib/finite_diff.py": "crlf", "hwlib/policy_search.py": "bom",
                      "hwlib/settings.py": "bom-crlf", "hwlib/logreg.py": "tabs-trailing"}


def test_a_kit_whose_files_are_saved_each_its_own_way_scores_every_point(tmp_path):
    kit = saved_copy(KIT, tmp_path / "kit", "lf")
    for name, how in SAVED_EACH_ITS_WAY.items():
        (kit / name).write_bytes(saved((KIT / name).read_text(encoding="utf-8"), how))
    assert {how for how in SAVED_EACH_ITS_WAY.values()} == set(SAVED) - {"lf"}
    result, stdout = grade_cli(kit, tmp_path / "result.json")
    earned = {entry["id"]: entry["auto_earned"] for entry in result["todos"] if entry["auto_possible"]}
    assert earned == {todo: TODO_BY_ID[todo].auto for todo in AUTO_TODOS}, stdout
    assert result["total"]["auto_earned"] == AUTO_POINTS
    # re-indenting a whole file with tabs does change its lines outside the blocks; nothing else differs
    differ = [note for note in result["notes"] if "differ from the kit's" in note]
    assert [note.split(":")[0] for note in differ] == ["hwlib/logreg.py"], result["notes"]


def test_the_student_preview_gives_a_crlf_copy_the_verdicts_of_the_lf_one(tmp_path, tmp_path_factory):
    """In the student edition (no reference: the answer key), a kit with every TODO done earns the
    same verdict per check whether its files end lines with LF or CRLF."""
    edition = tmp_path / "edition"
    editions.build(edition, tmp_path_factory, keep=frozenset(TODO_BY_ID))
    assert (edition / ANSWER_KEY).is_file()
    crlf = saved_copy(edition, tmp_path / "crlf", "crlf", prefix="")
    (crlf / ANSWER_KEY).write_bytes((edition / ANSWER_KEY).read_bytes())  # the key is data, not a file a student saves

    def verdicts(kit, name):
        result, _ = grade_cli(kit, tmp_path / f"{name}.json", cwd=kit)
        return {(entry["id"], check["check"]): check["passed"] for entry in result["todos"] for check in entry["checks"]}, result

    lf, lf_result = verdicts(edition, "lf")
    windows, windows_result = verdicts(crlf, "crlf")
    assert lf and all(lf.values()), lf
    assert windows == lf
    assert windows_result["total"]["auto_earned"] == lf_result["total"]["auto_earned"] > 0


# --------------------------------------------------------------------------------------------
# The release tool builds the same edition from a Windows checkout
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("how", ["crlf", "bom-crlf"])
def test_the_student_edition_from_a_windows_checkout_is_the_one_from_lf(how, tmp_path):
    lf = saved_copy(KIT, tmp_path / "lf", "lf", prefix="")
    windows = saved_copy(KIT, tmp_path / "windows", how, prefix="")
    assert b"\r\n" in (windows / "hwlib" / "finite_diff.py").read_bytes()
    assert b"\r\n" in (windows / "notebooks" / "p1_cartpole_finite_difference.ipynb").read_bytes()
    build_student_edition(lf, tmp_path / "from-lf", answer_key=False)
    build_student_edition(windows, tmp_path / "from-windows", answer_key=False)

    def tree(root):
        return {path.relative_to(root).as_posix(): (path.read_bytes(), path.stat().st_mode & 0o777)
                for path in sorted(root.rglob("*")) if path.is_file()}

    from_lf, from_windows = tree(tmp_path / "from-lf"), tree(tmp_path / "from-windows")
    assert sorted(from_windows) == sorted(from_lf)
    different = [name for name in from_lf if from_lf[name] != from_windows[name]]
    assert not different, different
    assert not any(b"\r" in data for data, _ in from_windows.values())


@pytest.mark.parametrize("paths, clash", [
    (["hwlib/a.py", "hwlib/b.py", "notebooks/p1.ipynb"], None),
    (["hwlib/a.py", "hwlib/A.py"], ("hwlib/A.py", "hwlib/a.py")),
    (["hwlib/stra\u00dfe.py", "hwlib/STRASSE.py"], ("hwlib/STRASSE.py", "hwlib/stra\u00dfe.py")),  # casefold: ss
    (["hwlib/\u00e9.py", "hwlib/e\u0301.py"], ("hwlib/e\u0301.py", "hwlib/\u00e9.py")),  # NFC and NFD
    (["hwlib/x", "HWLIB/X/y.py"], ("HWLIB/X/", "hwlib/x")),  # a file and a folder of one name
    (["hwlib/a.py", "hwlib/a.py"], None),  # the same path twice is not a clash (readers name it otherwise)
])
def test_name_clash_finds_names_that_are_one_file_on_macos_or_windows(paths, clash):
    assert markers.name_clash(paths) == clash
