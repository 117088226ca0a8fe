"""The Chrome, Edge or Chromium this machine has (``chromium_path``), driven by Playwright (which never downloads a
browser here): ``typeset_pages`` typesets the
report's HTML pages once and saves them static (formulas as HTML, MathJax's fonts embedded, no script), and
``print_pdf`` prints answers.pdf from the saved page with nbconvert's ``webpdf`` exporter.

nbconvert's exporter has no setting for the browser it starts nor for the paper: it calls Playwright's
``launch`` without a path, and its ``pdf`` with Playwright's default paper (US Letter). ``print_pdf`` runs it
with those two defaults changed, and nothing else: the browser is the machine's (``chromium_path``), and the paper
is the page's own CSS size (A4, in templates/kit_answers/static/answers.css).
"""

from __future__ import annotations

import base64
import os
import re
import shutil
import sys
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlparse
from urllib.request import url2pathname

from hwtools.files import scratch_folder

# The browser, started the way a closed network needs (no background traffic).
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
PAGE_TIMEOUT_MS = 120_000  # loading a page, and typesetting its formulas

# Run in the typeset page before it is saved: no script is left (the page needs none), nor MathJax's helpers.
STATIC_PAGE_JS = """() => {
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
FONT_TYPES = {"woff": "font/woff", "woff2": "font/woff2", "otf": "font/otf", "ttf": "font/ttf"}


# The browsers that print the PDF, where each system installs them, tried in the order of browser_candidates():
# macOS's apps below /Applications and ~/Applications, Windows's programs below the folders these variables name,
# Linux's names on PATH, then in the folders of Debian's and Ubuntu's packages and snaps, then Google's and
# Microsoft's own packages' folders.
MAC_APPS = ("Google Chrome.app/Contents/MacOS/Google Chrome", "Chromium.app/Contents/MacOS/Chromium",
            "Microsoft Edge.app/Contents/MacOS/Microsoft Edge")
WINDOWS_FOLDERS = ("PROGRAMFILES", "PROGRAMFILES(X86)", "LOCALAPPDATA")
WINDOWS_PROGRAMS = ("Google/Chrome/Application/chrome.exe", "Microsoft/Edge/Application/msedge.exe",
                    "Chromium/Application/chrome.exe")
LINUX_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "microsoft-edge",
               "microsoft-edge-stable")
LINUX_FOLDERS = ("/usr/bin", "/snap/bin", "/var/lib/flatpak/exports/bin")  # Debian's and Ubuntu's packages, snaps
LINUX_PROGRAMS = ("/opt/google/chrome/chrome", "/opt/microsoft/msedge/msedge")  # Google's and Microsoft's packages
NO_BROWSER = ("no Chrome, Edge or Chromium found: install one (or set HWLIB_CHROMIUM to its program) and run this "
              "again, or compile answers.tex (pdflatex answers.tex)")


def browser_candidates():
    """The programs ``chromium_path`` tries, in order, on this system (``sys.platform``)."""
    if sys.platform == "darwin":
        return [Path(folder, app) for folder in ("/Applications", Path.home() / "Applications") for app in MAC_APPS]
    if sys.platform == "win32":
        return [Path(os.environ[folder], *program.split("/")) for folder in WINDOWS_FOLDERS if os.environ.get(folder)
                for program in WINDOWS_PROGRAMS]
    return [Path(found) for found in map(shutil.which, LINUX_NAMES) if found] + [
        Path(folder, name) for folder in LINUX_FOLDERS for name in LINUX_NAMES] + [Path(program) for program in LINUX_PROGRAMS]


def chromium_path():
    """The Chrome, Edge or Chromium that prints the PDF, or None: ``$HWLIB_CHROMIUM`` if set (and then only it),
    else the first of ``browser_candidates()`` there is."""
    chosen = os.environ.get("HWLIB_CHROMIUM")
    for candidate in [Path(chosen)] if chosen else browser_candidates():
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return candidate
    return None


def file_path(url):
    """The path a ``file:`` URL names, by the standard library's own conversion for this system
    (``url2pathname``: ``file:///C:/Users/...`` is ``C:\\Users\\...`` on Windows, not ``/C:/Users/...``)."""
    return Path(url2pathname(urlparse(url).path))


def embed_local_fonts(page_html):
    """``page_html`` with every local font file it refers to (MathJax's) embedded as a data URI; a font that is
    not there is dropped (an empty data URI), so that the saved page names no file of this machine."""

    def embed(match):
        path = file_path(match.group(2))
        if not path.is_file():
            return "url(data:,)"
        mime = FONT_TYPES[path.suffix.lstrip(".")]
        return f"url(data:{mime};base64,{base64.b64encode(path.read_bytes()).decode('ascii')})"

    return LOCAL_FONT_URL.sub(embed, page_html)


@dataclass(frozen=True)
class Page:
    """One HTML page to typeset in Chromium: read ``source`` (with MathJax), save the static result to ``target``."""

    source: Path
    target: Path


def typeset_pages(pages, chromium, math=True):
    """Typeset and save every page in one headless Chromium; returns the names of pages whose formulas did not typeset.

    ``math``: wait for the page's MathJax to mark it typeset (templates/kit_mathjax.html.j2); False when
    there is no MathJax.
    """
    from playwright.sync_api import Error as PlaywrightError
    from playwright.sync_api import sync_playwright

    untypeset = []
    # The browser's profile beside the pages (a snap's /tmp is its own), removed without a fuss where Windows
    # still holds a file of it a moment after the browser closed.
    with scratch_folder(".chromium-profile-", pages[0].source.parent) as profile, sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            str(profile), executable_path=str(chromium), args=CHROMIUM_ARGS, headless=True
        )
        # Only the local files load: anything else a page asks for is cut off at once.
        context.route(re.compile(r"^(?!file:)"), lambda route: route.abort())
        try:
            for page_spec in pages:
                page = context.new_page()
                page.goto(page_spec.source.as_uri(), wait_until="load", timeout=PAGE_TIMEOUT_MS)
                if math:
                    try:
                        page.wait_for_function("document.documentElement.getAttribute('data-math') === 'typeset'",
                                               timeout=PAGE_TIMEOUT_MS)
                    except PlaywrightError:
                        untypeset.append(page_spec.target.name)
                page.evaluate(STATIC_PAGE_JS)
                page_spec.target.write_text(embed_local_fonts(page.content()), encoding="utf-8")
                page.close()
        finally:
            context.close()
    return untypeset


