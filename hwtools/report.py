"""The homework report in one command: ``python -m hwtools.report OUT_DIR``.

Writes into OUT_DIR (created if needed):

| file                                   | what                                                         |
|----------------------------------------|--------------------------------------------------------------|
| ``p1_cartpole_finite_difference.html`` | problem 1's notebook, executed from a fresh kernel           |
| ``p2_food_cutting_logistic_regression.html`` | problem 2's notebook, likewise                         |
| ``p1_random_policy_histogram.png``     | 1.1.3: rewards of 1000 random policies                       |
| ``p1_training_curve.png``              | 1.3.3: reward per training iteration                         |
| ``p1_learning_rate_sweep.png``         | 1.3.3: share of seeds converging within 7 iterations, per rate |
| ``p2_training_curve.png``              | 2.3.2: training accuracy per iteration                       |
| ``p2_confusion_matrix.png``            | 2.3.2: confusion matrix of the test set                      |
| ``answers.md``                         | every answer the handout asks to report, with the figures    |
| ``answers.pdf``                        | the same, printed by headless Chromium                       |

The numbers come from ``compute_answers()``, a plain dict built with the same library calls
and seeds as the notebooks; the figures are drawn by the ``hwlib.plots`` functions from the
same inputs. Every random step is seeded, so two runs give the same numbers.

The PDF is printed by Debian's Chromium (``/usr/bin/chromium``, or the path in the environment
variable ``HWLIB_CHROMIUM``) driven by Playwright, which never downloads a browser. Without
Chromium everything else is still written and the command says the PDF was skipped.
"""

from __future__ import annotations

import argparse
import base64
import html
import json
import os
import re
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hwlib import policy_search
from hwlib.cartpole import (
    ALWAYS_LEFT_PARAMS,
    ALWAYS_RIGHT_PARAMS,
    BALANCING_PARAMS,
    MAX_EPISODE_REWARD,
    THETA_THRESHOLD_RADIANS,
    X_THRESHOLD,
    CartPoleLinearPolicy,
    play_episode,
    random_policy_rewards,
    run_policy,
)
from hwlib.food_data import load_food_cutting
from hwlib.logreg import (
    MultiClassLogisticRegressionClassifier,
    accuracy,
    confusion_matrix,
    first_iteration_above,
    train_test_split,
)
from hwlib.plots.training import plot_learning_rate_sweep, plot_reward_histogram, plot_training_curve
from hwlib.plots.food import TARGET_ACCURACY, plot_confusion_matrix, plot_training_accuracy
from hwlib.policy_search import iterations_to_converge, learning_rate_sweep, train_cartpole_policy

KIT_ROOT = Path(__file__).resolve().parent.parent
NOTEBOOK_DIR = KIT_ROOT / "notebooks"
NOTEBOOKS = ("p1_cartpole_finite_difference.ipynb", "p2_food_cutting_logistic_regression.ipynb")
CELL_TIMEOUT = 600  # seconds one notebook cell may take

FIGURES = (
    "p1_random_policy_histogram.png",
    "p1_training_curve.png",
    "p1_learning_rate_sweep.png",
    "p2_training_curve.png",
    "p2_confusion_matrix.png",
)
ANSWERS_MD = "answers.md"
ANSWERS_PDF = "answers.pdf"

# The settings of the notebooks' cells, so that the report shows the notebooks' numbers.
# Problem 1, cell 1.1.2: the parameters tried by hand.
TRIED_PARAMS = {
    "always left": ALWAYS_LEFT_PARAMS,
    "always right": ALWAYS_RIGHT_PARAMS,
    "angle only": (0.0, 0.0, -1.0, 0.0),
    "balancing (hand-tuned)": BALANCING_PARAMS,
}
TRIED_SEEDS = range(5)
# 1.1.3, 1.3.3 and the sweep.
NUM_RANDOM_POLICIES, RANDOM_POLICY_SEED = 1000, 0
NUM_TRAINING_ITERATIONS, NUM_ROLLOUTS_PER_EVAL, TRAINING_SEED = 20, 20, 0
SWEEP_RATES = np.geomspace(1e-4, 1e-2, 8)
SWEEP_SEEDS = 20
# Problem 2: the split and the training of the notebook.
TEST_FRACTION, SPLIT_SEED = 0.3, 0
P2_LEARNING_RATE, P2_NUM_ITERATIONS = 0.1, 100

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


