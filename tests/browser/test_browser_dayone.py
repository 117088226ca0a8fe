"""Day one in JupyterLab, as a student sees it (headless Chromium, 1280 x 720, file browser open).

- **Quick start.** JupyterLab serves the kit's folder, as the README's command starts it: one
  click on the file browser's root shows ``hwlib/`` beside ``notebooks/``, and one click on a
  TODO's link (1.1.1's, 1.3.2's) opens its file in an editor tab, scrolled to the TODO: its comment
  and stub on screen, with the function's ``def`` line above them.
- **Notebook 7**, under a JupyterHub's base URL: a TODO's second link ("VS Code: line N", the form VS Code
  follows) opens its file, read-only, in a new browser tab (Notebook 7's way for a file it does not edit
  from a link; its students open the file from its file browser to edit it: docs/student-README.md).
- **The untouched student edition.** Run All stops at the first cell that needs a TODO; its
  output, on screen without scrolling, begins with "TODO 1.1.1 is not done yet". Then every
  code cell is run in turn (Shift+Enter, as a student steps through): each cell that needs a
  TODO shows "TODO x.y.z is not done yet" on the first line of its output, check cells included,
  and the cells that need none run.
- **The check cells** of the instructor's edition show every visible check passing.

Error outputs are read by their text, whatever mime type JupyterLab renders them with. The kit
under test is imported by the kernels through ``PYTHONPATH`` (the server's environment), so the
untouched edition's stubs are what runs. Chromium is Debian's; without it the tests are skipped,
except in CI (CI=true), where that is a failure. ``pytest -m "not browser"`` leaves them out.
"""

from __future__ import annotations

import contextlib
import re
import shutil
import time
import urllib.parse
from pathlib import Path

import pytest

from lab_under_test import running_jupyterlab
from test_browser import ARTIFACTS, browser, chromium, menu, screenshot_on_failure  # noqa: F401 (fixtures by name)

pytestmark = pytest.mark.browser

KIT = Path(__file__).resolve().parents[2]
P1, P2 = "p1_cartpole_finite_difference.ipynb", "p2_food_cutting_logistic_regression.ipynb"
TIMEOUT_MS = 240_000  # one notebook's Run All on a busy 2-core machine
CELL_TIMEOUT_MS = 120_000  # one cell
NOT_DONE = re.compile(r"^TODO \d+\.\d+\.\d+ is not done yet: ")
# Code cells that need no TODO (by their first line): they run on day one.
NEEDS_NO_TODO = ("%matplotlib inline", "env = cartpole.make_env()", "### BEGIN TODO 1.1.2")


@pytest.fixture(scope="module")
def day_one_kit(tmp_path_factory):
    from day_one import day_one_edition

    return day_one_edition(tmp_path_factory.mktemp("day-one") / "kit", tmp_path_factory)


@pytest.fixture(scope="module")
def day_one_lab(chromium, day_one_kit, tmp_path_factory):
    """JupyterLab on the untouched student edition, served from its root as the quick start does;
    its kernels import that edition (PYTHONPATH, set only while the server starts)."""
    with contextlib.ExitStack() as stack:
        with pytest.MonkeyPatch.context() as patch:
            patch.setenv("PYTHONPATH", str(day_one_kit))
            lab = stack.enter_context(running_jupyterlab(day_one_kit, tmp_path_factory.mktemp("lab-state")))
        yield lab


@pytest.fixture(scope="module")
def day_one_notebook7(chromium, day_one_kit, tmp_path_factory):
    """Notebook 7 (``jupyter notebook``) on the untouched student edition, under a JupyterHub user's base URL."""
    with running_jupyterlab(day_one_kit, tmp_path_factory.mktemp("notebook7-state"), app="notebook",
                            prefix="/user/student/") as server:
        yield server


@pytest.fixture(scope="module")
def instructor_lab(chromium, tmp_path_factory):
    """JupyterLab on a copy of the instructor's notebooks (the kernels import this kit)."""
    root = tmp_path_factory.mktemp("lab-root")
    shutil.copytree(KIT / "notebooks", root / "notebooks", ignore=shutil.ignore_patterns(".ipynb_checkpoints"))
    with running_jupyterlab(root, tmp_path_factory.mktemp("lab-state")) as lab:
        yield lab


@pytest.fixture()
def page(browser):
    page = browser.new_page()
    page.set_default_timeout(CELL_TIMEOUT_MS)
    yield page
    with contextlib.suppress(Exception):
        page.close()


def shut_kernels(lab):
    with contextlib.suppress(Exception):
        for kernel in lab.api("GET", "/api/kernels") or []:
            lab.api("DELETE", f"/api/kernels/{kernel['id']}")


# --- driving JupyterLab ------------------------------------------------------------------------

IDLE = re.compile(r"\| Idle$")


def wait_idle(page, timeout=CELL_TIMEOUT_MS):
    page.locator("#jp-main-statusbar .jp-StatusBar-TextItem", has_text=IDLE).first.wait_for(timeout=timeout)
    page.wait_for_function("() => ![...document.querySelectorAll('.jp-NotebookPanel .jp-InputPrompt')]"
                           ".some(p => p.textContent.trim() === '[*]:')", timeout=timeout, polling=200)


