"""The homework report in one command: ``python -m hwtools.report OUT_DIR [--name "NAME / ANDREW ID"]``.

Writes into OUT_DIR (created if needed):

| file                                         | what                                                         |
|----------------------------------------------|--------------------------------------------------------------|
| ``p1_cartpole_finite_difference.html``       | problem 1's notebook, executed from a fresh kernel           |
| ``p2_food_cutting_logistic_regression.html`` | problem 2's notebook, likewise                               |
| ``p1_random_policy_histogram.png``           | 1.1.3: rewards of the random policies, the share at the maximum marked |
| ``p1_training_curve.png``                    | 1.3.3: reward per training iteration                         |
| ``p1_learning_rate_sweep.png``               | 1.3.3: share of seeds converging within 7 iterations, per rate |
| ``p2_training_curve.png``                    | 2.3.2: training accuracy per iteration                       |
| ``p2_confusion_matrix.png``                  | 2.3.2: confusion matrix of the test set                      |
| ``p1_*.pdf``, ``p2_*.pdf``                   | the same five figures as PDF, for answers.tex                |
| ``answers.md``                               | every answer the handout asks to report, the 2.1.1 derivation and the figures |
| ``answers.tex``                              | the same as a LaTeX homework, a section per handout item, with places for your words |
| ``answers.html``                             | the same as answers.md, as one self-contained page           |
| ``answers.pdf``                              | answers.html printed by nbconvert's webpdf exporter in Chrome, Edge or Chromium, with page numbers and the name line |

Every result is computed once, by the notebooks: the report reads them from the notebooks' kernels and
never trains, sweeps or samples again. Where to look:

| module        | what it holds                                                                        |
|---------------|--------------------------------------------------------------------------------------|
| ``notebooks`` | running the notebooks and reading their variables and the 2.1.1 Markdown back        |
| ``results``   | those values checked at the door (``ProblemOne``, ``ProblemTwo``)                    |
| ``answers``   | the answers: what is reported, in the notebooks' number formats, and answers.md      |
| ``figures``   | the five figures, drawn by ``hwlib.plots`` and saved as PNG, PDF and SVG             |
| ``latex``     | answers.tex, from ``templates/answers.tex.j2`` (derivation converted by pandoc)      |
| ``pages``     | the HTML pages, by nbconvert's HTMLExporter with ``templates/kit_*``, and MathJax    |
| ``chromium``  | the machine's Chrome, Edge or Chromium: typesetting the pages static, printing answers.pdf |
| ``command``   | ``build_report`` and ``main``, the command itself                                    |

This package's names below are the ones the tests and the rest of the kit use.
"""

from hwtools.report.answers import (
    NAME_BLANK,
    NAME_LABEL,
    answer_text,
    answers_markdown,
    compute_answers,
    describe_episode,
    final_params_text,
    name_line,
    rewards_text,
    tried_params_text,
)
from hwtools.report.chromium import CHROMIUM_ARGS, Page, chromium_path, embed_local_fonts, print_pdf, typeset_pages
from hwtools.report.command import ANSWERS_HTML, ANSWERS_MD, ANSWERS_PDF, build_report, check_name, check_out_dir, main
from hwtools.report.figures import FIGURE_CAPTIONS, FIGURE_DPI, FIGURES, figure_svg, make_figures, pdf_name, save_figure
from hwtools.report.latex import ANSWERS_TEX, answers_latex, derivation_latex, pandoc_available, tex, write_answers_tex
from hwtools.report.notebooks import (
    DERIVATION_TODO,
    KIT_ROOT,
    NOTEBOOK_DIR,
    NOTEBOOK_VARIABLES,
    NOTEBOOKS,
    P1_NOTEBOOK,
    P2_NOTEBOOK,
    VARIABLE_ORIGIN,
    ReportError,
    derivation_markdown,
    execute_notebook,
    export_cell_source,
    notebook_title,
    read_exported,
)
from hwtools.report.pages import (
    MATHJAX_COPY,
    answers_html,
    answers_notebook,
    copy_mathjax,
    css_string,
    mathjax_dir,
    notebook_html,
    page_margins_css,
)
from hwtools.report.results import ProblemOne, ProblemTwo, SweepSummary, problem_one, problem_two

__all__ = [
    "ANSWERS_HTML", "ANSWERS_MD", "ANSWERS_PDF", "ANSWERS_TEX", "CHROMIUM_ARGS", "DERIVATION_TODO", "FIGURES",
    "FIGURE_CAPTIONS", "FIGURE_DPI", "KIT_ROOT", "MATHJAX_COPY", "NAME_BLANK", "NAME_LABEL", "NOTEBOOKS",
    "NOTEBOOK_DIR", "NOTEBOOK_VARIABLES", "P1_NOTEBOOK", "P2_NOTEBOOK", "VARIABLE_ORIGIN", "Page", "ProblemOne",
    "ProblemTwo", "ReportError", "SweepSummary", "answer_text", "answers_html", "answers_latex", "answers_markdown",
    "answers_notebook", "build_report", "check_name", "check_out_dir", "chromium_path", "compute_answers",
    "copy_mathjax", "css_string", "derivation_latex", "derivation_markdown", "describe_episode", "embed_local_fonts",
    "execute_notebook", "export_cell_source", "figure_svg", "final_params_text", "main", "make_figures",
    "mathjax_dir", "name_line", "notebook_html", "notebook_title", "page_margins_css", "pandoc_available",
    "pdf_name", "print_pdf", "problem_one", "problem_two", "read_exported", "rewards_text", "save_figure", "tex",
    "tried_params_text", "typeset_pages", "write_answers_tex",
]
