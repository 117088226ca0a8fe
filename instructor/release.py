"""Build the student edition of the kit from the instructor's kit (the one source of truth).

    python -m instructor.release student OUT_DIR [--source KIT_DIR] [--force] [--keep TODO ...]
    python -m instructor.release gradescope OUT.zip [--source KIT_DIR] [--force]   (see instructor/gradescope.py)

Solution code is fenced, in ``hwlib`` and in the notebooks' code cells, by comment lines

    ### BEGIN SOLUTION 1.2.1
    ### HINT: one line for the student (optional; else the hint table below)
    ...
    ### END SOLUTION 1.2.1

and, in Markdown cells, by ``<!-- BEGIN SOLUTION 2.1.1 -->`` ... ``<!-- END SOLUTION 2.1.1 -->``.
In the student edition

* a fenced block in library code becomes the student's starting point between kept markers
  ``### BEGIN TODO 1.2.1`` / ``### END TODO 1.2.1`` (the grader takes the student's code from
  between them): the hint as a ``# TODO`` comment, then the block's ``### STUB: code`` lines (or
  ``pass``), so the skeleton around it (signature, givens, return) reads as the student's start;
  a fenced block at module level may only assign names, and each name becomes
  ``NAME = None  # TODO 1.3.3: <hint>`` (so the module still imports);
* a fenced block in a notebook code cell becomes ``# TODO <id>: <hint>``, ``# YOUR CODE HERE``,
  ``raise NotImplementedError()`` (or its ``### STUB:`` lines) between the same kept markers; in a
  Markdown cell it becomes ``YOUR ANSWER HERE``;
* every notebook's outputs, execution counts, execution timings and stored widget state are cleared;
* instructor-only files (``INSTRUCTOR_ONLY``: this tool, tests/hidden/, the tests of this tool
  and of the grader's proof, the wrong-solution fixtures, the logistic-regression benchmark whose
  reference loop spells out answers) are left out, and so are the top-level tests marked
  ``@pytest.mark.hidden`` in the other test files;
* ``pyproject.toml`` runs the notebooks with ``--nbval-lax`` (stored notebooks have no outputs
  to compare, so cells must only run without error), and the README gets a short note for
  students; README parts between ``<!-- BEGIN INSTRUCTOR ONLY -->`` and
  ``<!-- END INSTRUCTOR ONLY -->`` are left out.

The kit's files are those ``git ls-files --cached --others --exclude-standard`` lists (tracked
plus untracked, without git-ignored ones); outside a git repository, a sorted walk that skips
virtual environments, caches, build output and the course data. Nothing is written until every
file has been transformed, and the output depends only on the input (sorted, no timestamps),
so two builds are byte-identical. A marker without its pair, nested markers, mismatched ids or
a block without a TODO id stop the build with ``file:line: message``.
"""

from __future__ import annotations

import argparse
import ast
import json
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from hwtools.todos import TODO_BY_ID

# Left out of the student edition: path prefixes relative to the kit (folders end with "/").
INSTRUCTOR_ONLY = (
    "instructor/",  # the release tool, hidden checks, wrong solutions: one folder
    "tests/test_release.py",
    "tests/test_grading.py",
    "tests/test_classroom.py",  # classes built from the wrong solutions and cheats, graded against the reference
    "tests/test_gradescope.py",
    "tests/test_student_edition.py",
    "tests/hidden/",
    "tests/wrong_solutions/",
    "tests/natural_solutions/",  # working solutions of every TODO
    "tests/cheats/",
    # Its per-sample reference loop spells out the gradient of 2.1.1 and the labels of 2.3.1.
    "benchmarks/bench_logreg.py",
    "benchmarks/requirements-bench.txt",
    "benchmarks/bench_grading.py",  # it grades against the reference solution
    "benchmarks/bench_classroom.py",
    "benchmarks/bench_dayone.py",  # it builds a student edition with the solutions kept
    "tests/day_one.py",  # the helper of the student-edition tests
)

ANSWER_KEY = "hwtools/grade/answer_key.json"  # written by the build: the visible checks' expected values

# Only the homework holds solution blocks; tooling elsewhere (the grader) may talk about markers freely.
HOMEWORK_FOLDERS = ("hwlib/", "notebooks/")

