"""The TODO markers of the kit's files, read by one set of rules: the release tool (``instructor/``)
writes the student edition with it and the grader (``hwtools/grade/``) reads submissions with it.

A handout TODO's code is one block, fenced in Python files and notebook code cells by two comment
lines, ``### BEGIN <style> 1.2.1`` and ``### END <style> 1.2.1``, whose style is SOLUTION in the
instructor's kit and TODO in the student edition; in notebook Markdown cells by
``<!-- BEGIN <style> 2.1.1 -->`` and ``<!-- END <style> 2.1.1 -->``. Right after a code BEGIN, a
``###`` comment line ``HINT: text`` gives the student's hint and ``###`` lines ``STUB: code``
the code the student starts from (the release tool reads them; both are optional).

The rules, for every caller:

* a file is read as Python reads a source file (``decode_python``): the encoding from a UTF-8 BOM
  or a coding line (else UTF-8), the BOM dropped, and ``\\r\\n``, ``\\r`` and ``\\n`` all end a line;
* a marker is alone on its line: any indentation (spaces, tabs), any spaces or tabs between its
  words and after it, ``###`` with or without a space before BEGIN/END; the words are upper case
  and the id is dotted numbers (``1.2.1``);
* the block's indentation is its BEGIN line's; blocks do not nest, and an END closes the open
  BEGIN of the same id;
* a notebook is nbformat 4, any minor version, as JupyterLab, VS Code or Colab save it
  (``read_notebook``): a cell's source is a string or a list of lines, cell ids and extra
  metadata may be there or not, and line ends inside the sources may be ``\\r\\n``.

``strict=True`` adds what the instructor's source must also satisfy (the release tool asks for it):
no line that looks like a marker but is not one, an END indented like its BEGIN. The grader reads
a student's file without it: an END marker's indentation changes no Python.

Which files are the kit's at all is one rule too (``is_leftover``): every reader of a kit's files
(the release build, hand-in, the grader's reader of a kit or a submission, a class's folder) leaves
out what editors, Jupyter and Python leave beside them.

Standard library only, and nothing of the kit: the grader's trusted process imports this module.
"""

from __future__ import annotations

import io
import json
import re
import tokenize
import unicodedata
from dataclasses import dataclass

ID_PATTERN = r"[0-9]+(?:\.[0-9]+)+"
STYLES = ("SOLUTION", "TODO")  # SOLUTION: the instructor's kit; TODO: the student edition
CODE, MARKDOWN = "code", "markdown"  # the two dialects: comment lines, HTML comments

_BLANK = r"[^\S\n]"  # white space within a line
_WORDS = rf"(?P<kind>BEGIN|END){_BLANK}+(?P<style>[A-Z]+)(?P<rest>(?:{_BLANK}.*?)?)"
_MARKER = {
    CODE: re.compile(rf"^(?P<indent>[ \t\f]*)###{_BLANK}*{_WORDS}{_BLANK}*$"),
    MARKDOWN: re.compile(rf"^(?P<indent>{_BLANK}*)<!--{_BLANK}*{_WORDS}{_BLANK}*-->{_BLANK}*$"),
}
_HINT = re.compile(rf"^{_BLANK}*###{_BLANK}*HINT:{_BLANK}*(?P<hint>.*?){_BLANK}*$")
_STUB = re.compile(rf"^{_BLANK}*###{_BLANK}*STUB:(?: (?P<code>.*?))?{_BLANK}*$")


# The leftovers of editors, Jupyter, Python and archivers: never a file of the kit, wherever they lie.
# Any name starting with a dot is one (JupyterLab's .ipynb_checkpoints/ and .virtual_documents/, vim's
# .cartpole.py.swp, .git/, .venv/, macOS's .DS_Store and ._ files) except the kit's own dot-files.
KIT_DOT_NAMES = frozenset({".ci", ".gitignore", ".gitattributes"})
LEFTOVER_NAMES = frozenset({"__pycache__", "__MACOSX", "venv", "node_modules"})
LEFTOVER_ENDINGS = ("~", ".swp", ".swo", ".pyc", ".pyo")  # emacs and gedit backups, vim swap files, bytecode


