"""The grader's tests: after every test, reap the pool users' zombies this process adopted
(``process_watch``: under the user fallback the grader's process is a subreaper). The student editions they
grade are built with the test run's one answer key (``tests/instructor/editions.py``)."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "instructor"))


@pytest.fixture(autouse=True)
def _reap_adopted_orphans():
    yield
    if "process_watch" in sys.modules:
        sys.modules["process_watch"].reap_adopted_orphans()
