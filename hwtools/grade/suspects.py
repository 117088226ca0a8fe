"""What a student's block reaches for that a homework solution does not need: named in the feedback, never a reason for points.

``scan_body(body, module_level)`` reads the block's syntax tree (it never runs it) and names
ending the process, other processes, the network, files, patching modules, objects with a custom
``__eq__``... The grader's verdicts come from the values the code returns alone.
"""

from __future__ import annotations

import ast

from hwtools.grade.blocks import parse, reindent

_SUSPECT_MODULES = {
    "_pytest": "pytest's internals", "pytest": "pytest", "unittest": "unittest", "socket": "the network (socket)",
    "urllib": "the network (urllib)", "http": "the network (http)", "requests": "the network (requests)",
    "subprocess": "other programs (subprocess)", "multiprocessing": "other processes (multiprocessing)",
    "ctypes": "ctypes", "builtins": "builtins", "importlib": "importlib", "inspect": "inspect", "gc": "gc",
    "signal": "signals", "resource": "resource limits", "shutil": "files (shutil)", "glob": "files (glob)",
    "pathlib": "files (pathlib)", "pickle": "pickle", "json": "json files", "threading": "threads",
}
_SUSPECT_CALLS = {
    "sys.exit": "sys.exit", "os._exit": "os._exit", "exit": "exit()", "quit": "quit()", "os.fork": "os.fork",
    "os.kill": "os.kill", "os.system": "os.system", "os.popen": "os.popen", "os.setsid": "os.setsid",
    "os.remove": "deleting files", "os.unlink": "deleting files", "os.listdir": "listing folders",
    "os.walk": "listing folders", "os.environ": "the environment", "open": "open() on files",
    "exec": "exec", "eval": "eval", "compile": "compile", "__import__": "__import__", "globals": "globals()",
    "setattr": "setattr", "np.testing": "numpy.testing", "numpy.testing": "numpy.testing",
    "math.isclose": "math.isclose", "sys.modules": "sys.modules", "sys.settrace": "sys.settrace",
}
_SUSPECT_METHODS = {"__eq__", "__ne__", "__bool__", "__array__", "__float__", "__getattr__", "__del__"}


def scan_body(body, module_level=False):
    """Sorted short names of what the block uses that a homework solution does not need:
    ending the process, other processes, the network, files, patching modules, objects with a
    custom ``__eq__``... The feedback names them; they change no points."""
    try:
        tree = parse("\n".join(reindent(body, "")) if module_level else
                         "def _block():\n" + "\n".join(reindent(body, "    ") + ["    pass"]))
    except SyntaxError:
        return []
    seen = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""] + [f"{node.module}.{alias.name}" for alias in node.names]
        else:
            names = []
        for name in names:
            top = name.split(".")[0]
            if top in _SUSPECT_MODULES:
                seen.add(_SUSPECT_MODULES[top])
            if name in _SUSPECT_CALLS:
                seen.add(_SUSPECT_CALLS[name])
        if isinstance(node, (ast.Attribute, ast.Name)):
            dotted = _dotted(node)
            if dotted in _SUSPECT_CALLS:
                seen.add(_SUSPECT_CALLS[dotted])
        if isinstance(node, ast.FunctionDef) and node.name in _SUSPECT_METHODS:
            seen.add(f"a custom {node.name}")
        if isinstance(node, (ast.Assign, ast.AugAssign)):
            for target in (node.targets if isinstance(node, ast.Assign) else [node.target]):
                dotted = _dotted(target) if isinstance(target, ast.Attribute) else None
                if dotted and "." in dotted and dotted.split(".")[0] in {"np", "numpy", "math", "sys", "os", "builtins",
                                                                        "hwlib", "_pytest", "pytest"}:
                    seen.add(f"replacing {dotted}")
    return sorted(seen)


def _dotted(node):
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
        return ".".join(reversed(parts))
    return None
