"""The five figures the handout asks for, drawn by ``hwlib.plots`` from the notebooks' values (never computed
again), and saved three ways: PNG files (answers.md), PDF files beside answers.tex, and inline SVG for
answers.html (text kept as text, so the PDF's figure labels can be searched).
"""

from __future__ import annotations

import io
from pathlib import Path

from hwlib.logreg import confusion_matrix
from hwlib.plots.food import plot_confusion_matrix, plot_training_accuracy
from hwlib.plots.training import plot_learning_rate_sweep, plot_reward_histogram, plot_training_curve

# The figures, in the order of the answers: PNG file name -> what it shows (the caption).
FIGURE_CAPTIONS = {
    "p1_random_policy_histogram.png": "Histogram of the rewards of the random policies",
    "p1_training_curve.png": "Training curve",
    "p1_learning_rate_sweep.png": "Learning-rate sweep",
    "p2_training_curve.png": "Training accuracy per iteration",
    "p2_confusion_matrix.png": "Confusion matrix of the test set",
}
FIGURES = tuple(FIGURE_CAPTIONS)
FIGURE_DPI = 150


def make_figures(p1, p2):
    """The five figures of the handout, ``{file name: Figure}``, drawn from ``ProblemOne`` and ``ProblemTwo``."""
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


def pdf_name(png_name):
    """The PDF file beside answers.tex that holds the figure of ``png_name``."""
    return Path(png_name).with_suffix(".pdf").name


def save_figure(figure, out_dir, png_name):
    """Write the figure as ``png_name`` and as its PDF (text kept as text, no date: the same bytes every run);
    returns the two paths."""
    png, pdf = Path(out_dir) / png_name, Path(out_dir) / pdf_name(png_name)
    figure.savefig(png, format="png", dpi=FIGURE_DPI)
    figure.savefig(pdf, format="pdf", metadata={"CreationDate": None})
    return png, pdf


def figure_svg(figure):
    """The figure as inline SVG with its text kept as text (searchable in the PDF), same ids every run."""
    import matplotlib

    buffer = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "hwtools-report"}):
        figure.savefig(buffer, format="svg", metadata={"Date": None})
    svg = buffer.getvalue()
    return svg[svg.index("<svg"):]
