"""The homework report in one command: ``python -m hwtools.report OUT_DIR [--name "NAME / ANDREW ID"]``.

Writes into OUT_DIR (created if needed):

| file                                         | what                                                         |
|----------------------------------------------|--------------------------------------------------------------|
| ``p1_cartpole_finite_difference.html``       | problem 1's notebook, executed from a fresh kernel           |
| ``p2_food_cutting_logistic_regression.html`` | problem 2's notebook, likewise                               |
| ``p1_random_policy_histogram.png``           | 1.1.3: rewards of the random policies, the share at 500 marked |
| ``p1_training_curve.png``                    | 1.3.3: reward per training iteration                         |
| ``p1_learning_rate_sweep.png``               | 1.3.3: share of seeds converging within 7 iterations, per rate |
| ``p2_training_curve.png``                    | 2.3.2: training accuracy per iteration                       |
| ``p2_confusion_matrix.png``                  | 2.3.2: confusion matrix of the test set                      |
| ``answers.md``                               | every answer the handout asks to report, the 2.1.1 derivation and the figures |
| ``answers.html``                             | the same as one self-contained page                          |
| ``answers.pdf``                              | the same, printed by headless Chromium, with page numbers and the name line |

Every result is computed once, by the notebooks. The report executes both notebooks from a
fresh kernel and, in the same kernel after the last cell, runs one extra cell that writes the
variables listed in ``NOTEBOOK_VARIABLES`` to a JSON file in a temporary folder (no pickle).
Every number and figure of the answers is made from those values: the report never trains,
sweeps or samples again, and it copies no setting (what it states about the setup comes from
``hwlib.settings``). The 2.1.1 derivation is the Markdown under the notebook's 2.1.1 heading.

Formulas are typeset by MathJax 2 from the ``jupyter-server-mathjax`` package (the Jupyter
project's own copy of MathJax; nothing is fetched from the network). With Chromium, every HTML
page is typeset once in headless Chromium and saved with the formulas as inline SVG, so the
pages need no script and read the same offline anywhere. Without Chromium, the pages load a
copy of MathJax written next to them (``mathjax/``), and answers.pdf is skipped.

The PDF is printed by Debian's Chromium (``/usr/bin/chromium``, or the path in the environment
variable ``HWLIB_CHROMIUM``) driven by Playwright, which never downloads a browser.
"""

from __future__ import annotations

import argparse
import html
import inspect
import io
import json
import os
import re
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from importlib.util import find_spec
from pathlib import Path
from typing import NamedTuple

import numpy as np

from hwlib import settings
from hwlib.cartpole import (
    MAX_EPISODE_REWARD,
    THETA_THRESHOLD_RADIANS,
    X_THRESHOLD,
    CartPoleLinearPolicy,
    play_episode,
    run_policy,
)
from hwlib.logreg import confusion_matrix
from hwlib.plots.food import plot_confusion_matrix, plot_training_accuracy
from hwlib.plots.training import plot_learning_rate_sweep, plot_reward_histogram, plot_training_curve
from hwlib.policy_search import iterations_to_converge

KIT_ROOT = Path(__file__).resolve().parent.parent
NOTEBOOK_DIR = KIT_ROOT / "notebooks"
P1_NOTEBOOK = "p1_cartpole_finite_difference.ipynb"
P2_NOTEBOOK = "p2_food_cutting_logistic_regression.ipynb"
NOTEBOOKS = (P1_NOTEBOOK, P2_NOTEBOOK)
CELL_TIMEOUT = 600  # seconds one notebook cell may take

# What the report reads from each notebook's kernel: variable -> the attributes read (() = the value itself).
NOTEBOOK_VARIABLES = {
    P1_NOTEBOOK: {
        "tried": (),
        "random_rewards": (),
        "learning_rate": (),
        "run": ("rewards", "policy.params"),
        "sweep": ("learning_rates", "converged_fraction", "seeds", "deadline"),
    },
    P2_NOTEBOOK: {
        "data": ("names", "source", "path", "labels.shape"),
        "train_accuracies": (),
        "test_accuracy": (),
        "test_predictions": (),
        "y_test": (),
        "first_above_99": (),
    },
}
# Where each variable is made, for the error messages.
VARIABLE_ORIGIN = {
    "tried": "TODO 1.1.2: a dict, name -> the 4 parameters you tried",
    "random_rewards": "1.1.3: the rewards of the random policies",
    "learning_rate": "1.3.3: the learning rate the notebook trains with",
    "run": "1.3.3: the TrainingRun of the notebook's training",
    "sweep": "1.3.3: the learning-rate sweep",
    "data": "the cell that loads the food-cutting data",
    "train_accuracies": "2.3.2: the training accuracy per iteration",
    "test_accuracy": "2.3.2: the test accuracy",
    "test_predictions": "2.3.2: the predictions on the test set",
    "y_test": "the train/test split",
    "first_above_99": "2.3.2: the first iteration above 99%",
}
DERIVATION_TODO = "2.1.1"

