"""The kits the grader writes and runs: a kit per TODO's run, the reference server's kit, a submission.

A kit is the reference's ``hwlib/`` (``blocks.KitLayout``) with each TODO block chosen: the
student's code, the reference's, or a stub (``composite_files``), plus the folder that runs in
the sandbox (``in_sandbox/``, copied whole as ``_hwgrade/``: ``sandboxed_files``). A student's
run gets its own TODO's code and a stub in every other block, so no kit a student's code runs in
holds reference code; the reference server's kit holds every solution but 1.3.3's.

Standard library only: the grader's trusted process imports this module, never ``hwlib``.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import io
import os
import shutil
import tokenize
from pathlib import Path, PurePosixPath

from hwtools import markers
from hwtools.grade import blocks
from hwtools.grade.blocks import parse, reindent

IN_SANDBOX = Path(__file__).resolve().parent / "in_sandbox"
WORKER = IN_SANDBOX / "worker.py"  # the entry point of every sandboxed process
SANDBOXED_PACKAGE = "_hwgrade"  # the name the folder in_sandbox/ has in a kit


def sandboxed_files():
    """{relative path: text} of the folder ``in_sandbox/``, as the package ``_hwgrade`` of a kit:
    what runs in every sandboxed process (worker, loop, probes, proxies, message format)."""
    return dict(_sandboxed_files())


@functools.lru_cache(maxsize=1)
def _sandboxed_files():
    return tuple((f"{SANDBOXED_PACKAGE}/{path.relative_to(IN_SANDBOX).as_posix()}", path.read_text(encoding="utf-8"))
                 for path in sorted(IN_SANDBOX.rglob("*.py")))


def stub_lines(block, todo):
    """What stands in for a block that a check does not run: a raise in a function, ``NAME = None``
    for each name a module-level block assigns."""
    if not block.module_level:
        return [f'{block.indent}raise NotImplementedError("TODO {todo} is not part of this check")']
    names = []
    try:
        tree = parse("\n".join(reindent(block.body, "")))
    except SyntaxError:
        tree = ast.Module(body=[], type_ignores=[])
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        names.extend(target.id for target in targets if isinstance(target, ast.Name))
    return [f"{name} = None" for name in names] or ["pass"]


def compose_file(text, blocks, choose, spans=None):
    """``text`` with every block replaced by ``choose(block, number)`` (lines; ``number`` counts the
    blocks of that TODO in this file), markers dropped. ``spans``: a dict to fill with each block's
    lines in the result, {block: (first, last)} (1-based, inclusive)."""
    lines = text.split("\n")
    out, position, seen = [], 0, {}
    for block in blocks:
        number = seen[block.todo] = seen.get(block.todo, -1) + 1
        out.extend(lines[position:block.begin])
        chosen = choose(block, number)
        if spans is not None:
            spans[block] = (len(out) + 1, len(out) + max(len(chosen), 1))
        out.extend(chosen)
        position = block.end + 1
    out.extend(lines[position:])
    return "\n".join(out)


def _has_code(lines):
    try:
        tokens = tokenize.generate_tokens(io.StringIO("\n".join(lines) + "\n").readline)
        return any(token.type not in (tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT,
                                      tokenize.DEDENT, tokenize.ENDMARKER) for token in tokens)
    except (tokenize.TokenError, IndentationError, SyntaxError):
        return True


def placement_problem(layout, todo, bodies, places=None):
    """None if the student's blocks ``bodies`` of ``todo`` parse in their place (``blocks.check_in_place``:
    the kit's file around them, every other block a stub), else the reason, naming the line of the
    student's file (``places``: (relative path, the index of each block's BEGIN line), as
    ``Submission.places`` has it) and of the block."""
    for relative, file_blocks in layout.blocks_by_file.items():
        mine = [block for block in file_blocks if block.todo == todo]
        if not mine:
            continue
        spans = {}
        text = compose_file(layout.files[relative], file_blocks, _chooser({todo: bodies}, set()), spans)
        begins = places[1] if places and places[0] == relative and len(places[1]) == len(mine) else \
            [block.begin for block in mine]
        shown = places[0] if places else relative

        def where(index, line):
            return f"{shown} line {begins[index] + 1 + line} (line {line} of your block" + \
                (f" {index + 1})" if len(mine) > 1 else ")")

        return blocks.check_in_place(text, [spans[block] for block in mine], where)
    return None


def _chooser(student_bodies, reference_todos):
    """``choose`` for ``compose_file``: the student's code, the reference's, or a stub (see ``composite_files``)."""
    def choose(block, number):
        if block.todo in student_bodies:
            lines = reindent(student_bodies[block.todo][number], block.indent)
            if not _has_code(lines):
                lines.append(f"{block.indent}pass")
            return lines
        if block.todo in reference_todos:
            return list(block.body)
        return stub_lines(block, block.todo)

    return choose


def composite_files(layout, student_bodies, reference_todos, only=None):
    """{relative path: text} of a kit built from ``layout`` (the reference): blocks of the TODOs in
    ``student_bodies`` get that code, blocks in ``reference_todos`` keep the reference's, every
    other block is stubbed. ``only``: the relative paths to include, with the kit's modules they
    import (``kit_imports``: ``hwlib/machinery/todos.py`` once a module imports it), and an empty package
    ``__init__`` where the reference's is left out."""
    files, choose = {}, _chooser(student_bodies, reference_todos)
    if only is not None:
        only = kit_imports(layout.files, only)
    for relative, text in layout.files.items():
        if only is not None and relative not in only:
            continue
        file_blocks = layout.blocks_by_file.get(relative, [])
        files[relative] = compose_file(text, file_blocks, choose) if file_blocks else text
    if only is not None:
        for relative in list(files):
            for parent in PurePosixPath(relative).parents:
                init = (parent / "__init__.py").as_posix()
                if parent.parts and init not in files:
                    files[init] = ""
    return files


