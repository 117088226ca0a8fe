"""The report's HTML pages, made by nbconvert's HTMLExporter with the kit's two templates (``templates/``): the
executed notebooks (``kit_notebook``, nbconvert's JupyterLab page) and answers.html (``kit_answers``, the
answers notebook built here from answers.md), their formulas set by the local MathJax of the
``jupyter-server-mathjax`` package through nbconvert's own MathJax macro.

The pages load MathJax when opened; ``hwtools.report.chromium`` typesets them once and saves them static.
Without Chromium they stay as written here, next to a copy of MathJax (``copy_mathjax``).
"""

from __future__ import annotations

import re
import shutil
from importlib.util import find_spec
from pathlib import Path

from hwtools.report.answers import TITLE, name_line

TEMPLATES = Path(__file__).resolve().with_name("templates")
MATHJAX_COPY = "mathjax"  # the folder of MathJax written next to the pages when there is no Chromium
# The combined configuration file of MathJax 2 that jupyter-server-mathjax ships (TeX input, HTML-CSS output).
MATHJAX_QUERY = "?config=TeX-AMS-MML_HTMLorMML-full"
# A figure of answers.md: a line of its own, "![caption](name.png)".
FIGURE_LINE = re.compile(r"^!\[([^\]]*)\]\(([^)\s]+\.png)\)$", flags=re.MULTILINE)


def mathjax_dir():
    """The MathJax 2 folder of the ``jupyter-server-mathjax`` package, or None if it is not installed."""
    spec = find_spec("jupyter_server_mathjax")
    if spec is None or not spec.submodule_search_locations:
        return None
    folder = Path(list(spec.submodule_search_locations)[0]) / "static"
    return folder if (folder / "MathJax.js").is_file() else None


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


def exporter(template_name, mathjax_url):
    """nbconvert's HTMLExporter with one of the kit's templates, loading MathJax.js from ``mathjax_url``
    (None: no formulas typeset)."""
    from nbconvert import HTMLExporter

    return HTMLExporter(
        template_name=template_name,
        extra_template_basedirs=[str(TEMPLATES)],  # the templates kit_notebook and kit_answers
        extra_template_paths=[str(TEMPLATES)],  # kit_mathjax.html.j2, which both import
        mathjax_url=mathjax_url + MATHJAX_QUERY if mathjax_url else "",
    )


def notebook_html(notebook, name, mathjax_url):
    """The executed notebook as HTML (JupyterLab's look), its formulas typeset by the MathJax at ``mathjax_url``."""
    body, _ = exporter("kit_notebook", mathjax_url).from_notebook_node(notebook, resources={"metadata": {"name": name}})
    return body


def css_string(text):
    """``text`` as a CSS string, quotes included; safe inside a <style> element (no "</style>" can close it)."""
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("<", "\\3c ").replace(">", "\\3e ")
    return f'"{escaped}"'


def page_margins_css(name):
    """The printed page's margins: the title and the name line at the top, "page N of M" at the bottom (CSS)."""
    return (
        "@page {\n"
        f"  @top-left {{ content: {css_string(TITLE)}; }}\n"
        f"  @top-right {{ content: {css_string(name_line(name))}; }}\n"
        '  @bottom-center { content: "page " counter(page) " of " counter(pages); }\n'
        "}"
    )


def answers_notebook(markdown_text, figures, name=None):
    """answers.md as a notebook: its Markdown in cells, each figure line "![caption](name.png)" an output of
    the SVG in ``figures[name]``; the title names the student (``name_line``)."""
    import nbformat

    cells, start = [], 0
    for match in FIGURE_LINE.finditer(markdown_text):
        cells.append(nbformat.v4.new_markdown_cell(markdown_text[start:match.start()].strip("\n")))
        figure = nbformat.v4.new_output(
            "display_data", data={"image/svg+xml": figures[match.group(2)], "text/plain": match.group(1)}
        )
        cells.append(nbformat.v4.new_code_cell("", outputs=[figure]))
        start = match.end()
    cells.append(nbformat.v4.new_markdown_cell(markdown_text[start:].strip("\n")))
    cells = [cell for cell in cells if cell.cell_type == "code" or cell.source]
    title = f"Homework 1 — answers — {name_line(name)}"
    return nbformat.v4.new_notebook(cells=cells, metadata={"title": title})


def answers_html(markdown_text, figures, mathjax_url, name=None):
    """answers.md as one page: the figures inline as SVG, the formulas typeset by the MathJax at ``mathjax_url``,
    the title and the name line at the top of every printed page and "page N of M" at the bottom."""
    resources = {
        "metadata": {"name": "answers"},
        "kit": {"page_margins": page_margins_css(name)},
    }
    body, _ = exporter("kit_answers", mathjax_url).from_notebook_node(answers_notebook(markdown_text, figures, name),
                                                                       resources=resources)
    return body
