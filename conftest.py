"""Shared test setup: a non-interactive matplotlib backend for every test and notebook kernel, and
failure reports that name the TODO (``hwtools/pytest_todo.py``)."""

import os

os.environ["MPLBACKEND"] = "Agg"

pytest_plugins = ("hwtools.pytest_todo",)


def pytest_configure(config):
    # The README's test command shares test files between two processes (pytest-xdist's
    # --dist loadfile). By default xdist sends the files with the most tests first, which leaves the
    # long files with few tests (a class run, a copy of the clone) to the end, run by one process
    # while the other waits: keep the folder order instead (benchmarks/RESULTS.md, the test suite).
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False