FIGURES = (
    "p1_random_policy_histogram.png",
    "p1_training_curve.png",
    "p1_learning_rate_sweep.png",
    "p2_training_curve.png",
    "p2_confusion_matrix.png",
)
FIGURE_DPI = 150
ANSWERS_MD = "answers.md"
ANSWERS_HTML = "answers.html"
ANSWERS_PDF = "answers.pdf"
MATHJAX_COPY = "mathjax"  # the folder of MathJax written next to the pages when there is no Chromium
NAME_BLANK = "_" * 28
NAME_LABEL = "Name / Andrew ID:"

# Debian's Chromium, started the way this machine's closed network needs (no background traffic).
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-quic",
]


def chromium_path():
    """Debian's Chromium (or ``$HWLIB_CHROMIUM``) if it is there, else None."""
    candidate = Path(os.environ.get("HWLIB_CHROMIUM", "/usr/bin/chromium"))
    if candidate.is_file() and os.access(candidate, os.X_OK):
        return candidate
    found = shutil.which("chromium")
    return Path(found) if found else None


class ReportError(Exception):
    """A problem the user can fix: a bad OUT_DIR, a missing notebook, a failing cell, a TODO left."""


# --- reading the notebooks' kernels ----------------------------------------------------------


def _report_export_variables(namespace, wanted, path):
    """Write the variables ``wanted`` ({name: attribute paths}) of ``namespace`` to ``path`` as JSON.

    Runs INSIDE the notebook's kernel: the report sends this function's source as one extra cell
    after the notebook's last, so it may use nothing from its module. Arrays become nested lists;
    whatever cannot be written is listed under "problems" for the report to explain.
    """
    import json
    from pathlib import Path

    import numpy as np

    def plain(value):
        if value is None or isinstance(value, (bool, str, int, float)):
            return value
        if isinstance(value, np.generic):
            return value.item()
        if isinstance(value, np.ndarray):
            return plain(value.tolist()) if value.dtype == object else value.tolist()
        if isinstance(value, Path):
            return str(value)
        if isinstance(value, dict):
            return {str(key): plain(item) for key, item in value.items()}
        if isinstance(value, (list, tuple)):
            return [plain(item) for item in value]
        raise TypeError(f"a {type(value).__name__}")

    values, problems = {}, []
    for name, attributes in wanted.items():
        if name not in namespace:
            problems.append(f"`{name}` is not defined")
            continue
        entry = {}
        for attribute in attributes or [None]:
            target, label = namespace[name], name
            try:
                for part in attribute.split(".") if attribute else []:
                    label = f"{label}.{part}"
                    target = getattr(target, part)
                entry[attribute] = plain(target)
            except AttributeError:
                problems.append(f"`{name}` has no attribute `{label}` (it is a {type(namespace[name]).__name__})")
            except TypeError as error:
                problems.append(f"`{label}` holds {error}, which the report cannot read")
        if len(entry) == len(attributes or [None]):
            values[name] = entry[None] if not attributes else entry
    Path(path).write_text(json.dumps({"values": values, "problems": problems}), encoding="utf-8")


def export_cell_source(wanted, path):
    """The extra cell run after a notebook's last: ``_report_export_variables`` and one call of it."""
    function = inspect.getsource(_report_export_variables)
    call = f"_report_export_variables(globals(), {dict(wanted)!r}, {str(path)!r})"
    return f"{function}\n\n{call}\ndel _report_export_variables\n"


def _native_kernel_dir(tmp_dir):
    """A kernelspec folder whose 'python3' is this very Python, whatever other kernels are installed."""
    from ipykernel.kernelspec import get_kernel_dict

    spec_dir = Path(tmp_dir) / "kernels" / "python3"
    spec_dir.mkdir(parents=True)
    spec = get_kernel_dict()  # ipykernel's own spec, with argv[0] = sys.executable
    spec["argv"][0] = sys.executable
    (spec_dir / "kernel.json").write_text(json.dumps(spec))
    return spec_dir.parent


def execute_notebook(path, kernel_dir, export=None):
    """Run every cell of the notebook at ``path`` in a fresh kernel started in its folder.

    ``export=(wanted, json_path)`` runs one more cell in the same kernel after the last, which
    writes the variables ``wanted`` to ``json_path`` (see ``_report_export_variables``); that cell
    is not part of the notebook returned. The kernel is this environment's Python and sees no
    MPLBACKEND, so figures come out inline as a student sees them. Raises
    ``nbclient.exceptions.CellExecutionError`` if a cell fails.
    """
    import nbformat
    import zmq
    from jupyter_client import KernelManager
    from jupyter_client.kernelspec import KernelSpecManager
    from nbclient import NotebookClient

    notebook = nbformat.read(path, as_version=4)
    if export is not None:
        notebook.cells.append(nbformat.v4.new_code_cell(export_cell_source(*export)))
    env = {key: value for key, value in os.environ.items() if key != "MPLBACKEND"}
    kernel_manager = KernelManager(
        kernel_name="python3", kernel_spec_manager=KernelSpecManager(kernel_dirs=[str(kernel_dir)])
    )
    if zmq.has("curve") and "transport_encryption" in kernel_manager.trait_names():
        kernel_manager.transport_encryption = "auto"  # encrypt the kernel's local sockets where it can
    client = NotebookClient(
        notebook, km=kernel_manager, timeout=CELL_TIMEOUT, kernel_name="python3",
        resources={"metadata": {"path": str(Path(path).parent)}},
    )
    try:
        client.execute(env=env)
    finally:
        if kernel_manager.has_kernel:
            kernel_manager.shutdown_kernel(now=False)
        if export is not None:
            notebook.cells.pop()
    return notebook


