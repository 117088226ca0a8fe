"""The Windows-like Python of ``foreign_os.py`` (issue 32.7): in a ``student_python(..., foreign=True)``,
a probe in a ``hwtools/`` package, run as the grader runs its worker (``python -B -s``), is refused every
facility it tries, and the same probe outside the kit has them all, called from the kit too (a
library the kit calls has its own branches for Windows); ``PATH`` holds no bubblewrap, ``prlimit`` or
Chromium.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from day_one import kit_env, student_python
from foreign_os import HUB_FOLDERS, HUB_SCRATCH, UNIX_MODULES, UNIX_NAMES

PROBE = r'''
import json, os, pathlib, select, shutil, signal, socket, sys

def attempt(action):
    try:
        return repr(action())
    except Exception as error:
        return f"{type(error).__name__}: {error}"

def facilities():
    tried = {f"import {name}": attempt(lambda: exec(f"import {name}", dict(globals()))) for name in UNIX_MODULES}
    tried["importlib.import_module('fcntl')"] = attempt(lambda: __import__("importlib").import_module("fcntl").__name__)
    for module, names in UNIX_NAMES.items():
        tried.update({f"{module}.{name}": attempt(lambda: hasattr(sys.modules[module], name)) for name in names})
    tried.update(asked())
    pair = socket.socketpair()
    tried["select a socket"] = attempt(lambda: select.select([pair[0]], [pair[1]], [], 0)[1] == [pair[1]])
    return tried

def asked():
    read, write = os.pipe()
    return {"select a pipe": attempt(lambda: select.select([read], [write], [], 0)),
            "select nothing": attempt(lambda: select.select([], [], [], 0)),
            "os.listdir /proc": attempt(lambda: len(os.listdir("/proc")) > 0),
            "os.scandir /proc/self": attempt(lambda: len(list(os.scandir("/proc/self"))) > 0),
            "os.stat /proc/self": attempt(lambda: os.stat("/proc/self").st_mode > 0),
            "os.path.exists /proc": attempt(lambda: os.path.exists("/proc")),
            "os.path.isdir /proc/1": attempt(lambda: os.path.isdir("/proc/1")),
            "open /proc/self/status": attempt(lambda: len(open("/proc/self/status").read()) > 0),
            "pathlib /proc/self/status": attempt(lambda: len(pathlib.Path("/proc/self/status").read_text()) > 0),
            "pathlib /proc iterdir": attempt(lambda: len(list(pathlib.Path("/proc").iterdir())) > 0)}

if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    import elsewhere
    json.dump({"here": facilities(), "elsewhere, called from here": elsewhere.asked(),
               "programs": [name for name in ("bwrap", "prlimit", "chromium", "python", "sh") if shutil.which(name)]},
              sys.stdout)
'''
REFUSED_SELECT = "OSError: [Errno 88] [WinError 10038] An operation was attempted on something that is not a socket"
ASKED = {"select a pipe": REFUSED_SELECT, "select nothing": "OSError: [Errno 22] [WinError 10022] An invalid argument was supplied",
         "os.listdir /proc": "FileNotFoundError: [Errno 2] No such file or directory: '/proc'",
         "os.scandir /proc/self": "FileNotFoundError: [Errno 2] No such file or directory: '/proc/self'",
         "os.stat /proc/self": "FileNotFoundError: [Errno 2] No such file or directory: '/proc/self'",
         "os.path.exists /proc": "False", "os.path.isdir /proc/1": "False",
         "open /proc/self/status": "FileNotFoundError: [Errno 2] No such file or directory: '/proc/self/status'",
         "pathlib /proc/self/status": "FileNotFoundError: [Errno 2] No such file or directory: '/proc/self/status'",
         "pathlib /proc iterdir": "FileNotFoundError: [Errno 2] No such file or directory: '/proc'"}


@pytest.fixture(scope="module")
def probes(tmp_path_factory):
    """(the foreign Python, the probe in the kit, the same probe outside it)."""
    root = tmp_path_factory.mktemp("foreign-os")
    python = student_python(root / "venv", foreign=True)
    code = root / "code"
    (code / "hwtools").mkdir(parents=True)
    text = f"UNIX_MODULES = {sorted(UNIX_MODULES)!r}\nUNIX_NAMES = {{{', '.join(f'{m.__name__!r}: {sorted(n)!r}' for m, n in UNIX_NAMES.items())}}}\n{PROBE}"
    for path in (code / "hwtools" / "probe.py", code / "elsewhere.py"):
        path.write_text(text)
    return python, code / "hwtools" / "probe.py", code / "elsewhere.py"


def probe(python, script):
    done = subprocess.run([str(python), "-B", "-s", str(script)], capture_output=True, text=True, timeout=120,
                          cwd=script.parent, env=kit_env(script.parent, python))
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout)


def test_the_kit_is_refused_every_unix_only_facility_and_other_code_is_not(probes):
    python, in_kit, outside = probes
    kit = probe(python, in_kit)
    assert kit["here"] == {**{f"import {name}": f"ModuleNotFoundError: No module named {name!r}" for name in UNIX_MODULES},
                           "importlib.import_module('fcntl')": "ModuleNotFoundError: No module named 'fcntl'",
                           **{f"{module.__name__}.{name}": "False" for module, names in UNIX_NAMES.items() for name in names},
                           **ASKED, "select a socket": "True"}
    other = kit["elsewhere, called from here"]
    assert not any("Error" in result for result in other.values()) and other["os.path.exists /proc"] == "True", other
    assert kit["programs"] == ["python", "sh"]
    other = probe(python, outside)["here"]
    refused = {facility: result for facility, result in other.items() if "Error" in result}
    assert not refused, refused
    assert other["os.path.exists /proc"] == other["select a socket"] == "True"
    assert other["os.killpg"] == other["signal.SIGKILL"] == other["select.poll"] == "True"


# --- what each system does differently (issue 39): the kit's code and other code in every process ----------------

BEHAVIOUR = r'''
import json, multiprocessing, os, shutil, signal, subprocess, sys, threading, time

def limit(name, value):
    import resource
    return resource.setrlimit(getattr(resource, name), (value, resource.RLIM_INFINITY))

def attempt(action):
    try:
        return repr(action())
    except BaseException as error:
        return f"{type(error).__name__}: {error}"

def interrupted_wait():
    """SIGINT to this process 0.3 s into a 3 s wait: how long the wait lasted before KeyboardInterrupt. Python's own
    handler first: a test run started in a shell's background ignores SIGINT, and so would this probe."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    begun = time.monotonic()
    threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
    try:
        threading.Event().wait(3.0)
    except KeyboardInterrupt:
        pass
    time.sleep(0.1)  # where KeyboardInterrupt comes after the wait, it comes here
    return "long" if time.monotonic() - begun > 2.5 else "short"