# Never part of a kit, whatever git says: at any depth, and (build output) at the top.
SKIPPED_PARTS = {".git", ".venv", "venv", "__pycache__", ".pytest_cache", ".ipynb_checkpoints"}
SKIPPED_TOP = {"build", "dist", "test-artifacts"}
SKIPPED_SUFFIXES = (".pyc", ".egg-info")

# One-line hints per TODO, used where a block has no "### HINT:" line of its own.
HINTS = {
    "1.1.1": "equation (1): action 1 when the dot product of the parameters and the observation is negative, else 0",
    "1.2.1": "central differences, equation (3), one coordinate at a time",
    "1.3.1": "the mean total reward of num_rollouts episodes",
    "1.3.2": "one gradient-ascent step, equation (4), and the reward after it",
    "1.3.3": "a learning rate with which training converges within 7 iterations",
    "2.1.1": "the gradient of equation (7) that you derived",
    "2.2.1": "the sigmoid of equation (5), elementwise",
    "2.2.2": "the probability of the positive class for each row of X, with the constant 1 feature appended",
    "2.2.3": "one gradient ascent step, equation (8), with the gradient you derived in 2.1.1",
    "2.3.1": "for each class: one-vs-rest labels (1 for class c, 0 otherwise) and one step of classifier c",
}
NOTEBOOK_HINTS = {
    "1.1.2": "a few parameter vectors you tried with the sliders, each with a name",
    "2.3.2": "train the one-vs-rest classifier with the settings and compute the accuracies the report needs",
}

STUDENT_NOTE = """\
> **Student edition.** The code of the handout's TODOs is yours to write. In `hwlib/` each one
> sits between `### BEGIN TODO 1.2.1` and `### END TODO 1.2.1` inside the function the handout
> names: write your code there and leave the two marker lines as they are (the grader reads your
> code from between them). In the notebooks a TODO is a `# YOUR CODE HERE` cell or a
> YOUR ANSWER HERE text. Until you fill them in, the tests of those TODOs fail.
> `.venv/bin/python -m hwtools.grade` checks your functions and prints your automatic points per
> TODO (the report items are graded by hand). The notebooks are stored without outputs, so
> `pytest` runs them with `--nbval-lax`: every cell must run without error, but outputs are not
> compared.
"""

ID_PATTERN = r"[0-9]+(?:\.[0-9]+)+"
CODE_MARKER = re.compile(r"^(?P<indent>[ \t]*)###[ \t]*(?P<kind>BEGIN|END)[ \t]+SOLUTION(?P<rest>.*?)[ \t]*$")
MARKDOWN_MARKER = re.compile(r"^[ \t]*<!--[ \t]*(?P<kind>BEGIN|END)[ \t]+SOLUTION(?P<rest>.*?)[ \t]*-->[ \t]*$")
HINT_LINE = re.compile(r"^[ \t]*###[ \t]*HINT:[ \t]*(?P<hint>.*?)[ \t]*$")
STUB_LINE = re.compile(r"^[ \t]*###[ \t]*STUB:(?: (?P<code>.*?))?[ \t]*$")
NEAR_MISS = re.compile(r"\b(BEGIN|END)[ \t_-]*SOLUTION\b")
HIDDEN_MARK = re.compile(r"(?:pytest\.)?mark\.hidden\b(?:\(\))?")
INSTRUCTOR_BLOCK = re.compile(r"^[ \t]*<!--[ \t]*(?P<kind>BEGIN|END)[ \t]+INSTRUCTOR ONLY[ \t]*-->[ \t]*$")


class ReleaseError(Exception):
    """A problem in the source kit, located as ``file:line: message``."""


@dataclass(frozen=True)
class Block:
    todo: str
    begin: int  # index of the BEGIN line
    end: int  # index of the END line
    indent: str
    hint: str | None
    body_start: int  # first line of the solution itself (after the HINT and STUB lines)
    stub: tuple = ()  # the "### STUB: code" lines: the code the student starts from


# --------------------------------------------------------------------------------------------
# Markers
# --------------------------------------------------------------------------------------------


