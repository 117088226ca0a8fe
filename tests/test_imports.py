"""Dependencies point one way: no import cycles in hwlib, and hwlib never imports the tools."""

import ast
from pathlib import Path

import pytest

KIT = Path(__file__).resolve().parents[1]


def module_name(path):
    parts = list(path.relative_to(KIT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path, modules):
    """The kit modules ``path`` imports anywhere in it (inside functions too: a late import is still a
    dependency), as names in ``modules``. ``from hwlib import x`` counts as ``hwlib.x`` when x is a module."""
    package = module_name(path) if path.name == "__init__.py" else module_name(path).rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else []))
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base)
    return {name for name in found if name in modules}


def graph(package):
    files = {module_name(path): path for path in (KIT / package).rglob("*.py")}
    return {name: imports_of(path, files) - {name} for name, path in files.items()}, files


def cycles(edges):
    """Every strongly connected group of more than one module (Tarjan)."""
    index, low, stack, on_stack, groups, counter = {}, {}, [], set(), [], [0]

    def visit(node):
        index[node] = low[node] = counter[0]
        counter[0] += 1
        stack.append(node)
        on_stack.add(node)
        for other in edges.get(node, ()):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            group = []
            while True:
                other = stack.pop()
                on_stack.discard(other)
                group.append(other)
                if other == node:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for node in sorted(edges):
        if node not in index:
            visit(node)
    return groups


def without_package_init(edges, package):
    # Importing hwlib.x runs hwlib/__init__ first, but that is Python's order, not a dependency of x on
    # everything __init__ re-exports: leave the package's own __init__ out, as import-linter does.
    return {name: targets - {package} for name, targets in edges.items() if name != package}


@pytest.mark.parametrize("package", ["hwlib"])
def test_no_import_cycles(package):
    edges, _ = graph(package)
    assert cycles(without_package_init(edges, package)) == []


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_hwlib_never_imports_the_tools():
    for path in (KIT / "hwlib").rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            names = [alias.name for alias in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            assert not any(name.split(".")[0] in {"hwtools", "instructor"} for name in names), path