def read_exported(json_path, notebook_name):
    """The values one notebook's extra cell wrote, or a ReportError naming what is missing and where it is made."""
    try:
        exported = json.loads(Path(json_path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise ReportError(f"{notebook_name}: the notebook's values could not be read back: {error}") from None
    if exported["problems"]:
        lines = []
        for problem in exported["problems"]:
            name = re.match(r"`([^`.]+)", problem).group(1)
            lines.append(f"  - {problem} (made in {VARIABLE_ORIGIN.get(name, 'the notebook')})")
        raise ReportError(
            f"{notebook_name}: the report reads these variables after the last cell, and some are missing or "
            "unreadable; keep the notebook's variable names:\n" + "\n".join(lines)
        )
    return exported["values"]


# --- the values, checked -----------------------------------------------------------------------


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


HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
MARKER_COMMENT = re.compile(r"^\s*<!--.*?-->\s*$")


def derivation_markdown(notebook, todo=DERIVATION_TODO):
    """The Markdown under the notebook's ``todo`` heading (e.g. "### 2.1.1 ..."): the rest of that cell and the
    Markdown cells after it, up to the next heading of the same or a higher level or the next code cell.
    The solution/TODO marker comments are left out; None if the notebook has no such heading."""
    collected, level = [], None
    for cell in notebook.cells:
        if level is not None and cell.cell_type != "markdown":
            break
        if cell.cell_type != "markdown":
            continue
        for line in cell.source.split("\n"):
            heading = HEADING.match(line)
            if level is None:
                if heading and re.match(rf"{re.escape(todo)}\b", heading.group(2)):
                    level = len(heading.group(1))
                continue
            if heading and len(heading.group(1)) <= level:
                return _tidy_markdown(collected)
            if not MARKER_COMMENT.match(line):
                collected.append(line)
        if level is not None:
            collected.append("")
    return None if level is None else _tidy_markdown(collected)


def _tidy_markdown(lines):
    return "\n".join(lines).strip()


# --- the answers -----------------------------------------------------------------------------
# The notebooks print these numbers in the same formats (see the README's Report section).


def rewards_text(rewards):
    """Rewards per iteration as the report and the p1 notebook print them: one decimal each."""
    return ", ".join(f"{reward:.1f}" for reward in rewards)


def final_params_text(params):
    """Learned parameters as the report and the p1 notebook print them: three decimals each."""
    return "[" + ", ".join(f"{value:.3f}" for value in params) + "]"


def tried_params_text(params):
    """Parameters tried by hand, as typed (shortest form)."""
    return "(" + ", ".join(f"{value:g}" for value in params) + ")"


def describe_episode(episode):
    """What the cart does in ``episode``, in words: how it pushes and how the episode ends."""
    right = float(np.mean(episode.actions)) if episode.num_steps else 0.0
    if right == 0.0:
        pushes = "pushes left at every step"
    elif right == 1.0:
        pushes = "pushes right at every step"
    else:
        pushes = f"pushes right in {right:.0%} of the steps and left in the rest"
    cart_x, _, angle, _ = episode.states[-1]
    steps = episode.num_steps
    if episode.total_reward >= MAX_EPISODE_REWARD:
        low, high = episode.states[:, 0].min(), episode.states[:, 0].max()
        ends = f"balances the pole for all {steps} steps, the cart staying between x = {low:.2f} and {high:.2f}"
    elif abs(cart_x) > X_THRESHOLD:
        ends = f"the cart runs off the {'right' if cart_x > 0 else 'left'} end of the track after {steps} steps"
    elif abs(angle) > THETA_THRESHOLD_RADIANS:
        ends = f"the pole falls to the {'right' if angle > 0 else 'left'} ({np.degrees(angle):+.1f}°) after {steps} steps"
    else:
        ends = f"the episode ends after {steps} steps"
    return f"{pushes}; {ends}"


def compute_answers(p1, p2):
    """Every number the handout asks to report, as a plain dict (JSON-serialisable), from the notebooks' values.

    Only the 1.1.2 table plays episodes here: one per seed of ``settings.HAND_TUNING_SEEDS`` for each
    parameter vector the student tried, to describe what it does.
    """
    seeds = list(settings.HAND_TUNING_SEEDS)
    tried = []
    for name, params in p1.tried.items():
        tried.append({
            "name": name,
            "params": [float(value) for value in params],
            "behaviour": describe_episode(play_episode(CartPoleLinearPolicy(params), seed=seeds[0])),
            "rewards": [int(run_policy(CartPoleLinearPolicy(params), seed=seed)) for seed in seeds],
        })
    rewards = p1.random_rewards
    num_at_max = int(np.sum(rewards >= MAX_EPISODE_REWARD))
    converged_at = iterations_to_converge(p1.training_rewards)
    deadline = settings.CONVERGENCE_DEADLINE
    accuracies = p2.train_accuracies
    return {
        "p1_hand_tuning": {"seeds": seeds, "tried": tried},
        "p1_random_policies": {
            "num_policies": len(rewards),
            "num_at_max": num_at_max,
            "share_at_max": num_at_max / len(rewards),
            "median_reward": float(np.median(rewards)),
        },
        "p1_training": {
            "learning_rate": p1.learning_rate,
            "num_iterations": len(p1.training_rewards) - 1,
            "num_rollouts_per_eval": settings.NUM_ROLLOUTS,
            "rewards": [float(reward) for reward in p1.training_rewards],
            "final_params": [float(value) for value in p1.final_params],
            "converged_at": converged_at,
            "deadline": deadline,
            "converged_within_deadline": converged_at is not None and converged_at <= deadline,
        },
        "p1_learning_rate_sweep": {
            "learning_rates": [float(rate) for rate in p1.sweep.learning_rates],
            "num_seeds": len(p1.sweep.seeds),
            "deadline": p1.sweep.deadline,
            "converged_fraction": [float(fraction) for fraction in p1.sweep.converged_fraction],
        },
        "p2_results": {
            "data_source": p2.data_source,
            "data_file": p2.data_path,
            "num_train": p2.num_samples - len(p2.y_test),
            "num_test": len(p2.y_test),
            "learning_rate": settings.P2_LEARNING_RATE,
            "num_iterations": len(accuracies) - 1,
            "final_train_accuracy": float(accuracies[-1]),
            "test_accuracy": p2.test_accuracy,
            "first_iteration_above_99": p2.first_above_99,
            "target_iterations": settings.TARGET_ITERATIONS,
        },
        "p2_derivation": p2.derivation,
    }


def make_figures(p1, p2):
    """The five figures of the handout, ``{file name: Figure}``, drawn from the notebooks' values."""
    source = p2.data_source
    return {
        "p1_random_policy_histogram.png": plot_reward_histogram(p1.random_rewards),
        "p1_training_curve.png": plot_training_curve(p1.training_rewards, learning_rate=p1.learning_rate),
        "p1_learning_rate_sweep.png": plot_learning_rate_sweep(p1.sweep, chosen_learning_rate=p1.learning_rate),
        "p2_training_curve.png": plot_training_accuracy(p2.train_accuracies, data_source=source),
        "p2_confusion_matrix.png": plot_confusion_matrix(
            confusion_matrix(p2.y_test, p2.test_predictions, len(p2.food_names)), p2.food_names, data_source=source
        ),
    }


def figure_svg(figure):
    """The figure as inline SVG with its text kept as text (searchable in the PDF), same ids every run."""
    import matplotlib

    buffer = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "hwtools-report"}):
        figure.savefig(buffer, format="svg", metadata={"Date": None})
    svg = buffer.getvalue()
    return svg[svg.index("<svg"):]