def find_blocks(lines, where, style="code"):
    """The fenced blocks of ``lines`` (strings without line ends).

    ``where(index)`` names the location of line ``index`` for error messages. ``style`` is
    "code" (``### BEGIN SOLUTION id``) or "markdown" (``<!-- BEGIN SOLUTION id -->``).
    """
    marker = CODE_MARKER if style == "code" else MARKDOWN_MARKER
    blocks, open_block = [], None
    for index, line in enumerate(lines):
        match = marker.match(line)
        if match is None:
            if NEAR_MISS.search(line):
                raise ReleaseError(f"{where(index)}: malformed solution marker {line.strip()!r}; "
                                   f"write {_marker_example(style, 'BEGIN', '1.2.1')!r}")
            continue
        kind, todo = match["kind"], _marker_id(match["rest"], line, where(index), style)
        if kind == "BEGIN":
            if open_block is not None:
                raise ReleaseError(f"{where(index)}: nested BEGIN SOLUTION {todo}: "
                                   f"BEGIN SOLUTION {open_block[0]} of {where(open_block[1])} is still open")
            open_block = (todo, index, match.groupdict().get("indent") or "")
        else:
            if open_block is None:
                raise ReleaseError(f"{where(index)}: END SOLUTION {todo} without a BEGIN SOLUTION")
            if todo != open_block[0]:
                raise ReleaseError(f"{where(index)}: END SOLUTION {todo} closes BEGIN SOLUTION {open_block[0]} "
                                   f"of {where(open_block[1])}: the ids differ")
            indent = match.groupdict().get("indent") or ""
            if style == "code" and indent != open_block[2]:
                raise ReleaseError(f"{where(index)}: END SOLUTION {todo} is not indented like its BEGIN "
                                   f"({where(open_block[1])})")
            begin = open_block[1]
            hint, body_start, stub = None, begin + 1, []
            if style == "code" and body_start < index:
                hint_match = HINT_LINE.match(lines[body_start])
                if hint_match:
                    hint, body_start = hint_match["hint"], body_start + 1
                while body_start < index and STUB_LINE.match(lines[body_start]):
                    stub.append(STUB_LINE.match(lines[body_start])["code"])
                    body_start += 1
            blocks.append(Block(todo, begin, index, open_block[2], hint, body_start, tuple(stub)))
            open_block = None
    if open_block is not None:
        raise ReleaseError(f"{where(open_block[1])}: BEGIN SOLUTION {open_block[0]} has no END SOLUTION {open_block[0]}")
    return blocks


def file_blocks(path, name=None):
    """(block, the lines it indexes into, style) for every solution block of one kit file: a Python
    file, or the code and Markdown cells of a notebook; any other file has none. ``name`` (default:
    ``path``) locates errors."""
    path = Path(path)
    name = name or str(path)
    if path.suffix == ".py":
        sources = [("code", path.read_text(encoding="utf-8"))]
    elif path.suffix == ".ipynb":
        sources = [(cell["cell_type"], "".join(cell["source"]))
                   for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]]
    else:
        return []
    found = []
    for style, source in sources:
        if style in ("code", "markdown"):
            lines = source.split("\n")
            found += [(block, lines, style) for block in find_blocks(lines, lambda index: f"{name}:{index + 1}", style)]
    return found


def _marker_id(rest, line, location, style):
    todo = rest.strip()
    if not todo:
        raise ReleaseError(f"{location}: solution marker without a TODO id: {line.strip()!r}; "
                           f"write {_marker_example(style, 'BEGIN', '1.2.1')!r}")
    if not re.fullmatch(ID_PATTERN, todo):
        raise ReleaseError(f"{location}: {todo!r} is not a TODO id (like 1.2.1) in {line.strip()!r}")
    if todo not in TODO_BY_ID:
        raise ReleaseError(f"{location}: unknown TODO id {todo}; the handout's are {', '.join(TODO_BY_ID)}")
    return todo


def _marker_example(style, kind, todo):
    return f"### {kind} SOLUTION {todo}" if style == "code" else f"<!-- {kind} SOLUTION {todo} -->"


def _string_literal(text):
    return f'"{text}"' if '"' not in text and "\\" not in text else repr(text)


