"""The command ``python -m hwtools.report OUT_DIR [--name "NAME / ANDREW ID"] [--no-pdf]``: ``build_report``
writes the whole report (the steps in order: run the notebooks, check their values, the answers, the
figures, answers.tex, the HTML pages, answers.pdf), saying what it does as it goes; ``main`` is its door.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from pathlib import Path

from hwtools.files import printable_output, scratch_folder
from hwtools.report.answers import NAME_LABEL, answers_markdown, compute_answers
from hwtools.report.chromium import NO_BROWSER, Page, chromium_path, print_pdf, typeset_pages
from hwtools.report.figures import FIGURES, figure_svg, make_figures, save_figure
from hwtools.report.latex import ANSWERS_TEX, answers_latex, write_answers_tex
from hwtools.report.notebooks import (
    DERIVATION_TODO,
    NOTEBOOK_DIR,
    NOTEBOOK_VARIABLES,
    NOTEBOOKS,
    P1_NOTEBOOK,
    P2_NOTEBOOK,
    ReportError,
    derivation_markdown,
    execute_notebook,
    native_kernel_dir,
    read_exported,
)
from hwtools.report.pages import MATHJAX_COPY, answers_html, copy_mathjax, mathjax_dir, notebook_html
from hwtools.report.results import problem_one, problem_two

ANSWERS_MD = "answers.md"
ANSWERS_HTML = "answers.html"
ANSWERS_PDF = "answers.pdf"


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


def _run_notebooks(notebooks, tmp, step):
    """Execute each notebook in a fresh kernel: ({name: executed notebook}, {name: the values its kernel exported})."""
    from nbclient.exceptions import CellExecutionError

    kernel_dir = native_kernel_dir(tmp)
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
    return executed, values


def build_report(out_dir, progress=print, pdf=True, name=None):
    """Write the whole report into ``out_dir``; returns ``{name: path}`` of the files written."""
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
    # The scratch folder (the pages the browser reads among its files) is in OUT_DIR, not the system's temporary
    # folder: Ubuntu's Chromium is a snap, with a /tmp of its own that does not show the system's.
    with scratch_folder(".report-scratch-", out_dir) as tmp:
        executed, values = _run_notebooks(notebooks, tmp, step)
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
            png, figure_pdf = save_figure(figures[figure_name], out_dir, figure_name)
            svgs[figure_name] = figure_svg(figures[figure_name])
            written.update({png.name: png, figure_pdf.name: figure_pdf})
        markdown_text = answers_markdown(answers, name)
        markdown_path = out_dir / ANSWERS_MD
        markdown_path.write_text(markdown_text, encoding="utf-8")
        written[ANSWERS_MD] = markdown_path
        step(f"answers: written to {markdown_path}")

        latex_text, latex_note = answers_latex(answers, name)
        tex_path, kept = write_answers_tex(out_dir, latex_text)
        written[ANSWERS_TEX] = tex_path
        if kept is not None:
            step(f"answers.tex: {kept}")
        step(f"answers.tex: written to {tex_path} (its figures are the PDF files beside it)" + (
            f"; converting the {DERIVATION_TODO} derivation SKIPPED - {latex_note}: it is in answers.tex as the Markdown"
            " you wrote" if latex_note else ""))

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
        pages.append(Page(source, out_dir / ANSWERS_HTML))
        written.update({page.target.name: page.target for page in pages})
        page_names = ", ".join(page.target.name for page in pages)

        if chromium is None:
            step(f"PDF: SKIPPED - {NO_BROWSER}")
            step(f"pages: written {page_names}" + (
                f" (they typeset their formulas when opened, from the {MATHJAX_COPY}/ folder beside them)" if mathjax else ""))
        else:
            step(f"pages: typesetting the formulas with {chromium} ...")
            untypeset = typeset_pages(pages, chromium, math=mathjax is not None)
            if untypeset:
                step(f"pages: WARNING - formulas not typeset in {', '.join(untypeset)} (MathJax did not finish)")
            if pdf:
                step(f"PDF: printing {ANSWERS_PDF} with nbconvert's webpdf exporter in {chromium} ...")
                answers_page = (out_dir / ANSWERS_HTML).read_text(encoding="utf-8")
                written[ANSWERS_PDF] = print_pdf(answers_page, out_dir / ANSWERS_PDF, chromium)
            step(f"pages: written {page_names}" + (f" and {ANSWERS_PDF}" if pdf else ""))
    step(f"report complete: {len(written)} files in {out_dir}")
    return written


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m hwtools.report",
        description="Execute both notebooks and write the homework report (HTML, PNG and PDF figures, answers.md, "
                    "answers.tex, answers.html, answers.pdf) into OUT_DIR.",
    )
    parser.add_argument("out_dir", metavar="OUT_DIR", help="folder to write the report into (created if missing)")
    parser.add_argument("--name", metavar="\"NAME / ANDREW ID\"",
                        help=f"fills the '{NAME_LABEL}' line on every page (left blank to write by hand if not given)")
    parser.add_argument("--no-pdf", action="store_true", help="do not print answers.pdf")
    args = parser.parse_args(argv)
    printable_output()
    try:
        build_report(args.out_dir, progress=lambda message: print(message, flush=True), pdf=not args.no_pdf, name=args.name)
    except ReportError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    return 0
