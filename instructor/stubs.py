"""What a student starts from in place of each solution block, and the student version of a Python file.

In library code a block becomes, between kept ``### BEGIN TODO x.y.z`` / ``### END TODO x.y.z``
markers (the grader reads the student's code from between them):

* in a function: the hint as a ``# TODO x.y.z: <hint>`` comment, the block's ``### STUB:`` lines,
  and ``raise TodoNotDone("x.y.z")`` (unless a STUB line raises already), so an untouched TODO
  says which TODO it is where it is called instead of returning zeros. ``TodoNotDone`` is the
  kit's "not done yet" exception (``hwlib/machinery/todos.py``); a module with such a block imports it. In a
  kit without that module the stub is the STUB lines or ``pass``, as before;
* at module level (``settings.LEARNING_RATE``): the hint comment, then ``NAME = None`` for every
  name the block assigns, so the module still imports.

The hint comment of a module-level or notebook stub is wrapped at ``HINT_WIDTH`` columns, so its
lines do not run off an editor's view; a function stub's stays one line, since the notebooks link to
the lines of the library TODOs below it (``#line=``).

In a notebook code cell a block becomes the hint, then its STUB lines (the starting values a cell
runs with) or, in a kit with ``TodoNotDone``, ``from hwlib import TodoNotDone`` and ``raise
TodoNotDone("x.y.z")``: the cell stops with the same two lines as a library stub (in a kit without
it, ``# YOUR CODE HERE`` and ``raise NotImplementedError()``). In a Markdown cell, ``YOUR ANSWER HERE``.
"""

from __future__ import annotations

import ast
import textwrap

from hwtools import markers
from instructor.kit import ReleaseError, find_blocks

NOT_DONE = "TodoNotDone"  # the exception an untouched function stub raises
NOT_DONE_MODULE = "hwlib/machinery/todos.py"  # where the kit defines it; with this file, every function stub raises it
HINT_WIDTH = 100  # columns of a module-level or notebook stub's "# TODO x.y.z: <hint>" comment, then more lines

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


# --------------------------------------------------------------------------------------------
# Python files
# --------------------------------------------------------------------------------------------


def transform_python(text, path, keep=frozenset(), replace=None, require_not_done=False):
    """The student version of one Python file's text (``\\n`` line ends).

    Blocks of TODOs in ``keep`` keep their solution (without the marker lines); ``replace``
    maps a TODO id to code put in place of its blocks (a wrong solution, for the grader's proof).
    ``require_not_done``: the kit defines ``TodoNotDone``, so a module with a block in a function
    must import it (else the build stops, naming the module).
    """
    lines = markers.split_lines(text)
    blocks = find_blocks(lines, lambda index: f"{path}:{index + 1}")
    check_replacements(blocks, replace, path)
    if not blocks:
        return "\n".join(lines)
    not_done = _binds_not_done(text, path)
    if require_not_done and not not_done and any(block.indent for block in blocks):
        first = next(block for block in blocks if block.indent)
        raise ReleaseError(f"{path}:{first.begin + 1}: the stub of TODO {first.todo} raises {NOT_DONE}; import it in "
                           f"this module (from hwlib.machinery.todos import {NOT_DONE})")
    result = "\n".join(replace_blocks(lines, blocks, keep, replace, lambda block: python_stub(block, lines, path, not_done),
                                      wrap=todo_markers))
    try:
        compile(result, str(path), "exec", dont_inherit=True)
    except SyntaxError as error:
        raise ReleaseError(f"{path}:{error.lineno}: the student version does not compile ({error.msg}); "
                           "move the solution markers so that a stub can stand in for the block") from None
    return result


def python_stub(block, lines, path, not_done=False):
    """The student's starting point for one block, between kept ``### BEGIN TODO`` / ``### END TODO``
    markers: the hint as a comment, then the block's STUB lines and (``not_done``: the module has
    ``TodoNotDone``) ``raise TodoNotDone("x.y.z")``, or ``pass``. The skeleton around the block is
    the same in both editions."""
    if block.indent:
        stub = [f"{block.indent}{line}" if line else "" for line in block.stub]
        if not_done and not any(line.lstrip().startswith("raise") for line in block.stub):
            stub.append(f'{block.indent}raise {NOT_DONE}("{block.todo}")')
        return todo_markers(block, [*_hint_comment(block, HINTS, path, width=None), *(stub or [f"{block.indent}pass"])])
    # Module level: a raise would stop the import, so every assigned name becomes None.
    try:
        tree = ast.parse("\n".join(block.code))
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
    return todo_markers(block, [*_hint_comment(block, HINTS, path), *(f"{name} = None" for name in names)])