def name_line(name):
    return f"{NAME_LABEL} {name if name else NAME_BLANK}"


def answers_markdown(answers, name=None):
    """answers.md: each handout question that asks for a report item, answered."""
    hand, rand, train = answers["p1_hand_tuning"], answers["p1_random_policies"], answers["p1_training"]
    sweep, food = answers["p1_learning_rate_sweep"], answers["p2_results"]
    seeds = hand["seeds"]
    seed_range = f"{seeds[0]}–{seeds[-1]}" if len(seeds) > 1 else f"{seeds[0]}"
    converged = train["converged_at"]
    lines = [
        "# Robot Autonomy — Homework 1: answers",
        "",
        f"**{NAME_LABEL}** {html.escape(name) if name else NAME_BLANK}",
        "",
        "Made by `python -m hwtools.report` from the executed notebooks: every number and figure below is the",
        "notebooks' own (the notebooks are next to this file as HTML).",
        "",
        "## Problem 1: reinforcement learning by finite differences",
        "",
        "### 1.1.2 Parameters tried by hand and the behaviour they gave",
        "",
        "The parameter vectors of the notebook's `tried`. The policy pushes right (action 1) when θᵀs < 0 and left",
        "otherwise; s = (cart position, cart velocity, pole angle, pole angular velocity). What the cart does is",
        f"described for the start state of seed {seeds[0]}; the rewards are one episode from each start state of seeds {seed_range}.",
        "",
        f"| parameters tried | θ | what the cart does (seed {seeds[0]}) | rewards, seeds {seed_range} |",
        "|---|---|---|---|",
    ]
    for entry in hand["tried"]:
        rewards = ", ".join(str(reward) for reward in entry["rewards"])
        lines.append(f"| {_table_cell(entry['name'])} | {tried_params_text(entry['params'])} | {entry['behaviour']} | {rewards} |")
    lines += [
        "",
        "### 1.1.3 Random policies",
        "",
        f"- {rand['num_at_max']} of {rand['num_policies']} random policies reached the maximum reward of 500:"
        f" **{rand['share_at_max']:.1%}**",
        f"- median reward: {rand['median_reward']:.1f}",
        "",
        "![Histogram of the rewards of the random policies](p1_random_policy_histogram.png)",
        "",
        "### 1.3.3 Learning rate and learning curve",
        "",
        f"- learning rate: **{train['learning_rate']:g}**",
        f"- final parameters: **{final_params_text(train['final_params'])}**",
        "- converged (500 from then on) at iteration: " + (
            f"**{converged}** (deadline {train['deadline']}: {'met' if train['converged_within_deadline'] else 'missed'})"
            if converged is not None else f"**None** (not within {train['num_iterations']} iterations)"
        ),
        f"- reward per iteration: {rewards_text(train['rewards'])}",
        "",
        f"Iteration 0 is before the first update; each reward is the mean of {train['num_rollouts_per_eval']} episodes.",
        "",
        "![Training curve](p1_training_curve.png)",
        "",
        f"How sensitive is this to the learning rate? The share of {sweep['num_seeds']} seeds that converge within"
        f" {sweep['deadline']} iterations:",
        "",
        "| learning rate | " + " | ".join(f"{rate:.1e}" for rate in sweep["learning_rates"]) + " |",
        "|---|" + "---|" * len(sweep["learning_rates"]),
        "| converged | " + " | ".join(f"{fraction:.0%}" for fraction in sweep["converged_fraction"]) + " |",
        "",
        "![Learning-rate sweep](p1_learning_rate_sweep.png)",
        "",
        "## Problem 2: classification by logistic regression",
        "",
        f"### {DERIVATION_TODO} The gradient of the log-likelihood",
        "",
        "The derivation as written in the notebook:",
        "",
        answers["p2_derivation"] or "*(not found: the notebook has no 2.1.1 heading with an answer under it)*",
        "",
        "### 2.3.2 Training curve and accuracy",
        "",
        f"- data: **{food['data_source']}** — " + (
            f"read from `{food['data_file']}`." if food["data_file"] else
            "the course's data.npz was not found in the kit's data/ folder, so the kit's synthetic data set with the"
            " same layout was used: these are not the numbers of the real data."
        ),
        f"- split: {food['num_train']} training and {food['num_test']} test samples;"
        f" learning rate {food['learning_rate']:g}, {food['num_iterations']} iterations from zero weights.",
        f"- final train accuracy: **{food['final_train_accuracy']:.3f}**",
        f"- test accuracy: **{food['test_accuracy']:.3f}**",
        f"- first iteration with train accuracy above 99%: **{food['first_iteration_above_99']}**" + (
            f" (deadline {food['target_iterations']}: "
            f"{'met' if food['first_iteration_above_99'] <= food['target_iterations'] else 'missed'})"
            if food["first_iteration_above_99"] is not None else f" (never within {food['num_iterations']} iterations)"
        ),
        "",
        "![Training accuracy per iteration](p2_training_curve.png)",
        "",
        "![Confusion matrix of the test set](p2_confusion_matrix.png)",
        "",
    ]
    return "\n".join(lines)


