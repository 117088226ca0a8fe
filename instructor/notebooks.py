"""The student version of a notebook: solution blocks stubbed, outputs, execution counts and timings
cleared, stored widget state dropped, written in the layout Jupyter itself writes.

The notebook is read by ``hwtools.markers`` (nbformat 4 of any minor version, a cell's source as a
string or a list of lines, ``\\r\\n`` inside the sources), so a notebook saved by JupyterLab,
VS Code or Colab, or checked out with Windows line ends, gives the same student version.
"""

from __future__ import annotations

import json

from hwtools import markers
from instructor.kit import SOLUTION, ReleaseError, find_blocks
from instructor.stubs import check_replacements, markdown_stub, notebook_code_stub, replace_blocks


def transform_notebook(text, path, keep=frozenset(), replace=None, not_done=False):
    """The student version of a notebook's JSON text: stubs, no outputs, no stored widget state.
    ``not_done``: the kit defines ``TodoNotDone``, which a code cell's stub then raises."""
    try:
        notebook = markers.read_notebook(text, path)
    except markers.MarkerError as error:
        raise ReleaseError(str(error)) from None
    raw_lines = markers.split_lines(text)
    replaced, seen = {}, {}
    for info in markers.notebook_cells(notebook):
        cell = notebook["cells"][info.index]
        lines = list(info.lines)

        def where(line_index, info=info, cell=cell, lines=lines):
            file_line = _notebook_file_line(raw_lines, cell, lines[line_index])
            at = f"{path}:{file_line}" if file_line else str(path)
            return f"{at} (cell {info.index + 1}, line {line_index + 1} of the cell)"

        blocks = []
        if info.kind == "code":
            blocks = find_blocks(lines, where, "code")
            new_lines = replace_blocks(lines, blocks, keep, replace, lambda block: notebook_code_stub(block, path, not_done), seen)
        elif info.kind == "markdown":
            blocks = find_blocks(lines, where, "markdown")
            new_lines = replace_blocks(lines, blocks, keep, replace, lambda block: markdown_stub(block, path), seen)
        else:
            for line_index, line in enumerate(lines):
                if markers.names_marker(line, SOLUTION):
                    raise ReleaseError(f"{where(line_index)}: solution markers are only understood in code and Markdown cells")
            new_lines = lines
        for block in blocks:
            replaced.setdefault(block.todo, []).append(block)
        new_text = "\n".join(new_lines)
        source = cell.get("source", "")
        if new_text != ("".join(source) if isinstance(source, list) else source):  # a stub, or "\r\n" made "\n"
            cell["source"] = new_text.splitlines(keepends=True) if info.source_is_list else new_text
        if info.kind == "code":
            cell["outputs"] = []
            cell["execution_count"] = None
        metadata = cell.get("metadata", {})
        for key in ("execution", "collapsed", "scrolled"):
            metadata.pop(key, None)
    notebook.get("metadata", {}).pop("widgets", None)
    for todo in replace or {}:
        check_replacements(replaced.get(todo, []), {todo: replace[todo]}, path)
    return json.dumps(notebook, indent=1, sort_keys=True, ensure_ascii=False) + "\n"


def _notebook_file_line(raw_lines, cell, line_text):
    """Best effort: the line of the .ipynb file that stores ``line_text`` of ``cell``."""
    cell_id = cell.get("id")
    start = 0
    if cell_id:
        needle = f'"id": {json.dumps(cell_id)}'
        start = next((number for number, raw in enumerate(raw_lines) if needle in raw), 0)
    for number in range(start, len(raw_lines)):
        stored = raw_lines[number].strip().rstrip(",")
        if stored.startswith('"'):
            try:
                if markers.normalise_newlines(json.loads(stored)).rstrip("\n") == line_text:
                    return number + 1
            except (json.JSONDecodeError, AttributeError):
                continue
    return None