def open_notebook(page, lab, name):
    page.goto(lab.url(f"notebooks/{name}"), timeout=TIMEOUT_MS)
    page.locator(".jp-NotebookPanel .jp-Notebook .jp-Cell").first.wait_for(timeout=TIMEOUT_MS)
    wait_idle(page, TIMEOUT_MS)


CELLS_JS = """() => {
    const area = document.querySelector('.jp-NotebookPanel .jp-WindowedPanel-outer')
        || document.querySelector('.jp-NotebookPanel .jp-Notebook');
    const view = area.getBoundingClientRect();
    return [...document.querySelectorAll('.jp-NotebookPanel .jp-CodeCell')].map(cell => {
        const output = cell.querySelector('.jp-OutputArea');
        const box = output ? output.getBoundingClientRect() : null;
        return {
            source: cell.querySelector('.jp-InputArea .cm-content')?.innerText ?? '',
            prompt: cell.querySelector('.jp-InputPrompt')?.textContent.trim() ?? '',
            output: output ? output.innerText : '',
            onScreen: !!box && box.height > 0 && box.top >= view.top && box.top + 24 <= view.bottom,
        };
    });
}"""


def cells(page):
    found = page.evaluate(CELLS_JS)
    for cell in found:
        cell["lines"] = [line for line in cell["output"].splitlines() if line.strip()]
    return found


def run_all(page):
    menu(page, "Edit", "Clear Outputs of All Cells")
    menu(page, "Run", "Run All Cells")
    page.wait_for_timeout(500)
    wait_idle(page, TIMEOUT_MS)
    return cells(page)


def first_line_names_a_todo(cell):
    return bool(cell["lines"]) and bool(NOT_DONE.match(cell["lines"][0]))


# --- the tests ---------------------------------------------------------------------------------


# A TODO's link by the code its cell names, the file it opens and what must then be on screen in
# the editor: the function's def line, the TODO's comment and its stub's last line.
LINKS = [("CartPoleLinearPolicy.__call__", "cartpole.py", ("def __call__(", "# TODO 1.1.1:", 'raise TodoNotDone("1.1.1")')),
         ("the loop of train_cartpole_policy", "policy_search.py",
          ("def train_cartpole_policy(", "# TODO 1.3.2:", 'raise TodoNotDone("1.3.2")'))]

EDITOR_LINES_ON_SCREEN_JS = """() => {
    const editor = [...document.querySelectorAll('.jp-FileEditor')].find(element => element.offsetParent !== null);
    if (!editor) return [];
    const view = editor.querySelector('.cm-scroller').getBoundingClientRect();
    return [...editor.querySelectorAll('.cm-line')].filter(line => {
        const box = line.getBoundingClientRect();
        return box.height > 0 && box.top >= view.top && box.bottom <= view.bottom;
    }).map(line => line.textContent);
}"""


def editor_lacks(page, wanted, timeout_s=10):
    """(those of ``wanted`` that begin no line of the editor on screen, whole lines only; those lines),
    once none is missing or at the timeout."""
    deadline = time.monotonic() + timeout_s
    while True:
        shown = page.evaluate(EDITOR_LINES_ON_SCREEN_JS)
        missing = [text for text in wanted if not any(line.strip().startswith(text) for line in shown)]
        if not missing or time.monotonic() > deadline:
            return missing, shown
        page.wait_for_timeout(200)


def test_quick_start_serves_the_kit_so_hwlib_is_one_click_away(page, day_one_lab):
    with screenshot_on_failure(page, "dayone-quick-start"):
        open_notebook(page, day_one_lab, P1)
        # The file browser opens on the notebook's folder; one click on its root shows the kit.
        page.locator(".jp-BreadCrumbs-home").first.click()
        listing = page.locator(".jp-DirListing-content .jp-DirListing-itemText")
        listing.filter(has_text=re.compile(r"^hwlib$")).first.wait_for()
        assert {"hwlib", "notebooks"} <= set(listing.all_inner_texts()), listing.all_inner_texts()
        for code, file, wanted in LINKS:
            page.locator(".lm-TabBar-tab .lm-TabBar-tabLabel", has_text=P1).first.click()  # back to the notebook
            cell = page.locator(".jp-NotebookPanel .jp-RenderedMarkdown", has_text=code).first
            link = cell.locator("a", has_text=f"hwlib/{file}").first
            link.scroll_into_view_if_needed()
            link.click()
            tab = page.locator(".lm-TabBar-tab .lm-TabBar-tabLabel", has_text=re.compile(rf"^{re.escape(file)}$"))
            tab.first.wait_for()
            # The link's #line= fragment scrolled the editor to the TODO (once the file has loaded):
            # its comment and stub on screen, and the function they are in above them.
            missing, shown = editor_lacks(page, wanted)
            assert not missing, f"{file}: {missing} not on screen; the editor shows {shown}"
    shut_kernels(day_one_lab)