def _table_cell(text):
    return html.escape(str(text)).replace("|", "\\|")


# --- HTML, formulas and the PDF ------------------------------------------------------------------

PAGE_STYLE = """
body { font-family: 'DejaVu Sans', 'Liberation Sans', Arial, sans-serif; font-size: 10.5pt; line-height: 1.4; color: #111;
       max-width: 178mm; margin: 0 auto; }
h1 { font-size: 18pt; margin: 0 0 0.3em 0; }
h2 { font-size: 14pt; border-bottom: 1px solid #999; padding-bottom: 0.1em; margin-top: 1.1em; break-after: avoid; }
h3 { font-size: 12pt; margin: 1em 0 0.4em 0; break-after: avoid; }
p, ul { margin: 0.4em 0; }
.anchor-link { display: none; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 9pt; break-inside: avoid; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.45em; text-align: left; vertical-align: top; }
th { background: #eee; }
td:nth-child(2) { white-space: nowrap; }
.figure { margin: 0.5em 0; break-inside: avoid; }
.figure svg { width: 100%; height: auto; display: block; }
code { font-family: 'DejaVu Sans Mono', monospace; font-size: 9.5pt; }
.MathJax_SVG_Display { break-inside: avoid; }
@page { size: A4; }
"""

# MathJax 2 (TeX input, HTML-CSS output in its STIX web fonts), typesetting the $...$ and $$...$$ of the
# Markdown; the page is marked when everything is typeset. The combined configuration file is the
# one that jupyter-server-mathjax ships.
MATHJAX_QUERY = "?config=TeX-AMS-MML_HTMLorMML-full"
MATHJAX_CONFIG = """<script type="text/x-mathjax-config">
MathJax.Hub.Config({
  jax: ["input/TeX", "output/HTML-CSS"],
  TeX: {extensions: ["AMSmath.js", "AMSsymbols.js", "noErrors.js", "noUndefined.js"]},
  tex2jax: {inlineMath: [["$", "$"], ["\\\\(", "\\\\)"]], displayMath: [["$$", "$$"], ["\\\\[", "\\\\]"]],
            processEscapes: true, processEnvironments: true},
  "HTML-CSS": {availableFonts: [], preferredFont: null, webFont: "STIX-Web", imageFont: null,
               linebreaks: {automatic: true}},
  menuSettings: {assistiveMML: false, zoom: "None"},
  messageStyle: "none", showMathMenu: false, showProcessingMessages: false
});
MathJax.Hub.Register.StartupHook("End", function () {
  MathJax.Hub.Queue(function () { document.documentElement.setAttribute("data-math", "typeset"); });
});
</script>
"""
MATHJAX_SENTINEL = "hwtools-report-mathjax.js"