# --- the numbers ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Results:
    """Everything the answers and figures are made of, computed once."""

    random_rewards: np.ndarray
    training_rewards: np.ndarray
    final_params: np.ndarray
    sweep: policy_search.SweepResult
    food_names: tuple
    data_source: str
    data_path: str | None
    num_train: int
    num_test: int
    train_accuracies: np.ndarray
    test_accuracy: float
    test_confusion: np.ndarray


def compute_results(progress=None):
    """Run the computations of both notebooks with their seeds; returns a ``Results``."""
    progress = progress or (lambda message: None)
    if policy_search.DEFAULT_LEARNING_RATE is None:
        raise ReportError("hwlib/policy_search.py: set DEFAULT_LEARNING_RATE to the learning rate you chose (TODO 1.3.3)")
    progress("problem 1: 1000 random policies")
    _, random_rewards = random_policy_rewards(num_policies=NUM_RANDOM_POLICIES, seed=RANDOM_POLICY_SEED)
    progress("problem 1: training with the default learning rate")
    run = train_cartpole_policy(
        num_training_iterations=NUM_TRAINING_ITERATIONS,
        num_rollouts_per_eval=NUM_ROLLOUTS_PER_EVAL,
        learning_rate=policy_search.DEFAULT_LEARNING_RATE,
        seed=TRAINING_SEED,
    )
    progress(f"problem 1: learning-rate sweep ({len(SWEEP_RATES)} rates x {SWEEP_SEEDS} seeds)")
    sweep = learning_rate_sweep(SWEEP_RATES, num_seeds=SWEEP_SEEDS)
    progress("problem 2: loading the data and training the one-vs-rest classifier")
    data = load_food_cutting()
    X_train, X_test, y_train, y_test = train_test_split(data.features, data.labels, test_fraction=TEST_FRACTION, seed=SPLIT_SEED)
    model = MultiClassLogisticRegressionClassifier(n_features=X_train.shape[1], n_classes=len(data.names))
    train_accuracies = model.fit(X_train, y_train, learning_rate=P2_LEARNING_RATE, n_iters=P2_NUM_ITERATIONS)
    test_predictions = model.predict(X_test)
    return Results(
        random_rewards=random_rewards,
        training_rewards=run.rewards,
        final_params=np.asarray(run.policy.params, dtype=float),
        sweep=sweep,
        food_names=tuple(data.names),
        data_source=data.source,
        data_path=None if data.path is None else str(data.path),
        num_train=len(X_train),
        num_test=len(X_test),
        train_accuracies=train_accuracies,
        test_accuracy=accuracy(y_test, test_predictions),
        test_confusion=confusion_matrix(y_test, test_predictions, len(data.names)),
    )


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


def compute_answers(results=None):
    """Every number the handout asks to report, as a plain dict (JSON-serialisable).

    Pass the ``Results`` of ``compute_results()`` to reuse them; by default they are computed.
    """
    results = compute_results() if results is None else results
    tried = []
    for name, params in TRIED_PARAMS.items():
        episode = play_episode(CartPoleLinearPolicy(params), seed=0)
        tried.append({
            "name": name,
            "params": [float(value) for value in params],
            "behaviour_seed_0": describe_episode(episode),
            "rewards": [int(run_policy(CartPoleLinearPolicy(params), seed=seed)) for seed in TRIED_SEEDS],
        })
    random_rewards = results.random_rewards
    num_at_max = int(np.sum(random_rewards == MAX_EPISODE_REWARD))
    converged_at = iterations_to_converge(results.training_rewards)
    train_accuracies = results.train_accuracies
    return {
        "p1_hand_tuning": {"seeds": list(TRIED_SEEDS), "tried": tried},
        "p1_random_policies": {
            "num_policies": len(random_rewards),
            "num_at_max": num_at_max,
            "percent_at_max": round(100.0 * num_at_max / len(random_rewards), 1),
            "median_reward": float(np.median(random_rewards)),
        },
        "p1_training": {
            "learning_rate": float(policy_search.DEFAULT_LEARNING_RATE),
            "num_iterations": NUM_TRAINING_ITERATIONS,
            "num_rollouts_per_eval": NUM_ROLLOUTS_PER_EVAL,
            "rewards": [float(reward) for reward in results.training_rewards],
            "final_params": [round(float(value), 4) for value in results.final_params],
            "converged_at": converged_at,
            "converged_within_7": converged_at is not None and converged_at <= policy_search.CONVERGENCE_DEADLINE,
        },
        "p1_learning_rate_sweep": {
            "learning_rates": [float(rate) for rate in results.sweep.learning_rates],
            "num_seeds": len(results.sweep.seeds),
            "converged_fraction": [float(fraction) for fraction in results.sweep.converged_fraction],
        },
        "p2_results": {
            "data_source": results.data_source,
            "data_file": results.data_path,
            "num_train": results.num_train,
            "num_test": results.num_test,
            "learning_rate": P2_LEARNING_RATE,
            "num_iterations": P2_NUM_ITERATIONS,
            "final_train_accuracy": round(float(train_accuracies[-1]), 4),
            "test_accuracy": round(float(results.test_accuracy), 4),
            "first_iteration_above_99": first_iteration_above(train_accuracies, TARGET_ACCURACY),
        },
    }