def is_leftover(path):
    """True where ``path`` (relative to a kit or a submission: a string with ``/`` or ``\\``, or a
    ``PurePath``) is an editor's, Jupyter's or Python's leftover or lies inside one: a part that starts
    with a dot (other than ``KIT_DOT_NAMES``), is in ``LEFTOVER_NAMES``, ends in ``LEFTOVER_ENDINGS``
    or is an emacs autosave ``#name#``. Every reader of a kit's files asks this one function."""
    parts = str(path).replace("\\", "/").split("/")
    return any(
        (part.startswith(".") and part not in KIT_DOT_NAMES and part not in (".", ".."))
        or part in LEFTOVER_NAMES or part.endswith(LEFTOVER_ENDINGS) or (len(part) > 1 and part[0] == part[-1] == "#")
        for part in parts
    )


def folded(path):
    """``path`` as a case-insensitive, normalising file system (macOS, Windows) sees it: Unicode NFC
    (macOS stores NFD), case folded (``str.casefold``: "ß" is "ss"), NFC again."""
    return unicodedata.normalize("NFC", unicodedata.normalize("NFC", str(path)).casefold())


def name_clash(paths):
    """The first two of ``paths`` (relative, ``/``-separated files) that are one file on macOS or
    Windows (``folded``: only letter case or Unicode normalisation differ, or a file has the folded
    name of another's folder), as a pair; None when every path stays itself on every system. A kit
    or a submission with such a pair is refused by every reader (the grader's, the hand-in's):
    unzipped there, one file would overwrite the other and a reviewer would read other code."""
    files, folders = {}, {}
    for path in sorted(str(path).replace("\\", "/") for path in paths):
        key = folded(path)
        if key in files and files[key] != path:
            return files[key], path
        files.setdefault(key, path)
        parts = path.split("/")
        for depth in range(1, len(parts)):
            folders.setdefault(folded("/".join(parts[:depth])), "/".join(parts[:depth]))
    for key, path in files.items():
        if key in folders:
            return folders[key] + "/", path
    return None


class MarkerError(ValueError):
    """A file whose markers (or text) cannot be read; the message starts with where."""


@dataclass(frozen=True)
class Block:
    """One fenced block: line indices into the lines it was found in."""

    todo: str
    begin: int  # index of the BEGIN line
    end: int  # index of the END line
    indent: str  # the BEGIN line's indentation
    body: tuple  # every line between the two markers
    style: str = "SOLUTION"  # the BEGIN line's word: SOLUTION or TODO
    hint: str | None = None  # the text of the HINT line right after BEGIN
    stub: tuple = ()  # the code of the STUB lines after it
    body_start: int = 0  # index of the first line after the HINT and STUB lines
    end_indent: str = ""  # the END line's indentation

    @property
    def module_level(self):
        return self.indent == ""

    @property
    def code(self):
        """The block's own lines: the body without its HINT and STUB lines."""
        return self.body[self.body_start - self.begin - 1:]


# --------------------------------------------------------------------------------------------
# Text
# --------------------------------------------------------------------------------------------


def normalise_newlines(text):
    """``text`` with every ``\\r\\n`` and lone ``\\r`` made ``\\n`` (Python's universal newlines)."""
    return text.replace("\r\n", "\n").replace("\r", "\n")


def split_lines(text):
    """The lines of ``text`` without their ends; ``\\r\\n``, ``\\r`` and ``\\n`` each end a line, and
    nothing else does (as in Python's tokenizer, unlike ``str.splitlines``)."""
    return normalise_newlines(text).split("\n")


def python_encoding(data, name="<file>"):
    """The encoding Python reads source ``data`` (bytes) in: from a UTF-8 BOM or a coding line
    (PEP 263), else UTF-8 (``utf-8-sig`` where there is a BOM)."""
    try:
        return tokenize.detect_encoding(io.BytesIO(data).readline)[0]
    except SyntaxError as error:
        message = str(error.msg if hasattr(error, "msg") else error)
        if message.startswith("invalid or missing encoding declaration"):  # the first lines are not UTF-8
            raise MarkerError(f"{name}: not UTF-8 text") from None
        # "unknown encoding for NAME: CODEC", or a BOM beside another coding line
        raise MarkerError(f"{name}: the coding line cannot be read ({message.replace('<file>', name)})") from None


