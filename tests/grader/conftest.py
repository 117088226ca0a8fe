"""The grader's tests: after every test, reap the pool users' zombies this process adopted
(``process_watch``: under the user fallback the grader's process is a subreaper)."""

import sys

import pytest


@pytest.fixture(autouse=True)
def _reap_adopted_orphans():
    yield
    if "process_watch" in sys.modules:
        sys.modules["process_watch"].reap_adopted_orphans()