# Run in the typeset page before it is saved: no script is left (the page needs none), the slider
# panel (which needs a live kernel) is replaced by a note, and MathJax's helpers are removed.
STATIC_PAGE_JS = """() => {
  for (const view of document.querySelectorAll('script[type="application/vnd.jupyter.widget-view+json"]')) {
    const note = document.createElement('p');
    note.className = 'widget-note';
    note.textContent = '[Interactive widget: it works only in JupyterLab, with the notebook running.]';
    note.setAttribute('style', 'font-family: sans-serif; font-style: italic; color: #555; margin: 0.3em 0;');
    view.replaceWith(note);
  }
  for (const element of document.querySelectorAll(
      'script, #MathJax_Message, #MathJax_Font_Test, .MathJax_Preview, .MJX_Assistive_MathML, #MathJax_Hidden')) {
    element.remove();
  }
  const handlers = ['onclick', 'ondblclick', 'oncontextmenu', 'onmousedown', 'onmouseover', 'onmouseout', 'onfocus', 'onblur'];
  for (const element of document.querySelectorAll(handlers.map(name => '[' + name + ']').join(', '))) {
    for (const name of handlers) element.removeAttribute(name);
  }
}"""
# A font file the typeset page refers to; embedded in the saved page so that it reads the same anywhere.
LOCAL_FONT_URL = re.compile(r"""url\(\s*(['"]?)(file://[^'")]+?\.(?:woff2?|otf|ttf))(\?[^'")]*)?\1\s*\)""")


def mathjax_dir():
    """The MathJax 2 folder of the ``jupyter-server-mathjax`` package, or None if it is not installed."""
    spec = find_spec("jupyter_server_mathjax")
    if spec is None or not spec.submodule_search_locations:
        return None
    folder = Path(list(spec.submodule_search_locations)[0]) / "static"
    return folder if (folder / "MathJax.js").is_file() else None


def math_head(mathjax_url):
    """What a page's <head> needs to typeset its formulas with the MathJax.js at ``mathjax_url`` (nothing if None)."""
    if mathjax_url is None:
        return ""
    return f'{MATHJAX_CONFIG}<script src="{html.escape(mathjax_url + MATHJAX_QUERY)}"></script>\n'


def copy_mathjax(out_dir):
    """The parts of MathJax the pages use (TeX input, HTML-CSS output, STIX web fonts, English), copied to
    ``out_dir/mathjax`` for pages that typeset when opened; returns that folder."""
    source, target = mathjax_dir(), Path(out_dir) / MATHJAX_COPY
    needed = ("MathJax.js", "LICENSE", "config", "extensions", "jax/input/TeX", "jax/element", "jax/output/HTML-CSS",
              "fonts/HTML-CSS/STIX-Web/woff", "localization/en")
    if target.exists():
        shutil.rmtree(target)
    for part in needed:
        if (source / part).is_dir():
            shutil.copytree(source / part, target / part)
        elif (source / part).is_file():
            (target / part).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source / part, target / part)
    return target


def embed_local_fonts(page_html):
    """``page_html`` with every local font file it refers to (MathJax's) embedded as a data URI; a font that is
    not there is dropped (an empty data URI), so that the saved page names no file of this machine."""
    import base64
    from urllib.parse import unquote, urlparse

    def embed(match):
        path = Path(unquote(urlparse(match.group(2)).path))
        if not path.is_file():
            return "url(data:,)"
        kind = path.suffix.lstrip(".")
        mime = {"woff": "font/woff", "woff2": "font/woff2", "otf": "font/otf", "ttf": "font/ttf"}[kind]
        return f"url(data:{mime};base64,{base64.b64encode(path.read_bytes()).decode('ascii')})"

    return LOCAL_FONT_URL.sub(embed, page_html)


def answers_html(markdown_text, figures, mathjax_url, name=None):
    """answers.md as one page: the figures inline as SVG, the formulas typeset by the MathJax at ``mathjax_url``."""
    from nbconvert.filters import markdown2html

    body = markdown2html(markdown_text)

    def inline(match):
        return f'<div class="figure">{figures[html.unescape(match.group(1))]}</div>'

    body = re.sub(r'<p>\s*<img src="([^"]+\.png)"[^>]*>\s*</p>', inline, body)
    body = re.sub(r'<img src="([^"]+\.png)"[^>]*>', inline, body)
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<title>Homework 1 — answers — {html.escape(name_line(name))}</title>"
        f"<style>{PAGE_STYLE}</style>\n{math_head(mathjax_url)}</head><body>\n{body}\n</body></html>\n"
    )


