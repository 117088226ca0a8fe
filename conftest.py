"""Shared test setup: a non-interactive matplotlib backend for every test and notebook kernel, and
failure reports that name the TODO (``hwtools/pytest_todo.py``), and a test that runs over its time limit
failing alone on Windows too (``hwtools/pytest_overrun.py``)."""

import os
import shutil
import tempfile

import pytest

os.environ["MPLBACKEND"] = "Agg"

pytest_plugins = ("hwtools.pytest_todo", "hwtools.pytest_overrun")

# The README's test command (-n 3 --dist loadfile) hands each process a file at a time, in collection order: the
# heaviest files first, then the rest in folder order, so that the processes end together (longest first, as a
# scheduler would). By their times in the 2026-12-07 whole-suite run (benchmarks/RESULTS.md, the test suite).
HEAVIEST_FIRST = ("tests/grader/test_grading.py", "tests/grader/test_checks.py", "tests/browser/test_browser.py",
                  "tests/grader/test_classroom.py", "tests/grader/test_gradescope.py",
                  "tests/notebooks/test_other_systems.py", "tests/notebooks/test_report.py",
                  "tests/instructor/test_student_path.py", "tests/instructor/test_student_edition.py",
                  "tests/grader/test_sandbox.py", "tests/browser/test_browser_dayone.py")
# A file whose tests run once per system (a module-scoped run each): each system's tests are a unit of their own,
# so that the test processes share them.
BY_SYSTEM = "tests/notebooks/test_other_systems.py"


def pytest_configure(config):
    # xdist sends the files with the most tests first by default: keep the folder order instead.
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False
    # The learning-rate sweep's stored results (hwlib/machinery/reuse.py) go to a folder of this test run's
    # own, set before any kernel or server starts: no test reads what another run stored. The run's processes
    # (xdist's workers, which inherit it) share it, so that p1's sweep trains once per run where the same code
    # runs it again (nbval's p1, the JupyterLab tests' Run All): whichever comes first trains, the others read it.
    if hasattr(config, "workerinput") and os.environ.get("HWLIB_CACHE_DIR"):
        return  # the controller made it and removes it
    config.hwlib_cache_dir = os.environ["HWLIB_CACHE_DIR"] = tempfile.mkdtemp(prefix="hwlib-cache-")


def pytest_unconfigure(config):
    if getattr(config, "hwlib_cache_dir", None):
        shutil.rmtree(config.hwlib_cache_dir, ignore_errors=True)


def pytest_collection_modifyitems(items):
    rank = {path: index for index, path in enumerate(HEAVIEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.partition("::")[0], len(rank)))  # stable: the rest stay in order


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling  # noqa: PLC0415 - only where xdist runs the tests

    class EachSystemAUnit(LoadFileScheduling):
        def _split_scope(self, nodeid):
            if nodeid.startswith(BY_SYSTEM):
                return f"{BY_SYSTEM}[{nodeid.rpartition('[')[2]}"
            return super()._split_scope(nodeid)

    return EachSystemAUnit(config, log)