def behaviours(folder):
    held = os.path.join(folder, "held.pdf")
    with open(held, "w") as handle:
        handle.write("x")
    viewer = open(held)
    said = {
        "setrlimit RLIMIT_AS 1 GiB": attempt(lambda: limit("RLIMIT_AS", 2**30)),
        "setrlimit RLIMIT_CPU 600 s": attempt(lambda: limit("RLIMIT_CPU", 600)),
        "start method": multiprocessing.get_start_method(),
        "a child's piped Ł": attempt(lambda: subprocess.run([sys.executable, "-c", "print('\u0141')"], capture_output=True).returncode),
        "a UTF-8 child's piped Ł": attempt(lambda: subprocess.run([sys.executable, "-X", "utf8", "-c", "print('\u0141')"],
                                                                  capture_output=True).stdout),
        "open() encoding": attempt(lambda: open(os.path.join(folder, "text.txt"), "w").encoding),
        "remove a held file": attempt(lambda: os.remove(held)),
        "write in home": attempt(lambda: open(os.path.join(os.path.expanduser("~"), "note.txt"), "w").close()),
        "home writable to os.access, mkdir of it": [attempt(lambda: os.access(os.path.expanduser("~"), os.W_OK)),
                                                    attempt(lambda: os.mkdir(os.path.expanduser("~")))],
        "SIGINT in a wait": interrupted_wait(),
        "sys.platform, os.name": [sys.platform, os.name],
        "the user's folders": [os.environ.get(name) for name in ("USERPROFILE", "LOCALAPPDATA", "PROGRAMFILES")],
        "a child given USERPROFILE: its home, LOCALAPPDATA": attempt(lambda: subprocess.run(
            [sys.executable, "-c", "import os; print(os.path.expanduser('~'), os.environ.get('LOCALAPPDATA'))"],
            env={"USERPROFILE": folder}, capture_output=True).stdout.decode().split()),
        "a child given a HOME: its home, MPLCONFIGDIR": attempt(lambda: subprocess.run(
            [sys.executable, "-c", "import os; print(os.path.expanduser('~'), os.environ.get('MPLCONFIGDIR'))"],
            env={"HOME": folder}, capture_output=True).stdout.decode().split()),
        "the hub's folders": [os.environ.get(name) for name in HUB_FOLDERS],
        "home, and the caches' variables": [os.path.expanduser("~"), os.environ.get("HWLIB_CACHE_DIR"), os.environ.get("XDG_CACHE_HOME")],
        "browser, bwrap and prlimit on PATH": [name for name in ("chromium", "bwrap", "prlimit") if shutil.which(name)],
    }
    viewer.close()
    return said