# --- the files -----------------------------------------------------------------------------


def save_figures(results, out_dir):
    """The five figures of the handout as PNGs in ``out_dir``; returns their paths."""
    figures = {
        "p1_random_policy_histogram.png": plot_reward_histogram(results.random_rewards),
        "p1_training_curve.png": plot_training_curve(results.training_rewards, learning_rate=policy_search.DEFAULT_LEARNING_RATE),
        "p1_learning_rate_sweep.png": plot_learning_rate_sweep(results.sweep, chosen_learning_rate=policy_search.DEFAULT_LEARNING_RATE),
        "p2_training_curve.png": plot_training_accuracy(results.train_accuracies, target=TARGET_ACCURACY),
        "p2_confusion_matrix.png": plot_confusion_matrix(results.test_confusion, results.food_names),
    }
    paths = []
    for name in FIGURES:
        path = Path(out_dir) / name
        figures[name].savefig(path, format="png", dpi=120)
        paths.append(path)
    return paths


def _params_text(params):
    return "(" + ", ".join(f"{value:g}" for value in params) + ")"


def answers_markdown(answers):
    """answers.md: each handout question that asks for a report item, answered."""
    hand, rand, train = answers["p1_hand_tuning"], answers["p1_random_policies"], answers["p1_training"]
    sweep, food = answers["p1_learning_rate_sweep"], answers["p2_results"]
    seeds = hand["seeds"]
    lines = [
        "# Homework 1 — answers",
        "",
        "Generated by `python -m hwtools.report` from the kit's library, with the seeds the notebooks use;",
        "the executed notebooks are next to this file as HTML.",
        "",
        "## Problem 1: reinforcement learning by finite differences",
        "",
        "### 1.1.2 Parameters tried by hand and the behaviour they gave",
        "",
        "The policy pushes right (action 1) when θᵀs < 0 and left otherwise; s = (cart position, cart velocity,",
        "pole angle, pole angular velocity). Behaviour from the start state of `reset(seed=0)`; rewards of one",
        f"episode from each of the start states of seeds {seeds[0]}–{seeds[-1]}.",
        "",
        f"| parameters tried | θ | what the cart does (seed 0) | rewards, seeds {seeds[0]}–{seeds[-1]} |",
        "|---|---|---|---|",
    ]
    for entry in hand["tried"]:
        rewards = ", ".join(str(reward) for reward in entry["rewards"])
        lines.append(f"| {entry['name']} | {_params_text(entry['params'])} | {entry['behaviour_seed_0']} | {rewards} |")
    lines += [
        "",
        "θ = 0 gives θᵀs = 0, never negative, so the cart is pushed left at every step and the pole falls within about",
        "ten steps. No linear θ pushes right in every state, but θ = (0, −1, 0, 1) keeps pushing right once it starts.",
        "Weighting only the pole angle chases the pole but lets the cart swing; adding negative weights on the",
        "velocities damps the motion, and the hand-tuned θ balances the pole for the full 500 steps.",
        "",
        "### 1.1.3 Random policies",
        "",
        f"- Policies sampled: {rand['num_policies']}, entries uniform in [−1, 1] (seed 0).",
        f"- Percentage of the random policies that reached the maximum reward of 500: **{rand['percent_at_max']:.1f}%**"
        f" ({rand['num_at_max']} of {rand['num_policies']}).",
        f"- Median reward: {rand['median_reward']:g}.",
        "",
        "![Histogram of the rewards of the random policies](p1_random_policy_histogram.png)",
        "",
        "### 1.3.3 Learning rate and learning curve",
        "",
        f"- Learning rate: **{train['learning_rate']:g}**",
        f"- Final policy parameters: **[{', '.join(f'{value:.4f}' for value in train['final_params'])}]**",
        f"- Converged (reward 500 and never below it afterwards) at iteration: **{train['converged_at']}**"
        f" (within 7: {'yes' if train['converged_within_7'] else 'no'})",
        f"- Reward per iteration (iteration 0 is before the first update; each the mean of {train['num_rollouts_per_eval']} episodes):"
        f" {', '.join(f'{reward:g}' for reward in train['rewards'])}",
        "",
        "![Training curve](p1_training_curve.png)",
        "",
        f"How sensitive is this to the learning rate? The share of {sweep['num_seeds']} seeds that converge within 7 iterations:",
        "",
        "| learning rate | " + " | ".join(f"{rate:.1e}" for rate in sweep["learning_rates"]) + " |",
        "|---|" + "---|" * len(sweep["learning_rates"]),
        "| converged | " + " | ".join(f"{fraction:.0%}" for fraction in sweep["converged_fraction"]) + " |",
        "",
        "![Learning-rate sweep](p1_learning_rate_sweep.png)",
        "",
        "## Problem 2: classification by logistic regression",
        "",
        "### 2.3.2 Training curve and accuracy",
        "",
        f"- Data used: **{food['data_source']}** — " + (
            f"read from `{food['data_file']}`." if food["data_file"] else
            "the course's data.npz was not found in the kit's data/ folder, so the kit's synthetic data set with the"
            " same layout was used: these are not the numbers of the real data."
        ),
        f"- Split: {food['num_train']} training and {food['num_test']} test samples (70/30, seed 0);"
        f" learning rate {food['learning_rate']:g}, {food['num_iterations']} iterations from zero weights.",
        f"- Final train accuracy: **{food['final_train_accuracy']:.4f}**",
        f"- Test accuracy: **{food['test_accuracy']:.4f}**",
        "- First iteration with train accuracy above 99%: " + (
            f"**{food['first_iteration_above_99']}**" if food["first_iteration_above_99"] is not None
            else f"**never** within {food['num_iterations']} iterations"
        ),
        "",
        "![Training accuracy per iteration](p2_training_curve.png)",
        "",
        "![Confusion matrix of the test set](p2_confusion_matrix.png)",
        "",
    ]
    return "\n".join(lines)