# --------------------------------------------------------------------------------------------
# Python files
# --------------------------------------------------------------------------------------------


def transform_python(text, path, keep=frozenset(), replace=None):
    """The student version of one Python file's text.

    Blocks of TODOs in ``keep`` keep their solution (without the marker lines); ``replace``
    maps a TODO id to code put in place of its blocks (a wrong solution, for the grader's proof).
    """
    lines = text.split("\n")
    blocks = find_blocks(lines, lambda index: f"{path}:{index + 1}")
    _check_replacements(blocks, replace, path)
    if not blocks:
        return text
    result = "\n".join(_replace_blocks(lines, blocks, keep, replace, lambda block: _python_stub(block, lines, path),
                                      wrap=_todo_markers))
    try:
        compile(result, str(path), "exec", dont_inherit=True)
    except SyntaxError as error:
        raise ReleaseError(f"{path}:{error.lineno}: the student version does not compile ({error.msg}); "
                           "move the solution markers so that a stub can stand in for the block") from None
    return result


def _python_stub(block, lines, path):
    """The student's starting point for one block, between kept ``### BEGIN TODO`` / ``### END TODO``
    markers (the grader finds the student's code between them): the hint as a comment, then the
    block's STUB lines, or ``pass``. The skeleton around the block is the same in both editions."""
    body = lines[block.body_start:block.end]
    hint = _hint(block, HINTS, path)
    begin, end = f"{block.indent}### BEGIN TODO {block.todo}", f"{block.indent}### END TODO {block.todo}"
    if block.indent:
        stub = [f"{block.indent}{line}" if line else "" for line in block.stub] or [f"{block.indent}pass"]
        return [begin, f"{block.indent}# TODO {block.todo}: {hint}", *stub, end]
    # Module level: a raise would stop the import, so every assigned name becomes None.
    try:
        tree = ast.parse("\n".join(body))
    except SyntaxError as error:
        raise ReleaseError(f"{path}:{block.body_start + (error.lineno or 1)}: solution block {block.todo} "
                           f"does not parse ({error.msg})") from None
    names = []
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else None
        if targets is None or not all(isinstance(target, ast.Name) for target in targets):
            raise ReleaseError(f"{path}:{block.body_start + node.lineno}: a module-level solution block may only "
                               f"assign names (NAME = ...); move the code of TODO {block.todo} into a function")
        names.extend(target.id for target in targets)
    if not names:
        raise ReleaseError(f"{path}:{block.begin + 1}: module-level solution block {block.todo} assigns nothing")
    return [begin, *(f"{name} = None  # TODO {block.todo}: {hint}" for name in names), end]


def _todo_markers(block, body):
    return [f"{block.indent}### BEGIN TODO {block.todo}", *body, f"{block.indent}### END TODO {block.todo}"]


def _check_replacements(blocks, replace, path):
    for todo, codes in (replace or {}).items():
        count = sum(block.todo == todo for block in blocks)
        if count != len(_as_list(codes)):
            raise ReleaseError(f"{path}: TODO {todo} has {count} solution block(s) here, "
                               f"but {len(_as_list(codes))} replacement(s) were given")


def _as_list(codes):
    return [codes] if isinstance(codes, str) else list(codes)


def _hint(block, table, path):
    hint = block.hint or table.get(block.todo) or HINTS.get(block.todo)
    if not hint:
        raise ReleaseError(f"{path}:{block.begin + 1}: no hint for TODO {block.todo}: add a '### HINT: ...' line "
                           "after the BEGIN line or an entry in instructor/release.py's hint tables")
    return hint


def _indent(code, indent):
    lines = code.strip("\n").split("\n")
    return [(indent + line) if line.strip() else "" for line in lines]


