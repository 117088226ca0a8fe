"""What a Markdown doc of the kit names, and which of those names a kit lacks.

A doc names files and folders (`hwlib/cartpole.py`, `instructor/`, globs such as `hwlib/**/*.py`),
modules (`python -m hwtools.handin`, `hwtools.grade.sandbox`), names in a file
(`hwlib/logreg.py`: `sigmoid`; `HIDDEN_SEED` in `instructor/hidden_checks/__init__.py`) and other
docs (`[text](../benchmarks/RESULTS.md#grading)`). ``missing`` returns each one the kit at hand
lacks, read statically (nothing is imported). Used by ``tests/instructor/test_docs.py`` (the README and
``docs/`` against this kit) and ``tests/instructor/test_release.py`` (the student edition's README against the
edition).
"""

from __future__ import annotations

import ast
import fnmatch
import posixpath
import re
from pathlib import Path

PACKAGES = ("hwlib", "hwtools", "instructor")
ROOTS = (*PACKAGES, "tests", "benchmarks", "notebooks", "docs", "data", ".ci")
TOP_FILES = ("README.md", "requirements.txt", "pyproject.toml", "conftest.py")
# Named by the docs, made at run time or put there by the user, never part of a kit's files.
NOT_IN_A_KIT = ("data/data.npz", "data/audio", "data/audio/*", "hwtools/grade/answer_key.json")

PATH = re.compile(r"(?<![\w.~/-])((?:%s)/[\w.*/<>…-]*[\w*/>]|(?:%s))(?![\w/])"
                  % ("|".join(re.escape(root) for root in ROOTS), "|".join(re.escape(name) for name in TOP_FILES)))
MODULE = re.compile(r"(?<![\w/.])((?:%s)(?:\.\w+)+)" % "|".join(PACKAGES))
RUN_MODULE = re.compile(r"python3? -m ((?:%s)[\w.]*)" % "|".join(PACKAGES))
FILE_THEN_NAMES = re.compile(r"`([\w./]+\.py)`: ([^|;()\n]*)")
NAME_IN_FILE = re.compile(r"`([A-Za-z_][\w.]*)` in `([\w./]+\.py)`")
FILE_SUFFIX = re.compile(r"\.(md|py|txt|json|toml|ipynb)$")  # instructor.md is a doc, not a module
CODE_NAME = re.compile(r"`([A-Za-z_]\w*(?:\.\w+)*)`")
LINK = re.compile(r"\]\(([^)\s]+)\)")


def slug(heading):
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower().replace("`", ""))
    return text.replace(" ", "-")


class Kit:
    """A kit's files (relative POSIX paths) under ``root``: ``names`` is the list that counts (for this
    kit, ``kit_files``: what git has and would have, not what happens to lie on disk)."""

    def __init__(self, root, names):
        self.root = Path(root)
        self.files = set(names)
        self.folders = {posixpath.dirname(name) for name in self.files}
        for folder in list(self.folders):
            while folder:
                folder = posixpath.dirname(folder)
                self.folders.add(folder)

    def has_path(self, path):
        pattern = re.sub(r"<[^>]*>|…", "*", path.rstrip("/"))
        if any(fnmatch.fnmatchcase(pattern, allowed) or fnmatch.fnmatchcase(allowed, pattern) for allowed in NOT_IN_A_KIT):
            return True
        if "*" in pattern:
            return any(fnmatch.fnmatchcase(name, pattern) for name in self.files)
        return pattern in self.files or pattern in self.folders

    def module_file(self, dotted):
        base = dotted.replace(".", "/")
        for candidate in (f"{base}.py", f"{base}/__init__.py"):
            if candidate in self.files:
                return candidate
        return None

    def runnable(self, module):
        """Whether ``python -m module`` runs: a module file, or a package with ``__main__.py``."""
        base = module.replace(".", "/")
        return f"{base}.py" in self.files or f"{base}/__main__.py" in self.files

    def defines(self, file, dotted):
        """Whether ``file`` defines ``Name`` (at its top level) or ``Name.attribute`` (in class Name)."""
        tree = ast.parse((self.root / file).read_text(encoding="utf-8"))
        body = tree.body
        for part in dotted.split("."):
            found = None
            for node in body:
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.name == part:
                    found = node
                elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                    targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                    names = {elt.id for target in targets for elt in ast.walk(target) if isinstance(elt, ast.Name)}
                    found = found or (node if part in names else None)
                elif isinstance(node, (ast.Import, ast.ImportFrom)):
                    found = found or (node if any((alias.asname or alias.name).split(".")[0] == part for alias in node.names) else None)
            if found is None:
                return False
            body = found.body if isinstance(found, ast.ClassDef) else []
        return True

    def has_dotted(self, dotted):
        """``package.module[.name[.attribute]]``: the longest module prefix exists and defines the rest."""
        parts = dotted.split(".")
        for cut in range(len(parts), 0, -1):
            file = self.module_file(".".join(parts[:cut]))
            if file:
                return cut == len(parts) or self.defines(file, ".".join(parts[cut:]))
        return False

    def has_anchor(self, file, anchor):
        text = (self.root / file).read_text(encoding="utf-8")
        return anchor in {slug(line.lstrip("#")) for line in text.splitlines() if re.match(r"#{1,6} ", line)}


def missing(text, kit, location):
    """What the Markdown ``text``, read as the kit's file ``location``, names and ``kit`` lacks."""
    lacking = []
    for path in PATH.findall(text):
        if not kit.has_path(path):
            lacking.append(f"path {path}")
    for module in RUN_MODULE.findall(text):
        if not kit.runnable(module):
            lacking.append(f"python -m {module}")
    for dotted in MODULE.findall(text):
        if not FILE_SUFFIX.search(dotted) and not kit.has_dotted(dotted):
            lacking.append(f"module or name {dotted}")
    named = [(file, name) for file, rest in FILE_THEN_NAMES.findall(text) for name in CODE_NAME.findall(rest)]
    named += [(file, name) for name, file in NAME_IN_FILE.findall(text)]
    for file, name in named:
        if file in kit.files and file.endswith(".py") and not kit.defines(file, name):
            lacking.append(f"{name} in {file}")
    for target in LINK.findall(text):
        if re.match(r"[a-z]+:", target):
            continue
        path, _, anchor = target.partition("#")
        resolved = posixpath.normpath(posixpath.join(posixpath.dirname(location), path)) if path else location
        if not kit.has_path(resolved):
            lacking.append(f"link {target}")
        elif anchor and resolved.endswith(".md") and not kit.has_anchor(resolved, anchor):
            lacking.append(f"link {target} (no such heading)")
    return list(dict.fromkeys(lacking))
