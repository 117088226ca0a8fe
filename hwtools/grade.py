"""The autograder: run a kit's tests and give points per handout TODO.

    python -m hwtools.grade [KIT_DIR] [--tests TESTS_DIR] [--json FILE] [--timeout SECONDS]
                          [--todo ID ...] [--jobs N] [--python PYTHON]

Every test that decides a TODO's points carries ``@pytest.mark.todo("1.2.1")``. A TODO's
automatic points are **proportional**: ``auto points x (tests passed / tests tagged)``; a
skipped or timed-out test counts as not passed. TODOs that need a person (the derivation, the
written report) keep their points in the ``manual`` column and are never awarded here.

The tests run in a subprocess with the kit's own Python (``KIT_DIR/.venv/bin/python`` if it
exists), with ``hwlib`` imported from KIT_DIR, notebooks (nbval) and the browser test left out.
A small pytest plugin (this very file, loaded under another name so that a broken ``hwlib``
cannot stop it) records every test's outcome and arms a per-test timeout: an endless loop fails
that test after ``--timeout`` seconds; a hard hang or a crash of the interpreter ends the
subprocess, and the grader starts it again without the tests already decided. Either way the
other tests, and the other TODOs, are still graded.

Instructors grade a submission against their own tests, hidden ones included, with
``python -m hwtools.grade SUBMISSION_DIR --tests INSTRUCTOR_KIT/tests``.

This module uses only the standard library at import time, so it also runs as a plain script
(``python hwtools/grade.py``) should a broken ``hwlib`` stop ``python -m hwtools.grade``.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class Todo:
    """One TODO of the handout and how its points are given."""

    id: str
    title: str
    auto: float  # points decided by the tests tagged @pytest.mark.todo(id)
    manual: float = 0.0  # points a person gives
    manual_what: str = ""  # what that person grades
    needs: tuple = ()  # TODOs the handout chains before this one (their code is called by this one's tests)


TODOS = (
    Todo("1.1.1", "linear policy, eq. (1)", 2),
    Todo("1.1.2", "hand-tuning the policy", 0, 2, "report: parameters tried and the behaviour they gave"),
    Todo("1.1.3", "1000 random policies", 0, 1, "report: reward histogram, share of policies at 500"),
    Todo("1.2.1", "central finite differences, eq. (3)", 10),
    Todo("1.3.1", "parameter evaluation g(theta)", 5, needs=("1.1.1",)),
    Todo("1.3.2", "gradient ascent, eq. (4)", 5, needs=("1.3.1", "1.2.1")),
    Todo("1.3.3", "learning rate: converges within 7 iterations", 2, 3,
         "report: learning rate, final parameters, training curve", needs=("1.3.2",)),
    Todo("2.1.1", "derivation of the log-likelihood gradient", 0, 10, "the derivation (its code is checked by tests)",
         needs=("2.2.1", "1.2.1")),
    Todo("2.2.1", "sigmoid", 2),
    Todo("2.2.2", "predict_prob with the bias feature", 3, needs=("2.2.1",)),
    Todo("2.2.3", "gradient ascent step, eq. (8)", 5, needs=("2.2.1",)),
    Todo("2.3.1", "one-vs-rest fit", 5, needs=("2.2.2", "2.2.3")),
    Todo("2.3.2", "training run", 0, 5, "report: training curve, final train and test accuracy"),
)
TODO_BY_ID = {todo.id: todo for todo in TODOS}

DEFAULT_TIMEOUT = 120.0  # seconds per test
HARD_TIMEOUT_GRACE = 15.0  # at most this long after the soft timeout, the interpreter is ended from outside Python
TODO_MARK_RE = re.compile(r"""mark\.todo\(\s*["']([0-9]+(?:\.[0-9]+)+)["']""")


def prerequisites(todo_id):
    """Every TODO that ``todo_id`` needs, transitively (itself excluded), sorted."""
    seen, stack = set(), list(TODO_BY_ID[todo_id].needs)
    while stack:
        needed = stack.pop()
        if needed not in seen:
            seen.add(needed)
            stack.extend(TODO_BY_ID[needed].needs)
    return sorted(seen, key=_id_key)


def _id_key(todo_id):
    return tuple(int(part) for part in todo_id.split("."))


# --------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------


@dataclass
class TestResult:
    nodeid: str
    todo: str
    outcome: str  # passed, failed, skipped
    message: str = ""
    hidden: bool = False


@dataclass
class TodoGrade:
    todo: Todo
    tests: list = field(default_factory=list)
    errors: list = field(default_factory=list)  # problems that cost this TODO all its points

    @property
    def passed(self):
        return sum(test.outcome == "passed" for test in self.tests)

    @property
    def earned(self):
        if not self.todo.auto or not self.tests or self.errors:
            return 0.0  # manual TODOs' tests inform the grader; they never earn points here
        return round(self.todo.auto * self.passed / len(self.tests), 2)

    @property
    def first_failure(self):
        for test in self.tests:
            if test.outcome != "passed":
                return test
        return None

    def as_dict(self):
        failure = self.first_failure
        return {
            "id": self.todo.id,
            "title": self.todo.title,
            "auto_earned": self.earned,
            "auto_possible": self.todo.auto,
            "manual_possible": self.todo.manual,
            "manual": self.todo.manual_what,
            "tests_passed": self.passed,
            "tests_total": len(self.tests),
            "first_failure": None if failure is None else {"test": failure.nodeid, "error": f"{failure.outcome}: {failure.message}"},
            "errors": list(self.errors),
            "tests": [
                {"nodeid": t.nodeid, "outcome": t.outcome, "message": t.message, "hidden": t.hidden} for t in self.tests
            ],
        }


@dataclass
class Report:
    kit: str
    tests_dir: str
    grades: list
    errors: list = field(default_factory=list)  # problems not tied to one TODO

    def grade_of(self, todo_id):
        return next(grade for grade in self.grades if grade.todo.id == todo_id)

    @property
    def auto_earned(self):
        return round(sum(grade.earned for grade in self.grades), 2)

    @property
    def auto_possible(self):
        return sum(grade.todo.auto for grade in self.grades)

    @property
    def manual_possible(self):
        return sum(grade.todo.manual for grade in self.grades)

    def outcomes(self):
        """{nodeid: outcome} of every graded test."""
        return {test.nodeid: test.outcome for grade in self.grades for test in grade.tests}

    def as_dict(self):
        return {
            "kit": self.kit,
            "tests": self.tests_dir,
            "scoring": "auto points x tests passed / tests tagged with the TODO; manual points are never awarded here",
            "todos": [grade.as_dict() for grade in self.grades],
            "total": {
                "auto_earned": self.auto_earned,
                "auto_possible": self.auto_possible,
                "manual_possible": self.manual_possible,
            },
            "errors": list(self.errors),
        }

    def table(self):
        """The report as text: one row per TODO, and under a row that lost points the first
        failing test and the first line of its error."""
        header = ("TODO", "what", "auto points", "by hand", "tests passed")
        rows = []
        for grade in self.grades:
            todo = grade.todo
            rows.append((
                todo.id,
                todo.title,
                f"{grade.earned:g} / {todo.auto:g}" if todo.auto else "-",
                f"{todo.manual:g}" if todo.manual else "-",
                f"{grade.passed} / {len(grade.tests)}" if grade.tests or todo.auto else "-",
            ))
        widths = [max(len(row[col]) for row in [header, *rows]) for col in range(len(header))]

        def line(cells):
            return "  ".join(cell.ljust(width) for cell, width in zip(cells, widths)).rstrip()

        lines = [line(header), "-" * len(line(header))]
        indent = " " * (widths[0] + 2)
        for grade, row in zip(self.grades, rows):
            lines.append(line(row))
            todo = grade.todo
            if todo.manual:
                lines.append(f"{indent}by hand: {todo.manual_what}")
            if not todo.auto and not grade.tests and not grade.errors:
                continue
            failure = grade.first_failure
            if grade.errors:
                lines.append(f"{indent}error: {_shorten(grade.errors[0], 150)}")
            elif not grade.tests:
                lines.append(f"{indent}error: no tests for this TODO in this kit")
            else:
                if not todo.auto:
                    lines.append(f"{indent}its tests inform the person grading; they give no automatic points")
                if failure is not None:
                    lines.append(f"{indent}first failing test: {failure.nodeid}")
                    lines.append(f"{indent}  {failure.outcome}: {_shorten(failure.message, 140)}")
        lines.append("-" * len(line(header)))
        lines.append(
            f"total: {self.auto_earned:g} of {self.auto_possible:g} automatic points; "
            f"{self.manual_possible:g} more points are graded by hand"
        )
        lines.append("(a TODO's automatic points x its tests passed / its tests)")
        lines.extend(f"error: {error}" for error in self.errors)
        return "\n".join(lines)


def _shorten(text, width):
    text = " ".join(text.split())
    return text if len(text) <= width else text[: width - 3] + "..."


# --------------------------------------------------------------------------------------------
# Running the tests
# --------------------------------------------------------------------------------------------


def kit_python(kit_dir):
    """The kit's own interpreter (its .venv), else the one running this grader."""
    for candidate in (Path(kit_dir) / ".venv" / "bin" / "python", Path(kit_dir) / ".venv" / "Scripts" / "python.exe"):
        if candidate.exists():
            return str(candidate)
    return sys.executable


def tagged_test_files(tests_dir):
    """{test file: TODO ids it tags}, for every test_*.py under ``tests_dir`` that tags one."""
    files = {}
    for path in sorted(Path(tests_dir).rglob("test_*.py")):
        if "__pycache__" in path.parts:
            continue
        ids = todo_ids_in_file(path)
        if ids:
            files[path] = ids
    return files


def todo_ids_in_file(path):
    """The TODO ids a test file tags: its ``@pytest.mark.todo(...)`` decorators and ``pytestmark``
    (read from the syntax tree, so a marker inside a string does not count; a file that does not
    parse is read as text, and pytest will report it as broken)."""
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError:
        return set()
    try:
        tree = ast.parse(text)
    except SyntaxError:
        return set(TODO_MARK_RE.findall(text))
    marks = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            marks.extend(node.decorator_list)
        elif isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "pytestmark" for t in node.targets):
            marks.extend(node.value.elts if isinstance(node.value, (ast.List, ast.Tuple)) else [node.value])
    return {match for mark in marks for match in TODO_MARK_RE.findall(ast.unparse(mark))}


def grade(kit_dir=".", tests_dir=None, todo_ids=None, timeout=DEFAULT_TIMEOUT, jobs=None, python=None):
    """Grade the kit in ``kit_dir`` and return a ``Report``.

    ``tests_dir`` defaults to ``KIT_DIR/tests``; ``todo_ids`` limits grading to some TODOs;
    ``jobs`` subprocesses run side by side (default: one per CPU).
    """
    kit_dir = Path(kit_dir).resolve()
    if not (kit_dir / "hwlib").is_dir():
        raise GradeError(f"{kit_dir} is not a kit: it has no hwlib/ folder")
    tests_dir = (kit_dir / "tests") if tests_dir is None else Path(tests_dir).resolve()
    if not tests_dir.is_dir():
        raise GradeError(f"no tests folder {tests_dir}")
    selected = [todo.id for todo in TODOS] if not todo_ids else list(dict.fromkeys(todo_ids))
    unknown = [todo_id for todo_id in selected if todo_id not in TODO_BY_ID]
    if unknown:
        raise GradeError(f"unknown TODO id(s) {', '.join(unknown)}; known: {', '.join(TODO_BY_ID)}")
    grades = {todo_id: TodoGrade(TODO_BY_ID[todo_id]) for todo_id in selected}
    report = Report(str(kit_dir), str(tests_dir), list(grades.values()))
    python = python or kit_python(kit_dir)
    with tempfile.TemporaryDirectory(prefix="hwlib-grade-") as workdir:
        plugin_dir = Path(workdir) / "plugin"
        plugin_dir.mkdir()
        shutil.copyfile(__file__, plugin_dir / f"{PLUGIN_NAME}.py")
        if not tests_dir.is_relative_to(kit_dir):
            tests_dir = _stage_tests(tests_dir, Path(workdir) / "tests-root")
        files = tagged_test_files(tests_dir)
        # Every selected TODO with tests: manual TODOs' tests run too, to inform the person grading.
        tested = set().union(*files.values()) if files else set()
        groups = _split([todo_id for todo_id in selected if todo_id in tested], jobs or os.cpu_count() or 1)
        runs = []
        for index, group in enumerate(groups):
            group_files = sorted(str(path) for path, ids in files.items() if ids & set(group))
            runs.append(_GroupRun(group, group_files, kit_dir, tests_dir, python, timeout, plugin_dir, Path(workdir) / f"run{index}"))
        with ThreadPoolExecutor(max_workers=len(runs)) as pool:
            for run in pool.map(lambda run: run.execute(), runs):
                pass
    for run in runs:
        report.errors.extend(run.errors)
        for test in run.results.values():
            if test.todo in grades:
                grades[test.todo].tests.append(test)
        for todo_id, message in run.todo_errors:
            if todo_id in grades and message not in grades[todo_id].errors:
                grades[todo_id].errors.append(message)
    for grade_ in grades.values():
        order = {nodeid: position for run in runs for position, nodeid in enumerate(run.order)}
        grade_.tests.sort(key=lambda test: order.get(test.nodeid, len(order)))
    return report


class GradeError(Exception):
    pass


def _stage_tests(tests_dir, root):
    """Copy tests from another kit (with its pytest configuration and conftest.py) into a folder
    without an hwlib, so that pytest's rootdir on sys.path cannot bring that kit's hwlib in."""
    shutil.copytree(tests_dir, root / "tests", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    for name in ("pyproject.toml", "pytest.ini", "setup.cfg", "tox.ini", "conftest.py"):
        if (tests_dir.parent / name).is_file():
            shutil.copyfile(tests_dir.parent / name, root / name)
    return root / "tests"


def _split(items, count):
    count = max(1, min(count, len(items)))
    return [items[start::count] for start in range(count)]


PLUGIN_NAME = "hwlib_grade_plugin"


class _GroupRun:
    """The tests of some TODOs in one subprocess, started again after a hang or a crash."""

    def __init__(self, todo_ids, files, kit_dir, tests_dir, python, timeout, plugin_dir, workdir):
        self.todo_ids, self.files, self.kit_dir, self.tests_dir = todo_ids, files, kit_dir, tests_dir
        self.python, self.timeout, self.plugin_dir, self.workdir = python, float(timeout), plugin_dir, workdir
        self.results = {}  # nodeid -> TestResult
        self.order = []  # nodeids in collection order
        self.todo_of = {}  # nodeid -> (todo id, hidden)
        self.errors = []
        self.todo_errors = []  # (todo id, message)

    def execute(self):
        self.workdir.mkdir(parents=True, exist_ok=True)
        if not self.files:
            return self
        decided = set()
        for attempt in range(1, 1000):
            events_path = self.workdir / f"events{attempt}.jsonl"
            skip_path = self.workdir / f"skip{attempt}.txt"
            skip_path.write_text("\n".join(sorted(decided)), encoding="utf-8")
            returncode, stderr = self._run_pytest(events_path, skip_path)
            events = _read_events(events_path)
            started = None
            for event in events:
                kind = event["event"]
                if kind == "collected":
                    if event["nodeid"] not in self.order:
                        self.order.append(event["nodeid"])
                    self.todo_of[event["nodeid"]] = (event["todo"], event["hidden"])
                elif kind == "start":
                    started = event["nodeid"]
                elif kind == "result":
                    todo, hidden = self.todo_of.get(event["nodeid"], ("", False))
                    self.results[event["nodeid"]] = TestResult(event["nodeid"], todo, event["outcome"], event["message"], hidden)
                    decided.add(event["nodeid"])
                    started = None
                elif kind == "collect_error":
                    path = event["path"]
                    ids = [todo_id for todo_id in self.todo_ids if todo_id in todo_ids_in_file(path)]
                    message = f"{_relative(path, self.tests_dir)} could not be imported: {event['message']}"
                    for todo_id in ids:
                        self.todo_errors.append((todo_id, message))
                elif kind == "todo_error":
                    self.todo_errors.append((event["todo"], event["message"]))
                elif kind == "hwlib":
                    for module_file in event["files"]:
                        self._check_hwlib(module_file)
            finished = any(event["event"] == "finished" for event in events)
            if finished:
                return self
            if started is not None:  # the interpreter died or hung in this test: it fails, the rest runs again
                todo, hidden = self.todo_of.get(started, ("", False))
                reason = "timed out (the interpreter had to be stopped)" if returncode == "hung" else f"crashed the interpreter (exit status {returncode})"
                self.results[started] = TestResult(started, todo, "failed", reason, hidden)
                decided.add(started)
                continue
            # Ended before or between tests: nothing to gain from another attempt.
            tail = _last_line(stderr)
            message = f"pytest stopped (exit status {returncode}) before finishing: {tail}"
            for todo_id in self.todo_ids:
                self.todo_errors.append((todo_id, message))
            return self
        return self

    def _check_hwlib(self, hwlib_file):
        if not hwlib_file:
            return
        try:
            Path(hwlib_file).resolve().relative_to(self.kit_dir)
        except ValueError:
            message = f"the tests imported {hwlib_file}, not a file of the graded kit {self.kit_dir}"
            if message not in self.errors:
                self.errors.append(message)
            for todo_id in self.todo_ids:
                self.todo_errors.append((todo_id, message))

    def _run_pytest(self, events_path, skip_path):
        env = dict(os.environ)
        env.pop("PYTEST_ADDOPTS", None)
        env["PYTHONPATH"] = os.pathsep.join([str(self.kit_dir), str(self.plugin_dir)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
        env["MPLBACKEND"] = "Agg"
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        env["HWLIB_GRADE_EVENTS"] = str(events_path)
        env["HWLIB_GRADE_SKIP"] = str(skip_path)
        env["HWLIB_GRADE_TODOS"] = ",".join(self.todo_ids)
        env["HWLIB_GRADE_TIMEOUT"] = repr(self.timeout)
        command = [
            self.python, "-m", "pytest", *self.files,
            "-p", PLUGIN_NAME, "-p", "no:nbval", "-p", "no:cacheprovider",
            "-o", "addopts=", "-m", "not browser",
            "--continue-on-collection-errors", "-q", "--no-header", "-rN", "--tb=no",
        ]
        stderr_path = events_path.with_suffix(".stderr")
        with open(stderr_path, "wb") as stderr_file:
            process = subprocess.Popen(command, cwd=self.kit_dir, env=env, stdout=subprocess.DEVNULL, stderr=stderr_file)
            # A watchdog on progress: every test writes events; silence far beyond the hard timeout means a hang
            # the plugin could not end (it ends hung tests itself after timeout + grace).
            quiet_limit = 2 * self.timeout + HARD_TIMEOUT_GRACE + 30
            last_size, last_change = -1, time.monotonic()
            while True:
                try:
                    returncode = process.wait(timeout=0.2)
                    break
                except subprocess.TimeoutExpired:
                    size = events_path.stat().st_size if events_path.exists() else 0
                    if size != last_size:
                        last_size, last_change = size, time.monotonic()
                    elif time.monotonic() - last_change > quiet_limit:
                        process.kill()
                        process.wait()
                        returncode = "hung"
                        break
        stderr = stderr_path.read_text(encoding="utf-8", errors="replace")
        if returncode != "hung" and returncode < 0:
            returncode = f"signal {-returncode}"
        hang_file = Path(str(events_path) + ".hang")
        if hang_file.exists() and hang_file.stat().st_size:
            returncode = "hung"  # the plugin's faulthandler watchdog ended it after the hard timeout
        return returncode, stderr


def _relative(path, base):
    try:
        return str(Path(path).resolve().relative_to(Path(base).resolve().parent))
    except ValueError:
        return str(path)


def _last_line(text):
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    return lines[-1] if lines else "(no output)"


def _read_events(path):
    events = []
    if not path.exists():
        return events
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        try:
            events.append(json.loads(line))
        except json.JSONDecodeError:  # a line cut short by a crash
            continue
    return events


# --------------------------------------------------------------------------------------------
# The pytest plugin (active only when loaded as hwlib_grade_plugin by the grader)
# --------------------------------------------------------------------------------------------


class GradingTimeout(BaseException):
    """Raised in a test that ran longer than the grader's timeout. A BaseException, so that a
    student's ``except Exception`` cannot swallow it."""


_plugin_state = {}


def _emit(event):
    path = os.environ.get("HWLIB_GRADE_EVENTS")
    if not path:
        return
    with open(path, "a", encoding="utf-8") as events:
        events.write(json.dumps(event) + "\n")
        events.flush()


def _arm(seconds, what):
    import faulthandler
    import signal

    if hasattr(signal, "SIGALRM"):
        def on_alarm(signum, frame):
            raise GradingTimeout(f"timed out after {seconds:g} s ({what})")

        signal.signal(signal.SIGALRM, on_alarm)
        signal.setitimer(signal.ITIMER_REAL, seconds)
    # pytest captures the stderr file descriptor during tests, so the watchdog writes to a file
    # of its own, which tells the grader that the interpreter was ended for hanging.
    faulthandler.dump_traceback_later(seconds + min(HARD_TIMEOUT_GRACE, seconds), exit=True, file=_plugin_state["hang_file"])


def _disarm():
    import faulthandler
    import signal

    if hasattr(signal, "SIGALRM"):
        signal.setitimer(signal.ITIMER_REAL, 0)
    faulthandler.cancel_dump_traceback_later()


def _plugin_active():
    return __name__ == PLUGIN_NAME and bool(os.environ.get("HWLIB_GRADE_EVENTS"))


def _drop_editable_finders():
    """An editable install (``pip install -e``) of some kit must not fill in the modules the
    graded kit lacks: only PYTHONPATH, which starts with the graded kit, may find hwlib."""
    def editable(finder):
        return (getattr(finder, "__module__", "") or "").startswith("__editable__")

    sys.meta_path[:] = [finder for finder in sys.meta_path if not editable(finder)]
    sys.path_hooks[:] = [hook for hook in sys.path_hooks if not editable(hook)]
    sys.path_importer_cache.clear()


if _plugin_active():  # as early as pytest loads this plugin, before any test module imports hwlib
    _drop_editable_finders()


def pytest_configure(config):
    if not _plugin_active():
        return
    _plugin_state["timeout"] = float(os.environ.get("HWLIB_GRADE_TIMEOUT", DEFAULT_TIMEOUT))
    _plugin_state["outcomes"] = {}
    _plugin_state["rootpath"] = config.rootpath
    _plugin_state["hang_file"] = open(os.environ["HWLIB_GRADE_EVENTS"] + ".hang", "w", encoding="utf-8")  # noqa: SIM115
    _arm(_plugin_state["timeout"], "while importing the tests")


def pytest_collectreport(report):
    if _plugin_active() and report.failed:
        path = Path(str(_plugin_state["rootpath"])) / report.nodeid.split("::")[0]
        _emit({"event": "collect_error", "path": str(path), "message": _first_line(report.longrepr)})


def pytest_collection_modifyitems(session, config, items):
    if not _plugin_active():
        return
    _disarm()
    wanted = set(filter(None, os.environ.get("HWLIB_GRADE_TODOS", "").split(",")))
    skip_file = os.environ.get("HWLIB_GRADE_SKIP")
    already = set(Path(skip_file).read_text(encoding="utf-8").splitlines()) if skip_file and Path(skip_file).exists() else set()
    keep, deselected = [], []
    for item in items:
        ids = sorted({str(mark.args[0]) for mark in item.iter_markers("todo") if mark.args})
        if len(ids) > 1:
            for todo_id in ids:
                _emit({"event": "todo_error", "todo": todo_id, "message": f"{item.nodeid} is tagged with several TODOs: {', '.join(ids)}"})
        todo_id = ids[0] if len(ids) == 1 else None
        if todo_id is None or (wanted and todo_id not in wanted):
            deselected.append(item)
            continue
        _emit({"event": "collected", "nodeid": item.nodeid, "todo": todo_id, "hidden": item.get_closest_marker("hidden") is not None})
        if item.nodeid in already:
            deselected.append(item)
        else:
            keep.append(item)
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = keep
    _emit_hwlib_files()


def _emit_hwlib_files():
    """Where every imported hwlib module came from: the grader checks they are the kit's."""
    files = sorted({getattr(module, "__file__", "") or "" for name, module in list(sys.modules.items())
                    if name == "hwlib" or name.startswith("hwlib.")})
    _emit({"event": "hwlib", "files": files})


def pytest_runtest_logstart(nodeid, location):
    if _plugin_active():
        _emit({"event": "start", "nodeid": nodeid})
        _arm(_plugin_state["timeout"], "per-test timeout of the grader")


def pytest_runtest_logreport(report):
    if not _plugin_active():
        return
    outcomes = _plugin_state["outcomes"]
    current = outcomes.get(report.nodeid)
    if current and current[0] == "failed":
        return
    if report.failed:
        outcomes[report.nodeid] = ("failed", _first_line(report.longrepr))
    elif report.skipped and report.when != "teardown":
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else _first_line(report.longrepr)
        outcomes[report.nodeid] = ("skipped", str(reason))
    elif report.when == "call" and report.passed:
        outcomes[report.nodeid] = ("passed", "")


def pytest_runtest_logfinish(nodeid, location):
    if not _plugin_active():
        return
    _disarm()
    outcome, message = _plugin_state["outcomes"].pop(nodeid, ("failed", "no result reported"))
    _emit({"event": "result", "nodeid": nodeid, "outcome": outcome, "message": message})


def pytest_sessionfinish(session, exitstatus):
    if _plugin_active():
        _disarm()
        _emit_hwlib_files()
        _emit({"event": "finished", "exitstatus": int(exitstatus)})


def _first_line(longrepr):
    crash = getattr(longrepr, "reprcrash", None)
    text = crash.message if crash is not None and getattr(crash, "message", None) else str(longrepr)
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    if not lines:
        return ""
    if crash is not None:  # a test's failure: the exception's own first line
        return _shorten(lines[0], 300)
    # A collection error: a traceback whose "E   ..." lines hold the exception.
    errors = [line[1:].strip() for line in lines if line.startswith("E ")]
    return _shorten(errors[-1] if errors else lines[-1], 300)


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m hwtools.grade",
        description="Run the kit's tests and print the points per handout TODO.",
    )
    parser.add_argument("kit_dir", nargs="?", default=None,
                        help="the kit to grade (default: the current folder if it is a kit, else the kit of this grader)")
    parser.add_argument("--tests", dest="tests_dir", help="the tests to grade with (default: KIT_DIR/tests)")
    parser.add_argument("--json", dest="json_file", help="also write the report as JSON to this file")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT, help="seconds per test (default %(default)g)")
    parser.add_argument("--todo", dest="todo_ids", action="append", help="grade only this TODO (repeatable)")
    parser.add_argument("--jobs", type=int, default=None, help="test subprocesses side by side (default: one per CPU)")
    parser.add_argument("--python", help="interpreter to run the tests with (default: KIT_DIR/.venv's, else this one)")
    args = parser.parse_args(argv)
    if args.kit_dir is None:
        args.kit_dir = "." if Path("hwlib").is_dir() else str(Path(__file__).resolve().parents[1])
    try:
        report = grade(args.kit_dir, args.tests_dir, args.todo_ids, args.timeout, args.jobs, args.python)
    except GradeError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(report.table())
    if args.json_file:
        Path(args.json_file).write_text(json.dumps(report.as_dict(), indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