def drop_hidden_tests(text, path):
    """``text`` of a test file without its top-level tests (functions or classes) decorated
    ``@pytest.mark.hidden``. A hidden mark anywhere else (``pytestmark``, a method) is an error:
    whole hidden files belong in tests/hidden/, which the student edition leaves out."""
    if not HIDDEN_MARK.search(text):
        return text
    tree = ast.parse(text)
    lines = text.split("\n")
    drop = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            if any(HIDDEN_MARK.fullmatch(ast.unparse(decorator)) for decorator in node.decorator_list):
                first = min(decorator.lineno for decorator in node.decorator_list)
                end = node.end_lineno
                while end < len(lines) and not lines[end].strip():  # the blank lines after it
                    end += 1
                drop.update(range(first - 1, end))
    leftover = [index + 1 for index, line in enumerate(lines) if index not in drop and HIDDEN_MARK.search(line)]
    if leftover:
        raise ReleaseError(f"{path}:{leftover[0]}: only top-level tests can be marked hidden here; "
                           "put hidden test files in tests/hidden/, which the student edition leaves out")
    kept = [line for index, line in enumerate(lines) if index not in drop]
    while len(kept) > 1 and not kept[-1].strip() and not kept[-2].strip():
        kept.pop()  # a file that ended with a dropped test ends with one newline, as before
    return "\n".join(kept)


# --------------------------------------------------------------------------------------------
# Notebooks
# --------------------------------------------------------------------------------------------


def transform_notebook(text, path, keep=frozenset(), replace=None):
    """The student version of a notebook's JSON text: stubs, no outputs, no stored widget state."""
    notebook = json.loads(text)
    raw_lines = text.split("\n")
    replaced, seen = {}, {}
    for index, cell in enumerate(notebook.get("cells", [])):
        source = cell.get("source", "")
        source_text = "".join(source) if isinstance(source, list) else source
        lines = source_text.split("\n")

        def where(line_index, cell_index=index, cell=cell, lines=lines):
            file_line = _notebook_file_line(raw_lines, cell, lines[line_index])
            at = f"{path}:{file_line}" if file_line else str(path)
            return f"{at} (cell {cell_index + 1}, line {line_index + 1} of the cell)"

        kind = cell.get("cell_type")
        if kind == "code":
            blocks = find_blocks(lines, where, "code")
            new_lines = _replace_blocks(lines, blocks, keep, replace, lambda block: _notebook_code_stub(block, path), seen)
        elif kind == "markdown":
            blocks = find_blocks(lines, where, "markdown")
            new_lines = _replace_blocks(lines, blocks, keep, replace, lambda block: ["YOUR ANSWER HERE"], seen)
        else:
            for line_index, line in enumerate(lines):
                if NEAR_MISS.search(line):
                    raise ReleaseError(f"{where(line_index)}: solution markers are only understood in code and Markdown cells")
            new_lines = lines
        for block in blocks:
            replaced.setdefault(block.todo, []).append(block)
        if blocks:
            new_text = "\n".join(new_lines)
            cell["source"] = new_text.splitlines(keepends=True) if isinstance(source, list) else new_text
        if kind == "code":
            cell["outputs"] = []
            cell["execution_count"] = None
        metadata = cell.get("metadata", {})
        for key in ("execution", "collapsed", "scrolled"):
            metadata.pop(key, None)
    notebook.get("metadata", {}).pop("widgets", None)
    for todo in replace or {}:
        _check_replacements(replaced.get(todo, []), {todo: replace[todo]}, path)
    return json.dumps(notebook, indent=1, sort_keys=True, ensure_ascii=False) + "\n"


def _replace_blocks(lines, blocks, keep, replace, stub, seen=None, wrap=None):
    """``lines`` with each block stubbed, kept or replaced; ``seen`` counts each TODO's blocks
    across calls (the cells of one notebook), so the n-th block gets the n-th replacement.
    ``wrap(block, body)`` frames a kept or replaced body (library code keeps its TODO markers)."""
    out, position, seen = [], 0, ({} if seen is None else seen)
    wrap = wrap or (lambda block, body: body)
    for block in blocks:
        out.extend(lines[position:block.begin])
        if replace and block.todo in replace:
            number = seen[block.todo] = seen.get(block.todo, -1) + 1
            out.extend(wrap(block, _indent(_as_list(replace[block.todo])[number], block.indent)))
        elif block.todo in keep:
            out.extend(wrap(block, lines[block.body_start:block.end]))
        else:
            out.extend(stub(block))
        position = block.end + 1
    out.extend(lines[position:])
    return out


