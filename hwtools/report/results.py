"""The notebooks' values, checked at the door: ``problem_one`` and ``problem_two`` turn what the kernels
exported (plain JSON) into ``ProblemOne`` and ``ProblemTwo``, or raise a ReportError that names the
variable, what was expected, and the cell that makes it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hwtools.report.notebooks import P1_NOTEBOOK, P2_NOTEBOOK, VARIABLE_ORIGIN, ReportError


class SweepSummary(NamedTuple):
    """What the report needs of the notebook's learning-rate sweep (a ``SweepResult`` in the kernel)."""

    learning_rates: np.ndarray
    converged_fraction: np.ndarray
    seeds: np.ndarray
    deadline: int


@dataclass(frozen=True)
class ProblemOne:
    """Problem 1's results, as the notebook's kernel held them."""

    tried: dict  # name -> (4,) float64 array
    random_rewards: np.ndarray
    learning_rate: float
    training_rewards: np.ndarray
    final_params: np.ndarray
    sweep: SweepSummary


@dataclass(frozen=True)
class ProblemTwo:
    """Problem 2's results, as the notebook's kernel held them, and the 2.1.1 derivation (Markdown)."""

    food_names: tuple
    data_source: str
    data_path: str | None
    num_samples: int
    train_accuracies: np.ndarray
    test_accuracy: float
    test_predictions: np.ndarray
    y_test: np.ndarray
    first_above_99: int | None
    derivation: str


def _bad(notebook_name, name, problem):
    variable = re.match(r"\w+", name).group(0)
    return ReportError(f"{notebook_name}: `{name}` {problem} (made in {VARIABLE_ORIGIN.get(variable, 'the notebook')})")


def _vector(value, notebook_name, name, kind="f", length=None):
    try:
        array = np.asarray(value, dtype=np.float64 if kind == "f" else np.int64)
    except (TypeError, ValueError):
        raise _bad(notebook_name, name, "must be a 1-d array of numbers") from None
    if array.ndim != 1 or array.size == 0 or (length is not None and array.size != length):
        wanted = f"{length} values" if length is not None else "a non-empty 1-d array"
        raise _bad(notebook_name, name, f"must be {wanted}, got shape {array.shape}")
    if kind == "f" and not np.all(np.isfinite(array)):
        raise _bad(notebook_name, name, "must hold finite numbers")
    if kind == "i" and not np.array_equal(array, np.asarray(value, dtype=np.float64)):
        raise _bad(notebook_name, name, "must hold whole numbers")
    return array


def _number(value, notebook_name, name):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise _bad(notebook_name, name, f"must be a number, got {value!r}")
    return float(value)


def problem_one(values, notebook_name=P1_NOTEBOOK):
    """``ProblemOne`` from the values the p1 notebook's kernel exported."""
    tried = values["tried"]
    if not isinstance(tried, dict) or not tried:
        raise _bad(notebook_name, "tried", "must be a non-empty dict, name -> the 4 parameters tried")
    tried = {name: _vector(params, notebook_name, f"tried[{name!r}]", length=4) for name, params in tried.items()}
    random_rewards = _vector(values["random_rewards"], notebook_name, "random_rewards")
    learning_rate = _number(values["learning_rate"], notebook_name, "learning_rate")
    run, sweep = values["run"], values["sweep"]
    rates = _vector(sweep["learning_rates"], notebook_name, "sweep.learning_rates")
    summary = SweepSummary(
        learning_rates=rates,
        converged_fraction=_vector(sweep["converged_fraction"], notebook_name, "sweep.converged_fraction", length=rates.size),
        seeds=_vector(sweep["seeds"], notebook_name, "sweep.seeds", kind="i"),
        deadline=int(_number(sweep["deadline"], notebook_name, "sweep.deadline")),
    )
    return ProblemOne(
        tried=tried,
        random_rewards=random_rewards,
        learning_rate=learning_rate,
        training_rewards=_vector(run["rewards"], notebook_name, "run.rewards"),
        final_params=_vector(run["policy.params"], notebook_name, "run.policy.params", length=4),
        sweep=summary,
    )


def problem_two(values, derivation, notebook_name=P2_NOTEBOOK):
    """``ProblemTwo`` from the values the p2 notebook's kernel exported and its 2.1.1 Markdown."""
    data = values["data"]
    names = data["names"]
    if not isinstance(names, list) or not names or not all(isinstance(name, str) for name in names):
        raise _bad(notebook_name, "data.names", "must be the list of class names")
    if not isinstance(data["source"], str):
        raise _bad(notebook_name, "data.source", "must be a string")
    y_test = _vector(values["y_test"], notebook_name, "y_test", kind="i")
    predictions = _vector(values["test_predictions"], notebook_name, "test_predictions", kind="i", length=y_test.size)
    for name, labels in (("y_test", y_test), ("test_predictions", predictions)):
        if labels.min() < 0 or labels.max() >= len(names):
            raise _bad(notebook_name, name, f"must hold class indices 0..{len(names) - 1}")
    accuracies = _vector(values["train_accuracies"], notebook_name, "train_accuracies")
    first = values["first_above_99"]
    if first is not None:
        first = int(_vector([first], notebook_name, "first_above_99", kind="i")[0])
    return ProblemTwo(
        food_names=tuple(names),
        data_source=data["source"],
        data_path=data["path"],
        num_samples=int(data["labels.shape"][0]),
        train_accuracies=accuracies,
        test_accuracy=_number(values["test_accuracy"], notebook_name, "test_accuracy"),
        test_predictions=predictions,
        y_test=y_test,
        first_above_99=first,
        derivation=derivation,
    )
