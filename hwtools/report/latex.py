"""answers.tex: the report as a LaTeX homework a student adds prose to, rendered from ``templates/answers.tex.j2``
with the numbers of ``answer_text`` (escaped for LaTeX by nbconvert's ``escape_latex``), the figures as the
PDF files beside it, and the 2.1.1 derivation converted from the student's Markdown cell by pandoc (through
nbconvert's ``markdown2latex``, the filter of its own LaTeX exporter).

It compiles with pdfLaTeX from Debian's texlive-latex-base and texlive-latex-recommended (and on Overleaf).
A rerun never destroys a student's words: they are carried into the new answers.tex, or their file is
kept as it is and the new text written beside it (``words.py``).
"""

from __future__ import annotations

import re
from pathlib import Path

from hwtools.report.answers import SYNTHETIC_NOTE, answer_text
from hwtools.report.figures import FIGURE_CAPTIONS, pdf_name
from hwtools.report.notebooks import DERIVATION_TODO
from hwtools.report.words import ANSWERS_TEX, write_answers

TEMPLATES = Path(__file__).resolve().with_name("templates")
# Pandoc's reader for a Jupyter Markdown cell, as nbconvert's LaTeX template reads one: $...$, $$...$$ and
# \\(...\\) math, lists without a blank line before them.
MARKDOWN_READER = "markdown+lists_without_preceding_blankline+tex_math_double_backslash"
NAME_RULE = r"\rule{50mm}{0.4pt}"  # the name line to fill in by hand, without --name
# Characters the report's own text uses that pdfLaTeX's fonts may lack, in LaTeX.
UNICODE_TEX = {
    "—": "---", "–": "--", "°": r"\ensuremath{^\circ}", "θ": r"\ensuremath{\theta}", "ᵀ": r"\ensuremath{^\top}",
    "±": r"\ensuremath{\pm}", "×": r"\ensuremath{\times}", "≤": r"\ensuremath{\le}", "≥": r"\ensuremath{\ge}",
    "→": r"\ensuremath{\to}", "<": r"\textless{}", ">": r"\textgreater{}", "|": r"\textbar{}",
    "^": r"\textasciicircum{}",  # nbconvert's \^{} prints a modifier letter, not the caret
}


def tex(text):
    """Plain text as LaTeX: the characters of ``UNICODE_TEX`` as it says, the others through nbconvert's
    ``escape_latex``; a minus sign before a digit is kept on the line of its number."""
    from nbconvert.filters import escape_latex

    text, pieces = str(text), []
    for index, character in enumerate(text):
        if character == "-" and text[index + 1:index + 2].isdigit():
            pieces.append(r"\mbox{-}")
        else:
            pieces.append(UNICODE_TEX.get(character) or escape_latex(character))
    return "".join(pieces)


def _tex_all(value):
    """``tex`` of every string in ``value`` (nested dicts and lists); None stays None."""
    if value is None:
        return None
    if isinstance(value, dict):
        return {key: _tex_all(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_tex_all(item) for item in value]
    return tex(value)


def pandoc_available():
    """Whether nbconvert finds pandoc (the 2.1.1 derivation is converted with it; nbconvert itself warns if its
    version is not one it knows, and goes on)."""
    from nbconvert.utils.pandoc import PandocMissing, get_pandoc_version

    try:
        get_pandoc_version()
    except PandocMissing:
        return False
    return True


def derivation_latex(markdown):
    """The 2.1.1 derivation (Markdown with MathJax math) as LaTeX, and None; or, without pandoc, the Markdown as a
    verbatim block and a note saying so. A missing derivation is said in the text."""
    if not markdown:
        return rf"\emph{{(not found: the notebook has no {DERIVATION_TODO} heading with an answer under it)}}", None
    if pandoc_available():
        from nbconvert.filters import markdown2latex

        converted = markdown2latex(markdown, markup=MARKDOWN_READER, extra_args=["--wrap=preserve"]).strip()
        if converted:
            return converted, None
        note = "pandoc gave no LaTeX for it"
    else:
        note = "pandoc was not found (apt-get install pandoc)"
    verbatim = markdown.replace(r"\end{verbatim}", r"\end {verbatim}")
    text = (f"% The {DERIVATION_TODO} derivation as you wrote it in Markdown: {note}. Run the report again with pandoc,\n"
            f"% or write it here in LaTeX.\n\\begin{{verbatim}}\n{verbatim}\n\\end{{verbatim}}")
    return text, note


def answers_latex(answers, name=None):
    """answers.tex's text (without its stamp line) and the note of ``derivation_latex`` (None if converted)."""
    import jinja2

    text = _tex_all(answer_text(answers))
    text["sweep"] = list(zip(text["sweep_rates"], text["sweep_converged"], strict=True))
    data_file = answers["p2_results"]["data_file"]
    text["data_note"] = rf"read from \texttt{{{tex(data_file)}}}." if data_file else tex(SYNTHETIC_NOTE)
    derivation, note = derivation_latex(answers["p2_derivation"])
    environment = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(TEMPLATES)), undefined=jinja2.StrictUndefined, keep_trailing_newline=True,
        block_start_string="((*", block_end_string="*))", variable_start_string="(((", variable_end_string=")))",
        comment_start_string="((=", comment_end_string="=))",
    )
    rendered = environment.get_template("answers.tex.j2").render(
        t=text, derivation=derivation, name=tex(name) if name else NAME_RULE,
        figure_pdfs={png: pdf_name(png) for png in FIGURE_CAPTIONS},
        captions={png: tex(caption) for png, caption in FIGURE_CAPTIONS.items()},
    )
    return rendered.lstrip("\n"), note


def write_answers_tex(out_dir, text, words_from=None):
    """Write answers.tex of ``text`` into OUT_DIR, keeping the student's words from the answers.tex there (or in
    ``words_from``): ``words.write_answers``. Returns (answers.tex, the sentence saying how their words were kept,
    or None)."""
    note = write_answers(out_dir, text, words_from)
    return Path(out_dir) / ANSWERS_TEX, note