def kit_imports(files, paths):
    """``paths`` and every module of ``files`` ({relative path: text}) they import, directly or not
    (``import hwlib.x``, ``from hwlib.x import y``, ``from hwlib import x``, ``from . import x``);
    never a package's ``__init__.py``."""
    found, queue = set(), [path for path in paths if path in files]
    while queue:
        relative = queue.pop()
        if relative in found:
            continue
        found.add(relative)
        try:
            tree = parse(files[relative])
        except SyntaxError:
            continue
        package = PurePosixPath(relative).parent.parts
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name.split(".") for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = list(package[:len(package) - node.level + 1]) if node.level else []
                base += node.module.split(".") if node.module else []
                names = [base] + [base + [alias.name] for alias in node.names]
            else:
                continue
            for parts in names:
                candidate = "/".join(parts) + ".py"  # packages get an empty __init__ (see composite_files)
                if candidate in files and candidate not in found:
                    queue.append(candidate)
    return found | set(paths)


def files_digest(files):
    digest = hashlib.sha256()
    for relative in sorted(files):
        digest.update(relative.encode() + b"\0" + files[relative].encode() + b"\0")
    return digest.hexdigest()


def write_files(files, out_dir, held=None):
    """Make the folder ``out_dir`` hold the kit ``files`` ({relative path: text}) alone: read-only files in
    folders anyone may enter. ``held``: the files an earlier call put there, of which only those that
    differ are written again, and those ``files`` lacks removed with the folders they leave empty."""
    out_dir, held = Path(out_dir), held or {}
    out_dir.mkdir(parents=True, exist_ok=True)
    out_dir.chmod(0o755)
    folders, old = _folders(files), _folders(held)
    for relative in held.keys() - files.keys():
        (out_dir / relative).unlink()
    for folder in sorted(old - folders, key=lambda folder: len(folder.parts), reverse=True):
        (out_dir / folder).rmdir()
    for folder in sorted(folders - old, key=lambda folder: len(folder.parts)):
        (out_dir / folder).mkdir(exist_ok=True)
        (out_dir / folder).chmod(0o755)
    for relative, text in sorted(files.items()):
        if held.get(relative) != text:
            target = out_dir / relative
            target.unlink(missing_ok=True)
            target.write_text(text, encoding="utf-8")
            target.chmod(0o444)
    return out_dir


def _folders(files):
    return {folder for relative in files for folder in PurePosixPath(relative).parents if folder.parts}


def read_files(folder):
    """{relative path: text} of every file under ``folder`` (a kit written by hand: the sandbox's tests)."""
    folder = Path(folder)
    return {path.relative_to(folder).as_posix(): path.read_text(encoding="utf-8") for path in sorted(folder.rglob("*"))
            if path.is_file()}


def remove_tree(path):
    def make_writable(function, failed_path, _info):
        os.chmod(failed_path, 0o700)
        function(failed_path)

    shutil.rmtree(path, onerror=make_writable)


def write_submission(layout, out_dir, bodies=None, others="stub", style="TODO"):
    """Write a kit's ``hwlib/`` under ``out_dir`` as a student would hand it in: the blocks of the
    TODOs in ``bodies`` ({todo: code text, or a list of texts, one per block}) hold that code, every
    other block holds the reference solution (``others="reference"``) or a stub (``"stub"``: ``pass``,
    or ``NAME = None`` at module level), between ``### BEGIN/END {style}`` markers. For tests and
    generated classes of submissions."""
    bodies = dict(bodies or {})
    out_dir = Path(out_dir)
    for relative, text in layout.files.items():
        file_blocks = layout.blocks_by_file.get(relative, [])

        def choose(block, number):
            if block.todo in bodies:
                codes = bodies[block.todo]
                code = codes if isinstance(codes, str) else codes[number]
                lines = reindent(markers.split_lines(code.strip("\r\n")), block.indent)
            elif others == "reference":
                lines = list(block.body)
            else:
                lines = [f"{block.indent}# TODO {block.todo}: your code here"]
                lines += [f"{block.indent}pass"] if not block.module_level else stub_lines(block, block.todo)
            return [f"{block.indent}### BEGIN {style} {block.todo}"] + lines + [f"{block.indent}### END {style} {block.todo}"]

        target = out_dir / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(compose_file(text, file_blocks, choose) if file_blocks else text, encoding="utf-8")
    return out_dir


def worker_env(home):
    """The only environment a worker gets, with its home folder ``home`` (on Windows also the
    system's folder, which Python needs to start, and its temporary folder in ``home``)."""
    env = {"PATH": "/usr/bin:/bin", "HOME": home, "TMPDIR": "/tmp" if home.startswith("/tmp/") else home,
           "LANG": "C.UTF-8", "MPLBACKEND": "Agg", "PYTHONHASHSEED": "0", "PYTHONDONTWRITEBYTECODE": "1",
           "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    if os.name == "nt":
        env |= {"SYSTEMROOT": os.environ.get("SYSTEMROOT", r"C:\Windows"), "TEMP": home, "TMP": home,
                "USERPROFILE": home, "PATH": os.environ.get("PATH", "")}
    return env