def test_notebook7_link_opens_the_todos_file_under_a_hub_base_url(page, day_one_notebook7):
    """Notebook 7 opens a link to a file that is not a notebook in a new tab, read-only (its ``/tree/`` page
    sends a file to ``/files/``); the TODO's second link, resolved under the base URL, shows the TODO's code."""
    with screenshot_on_failure(page, "dayone-notebook7"):
        page.goto(day_one_notebook7.url(f"notebooks/{P1}"), timeout=TIMEOUT_MS)
        cell = page.locator(".jp-RenderedMarkdown", has_text="CartPoleLinearPolicy.__call__").first
        link = cell.locator("a", has_text=re.compile(r"^line \d+$")).first
        link.wait_for(timeout=TIMEOUT_MS)
        with page.context.expect_page() as opened:
            link.click()
        shown = opened.value
        try:
            shown.wait_for_load_state(timeout=TIMEOUT_MS)
            assert urllib.parse.urlsplit(shown.url).path == "/user/student/files/hwlib/cartpole.py", shown.url
            assert 'raise TodoNotDone("1.1.1")' in shown.locator("body").inner_text(timeout=CELL_TIMEOUT_MS)
        finally:
            shown.close()
    shut_kernels(day_one_notebook7)


def test_day_one_run_all_stops_at_the_first_todo_and_says_which_on_screen(page, day_one_lab):
    with screenshot_on_failure(page, "dayone-run-all"):
        open_notebook(page, day_one_lab, P1)
        shown = run_all(page)
        ran = [cell for cell in shown if re.fullmatch(r"\[\d+\]:", cell["prompt"])]
        stopped = ran[-1]
        on_screen_after_run_all = cells(page)[len(ran) - 1]["onScreen"]
        assert stopped["source"].startswith("policy = CartPoleLinearPolicy"), [cell["source"][:40] for cell in ran]
        assert first_line_names_a_todo(stopped) and stopped["lines"][0].startswith("TODO 1.1.1"), stopped["lines"][:6]
        assert len(stopped["lines"]) == 2, stopped["lines"]  # two lines, no traceback
        assert on_screen_after_run_all, "after Run All the message is not on screen: the student must scroll to it"
        assert all(cell["prompt"] in ("[ ]:", "") for cell in shown[len(ran):]), "Run All went on after the first TODO"
        ARTIFACTS.mkdir(exist_ok=True)
        page.screenshot(path=str(ARTIFACTS / "dayone-run-all.png"))
    shut_kernels(day_one_lab)


def test_day_one_every_cell_that_needs_a_todo_names_it_on_its_first_line(page, day_one_lab):
    """Shift+Enter through every code cell of problem 1, as a student steps through on day one."""
    with screenshot_on_failure(page, "dayone-step-through"):
        open_notebook(page, day_one_lab, P1)
        menu(page, "Edit", "Clear Outputs of All Cells")
        code = page.locator(".jp-NotebookPanel .jp-CodeCell")
        total = code.count()
        code.first.locator(".jp-InputPrompt").click()
        unnamed = []
        for index in range(total):
            cell = code.nth(index)
            cell.locator(".jp-InputPrompt").click()
            page.keyboard.press("Shift+Enter")
            page.wait_for_timeout(200)
            wait_idle(page)
            shown = cells(page)[index]
            if shown["source"].startswith(NEEDS_NO_TODO):
                if any(line.startswith("TODO ") for line in shown["lines"]):
                    unnamed.append(f"cell {index} needs no TODO but says {shown['lines'][:2]}")
            elif not first_line_names_a_todo(shown):
                unnamed.append(f"cell {index} ({shown['source'][:50]!r}) shows {shown['lines'][:3]}")
            elif shown["source"].startswith("check(") and len(shown["lines"]) > 3:
                unnamed.append(f"check cell {index} prints {len(shown['lines'])} lines on day one")
        assert total >= 25
        assert not unnamed, "\n".join(unnamed)
    shut_kernels(day_one_lab)


def test_check_cells_show_every_visible_check_passing_in_the_instructors_edition(page, instructor_lab):
    with screenshot_on_failure(page, "dayone-check-cells"):
        open_notebook(page, instructor_lab, P2)
        code = page.locator(".jp-NotebookPanel .jp-CodeCell")
        sources = [cell["source"] for cell in cells(page)]
        for index in [0] + [i for i, source in enumerate(sources) if source.startswith("check(")]:
            code.nth(index).locator(".jp-InputPrompt").click()
            page.keyboard.press("Shift+Enter")
            page.wait_for_timeout(200)
            wait_idle(page)
        shown = [cell for cell in cells(page) if cell["source"].startswith("check(")]
        assert len(shown) == 5
        for cell in shown:
            assert re.match(r"^TODO 2\.\d\.\d \(.*\): (all \d visible checks pass|the visible check passes)$", cell["lines"][0]), \
                cell["lines"]
            assert all(line.startswith("pass") for line in cell["lines"][1:] if line.startswith(("pass", "FAIL")))
    shut_kernels(instructor_lab)
