"""Issue 32.7: every module the student edition ships runs on macOS, Windows and Linux alike. A
Unix-only (or Windows-only) module, function, signal or path may appear in it only behind a
platform branch: an ``if`` on ``hasattr``/``getattr``, ``os.name``, ``sys.platform``, a module
imported where it exists (``x is None``), or the path itself (``os.path.isdir("/proc")``), taken
either around the use or as an early ``return``/``raise`` before it; an import inside a ``try``
that catches ImportError. (The whole student path, run with these taken away, is
``test_student_path.py``.)
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from instructor.release import student_files

pytestmark = pytest.mark.quick

REPO = Path(__file__).resolve().parents[2]
ONE_SYSTEM_MODULES = {"fcntl", "resource", "pwd", "grp", "termios", "pty", "tty", "posix", "crypt", "spwd", "syslog",
                      "msvcrt", "winreg", "_winapi"}
ONE_SYSTEM_NAMES = {
    "os": {"killpg", "setsid", "getsid", "getpgid", "setpgid", "getuid", "geteuid", "getgid", "getegid", "setuid",
           "fork", "pidfd_open", "chown", "getloadavg", "sched_getaffinity", "uname", "sync", "mkfifo", "O_CLOEXEC",
           "O_NOFOLLOW", "WNOHANG", "startfile"},
    "signal": {"SIGKILL", "SIGSTOP", "SIGCONT", "SIGHUP", "SIGALRM", "SIGUSR1", "SIGUSR2", "SIGCHLD", "alarm",
               "setitimer", "pidfd_send_signal", "CTRL_C_EVENT", "CTRL_BREAK_EVENT"},
    "select": {"select", "poll", "epoll", "kqueue"},  # Windows' select() takes sockets only
}
ONE_SYSTEM_PATHS = ("/proc", "/dev/shm", "/sys/fs/cgroup")


def _guarded_imports(tree):
    """Names bound by an import inside a ``try`` that catches ImportError (None where it failed)."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Try) and any(_catches_import_error(handler) for handler in node.handlers):
            for statement in node.body:
                if isinstance(statement, (ast.Import, ast.ImportFrom)):
                    names.update((alias.asname or alias.name).split(".")[0] for alias in statement.names)
    return names


def _catches_import_error(handler):
    kinds = handler.type.elts if isinstance(handler.type, ast.Tuple) else [handler.type]
    return handler.type is None or any(isinstance(kind, ast.Name) and kind.id in ("ImportError", "ModuleNotFoundError",
                                                                                   "Exception") for kind in kinds)


def _is_platform_test(test, optional):
    for node in ast.walk(test):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("hasattr", "getattr"):
            return True
        if isinstance(node, ast.Attribute) and (node.attr, getattr(node.value, "id", None)) in (("name", "os"),
                                                                                              ("platform", "sys")):
            return True
        if isinstance(node, ast.Compare) and isinstance(node.left, ast.Name) and node.left.id in optional and \
                all(isinstance(op, (ast.Is, ast.IsNot)) for op in node.ops):
            return True
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.startswith(ONE_SYSTEM_PATHS):
            return True  # os.path.isdir("/proc") and the like
    return False


def _ends_early(body):
    return bool(body) and isinstance(body[-1], (ast.Return, ast.Raise))


def unguarded(source, name="module.py"):
    """["file:line: what"] of every one-system module, name or path in ``source`` outside a platform branch."""
    tree = ast.parse(source)
    optional = _guarded_imports(tree)
    parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
    found = []

    def guarded(node):
        child, parent = node, parents.get(node)
        while parent is not None:
            if isinstance(parent, (ast.If, ast.IfExp, ast.While)) and _is_platform_test(parent.test, optional):
                return True  # inside the branch, or the test itself (os.path.isdir("/proc"))
            if isinstance(parent, ast.Try) and child in parent.body and \
                    any(_catches_import_error(handler) for handler in parent.handlers):
                return True
            for field in ("body", "orelse", "finalbody"):  # an earlier `if <platform test>: return` in the same block
                block = getattr(parent, field, None)
                if isinstance(block, list) and child in block:
                    for earlier in block[:block.index(child)]:
                        if isinstance(earlier, ast.If) and _is_platform_test(earlier.test, optional) and \
                                _ends_early(earlier.body):
                            return True
            child, parent = parent, parents.get(parent)
        return False

    for node in ast.walk(tree):
        what = None
        if isinstance(node, ast.Import):
            what = next((alias.name for alias in node.names if alias.name.split(".")[0] in ONE_SYSTEM_MODULES), None)
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in ONE_SYSTEM_MODULES:
            what = node.module
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and \
                node.attr in ONE_SYSTEM_NAMES.get(node.value.id, ()):
            what = f"{node.value.id}.{node.attr}"
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.startswith(ONE_SYSTEM_PATHS) \
                and not isinstance(parents.get(node), ast.Expr):  # a docstring is no call
            what = repr(node.value)
        if what and not guarded(node):
            found.append(f"{name}:{node.lineno}: {what}")
    return found