if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    import elsewhere
    json.dump({"kit": behaviours(sys.argv[1]), "other": elsewhere.behaviours(sys.argv[2])}, sys.stdout)
'''
WINDOWS_FOLDERS = ["{home}", "{home}/AppData/Local", "{venv}/Program Files"]  # USERPROFILE, LOCALAPPDATA, PROGRAMFILES
HELD = "PermissionError: [Errno 13] [WinError 32] The process cannot access the file because it is being used by another process: "
EXPECTED = {  # what a system does differently; "same" as on this Linux box
    "macos": {"kit": {"setrlimit RLIMIT_AS 1 GiB": "ValueError: current limit exceeds maximum limit", "start method": "spawn",
                      "sys.platform, os.name": ["darwin", "posix"]},
              "other": {"setrlimit RLIMIT_AS 1 GiB": "ValueError: current limit exceeds maximum limit", "start method": "spawn"}},
    "windows": {"kit": {"setrlimit RLIMIT_AS 1 GiB": "ModuleNotFoundError: No module named 'resource'",
                        "setrlimit RLIMIT_CPU 600 s": "ModuleNotFoundError: No module named 'resource'", "a child's piped Ł": "1", "open() encoding": "'cp1252'", "remove a held file": HELD + "'{folder}/held.pdf'",
                        "SIGINT in a wait": "long", "sys.platform, os.name": ["win32", "nt"], "the user's folders": WINDOWS_FOLDERS,
                        "a child given USERPROFILE: its home, LOCALAPPDATA": "['{folder}', 'None']"},
                "other": {"a child's piped Ł": "1", "SIGINT in a wait": "long", "the user's folders": WINDOWS_FOLDERS,
                          "a child given USERPROFILE: its home, LOCALAPPDATA": "['{folder}', 'None']"}},
    "hub": {side: {"write in home": "OSError: [Errno 30] Read-only file system: '{home}/note.txt'",
                   "home writable to os.access, mkdir of it": ["False",
                                                               "FileExistsError: [Errno 17] File exists: '{home}'"],
                   "a child given a HOME: its home, MPLCONFIGDIR": "['{folder}', 'None']",
                   "the hub's folders": [f"{{venv}}/{HUB_SCRATCH}/{folder}" for folder in HUB_FOLDERS.values()]}
            for side in ("kit", "other")},
}
ON_PATH = {"macos": [], "windows": [], "hub": [name for name in ("chromium", "bwrap", "prlimit") if shutil.which(name, path="/usr/bin")]}


@pytest.mark.parametrize("system", sorted(EXPECTED))
def test_each_profile_does_what_its_system_does(tmp_path, system):
    """In every process of the profile's Python, which has its own home and none of this test run's cache
    variables: macOS refuses a finite RLIMIT_AS and starts with "spawn" (every caller) and is "darwin" to the kit
    (made to fail once: with ``_platform`` left out, the kit read "linux"); Windows pipes a child's text in cp1252, strictly (every caller), opens the kit's files in cp1252,
    refuses the kit the removal of a file held open, and wakes no wait on SIGINT (every caller: Ctrl+C comes from
    another thread), and is "win32" and "nt" to the kit, with a user's session folders (USERPROFILE, LOCALAPPDATA,
    PROGRAMFILES) where a child given an environment of its own has only what it was given; a hub's home is
    read-only to the kit and other code alike (``os.access`` says so, ``mkdir`` of it is FileExistsError), the folders
    a hub's administrator must point elsewhere are set, none of them in a child given a HOME of its own, which keeps
    it, and its PATH has Debian's Chromium and prlimit, and a bwrap that fails. Everything else is as on this Linux
    box. Made to fail once: without ``_interrupt_from_a_thread`` the Windows profile's waits
    were "short"; with os.name not given the kit read "posix"; without ``_windows_session`` the folders were None;
    with it setting them in every process, the child's home was the profile's, not its USERPROFILE; on main's hub
    profile (bdcadf0) other code's write in the home succeeded ("None") and the hub's folders were None; without the
    ``os.access`` shim the home was writable to it ("True"); with ``mkdir`` of the home refused as a write, it said
    EROFS, not FileExistsError; with the hub's session in every process, a child given a HOME had the hub's."""
    home = tmp_path / "home"
    home.mkdir()
    python = student_python(tmp_path / "venv", system=system, home=home)
    code = tmp_path / "code"
    (code / "hwtools").mkdir(parents=True)
    for path in (code / "hwtools" / "probe.py", code / "elsewhere.py"):
        path.write_text(f"HUB_FOLDERS = {list(HUB_FOLDERS)!r}\n{BEHAVIOUR}")
    folders = {"kit": tmp_path / "kit-files", "other": tmp_path / "other-files"}
    for folder in folders.values():
        folder.mkdir()
    env = kit_env(code, python) | {"HOME": str(home)}
    done = subprocess.run([str(python), str(code / "hwtools" / "probe.py"), str(folders["kit"]), str(folders["other"])],
                          capture_output=True, text=True, timeout=120, cwd=code, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    said = json.loads(done.stdout)
    plain = {"setrlimit RLIMIT_AS 1 GiB": "None", "setrlimit RLIMIT_CPU 600 s": "None", "start method": "fork",
             "a child's piped Ł": "0", "a UTF-8 child's piped Ł": repr("Ł\n".encode()), "open() encoding": "'UTF-8'",
             "remove a held file": "None", "write in home": "None", "SIGINT in a wait": "short",
             "home writable to os.access, mkdir of it": ["True", f"FileExistsError: [Errno 17] File exists: '{home}'"],
             "sys.platform, os.name": ["linux", "posix"], "the user's folders": [None, None, None],
             "a child given USERPROFILE: its home, LOCALAPPDATA": f"['{home}', 'None']",
             "a child given a HOME: its home, MPLCONFIGDIR": f"['{home}', 'None']",
             "the hub's folders": [None] * len(HUB_FOLDERS),
             "home, and the caches' variables": [str(home), None, None], "browser, bwrap and prlimit on PATH": ON_PATH[system]}

    def placed(value, side):
        names = {"folder": folders[side], "home": home, "venv": tmp_path / "venv"}
        return value.format(**names) if isinstance(value, str) else [placed(one, side) for one in value]

    for side in ("kit", "other"):
        expected = plain | {name: placed(value, side) for name, value in EXPECTED[system][side].items()}
        assert said[side] == expected, side


def test_a_test_over_its_limit_fails_alone_and_the_run_ends_with_its_summary_on_windows(tmp_path):
    """Issue 39 problem 10: Windows has no SIGALRM, so pytest-timeout's thread method ends the whole run (no
    summary); the edition's own plugin (``hwtools/pytest_overrun.py``, registered by the kit's conftest.py) stops
    such a test first, and the run goes on to its summary. Made to fail once: without the plugin the Windows
    profile's run ended at pytest-timeout's "Timeout" banner, with no summary line."""
    python = student_python(tmp_path / "venv", system="windows")
    project = tmp_path / "edition"
    project.mkdir()
    (project / "conftest.py").write_text('pytest_plugins = ("hwtools.pytest_todo", "hwtools.pytest_overrun")\n')
    (project / "test_loop.py").write_text("import pytest\n\n\n@pytest.mark.timeout(8)\ndef test_loops():\n    while True:\n"
                                          "        pass\n\n\ndef test_after():\n    assert True\n")
    env = kit_env(Path(__file__).resolve().parents[2], python)  # the kit's hwtools on the path, as the edition's own
    done = subprocess.run([str(python), "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_loop.py"], cwd=project,
                          env=env, capture_output=True, encoding="cp1252", errors="replace", timeout=120)
    lines = done.stdout.strip().splitlines()
    assert re.fullmatch(r"1 failed, 1 passed in .*", lines[-1]), done.stdout[-2000:] + done.stderr[-2000:]
    assert "test_loop.py::test_loops ran over its time limit of 8 s and was stopped" in done.stdout