@contextmanager
def _playwright_defaults(chromium):
    """While nbconvert's webpdf exporter runs: Playwright's ``launch`` starts ``chromium`` and its ``pdf`` takes the
    page's CSS paper size, where nbconvert passes neither. Meanwhile PLAYWRIGHT_BROWSERS_PATH names an empty
    folder, so that a browser Playwright downloaded can never stand in for the machine's."""
    from playwright.async_api import BrowserType, Page as PlaywrightPage

    launch, pdf = BrowserType.launch, PlaywrightPage.pdf

    async def launch_chromium(self, *args, **kwargs):
        kwargs.setdefault("executable_path", str(chromium))
        return await launch(self, *args, **kwargs)

    async def pdf_at_css_size(self, *args, **kwargs):
        kwargs.setdefault("prefer_css_page_size", True)
        return await pdf(self, *args, **kwargs)

    saved_path = os.environ.get("PLAYWRIGHT_BROWSERS_PATH")
    with scratch_folder("hwtools-report-no-browsers-") as no_browsers:
        os.environ["PLAYWRIGHT_BROWSERS_PATH"] = str(no_browsers)
        BrowserType.launch, PlaywrightPage.pdf = launch_chromium, pdf_at_css_size
        try:
            yield
        finally:
            BrowserType.launch, PlaywrightPage.pdf = launch, pdf
            if saved_path is None:
                os.environ.pop("PLAYWRIGHT_BROWSERS_PATH", None)
            else:
                os.environ["PLAYWRIGHT_BROWSERS_PATH"] = saved_path


def print_pdf(page_html, pdf_path, chromium):
    """Print the static page ``page_html`` (typeset, nothing to load) to ``pdf_path`` with nbconvert's webpdf
    exporter in ``chromium``: the paper, the margins and the page's header and footer are the page's CSS."""
    from nbconvert.exporters.webpdf import WebPDFExporter

    browser_args = [arg for arg in CHROMIUM_ARGS if arg not in ("--headless", "--no-sandbox")]  # Playwright and
    exporter = WebPDFExporter(disable_sandbox=True, browser_args=browser_args)  # disable_sandbox add these two
    with _playwright_defaults(chromium):
        pdf_data = exporter.run_playwright(page_html)
    Path(pdf_path).write_bytes(pdf_data)
    return Path(pdf_path)
