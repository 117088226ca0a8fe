"""The grader's tests: after every test, reap the pool users' zombies this process adopted
(``process_watch``: under the user fallback the grader's process is a subreaper). The student editions they
grade are built with the test run's one answer key (``tests/instructor/editions.py``).

The test command's two processes (pytest-xdist, ``-n 2``) are two graders of the suite's own
submissions, each with its own turn of untrusted runs: the turn's lock is in the grading user's cache
(``$XDG_CACHE_HOME/hwgrade``, ``hwtools/grade/sandbox.py``), and each process, with the graders it
starts, has a cache of its own. Within a process, and for every grader it starts, runs never overlap
(test_sandbox proves it); across the two they would only wait for each other, which doubled the
suite's grading time (benchmarks/RESULTS.md, the test suite). The pool users' locks stay machine-wide.
"""

import os
import sys
from pathlib import Path

if os.environ.get("PYTEST_XDIST_WORKER"):
    _cache = os.environ.get("XDG_CACHE_HOME", "")
    _cache = Path(_cache) if os.path.isabs(_cache) else Path.home() / ".cache"
    os.environ["XDG_CACHE_HOME"] = str(_cache / f"hwgrade-tests-{os.environ['PYTEST_XDIST_WORKER']}")

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "instructor"))


@pytest.fixture(autouse=True)
def _reap_adopted_orphans():
    yield
    if "process_watch" in sys.modules:
        sys.modules["process_watch"].reap_adopted_orphans()