PDF_STYLE = """
body { font-family: 'DejaVu Sans', 'Liberation Sans', Arial, sans-serif; font-size: 10.5pt; line-height: 1.4; color: #111; }
h1 { font-size: 20pt; margin-bottom: 0.2em; }
h2 { font-size: 15pt; border-bottom: 1px solid #999; padding-bottom: 0.1em; margin-top: 1.4em; }
h3 { font-size: 12pt; margin-top: 1.2em; }
.anchor-link { display: none; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 9.5pt; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.5em; text-align: left; vertical-align: top; }
th { background: #eee; }
td:nth-child(2) { white-space: nowrap; }
img { max-width: 100%; max-height: 11cm; display: block; margin: 0.6em auto; page-break-inside: avoid; }
code { font-family: 'DejaVu Sans Mono', monospace; font-size: 9.5pt; }
"""


def answers_html(markdown_text, image_dir):
    """answers.md as one self-contained HTML page, the PNGs embedded as data URIs."""
    from nbconvert.filters import markdown2html

    body = markdown2html(markdown_text)

    def embed(match):
        path = Path(image_dir) / html.unescape(match.group(1))
        data = base64.b64encode(path.read_bytes()).decode("ascii")
        return f'src="data:image/png;base64,{data}"'

    body = re.sub(r'src="([^"]+\.png)"', embed, body)
    return (
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>Homework 1 — answers</title>"
        f"<style>{PDF_STYLE}</style></head><body>\n{body}\n</body></html>\n"
    )


def print_pdf(page_html, pdf_path, chromium):
    """Print ``page_html`` to ``pdf_path`` with headless Chromium (Playwright, never a download)."""
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="hwlib-report-chromium-") as profile, sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            profile, executable_path=str(chromium), args=CHROMIUM_ARGS, headless=True
        )
        try:
            page = context.new_page()
            page.set_content(page_html, wait_until="load", timeout=60_000)
            page.pdf(
                path=str(pdf_path), format="A4", print_background=True,
                margin={"top": "18mm", "bottom": "18mm", "left": "16mm", "right": "16mm"},
            )
        finally:
            context.close()


