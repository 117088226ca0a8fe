"""``python -m hwtools.report OUT_DIR``: every file is written, and answers.md holds the library's numbers.

The command runs once per test session (module fixture, about a minute: it executes both
notebooks and redoes their computations); the tests then read what it wrote and compare its
numbers with ``compute_answers()`` and with the library called directly.
"""

from __future__ import annotations

import html
import os
import re
import subprocess
import sys

import nbformat
import numpy as np
import pytest

from hwlib import report

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
REPORT_TIMEOUT = 900  # seconds; the run takes about a minute on 2 cores


@pytest.fixture(scope="module")
def report_and_answers(tmp_path_factory):
    """Run the command as a student would, into a folder that does not exist yet; while it runs
    (in its own process and kernels), compute the answers here for the tests to compare with."""
    out_dir = tmp_path_factory.mktemp("report") / "homework1-report"
    command = [sys.executable, "-m", "hwtools.report", str(out_dir)]
    with subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path_factory.getbasetemp()
    ) as process:
        try:
            answers = report.compute_answers()
            stdout, stderr = process.communicate(timeout=REPORT_TIMEOUT)
        except BaseException:
            process.kill()
            process.communicate()
            raise
    assert process.returncode == 0, f"the report failed:\n{stdout}\n{stderr}"
    return out_dir, stdout, answers


@pytest.fixture(scope="module")
def report_run(report_and_answers):
    out_dir, stdout, _ = report_and_answers
    return out_dir, stdout


@pytest.fixture(scope="module")
def out_dir(report_run):
    return report_run[0]


@pytest.fixture(scope="module")
def answers_md(out_dir):
    return (out_dir / report.ANSWERS_MD).read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def answers(report_and_answers):
    return report_and_answers[2]


def test_progress_is_shown(report_run):
    _, stdout = report_run
    for notebook_index in (1, 2):
        assert f"notebook {notebook_index}/2: executing" in stdout
        assert f"notebook {notebook_index}/2: done" in stdout
    assert "answers: written" in stdout
    assert "report complete" in stdout


@pytest.mark.parametrize("notebook", report.NOTEBOOKS)
def test_executed_notebook_as_html(out_dir, notebook):
    page = (out_dir / notebook.replace(".ipynb", ".html")).read_text(encoding="utf-8")
    assert page.lstrip().lower().startswith("<!doctype html>")
    title = report.notebook_title(report.NOTEBOOK_DIR / notebook)
    assert title in page or html.escape(title) in page, f"the title {title!r} is not in the HTML"
    # Executed with inline figures (MPLBACKEND unset in the kernel): the figures are embedded.
    assert "data:image/png;base64," in page
    assert "Traceback" not in page


@pytest.mark.parametrize("name", report.FIGURES)
def test_figure_png(out_dir, name):
    data = (out_dir / name).read_bytes()
    assert data.startswith(PNG_SIGNATURE), f"{name} is not a PNG"
    assert len(data) > 5_000, f"{name} is suspiciously small ({len(data)} bytes)"


def test_answers_md_links_every_figure(answers_md, out_dir):
    linked = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", answers_md)
    assert sorted(linked) == sorted(report.FIGURES)
    assert all((out_dir / name).is_file() for name in linked)


@pytest.mark.browser
def test_answers_pdf(report_run):
    out_dir, stdout = report_run
    if report.chromium_path() is None:
        if os.environ.get("CI") == "true":
            pytest.fail("Chromium is missing in CI, so answers.pdf was not printed (.ci/run installs Debian's chromium)")
        assert "PDF: SKIPPED" in stdout
        pytest.skip("Chromium is not installed (apt-get install chromium): answers.pdf is not printed here")
    data = (out_dir / report.ANSWERS_PDF).read_bytes()
    assert data.startswith(b"%PDF"), "answers.pdf is not a PDF"
    assert len(data) > 50_000, "answers.pdf should embed the five figures"


