"""Shared test setup: a non-interactive matplotlib backend for every test and notebook kernel, and
failure reports that name the TODO (``hwtools/pytest_todo.py``)."""

import os

os.environ["MPLBACKEND"] = "Agg"

pytest_plugins = ("hwtools.pytest_todo",)