def _native_kernel_dir(tmp_dir):
    """A kernelspec folder whose 'python3' is this very Python, whatever other kernels are installed."""
    from ipykernel.kernelspec import get_kernel_dict

    spec_dir = Path(tmp_dir) / "kernels" / "python3"
    spec_dir.mkdir(parents=True)
    spec = get_kernel_dict()  # ipykernel's own spec, with argv[0] = sys.executable
    spec["argv"][0] = sys.executable
    (spec_dir / "kernel.json").write_text(json.dumps(spec))
    return spec_dir.parent


def execute_notebook(path, kernel_dir):
    """Run every cell of the notebook at ``path`` in a fresh kernel started in its folder.

    The kernel is this environment's Python and sees no MPLBACKEND, so figures come out inline
    as a student sees them. Raises ``nbclient.exceptions.CellExecutionError`` if a cell fails.
    """
    import nbformat
    import zmq
    from jupyter_client import KernelManager
    from jupyter_client.kernelspec import KernelSpecManager
    from nbclient import NotebookClient

    notebook = nbformat.read(path, as_version=4)
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
    return notebook


def notebook_html(notebook, name):
    from nbconvert import HTMLExporter

    body, _ = HTMLExporter(template_name="lab").from_notebook_node(notebook, resources={"metadata": {"name": name}})
    return body


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


def build_report(out_dir, progress=print, pdf=True):
    """Write the whole report into ``out_dir``; returns ``{name: path}`` of the files written."""
    from nbclient.exceptions import CellExecutionError

    out_dir = check_out_dir(out_dir)
    notebooks = [NOTEBOOK_DIR / name for name in NOTEBOOKS]
    missing = [str(path) for path in notebooks if not path.is_file()]
    if missing:
        raise ReportError(f"notebook(s) not found: {', '.join(missing)}")
    written = {}
    started = time.monotonic()

    def step(message):
        progress(f"[{time.monotonic() - started:6.1f} s] {message}")

    with tempfile.TemporaryDirectory(prefix="hwlib-report-kernel-") as tmp:
        kernel_dir = _native_kernel_dir(tmp)
        for index, path in enumerate(notebooks, start=1):
            step(f"notebook {index}/{len(notebooks)}: executing {path.name} in a fresh kernel ...")
            begun = time.monotonic()
            try:
                notebook = execute_notebook(path, kernel_dir)
            except CellExecutionError as error:
                raise ReportError(f"{path.name}: a cell failed:\n{error}") from None
            target = out_dir / f"{path.stem}.html"
            target.write_text(notebook_html(notebook, path.stem), encoding="utf-8")
            written[target.name] = target
            step(f"notebook {index}/{len(notebooks)}: done in {time.monotonic() - begun:.1f} s -> {target}")

    results = compute_results(progress=lambda message: step(f"answers: {message}"))
    answers = compute_answers(results)
    step("figures: drawing " + ", ".join(FIGURES))
    for path in save_figures(results, out_dir):
        written[path.name] = path
    markdown_path = out_dir / ANSWERS_MD
    markdown_text = answers_markdown(answers)
    markdown_path.write_text(markdown_text, encoding="utf-8")
    written[ANSWERS_MD] = markdown_path
    step(f"answers: written to {markdown_path}")

    if pdf:
        chromium = chromium_path()
        if chromium is None:
            step("PDF: SKIPPED - Chromium not found (install Debian's chromium, or set HWLIB_CHROMIUM to its path)")
        else:
            step(f"PDF: printing {ANSWERS_PDF} with {chromium} ...")
            pdf_path = out_dir / ANSWERS_PDF
            print_pdf(answers_html(markdown_text, out_dir), pdf_path, chromium)
            written[ANSWERS_PDF] = pdf_path
            step(f"PDF: written to {pdf_path}")
    step(f"report complete: {len(written)} files in {out_dir}")
    return written


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m hwtools.report",
        description="Execute both notebooks and write the homework report (HTML, PNG figures, answers.md, answers.pdf) into OUT_DIR.",
    )
    parser.add_argument("out_dir", metavar="OUT_DIR", help="folder to write the report into (created if missing)")
    parser.add_argument("--no-pdf", action="store_true", help="do not print answers.pdf (no Chromium needed)")
    args = parser.parse_args(argv)
    try:
        build_report(args.out_dir, progress=lambda message: print(message, flush=True), pdf=not args.no_pdf)
    except ReportError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