# --- the numbers in answers.md --------------------------------------------------------------


def find(pattern, text):
    match = re.search(pattern, text, flags=re.MULTILINE)
    assert match, f"answers.md has no line matching {pattern!r}"
    return match.groups()


def floats(text):
    return [float(value.replace("\u2212", "-")) for value in re.split(r",\s*", text.strip())]


def test_hand_tuning_table(answers_md, answers):
    for entry in answers["p1_hand_tuning"]["tried"]:
        params, behaviour, rewards = find(rf"^\| {re.escape(entry['name'])} \| \(([^)]*)\) \| (.+?) \| ([\d, ]+) \|$", answers_md)
        assert floats(params) == entry["params"]
        assert behaviour == entry["behaviour_seed_0"]
        assert [int(value) for value in floats(rewards)] == entry["rewards"]


def test_random_policy_numbers(answers_md, answers):
    percent, num_at_max, num_policies = find(
        r"Percentage of the random policies that reached the maximum reward of 500: \*\*([\d.]+)%\*\* \((\d+) of (\d+)\)", answers_md
    )
    expected = answers["p1_random_policies"]
    assert float(percent) == expected["percent_at_max"]
    assert int(num_at_max) == expected["num_at_max"]
    assert int(num_policies) == expected["num_policies"] == 1000


def test_training_numbers(answers_md, answers):
    expected = answers["p1_training"]
    (learning_rate,) = find(r"^- Learning rate: \*\*([^*]+)\*\*", answers_md)
    assert float(learning_rate) == expected["learning_rate"]
    (params,) = find(r"^- Final policy parameters: \*\*\[([^\]]+)\]\*\*", answers_md)
    assert floats(params) == pytest.approx(expected["final_params"], abs=5e-5)
    (converged_at,) = find(r"at iteration: \*\*(\d+)\*\*", answers_md)
    assert int(converged_at) == expected["converged_at"]
    (rewards,) = find(r"^- Reward per iteration .*?: ([\d., ]+)$", answers_md)
    assert floats(rewards) == pytest.approx(expected["rewards"])


def test_learning_rate_sweep_table(answers_md, answers):
    expected = answers["p1_learning_rate_sweep"]
    (rates,) = find(r"^\| learning rate \| (.+) \|$", answers_md)
    (fractions,) = find(r"^\| converged \| (.+) \|$", answers_md)
    assert [float(value) for value in rates.split(" | ")] == pytest.approx(expected["learning_rates"], rel=0.05)
    assert [float(value.rstrip("%")) / 100 for value in fractions.split(" | ")] == pytest.approx(expected["converged_fraction"], abs=0.005)


def test_logistic_regression_numbers(answers_md, answers):
    expected = answers["p2_results"]
    (source,) = find(r"^- Data used: \*\*([^*]+)\*\*", answers_md)
    assert source == expected["data_source"]
    (train,) = find(r"^- Final train accuracy: \*\*([\d.]+)\*\*", answers_md)
    (test,) = find(r"^- Test accuracy: \*\*([\d.]+)\*\*", answers_md)
    (first,) = find(r"^- First iteration with train accuracy above 99%: \*\*(\d+|never)\*\*", answers_md)
    assert float(train) == pytest.approx(expected["final_train_accuracy"], abs=5e-5)
    assert float(test) == pytest.approx(expected["test_accuracy"], abs=5e-5)
    assert (None if first == "never" else int(first)) == expected["first_iteration_above_99"]


