"""A test that runs over its time limit fails on its own, and the run goes on to its summary, on Windows too.

pytest-timeout ends a test that runs over its limit (``timeout`` in pyproject.toml, or a test's
``@pytest.mark.timeout(N)``) by a signal where the system has SIGALRM. Windows has none: there its "thread"
method dumps the stacks and ends the whole pytest process (``os._exit``), so a student whose TODO loops
forever sees no summary and no other test's result. Where there is no SIGALRM, this plugin first raises
``TestRanOver`` in the test's thread a little before the limit (``MARGIN``), from a timer thread, as
``PyThreadState_SetAsyncExc`` does: Python code stops at its next line, the test fails saying so, and
the run goes on; pytest-timeout stays the backstop for a test stuck inside a C call.
Registered by the kit's top-level ``conftest.py``. Standard library and pytest only.
"""

from __future__ import annotations

import ctypes
import signal
import threading

import pytest

MARGIN = (0.1, 5.0)  # before the limit, this plugin stops a test: a tenth of its limit, at least 5 s (half a short one),
# so that pytest-timeout's thread, which counts the test's report too, does not end the run meanwhile


def _early(limit):
    return limit - max(MARGIN[0] * limit, min(MARGIN[1], limit / 2))


class TestRanOver(Exception):  # noqa: N818 - the name is what pytest prints
    """The test ran over its time limit and was stopped (the kit's own limit, on a system without SIGALRM)."""

    __test__ = False  # not a test class for pytest's collection


def _limit(item):
    marker = item.get_closest_marker("timeout")
    value = marker.args[0] if marker is not None and marker.args else item.config.getini("timeout") or 0
    try:
        return float(value)
    except (TypeError, ValueError):
        return 0.0


def _async_exception(thread_id, exception):
    """Have ``exception`` (a class; None: nothing) raised in the thread ``thread_id`` at its next bytecode."""
    call = ctypes.pythonapi.PyThreadState_SetAsyncExc
    call.argtypes = (ctypes.c_ulong, ctypes.c_void_p)
    call(thread_id, None if exception is None else id(exception))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    limit = 0.0 if hasattr(signal, "SIGALRM") else _limit(item)
    if limit <= 0:
        yield
        return
    test, lock, state = threading.get_ident(), threading.Lock(), {"done": False, "raised": False}

    def stop():
        with lock:
            if not state["done"]:
                state["raised"] = True
                _async_exception(test, TestRanOver)

    timer = threading.Timer(_early(limit), stop)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        with lock:
            state["done"] = True
            if state["raised"]:  # raised already, or still pending: never outside the test
                _async_exception(test, None)
        timer.cancel()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if call.excinfo is not None and call.excinfo.errisinstance(TestRanOver):
        report.longrepr = (f"{item.nodeid} ran over its time limit of {_limit(item):g} s and was stopped: code that "
                           "never ends (a loop in a TODO?) or a machine far too busy")
