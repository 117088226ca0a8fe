"""Shared test setup: a non-interactive matplotlib backend for every test and notebook kernel."""

import os

os.environ["MPLBACKEND"] = "Agg"