def test_every_module_the_edition_ships_guards_what_one_system_lacks():
    shipped = {name: data for name, (data, _) in student_files(REPO).items() if name.endswith(".py")}
    assert "hwtools/grade/sandbox.py" in shipped and "hwtools/grade/processes.py" in shipped
    found = [line for name, data in sorted(shipped.items()) for line in unguarded(data.decode("utf-8"), name)]
    assert not found, "\n".join(found)


@pytest.mark.parametrize("code", [
    "import fcntl\n",
    "import os, signal\ndef end(p):\n    os.killpg(p.pid, signal.SIGKILL)\n",
    "import os\ndef strays():\n    return os.listdir('/proc')\n",
    "import select\ndef wait(fd):\n    return select.select([fd], [], [], 1.0)\n",
    "import os\ndef end(p):\n    if p.pid:\n        return\n    os.killpg(p.pid, 9)\n",  # an early return on something else
])
def test_the_check_sees_an_unguarded_use(code):
    assert unguarded(code)


@pytest.mark.parametrize("code", [
    "try:\n    import fcntl\nexcept ImportError:\n    fcntl = None\n",
    "import os, signal\ndef end(p):\n    if hasattr(os, 'killpg'):\n        os.killpg(p.pid, signal.SIGKILL)\n",
    "import os\ndef strays():\n    if not os.path.isdir('/proc'):\n        return []\n    return os.listdir('/proc')\n",
    "import os\nif os.name == 'nt':\n    import msvcrt\n",
    "try:\n    import resource\nexcept ImportError:\n    resource = None\ndef cpu():\n    if resource is None:\n"
    "        return 0\n    return resource.getrlimit(resource.RLIMIT_CPU)\n",
])
def test_a_platform_branch_is_a_guard(code):
    assert unguarded(code) == []


def test_every_limit_goes_through_one_helper_that_takes_a_refusal_as_no_limit(monkeypatch):
    """Issue 39.1: the student's side sets resource limits only through ``set_limit`` (the grader's own and the
    worker's), and where the system refuses one (macOS: a finite RLIMIT_AS, ``ValueError``), has no such limit
    or no ``resource`` module (Windows), the helper says so by returning None and nothing else happens. Made to
    fail once: e0973d3's ``limit_own_memory`` raised ``ValueError: current limit exceeds maximum limit``."""
    import resource

    from hwtools.grade import sandbox
    from hwtools.grade.in_sandbox import worker

    shipped = {name: data.decode("utf-8") for name, (data, _) in student_files(REPO).items() if name.endswith(".py")}
    setters = sorted(name for name, text in shipped.items() if "setrlimit(" in text)
    assert setters == ["hwtools/grade/in_sandbox/worker.py"], setters  # the helper's file, nowhere else
    code = ("import resource\nfrom hwtools.grade.in_sandbox.worker import set_limit\n"
            "soft, hard = resource.getrlimit(resource.RLIMIT_AS)\n"
            "print(set_limit('RLIMIT_AS', 2**42, hard=False), set_limit('RLIMIT_AS', 2**43, hard=False),"
            " resource.getrlimit(resource.RLIMIT_AS)[1] == hard, set_limit('RLIMIT_CPU', 600), set_limit('RLIMIT_NONE', 1))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=REPO)
    assert done.stdout.split() == [str(2**42), str(2**42), "True", "600", "None"], done.stderr

    def refuse(which, limits):
        raise ValueError("current limit exceeds maximum limit")

    monkeypatch.setattr(resource, "setrlimit", refuse)
    assert worker.set_limit("RLIMIT_AS", 2**30) is None and sandbox.limit_own_memory() is None
    worker._set_limits(60, 2**30, 16)  # the worker goes on without them
    monkeypatch.setitem(sys.modules, "resource", None)  # Windows
    assert worker.set_limit("RLIMIT_CPU", 60) is None