def test_answers_are_the_library_numbers(answers):
    """compute_answers() against the library called directly, the way the notebooks call it."""
    from hwlib import (
        MultiClassLogisticRegressionClassifier,
        accuracy,
        first_iteration_above,
        load_food_cutting,
        random_policy_rewards,
        train_cartpole_policy,
        train_test_split,
    )
    from hwlib import policy_search

    _, rewards = random_policy_rewards(num_policies=1000, seed=0)
    assert answers["p1_random_policies"]["percent_at_max"] == round(100 * np.mean(rewards == 500), 1)

    run = train_cartpole_policy(
        num_training_iterations=20, num_rollouts_per_eval=20, learning_rate=policy_search.DEFAULT_LEARNING_RATE, seed=0
    )
    training = answers["p1_training"]
    assert training["learning_rate"] == policy_search.DEFAULT_LEARNING_RATE
    assert training["final_params"] == pytest.approx(run.policy.params, abs=5e-5)
    assert training["converged_at"] == policy_search.iterations_to_converge(run.rewards)
    assert training["rewards"] == pytest.approx(run.rewards)

    data = load_food_cutting()
    X_train, X_test, y_train, y_test = train_test_split(data.features, data.labels, test_fraction=0.3, seed=0)
    model = MultiClassLogisticRegressionClassifier(n_features=X_train.shape[1], n_classes=len(data.names))
    train_accuracies = model.fit(X_train, y_train, learning_rate=0.1, n_iters=100)
    food = answers["p2_results"]
    assert food["data_source"] == data.source
    assert food["final_train_accuracy"] == pytest.approx(train_accuracies[-1], abs=5e-5)
    assert food["test_accuracy"] == pytest.approx(accuracy(y_test, model.predict(X_test)), abs=5e-5)
    assert food["first_iteration_above_99"] == first_iteration_above(train_accuracies, 0.99)


# --- bad arguments: no run needed -----------------------------------------------------------


def test_out_dir_that_is_a_file_is_refused(tmp_path, capsys):
    not_a_folder = tmp_path / "report.txt"
    not_a_folder.write_text("a file")
    assert report.main([str(not_a_folder)]) == 1
    error = capsys.readouterr().err
    assert "exists and is not a directory" in error and str(not_a_folder) in error
    assert not_a_folder.read_text() == "a file"


def test_out_dir_under_a_file_is_refused(tmp_path):
    blocker = tmp_path / "blocker"
    blocker.write_text("")
    with pytest.raises(report.ReportError, match="cannot create OUT_DIR"):
        report.check_out_dir(blocker / "report")


def _stored_text(notebook_name):
    """Every printed line of a notebook as it is stored in the kit."""
    notebook = nbformat.read(report.NOTEBOOK_DIR / notebook_name, as_version=4)
    return "\n".join(output.get("text", "") for cell in notebook.cells if cell.cell_type == "code" for output in cell.outputs)


def test_report_settings_match_the_stored_p1_notebook(answers):
    # The report repeats the notebook's settings; this catches one of them changing alone.
    text = _stored_text("p1_cartpole_finite_difference.ipynb")
    random_policies, training = answers["p1_random_policies"], answers["p1_training"]
    assert f"{random_policies['num_at_max']} of {random_policies['num_policies']} random policies" in text
    assert f"learning rate: {training['learning_rate']}" in text
    assert f"converged (500 from then on) at iteration: {training['converged_at']}" in text
    assert f"final parameters: {np.round(training['final_params'], 3).tolist()}" in text
    for rate, fraction in zip(answers["p1_learning_rate_sweep"]["learning_rates"], answers["p1_learning_rate_sweep"]["converged_fraction"]):
        assert f"learning rate {rate:.1e}: {fraction:4.0%} of 20 seeds" in text


def test_report_settings_match_the_stored_p2_notebook(answers):
    results = answers["p2_results"]
    if results["data_source"] != "synthetic stand-in":
        pytest.skip("the stored notebook was run on the stand-in; this machine has the course's file")
    text = _stored_text("p2_food_cutting_logistic_regression.ipynb")
    assert f"final train accuracy: {results['final_train_accuracy']:.3f}" in text
    assert f"test accuracy:        {results['test_accuracy']:.3f}" in text
    assert f"first iteration with train accuracy above 99%: {results['first_iteration_above_99']}" in text