def decode_python(data, name="<file>"):
    """The text of Python source ``data`` (bytes) as Python reads it: the encoding from a BOM or a
    coding line (else UTF-8), the BOM dropped, universal newlines."""
    encoding = python_encoding(data, name)
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError:
        label = "UTF-8" if encoding in ("utf-8", "utf-8-sig") else encoding
        raise MarkerError(f"{name}: not {label} text") from None
    return normalise_newlines(text.removeprefix("\ufeff"))


# --------------------------------------------------------------------------------------------
# Markers
# --------------------------------------------------------------------------------------------


def match_marker(line, dialect=CODE, styles=STYLES):
    """The ``re.Match`` of a marker line (groups indent, kind, style, rest), or None."""
    match = _MARKER[dialect].match(line)
    return match if match is not None and match["style"] in styles else None


def names_marker(line, styles=STYLES):
    """The style word where ``line`` names BEGIN/END and a style anywhere (a marker or not), else None."""
    near = re.search(rf"\b(?:BEGIN|END)[ \t_-]*({'|'.join(styles)})\b", line)
    return near[1] if near is not None else None


def near_miss(line, dialect=CODE, styles=STYLES):
    """The style word where ``line`` names BEGIN/END and a style but is no marker of ``dialect``
    (``# BEGIN TODO 1.2.1``, ``### BEGIN_TODO 1.2.1``): a line its writer meant as one; else None."""
    style = names_marker(line, styles)
    return style if style is not None and match_marker(line, dialect, styles) is None else None


def marker_example(dialect, kind, todo, style="SOLUTION"):
    return f"### {kind} {style} {todo}" if dialect == CODE else f"<!-- {kind} {style} {todo} -->"


def find_blocks(lines, where=None, dialect=CODE, styles=STYLES, known=None, strict=False):
    """The blocks of ``lines`` (strings without line ends), in order.

    ``where(index)`` names line ``index`` in messages (default ``line N``); ``styles``: the words
    that make a marker; ``known``: the TODO ids allowed (None: any id); ``strict``: also refuse a
    line that looks like a marker but is not one, and an END not indented like its BEGIN.
    Raises MarkerError naming the line.
    """
    where = where or (lambda index: f"line {index + 1}")
    blocks, open_block = [], None  # open_block: (todo, index, indent, style)
    for index, line in enumerate(lines):
        match = match_marker(line, dialect, styles)
        if match is None:
            style = near_miss(line, dialect, styles) if strict else None
            if style:
                raise MarkerError(f"{where(index)}: malformed {style.lower()} marker {line.strip()!r}; "
                                  f"write {marker_example(dialect, 'BEGIN', '1.2.1', style)!r}")
            continue
        kind, style, indent = match["kind"], match["style"], match["indent"]
        todo = _marker_id(match["rest"], line, where(index), dialect, style, known)
        if kind == "BEGIN":
            if open_block is not None:
                raise MarkerError(f"{where(index)}: nested BEGIN {style} {todo}: BEGIN {open_block[3]} {open_block[0]} "
                                  f"of {where(open_block[1])} is still open")
            open_block = (todo, index, indent, style)
            continue
        if open_block is None:
            raise MarkerError(f"{where(index)}: END {style} {todo} without a BEGIN {style}")
        open_todo, begin, begin_indent, begin_style = open_block
        if todo != open_todo:
            raise MarkerError(f"{where(index)}: END {style} {todo} closes BEGIN {begin_style} {open_todo} "
                              f"of {where(begin)}: the ids differ")
        if strict and dialect == CODE and indent != begin_indent:
            raise MarkerError(f"{where(index)}: END {style} {todo} is not indented like its BEGIN ({where(begin)})")
        blocks.append(_block(lines, open_block, index, indent, dialect))
        open_block = None
    if open_block is not None:
        todo, begin, _, style = open_block
        raise MarkerError(f"{where(begin)}: BEGIN {style} {todo} has no END {style} {todo}")
    return blocks