def _notebook_code_stub(block, path):
    hint = _hint(block, NOTEBOOK_HINTS, path)
    body = [f"{block.indent}{line}" for line in block.stub] or [f"{block.indent}# YOUR CODE HERE", f"{block.indent}raise NotImplementedError()"]
    return _todo_markers(block, [f"{block.indent}# TODO {block.todo}: {hint}", *body])


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
                if json.loads(stored).rstrip("\n") == line_text:
                    return number + 1
            except json.JSONDecodeError:
                continue
    return None


# --------------------------------------------------------------------------------------------
# Other files
# --------------------------------------------------------------------------------------------


def transform_pyproject(text, path):
    """Run the notebooks with --nbval-lax: stored without outputs, they cannot be compared."""
    lines = text.split("\n")
    for index, line in enumerate(lines):
        if line.strip().startswith("addopts") and re.search(r"--nbval(?![-\w])", line):
            lines[index] = re.sub(r"--nbval(?![-\w])", "--nbval-lax", line)
            return "\n".join(lines)
    raise ReleaseError(f"{path}:1: no 'addopts' line with --nbval to turn into --nbval-lax for the student edition")


def transform_readme(text, path):
    """Drop the instructor-only parts and add the student note after the title."""
    lines = text.split("\n")
    out, open_line = [], None
    for index, line in enumerate(lines):
        match = INSTRUCTOR_BLOCK.match(line)
        if match:
            if match["kind"] == "BEGIN":
                if open_line is not None:
                    raise ReleaseError(f"{path}:{index + 1}: nested BEGIN INSTRUCTOR ONLY (line {open_line + 1} is still open)")
                open_line = index
            else:
                if open_line is None:
                    raise ReleaseError(f"{path}:{index + 1}: END INSTRUCTOR ONLY without a BEGIN INSTRUCTOR ONLY")
                open_line = None
            continue
        if open_line is None:
            out.append(line)
    if open_line is not None:
        raise ReleaseError(f"{path}:{open_line + 1}: BEGIN INSTRUCTOR ONLY has no END INSTRUCTOR ONLY")
    title = next((index for index, line in enumerate(out) if line.startswith("# ")), -1)
    note = STUDENT_NOTE.rstrip("\n").split("\n")
    return "\n".join(out[:title + 1] + [""] + note + out[title + 1:])


# --------------------------------------------------------------------------------------------
# The kit
# --------------------------------------------------------------------------------------------


