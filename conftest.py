"""Shared test setup: a non-interactive matplotlib backend for every test and notebook kernel, and
failure reports that name the TODO (``hwtools/pytest_todo.py``), and a test that runs over its time limit
failing alone on Windows too (``hwtools/pytest_overrun.py``)."""

import os
import shutil
import tempfile

import pytest

os.environ["MPLBACKEND"] = "Agg"

pytest_plugins = ("hwtools.pytest_todo", "hwtools.pytest_overrun")

# The tests that run student code (graders, sandboxes, class runs). Under the README's test command
# (-n 2 --dist loadfile) one process runs these files, starting with them, and the other everything
# else: measured balanced (benchmarks/RESULTS.md, the test suite) when runs of student code took turns
# machine-wide. They no longer do (hwtools/grade/sandbox.py: only a grading's own runs take turns); the
# split stays until another is measured shorter.
RUN_STUDENT_CODE = "tests/grader/"
# A file whose tests run once per system (a module-scoped run each): each system's tests are a unit of their own,
# so that the two processes share them.
BY_SYSTEM = "tests/notebooks/test_other_systems.py"


def pytest_configure(config):
    # xdist sends the files with the most tests first by default: keep the folder order instead.
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False
    # The learning-rate sweep's stored results (hwlib/machinery/reuse.py) go to a folder of this test run's
    # own, set before any kernel or server starts: no test reads what another run stored.
    config.hwlib_cache_dir = os.environ["HWLIB_CACHE_DIR"] = tempfile.mkdtemp(prefix="hwlib-cache-")


def pytest_unconfigure(config):
    if getattr(config, "hwlib_cache_dir", None):
        shutil.rmtree(config.hwlib_cache_dir, ignore_errors=True)


def pytest_collection_modifyitems(items):
    items.sort(key=lambda item: not item.nodeid.startswith(RUN_STUDENT_CODE))  # stable: files stay in order


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling  # noqa: PLC0415 - only where xdist runs the tests

    class StudentCodeFilesTogether(LoadFileScheduling):
        def _split_scope(self, nodeid):
            if nodeid.startswith(BY_SYSTEM):
                return f"{BY_SYSTEM}[{nodeid.rpartition('[')[2]}"
            return RUN_STUDENT_CODE if nodeid.startswith(RUN_STUDENT_CODE) else super()._split_scope(nodeid)

    return StudentCodeFilesTogether(config, log)