def _block(lines, open_block, end, end_indent, dialect):
    todo, begin, indent, style = open_block
    hint, body_start, stub = None, begin + 1, []
    if dialect == CODE:
        hint_match = _HINT.match(lines[body_start]) if body_start < end else None
        if hint_match:
            hint, body_start = hint_match["hint"], body_start + 1
        while body_start < end and _STUB.match(lines[body_start]):
            stub.append(_STUB.match(lines[body_start])["code"] or "")
            body_start += 1
    return Block(todo, begin, end, indent, tuple(lines[begin + 1:end]), style, hint, tuple(stub), body_start, end_indent)


def _marker_id(rest, line, location, dialect, style, known):
    todo = rest.strip()
    if not todo:
        raise MarkerError(f"{location}: {style.lower()} marker without a TODO id: {line.strip()!r}; "
                          f"write {marker_example(dialect, 'BEGIN', '1.2.1', style)!r}")
    if not re.fullmatch(ID_PATTERN, todo):
        raise MarkerError(f"{location}: {todo!r} is not a TODO id (like 1.2.1) in {line.strip()!r}")
    if known is not None and todo not in known:
        raise MarkerError(f"{location}: unknown TODO id {todo}; the handout's are {', '.join(known)}")
    return todo


# --------------------------------------------------------------------------------------------
# Notebooks and files
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Cell:
    """One notebook cell as the marker rules see it."""

    index: int  # position in the notebook
    kind: str  # "code", "markdown" or "raw"
    text: str  # the source as one string, universal newlines
    lines: tuple  # text split into lines
    source_is_list: bool  # stored as a list of lines (else as one string)
    id: str | None  # the cell id (nbformat 4.5), or None


def read_notebook(text, name="<notebook>"):
    """The notebook (a dict) of a .ipynb file's text (or bytes): JSON, a BOM allowed, nbformat 4."""
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError:
            raise MarkerError(f"{name}: not UTF-8 text") from None
    try:
        notebook = json.loads(text.removeprefix("\ufeff"))
    except json.JSONDecodeError as error:
        raise MarkerError(f"{name}:{error.lineno}: not a notebook (JSON: {error.msg})") from None
    if not isinstance(notebook, dict) or not isinstance(notebook.get("cells", []), list):
        raise MarkerError(f"{name}: not a notebook (no list of cells)")
    version = notebook.get("nbformat", 4)
    if version != 4:
        raise MarkerError(f"{name}: nbformat {version} notebook; open and save it in Jupyter to make it nbformat 4")
    return notebook


def cell_text(cell):
    """The source of a cell dict as one string with universal newlines (a string or a list of lines)."""
    source = cell.get("source", "")
    return normalise_newlines("".join(source) if isinstance(source, list) else str(source))


def notebook_cells(notebook):
    """The ``Cell`` of every cell of a notebook dict (``read_notebook``)."""
    cells = []
    for index, cell in enumerate(notebook.get("cells", [])):
        if not isinstance(cell, dict):
            continue
        text = cell_text(cell)
        cells.append(Cell(index, str(cell.get("cell_type", "")), text, tuple(text.split("\n")),
                          isinstance(cell.get("source"), list), cell.get("id")))
    return cells


def file_blocks(name, data, styles=STYLES, known=None, strict=False):
    """(block, the lines it indexes into, dialect) for every block of one file's ``data`` (bytes):
    a Python file (``name`` ends in .py), or a notebook's code and Markdown cells (.ipynb); any
    other file has none. Errors name ``name`` and the line (of the file, or of the cell)."""
    name = str(name)
    if name.endswith(".py"):
        lines = split_lines(decode_python(data, name))
        return [(block, lines, CODE) for block in find_blocks(lines, lambda index: f"{name}:{index + 1}",
                                                               CODE, styles, known, strict)]
    if not name.endswith(".ipynb"):
        return []
    found = []
    for cell in notebook_cells(read_notebook(data, name)):
        if cell.kind in (CODE, MARKDOWN):
            def where(index, cell=cell):
                return f"{name} (cell {cell.index + 1}, line {index + 1} of the cell)"

            lines = list(cell.lines)
            found += [(block, lines, cell.kind) for block in find_blocks(lines, where, cell.kind, styles, known, strict)]
    return found