def _binds_not_done(text, path):
    """True if the module's top level imports or defines ``TodoNotDone``."""
    try:
        tree = ast.parse(text)
    except SyntaxError as error:
        raise ReleaseError(f"{path}:{error.lineno}: does not parse ({error.msg})") from None
    for node in tree.body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            if any((alias.asname or alias.name) == NOT_DONE for alias in node.names):
                return True
        elif isinstance(node, ast.ClassDef) and node.name == NOT_DONE:
            return True
    return False


# --------------------------------------------------------------------------------------------
# Notebook cells
# --------------------------------------------------------------------------------------------


def notebook_code_stub(block, path, not_done=False):
    """The student's start for a notebook block: its STUB lines, else (``not_done``: the kit has
    ``TodoNotDone``, which ``hwlib`` exports) ``raise TodoNotDone("x.y.z")``, else a bare raise."""
    hint = _hint_comment(block, NOTEBOOK_HINTS, path)
    body = block.stub or ([f"from hwlib import {NOT_DONE}", f'raise {NOT_DONE}("{block.todo}")'] if not_done
                          else ["# YOUR CODE HERE", "raise NotImplementedError()"])
    return todo_markers(block, [*hint, *(f"{block.indent}{line}" for line in body)])


def markdown_stub(block, path):
    return ["YOUR ANSWER HERE"]


# --------------------------------------------------------------------------------------------
# Putting stubs, kept solutions or replacements in place of the blocks
# --------------------------------------------------------------------------------------------


def replace_blocks(lines, blocks, keep, replace, stub, seen=None, wrap=None):
    """``lines`` with each block stubbed, kept or replaced; ``seen`` counts each TODO's blocks
    across calls (the cells of one notebook), so the n-th block gets the n-th replacement.
    ``wrap(block, body)`` frames a kept or replaced body (library code keeps its TODO markers)."""
    out, position, seen = [], 0, ({} if seen is None else seen)
    wrap = wrap or (lambda block, body: body)
    for block in blocks:
        out.extend(lines[position:block.begin])
        if replace and block.todo in replace:
            number = seen[block.todo] = seen.get(block.todo, -1) + 1
            out.extend(wrap(block, _indent(as_list(replace[block.todo])[number], block.indent)))
        elif block.todo in keep:
            out.extend(wrap(block, list(block.code)))
        else:
            out.extend(stub(block))
        position = block.end + 1
    out.extend(lines[position:])
    return out


def todo_markers(block, body):
    return [f"{block.indent}### BEGIN TODO {block.todo}", *body, f"{block.indent}### END TODO {block.todo}"]


def check_replacements(blocks, replace, path):
    for todo, codes in (replace or {}).items():
        count = sum(block.todo == todo for block in blocks)
        if count != len(as_list(codes)):
            raise ReleaseError(f"{path}: TODO {todo} has {count} solution block(s) here, "
                               f"but {len(as_list(codes))} replacement(s) were given")


def as_list(codes):
    return [codes] if isinstance(codes, str) else list(codes)


def _hint_comment(block, table, path, width=HINT_WIDTH):
    """The lines of the block's ``# TODO x.y.z: <hint>`` comment, at its indent, wrapped at ``width``
    (None: one line)."""
    hint = block.hint or table.get(block.todo) or HINTS.get(block.todo)
    if not hint:
        raise ReleaseError(f"{path}:{block.begin + 1}: no hint for TODO {block.todo}: add a '### HINT: ...' line "
                           "after the BEGIN line or an entry in instructor/stubs.py's hint tables")
    if width is None:
        return [f"{block.indent}# TODO {block.todo}: {hint}"]
    return textwrap.wrap(f"TODO {block.todo}: {hint}", width, initial_indent=f"{block.indent}# ",
                         subsequent_indent=f"{block.indent}# ", break_long_words=False, break_on_hyphens=False)


def _indent(code, indent):
    lines = markers.normalise_newlines(code).strip("\n").split("\n")
    return [(indent + line) if line.strip() else "" for line in lines]
