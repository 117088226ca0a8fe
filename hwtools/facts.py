"""An offering's facts, read where each is written once: the TODO table (``hwlib/machinery/todos.py``:
points per TODO and per check) and the homework's settings (``hwlib/settings.py``: the episode cap,
rollouts, seeds, the learning-rate sweep). Both are loaded from their files by path, so the grader's
trusted side, ``python -m instructor.facts`` (which writes them into the notebooks, README and docs)
and the tests read them without importing the ``hwlib`` package. The hidden inputs' seed is
instructor-only: ``HIDDEN_SEED`` in ``instructor/hidden_checks/__init__.py``.
"""

import importlib.util
import sys
from pathlib import Path

from hwtools.todos import AUTO_POINTS, MANUAL_POINTS, TODO_BY_ID, TODOS  # noqa: F401 - re-exported

KIT = Path(__file__).resolve().parents[1]
TABLE = Path("hwlib/machinery/todos.py")
SETTINGS = Path("hwlib/settings.py")


def load(kit, relative):
    """The module at ``kit/relative`` (the TODO table or the settings), loaded from its file."""
    path = (Path(kit) / relative).resolve()
    name = f"hwtools._facts_{relative.stem}_{abs(hash(str(path)))}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = sys.modules[name] = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


settings = load(KIT, SETTINGS)
MAX_EPISODE_STEPS = settings.MAX_EPISODE_STEPS