def notebook_html(notebook, name, mathjax_url):
    """The executed notebook as HTML (JupyterLab's look), its formulas typeset by the MathJax at ``mathjax_url``."""
    from nbconvert import HTMLExporter

    exporter = HTMLExporter(template_name="lab", mathjax_url=MATHJAX_SENTINEL)
    body, _ = exporter.from_notebook_node(notebook, resources={"metadata": {"name": name}})
    tag = f'<script src="{MATHJAX_SENTINEL}"> </script>'
    if tag not in body:
        raise ReportError("nbconvert's HTML template changed: the MathJax script tag was not found")
    return body.replace(tag, math_head(mathjax_url))


def pdf_templates(name):
    """Playwright's header and footer: the name line on every page, and 'page N of M'."""
    style = "font-family: 'DejaVu Sans', Arial, sans-serif; font-size: 8pt; color: #444; width: 100%; margin: 0 16mm;"
    header = (
        f'<div style="{style} display: flex; justify-content: space-between;">'
        f"<span>Robot Autonomy — Homework 1: answers</span><span>{html.escape(name_line(name))}</span></div>"
    )
    footer = f'<div style="{style} text-align: center;">page <span class="pageNumber"></span> of <span class="totalPages"></span></div>'
    return header, footer


@dataclass(frozen=True)
class Page:
    """One HTML page to typeset in Chromium: read ``source`` (with MathJax), save the static result to ``target``,
    and print it to ``pdf`` if given."""

    source: Path
    target: Path
    pdf: Path | None = None


def render_pages(pages, chromium, name=None, math=True):
    """Typeset and save every page in one headless Chromium; returns the names of pages whose formulas did not typeset."""
    from playwright.sync_api import Error as PlaywrightError
    from playwright.sync_api import sync_playwright

    untypeset = []
    with tempfile.TemporaryDirectory(prefix="hwtools-report-chromium-") as profile, sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            profile, executable_path=str(chromium), args=CHROMIUM_ARGS, headless=True
        )
        # Only the local files load: the notebook template's CDN links (require.js, widgets) are cut off at once.
        context.route(re.compile(r"^(?!file:)"), lambda route: route.abort())
        try:
            for page_spec in pages:
                page = context.new_page()
                page.goto(page_spec.source.as_uri(), wait_until="load", timeout=120_000)
                if math:
                    try:
                        page.wait_for_function("document.documentElement.getAttribute('data-math') === 'typeset'",
                                               timeout=120_000)
                    except PlaywrightError:
                        untypeset.append(page_spec.target.name)
                page.evaluate(STATIC_PAGE_JS)
                page_spec.target.write_text(embed_local_fonts(page.content()), encoding="utf-8")
                if page_spec.pdf is not None:
                    header, footer = pdf_templates(name)
                    page.pdf(
                        path=str(page_spec.pdf), format="A4", print_background=True, display_header_footer=True,
                        header_template=header, footer_template=footer,
                        margin={"top": "18mm", "bottom": "16mm", "left": "16mm", "right": "16mm"},
                    )
                page.close()
        finally:
            context.close()
    return untypeset


# --- the command -----------------------------------------------------------------------------


def notebook_title(path):
    """The first Markdown heading of the notebook at ``path``."""
    import nbformat

    for cell in nbformat.read(path, as_version=4).cells:
        if cell.cell_type == "markdown":
            match = re.search(r"^#+\s+(.+)$", cell.source, flags=re.MULTILINE)
            if match:
                return match.group(1).strip()
    return Path(path).stem


def check_out_dir(out_dir):
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ReportError(f"OUT_DIR {out_dir} exists and is not a directory; give a folder (it is created if missing)")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ReportError(f"cannot create OUT_DIR {out_dir}: {error}") from None
    if not os.access(out_dir, os.W_OK):
        raise ReportError(f"OUT_DIR {out_dir} is not writable")
    return out_dir


def check_name(name):
    """``--name``: one line of printable text (or None for the blank line a student fills in by hand)."""
    if name is None:
        return None
    if not isinstance(name, str):
        raise ReportError(f"--name must be text, got {type(name).__name__}")
    name = name.strip()
    if not name or len(name) > 120 or any(not character.isprintable() for character in name):
        raise ReportError(f"--name must be one line of 1 to 120 printable characters, e.g. \"Ada Lovelace / alovelac\"; got {name!r}")
    return name