def kit_files(source):
    """The kit's files, as sorted POSIX paths relative to ``source``."""
    source = Path(source)
    names = None
    if (source / ".git").exists() and shutil.which("git"):
        result = subprocess.run(
            ["git", "-C", str(source), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
            capture_output=True, check=False,
        )
        if result.returncode == 0:
            names = [name for name in result.stdout.decode("utf-8").split("\0") if name]
    if names is None:
        names = [path.relative_to(source).as_posix() for path in source.rglob("*") if path.is_file() or path.is_symlink()]
    return sorted(name for name in set(names) if _is_kit_file(source, name))


def _is_kit_file(source, name):
    parts = PurePosixPath(name).parts
    if parts[0] in SKIPPED_TOP or any(part in SKIPPED_PARTS or part.endswith(SKIPPED_SUFFIXES) for part in parts):
        return False
    if parts[0] == "data" and (name.endswith(".npz") or (len(parts) > 1 and parts[1] == "audio")):
        return False  # the course's data is never copied
    path = source / name
    return path.is_file() and not path.is_symlink()


def is_instructor_only(name):
    return any(name == prefix or (prefix.endswith("/") and name.startswith(prefix)) for prefix in INSTRUCTOR_ONLY)


def student_files(source, keep=frozenset(), replace=None):
    """{relative path: (bytes, executable)} of the student edition, built in memory.

    ``keep``: TODO ids whose solutions stay; ``replace``: {(TODO id, relative path): code} put in
    place of that TODO's blocks in that file (the grader's proof uses both).
    """
    source = Path(source).resolve()
    replace = replace or {}
    files = {}
    for name in kit_files(source):
        if is_instructor_only(name):
            continue
        path = source / name
        data = path.read_bytes()
        executable = bool(path.stat().st_mode & 0o111)
        file_replace = {todo: code for (todo, file), code in replace.items() if file == name}
        if name.endswith(".py") and name.startswith(HOMEWORK_FOLDERS):
            data = transform_python(data.decode("utf-8"), name, keep, file_replace).encode("utf-8")
        elif name.endswith(".py") and name.startswith("tests/"):
            data = drop_hidden_tests(data.decode("utf-8"), name).encode("utf-8")
        elif name.endswith(".ipynb"):
            data = transform_notebook(data.decode("utf-8"), name, keep, file_replace).encode("utf-8")
        elif name == "pyproject.toml":
            data = transform_pyproject(data.decode("utf-8"), name).encode("utf-8")
        elif name == "README.md":
            data = transform_readme(data.decode("utf-8"), name).encode("utf-8")
        files[name] = (data, executable)
    missing = sorted(f"{file} (TODO {todo})" for todo, file in replace if file not in files)
    if missing:
        raise ReleaseError(f"{missing[0]}: no such file in the student edition to put a replacement into")
    return files


def build_student_edition(source, out_dir, keep=frozenset(), replace=None, force=False, answer_key=True):
    """Write the student edition of the kit in ``source`` into ``out_dir``. Returns the file list.

    With ``answer_key`` the grader's answer key for the visible checks (``ANSWER_KEY``: the
    reference's values on the visible inputs, nothing about hidden ones) is written too, so that
    ``python -m hwtools.grade`` works in the student edition; it runs the reference sandboxed.
    """
    source, out_dir = Path(source).resolve(), Path(out_dir).resolve()
    if out_dir == source or source.is_relative_to(out_dir):
        raise ReleaseError(f"{out_dir}: the output folder must not be the kit or contain it")
    files = student_files(source, keep, replace)
    if out_dir.exists():
        if not out_dir.is_dir():
            raise ReleaseError(f"{out_dir}: exists and is not a folder")
        if any(out_dir.iterdir()):
            if not force:
                raise ReleaseError(f"{out_dir}: not empty (pass --force to replace an earlier student edition)")
            if not ((out_dir / "hwlib").is_dir() and (out_dir / "pyproject.toml").is_file()):
                raise ReleaseError(f"{out_dir}: not empty and not a kit; refusing to delete it")
            shutil.rmtree(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for name, (data, executable) in sorted(files.items()):
        target = out_dir / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
        target.chmod(0o755 if executable else 0o644)
    if answer_key:
        from hwtools.grade import write_answer_key  # noqa: PLC0415 - only the full build needs the grader

        write_answer_key(source, out_dir / ANSWER_KEY)
        return sorted([*files, ANSWER_KEY])
    return sorted(files)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m instructor.release", description="Build an edition of the kit.")
    commands = parser.add_subparsers(dest="edition", required=True)
    student = commands.add_parser("student", help="the student edition: solutions replaced by stubs, no outputs, no instructor files")
    student.add_argument("out_dir", help="folder to write the student edition into (new or empty)")
    student.add_argument("--source", default=str(Path(__file__).resolve().parents[1]), help="the instructor's kit (default: this kit)")
    student.add_argument("--force", action="store_true", help="replace an earlier student edition in OUT_DIR")
    student.add_argument("--keep", action="append", default=[], metavar="TODO", help="keep this TODO's solution (for checking the tests)")
    student.add_argument("--no-answer-key", action="store_true",
                         help="skip the grader's answer key (then the student edition's grader has nothing to compare with)")
    from instructor import gradescope  # noqa: PLC0415 - the Gradescope bundle: instructor/gradescope.py

    gradescope.add_parser(commands, Path(__file__).resolve().parents[1])
    args = parser.parse_args(argv)
    if args.edition == "gradescope":
        return args.run(args)
    unknown = [todo for todo in args.keep if todo not in TODO_BY_ID]
    if unknown:
        parser.error(f"unknown TODO id(s) for --keep: {', '.join(unknown)}")
    try:
        names = build_student_edition(args.source, args.out_dir, keep=frozenset(args.keep), force=args.force,
                                      answer_key=not args.no_answer_key)
    except ReleaseError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    print(f"student edition: {len(names)} files in {args.out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