def build_report(out_dir, progress=print, pdf=True, name=None):
    """Write the whole report into ``out_dir``; returns ``{name: path}`` of the files written."""
    from nbclient.exceptions import CellExecutionError

    out_dir = check_out_dir(out_dir)
    name = check_name(name)
    notebooks = [NOTEBOOK_DIR / notebook_name for notebook_name in NOTEBOOKS]
    missing = [str(path) for path in notebooks if not path.is_file()]
    if missing:
        raise ReportError(f"notebook(s) not found: {', '.join(missing)}")
    written = {}
    started = time.monotonic()

    def step(message):
        progress(f"[{time.monotonic() - started:6.1f} s] {message}")

    chromium = chromium_path()
    mathjax = mathjax_dir()
    if mathjax is None:
        step("formulas: NOT TYPESET - the jupyter-server-mathjax package is missing (pip install -r requirements.txt)")
    with tempfile.TemporaryDirectory(prefix="hwtools-report-") as tmp:
        tmp = Path(tmp)
        kernel_dir = _native_kernel_dir(tmp)
        executed, values = {}, {}
        for index, path in enumerate(notebooks, start=1):
            step(f"notebook {index}/{len(notebooks)}: executing {path.name} in a fresh kernel ...")
            begun = time.monotonic()
            export_path = tmp / f"{path.stem}.values.json"
            try:
                executed[path.name] = execute_notebook(path, kernel_dir, export=(NOTEBOOK_VARIABLES[path.name], export_path))
            except CellExecutionError as error:
                message = re.sub(r"\x1b\[[0-9;]*m", "", str(error))  # the traceback without its terminal colours
                raise ReportError(f"{path.name}: a cell failed:\n{message}") from None
            values[path.name] = read_exported(export_path, path.name)
            step(f"notebook {index}/{len(notebooks)}: done in {time.monotonic() - begun:.1f} s; "
                 f"read {', '.join(NOTEBOOK_VARIABLES[path.name])} from its kernel")

        p1 = problem_one(values[P1_NOTEBOOK])
        derivation = derivation_markdown(executed[P2_NOTEBOOK])
        if not derivation or derivation.strip() == "YOUR ANSWER HERE":
            step(f"answers: WARNING - no {DERIVATION_TODO} derivation under the {DERIVATION_TODO} heading of {P2_NOTEBOOK} yet")
        p2 = problem_two(values[P2_NOTEBOOK], derivation)
        answers = compute_answers(p1, p2)
        step("figures: drawing " + ", ".join(FIGURES))
        figures = make_figures(p1, p2)
        svgs = {}
        for figure_name in FIGURES:
            path = out_dir / figure_name
            figures[figure_name].savefig(path, format="png", dpi=FIGURE_DPI)
            svgs[figure_name] = figure_svg(figures[figure_name])
            written[figure_name] = path
        markdown_text = answers_markdown(answers, name)
        markdown_path = out_dir / ANSWERS_MD
        markdown_path.write_text(markdown_text, encoding="utf-8")
        written[ANSWERS_MD] = markdown_path
        step(f"answers: written to {markdown_path}")

        # The pages: typeset in Chromium from the installed MathJax, or (no Chromium) with a copy of MathJax beside them.
        if chromium is not None and mathjax is not None:
            mathjax_url, page_dir = (mathjax / "MathJax.js").as_uri(), tmp
        elif mathjax is not None:
            copy_mathjax(out_dir)
            mathjax_url, page_dir = f"{MATHJAX_COPY}/MathJax.js", out_dir
        else:
            mathjax_url, page_dir = None, tmp if chromium is not None else out_dir
        pages = []
        for path in notebooks:
            source = page_dir / f"{path.stem}.html"
            source.write_text(notebook_html(executed[path.name], path.stem, mathjax_url), encoding="utf-8")
            pages.append(Page(source, out_dir / source.name))
        source = page_dir / ANSWERS_HTML
        source.write_text(answers_html(markdown_text, svgs, mathjax_url, name), encoding="utf-8")
        pages.append(Page(source, out_dir / ANSWERS_HTML, out_dir / ANSWERS_PDF if pdf else None))

        if chromium is None:
            step("PDF: SKIPPED - Chromium not found (install Debian's chromium, or set HWLIB_CHROMIUM to its path); "
                 "the HTML pages typeset their formulas when opened, from the mathjax/ folder beside them")
            written.update({page.target.name: page.target for page in pages})
        else:
            step(f"pages: typesetting the formulas{' and printing ' + ANSWERS_PDF if pdf else ''} with {chromium} ...")
            untypeset = render_pages(pages, chromium, name=name, math=mathjax is not None)
            for page in pages:
                written[page.target.name] = page.target
                if page.pdf is not None:
                    written[page.pdf.name] = page.pdf
            if untypeset:
                step(f"pages: WARNING - formulas not typeset in {', '.join(untypeset)} (MathJax did not finish)")
            step(f"pages: written {', '.join(page.target.name for page in pages)}" + (f" and {ANSWERS_PDF}" if pdf else ""))
    step(f"report complete: {len(written)} files in {out_dir}")
    return written


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m hwtools.report",
        description="Execute both notebooks and write the homework report (HTML, PNG figures, answers.md, answers.html, "
                    "answers.pdf) into OUT_DIR.",
    )
    parser.add_argument("out_dir", metavar="OUT_DIR", help="folder to write the report into (created if missing)")
    parser.add_argument("--name", metavar="\"NAME / ANDREW ID\"",
                        help=f"fills the '{NAME_LABEL}' line on every page (left blank to write by hand if not given)")
    parser.add_argument("--no-pdf", action="store_true", help="do not print answers.pdf")
    args = parser.parse_args(argv)
    try:
        build_report(args.out_dir, progress=lambda message: print(message, flush=True), pdf=not args.no_pdf, name=args.name)
    except ReportError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
