"""The notebooks as a student sees them: JupyterLab in headless Chromium, driven by Playwright.

nbval proves that the notebooks execute; this proves that the slider panel renders and responds
in JupyterLab (a widget front end that does not match the kernel's ipywidgets shows "Error
displaying widget" or "model not found" instead). The test starts JupyterLab from this very
Python environment (``tests/lab_under_test.py``) on a copy of the notebooks, in a 1280 x 720
window with the file browser open, opens each notebook, clears its outputs and runs all cells
from the Run menu. Then it works the slider panel like a student:

- the panel fits the notebook area, every control is named in full and has a real tooltip;
- a θ slider moved with the keyboard, and the presets clicked in quick succession, back and
  forth (the orders that once left the figure blank for good): after each, the panel's image has
  content (its PNG, decoded from the page, has no transparent pixel) and is exactly the figure
  ``hwlib.widgets.render_panel`` draws for the values the panel shows, and the reward shown is
  the one the kit's batch engine computes (``hwlib.cartpole.run_episodes``, which runs none of
  the student's code);
- ▶ Play moves the time step through the episode, and presets clicked while it plays leave the
  panel showing the last one.

The panel is found by its widgets (the ``hwlib-slider-panel`` class), not by cell index, and it
is checked even when a later cell of the notebook fails (that failure is reported by its own
test). Screenshots go to ``test-artifacts/``.

Chromium is Debian's (/usr/bin/chromium); Playwright never downloads a browser. Without it the
test is skipped, except in CI (CI=true), where that is a failure. ``pytest -m "not browser"``
leaves the test out.
"""

from __future__ import annotations

import base64
import contextlib
import io
import os
import re
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from lab_under_test import CHROMIUM_ARGS, chromium_path, running_jupyterlab

pytestmark = pytest.mark.browser

KIT_ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = KIT_ROOT / "notebooks"
P1_NOTEBOOK = "p1_cartpole_finite_difference.ipynb"
P2_NOTEBOOK = "p2_food_cutting_logistic_regression.ipynb"
ARTIFACTS = KIT_ROOT / "test-artifacts"
VIEWPORT = {"width": 1280, "height": 720}  # a laptop window; the file browser stays open beside the notebook

OPEN_TIMEOUT_MS = 60_000  # JupyterLab loaded, notebook shown, kernel idle
RUN_TIMEOUT_MS = 240_000  # all cells of one notebook run (p1 takes ~20 s on 2 cores)
WIDGET_TIMEOUT_MS = 30_000  # one change of the panel round-trips through the kernel
PLAY_TIMEOUT_MS = 60_000  # a 142-step episode played at 2 steps per 0.1 s frame takes ~7 s

# What a broken output looks like to a student: a widget the front end cannot show, a widget
# shown as its text repr (no widget front end at all), or an exception.
ERROR_MARKERS = ("Error displaying widget", "model not found", "Traceback", "VBox(children=")

PANEL = ".hwlib-slider-panel"
THETA_LABELS = ("θ₁ · cart position [m]", "θ₂ · cart velocity [m/s]", "θ₃ · pole angle [rad]", "θ₄ · pole angular velocity [rad/s]")
TIME_STEP_LABEL = "time step"


@pytest.fixture(scope="module")
def chromium():
    chromium = chromium_path()
    if chromium is None:
        reason = "Debian's Chromium is not installed at /usr/bin/chromium (apt-get install chromium); the browser test needs it"
        if os.environ.get("CI") == "true":
            pytest.fail(f"{reason}. In CI it must be there: .ci/run installs it.")
        pytest.skip(reason)
    return chromium


@pytest.fixture(scope="module")
def lab(chromium, tmp_path_factory):
    """JupyterLab serving a copy of the kit's notebooks, so the test can never change them."""
    root = tmp_path_factory.mktemp("lab-root")
    (root / "notebooks").mkdir()
    for notebook in NOTEBOOKS.glob("*.ipynb"):
        shutil.copy2(notebook, root / "notebooks" / notebook.name)
    with running_jupyterlab(root, tmp_path_factory.mktemp("lab-state")) as server:
        yield server


@pytest.fixture(scope="module")
def browser(chromium, tmp_path_factory):
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("chromium-profile")),  # a new, empty user data dir
            executable_path=str(chromium),
            args=CHROMIUM_ARGS,
            headless=True,
            viewport=VIEWPORT,
        )
        try:
            yield context
        finally:
            context.close()


def new_page(browser):
    page = browser.new_page()
    page.set_default_timeout(WIDGET_TIMEOUT_MS)
    console_errors = []
    page.on("console", lambda message: console_errors.append(message.text) if message.type == "error" else None)
    page.console_errors = console_errors
    return page


def close_page(page, lab):
    """Close the tab and shut down the kernels it started."""
    with contextlib.suppress(Exception):
        page.close()
    with contextlib.suppress(Exception):
        for kernel in lab.api("GET", "/api/kernels") or []:
            lab.api("DELETE", f"/api/kernels/{kernel['id']}")


@pytest.fixture()
def page(browser, lab):
    """A new tab, closed after the test together with the kernels it started."""
    page = new_page(browser)
    yield page
    close_page(page, lab)


@pytest.fixture(scope="module")
def p1(browser, lab):
    """Problem 1's notebook opened and run once (Run All Cells); both p1 tests look at it."""
    page = new_page(browser)
    with screenshot_on_failure(page, "p1-run"):
        open_notebook(page, lab, P1_NOTEBOOK)
        state = run_all_cells(page)
    yield page, state
    close_page(page, lab)


@contextlib.contextmanager
def screenshot_on_failure(page, name):
    """If the block fails, keep a full-page screenshot in test-artifacts/ to see why."""
    try:
        yield
    except BaseException:
        ARTIFACTS.mkdir(exist_ok=True)
        with contextlib.suppress(Exception):
            page.screenshot(path=str(ARTIFACTS / f"{name}-failure.png"), full_page=True)
        raise


# --- driving JupyterLab like a student -------------------------------------------------------


def open_notebook(page, lab, name):
    page.goto(lab.url(f"notebooks/{name}"), timeout=OPEN_TIMEOUT_MS)
    page.locator(".jp-NotebookPanel .jp-Notebook .jp-Cell").first.wait_for(timeout=OPEN_TIMEOUT_MS)
    # The kernel has started and is idle: the status bar says "Python 3 (ipykernel) | Idle".
    wait_for_idle_kernel(page, OPEN_TIMEOUT_MS)


def wait_for_idle_kernel(page, timeout):
    """The status bar's kernel item reads "Python 3 (ipykernel) | Idle"."""
    page.locator("#jp-main-statusbar .jp-StatusBar-TextItem", has_text=re.compile(r"\| Idle$")).first.wait_for(timeout=timeout)


def menu(page, menu_name, item_label):
    page.locator(".lm-MenuBar-item", has_text=re.compile(rf"^{re.escape(menu_name)}$")).click()
    page.locator(".lm-Menu-item:visible .lm-Menu-itemLabel", has_text=re.compile(rf"^{re.escape(item_label)}$")).click()


CELL_STATE_JS = """() => {
    const prompts = [...document.querySelectorAll('.jp-NotebookPanel .jp-CodeCell .jp-InputPrompt')]
        .map(element => element.textContent.trim());
    const errors = document.querySelectorAll(
        '.jp-NotebookPanel .jp-OutputArea-output[data-mime-type="application/vnd.jupyter.error"]').length;
    return {prompts, errors};
}"""


def run_all_cells(page):
    """Clear every output, then Run > Run All Cells, and wait until every code cell has run
    (each prompt shows its execution count) or a cell failed (Run All stops there)."""
    menu(page, "Edit", "Clear Outputs of All Cells")
    page.wait_for_function(
        "() => document.querySelectorAll('.jp-NotebookPanel .jp-OutputArea-output').length === 0",
        timeout=WIDGET_TIMEOUT_MS,
    )
    menu(page, "Run", "Run All Cells")
    page.wait_for_function(
        f"""() => {{
            const state = ({CELL_STATE_JS})();
            const pending = state.prompts.some(prompt => prompt === '[*]:');
            const allRan = state.prompts.length > 0 && state.prompts.every(prompt => /^\\[\\d+\\]:$/.test(prompt));
            return !pending && (allRan || state.errors > 0);
        }}""",
        timeout=RUN_TIMEOUT_MS,
        polling=250,
    )
    wait_for_idle_kernel(page, RUN_TIMEOUT_MS)
    return page.evaluate(CELL_STATE_JS)


def output_problems(page, outputs=".jp-NotebookPanel .jp-OutputArea-output"):
    """Every output a student would read as an error: error outputs and the markers above."""
    problems = [
        f"error output: {text[:2000]}"
        for text in page.locator(f'{outputs}[data-mime-type="application/vnd.jupyter.error"]').all_inner_texts()
    ]
    for text in page.locator(outputs).all_inner_texts():
        problems += [f"{marker!r} in output: {text[:2000]}" for marker in ERROR_MARKERS if marker in text]
    return problems


def check_ran_cleanly(page, state, name):
    problems = output_problems(page)
    not_run = [index for index, prompt in enumerate(state["prompts"]) if not re.fullmatch(r"\[\d+\]:", prompt)]
    assert not problems, f"{name}: outputs show errors:\n" + "\n".join(problems) + console_summary(page)
    assert not not_run, f"{name}: code cells {not_run} did not run (prompts {state['prompts']})" + console_summary(page)


def console_summary(page):
    errors = getattr(page, "console_errors", [])
    return "\nbrowser console errors:\n" + "\n".join(errors[-20:]) if errors else ""


def save_screenshot(locator, name):
    ARTIFACTS.mkdir(exist_ok=True)
    path = ARTIFACTS / name
    locator.screenshot(path=str(path))
    assert path.stat().st_size > 0
    return path


# --- reading the slider panel --------------------------------------------------------------------


def slider(panel, label):
    return panel.locator(".widget-hslider", has=panel.page.locator(f"label.widget-label:text-is('{label}')"))


def parse_number(text):
    return float(text.strip().replace("\u2212", "-"))


def read_params(panel):
    """The four weights the panel shows, read off the θ sliders' readouts (e.g. '−0.10')."""
    return tuple(parse_number(slider(panel, label).locator(".widget-readout").inner_text()) for label in THETA_LABELS)


def read_step(panel):
    return int(parse_number(slider(panel, TIME_STEP_LABEL).locator(".widget-readout").inner_text()))


def kit_reward(params, seed):
    """The reward of the kit's batch engine: the same as ``run_policy(CartPoleLinearPolicy(params), seed)``
    for a correct 1.1.1, and independent of the student's code."""
    from hwlib.cartpole import run_episodes

    return int(run_episodes(np.array([params], dtype=float), [seed])[0])


def shown_reward(panel):
    text = panel.locator(".hwlib-reward").inner_text()
    match = re.search(r"Total reward: (\d+)", text)
    assert match, f"the reward label reads {text!r}"
    return int(match.group(1))


def wait_for_reward(panel, params, what):
    """Wait until the label shows the reward the kit computes for ``params``; return it."""
    from playwright.sync_api import expect

    from hwlib.widgets import DEFAULT_SEED

    reward = kit_reward(params, DEFAULT_SEED)
    label = panel.locator(".hwlib-reward")
    try:
        expect(label).to_have_text(re.compile(rf"^\s*Total reward: {reward}\b"), timeout=WIDGET_TIMEOUT_MS)
    except AssertionError:
        pytest.fail(
            f"{what}: the panel shows {label.inner_text()!r} for parameters {params}, "
            f"but the kit computes {reward}" + console_summary(panel.page)
        )
    return reward


SETTLED_MS = 1500  # the readouts and the kernel must stay put this long before the panel counts as settled


def wait_for_params(panel, expected, what):
    """Wait until the θ readouts show ``expected`` and the panel has settled: the kernel idle and
    the readouts unchanged for ``SETTLED_MS``. (After quick clicks the readouts pass through the
    final values before the kernel has handled every click: the first match proves nothing.)"""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    panel.page.evaluate("window.hwlibSettledSince = null")
    try:
        panel.page.wait_for_function(
            """([element, labels, expected, settledMs]) => {
                const readouts = labels.map(label => {
                    const sliders = [...element.querySelectorAll('.widget-hslider')];
                    const found = sliders.find(s => s.querySelector('label.widget-label')?.textContent === label);
                    return found ? parseFloat(found.querySelector('.widget-readout').textContent.trim().replace('\u2212', '-')) : NaN;
                });
                const idle = [...document.querySelectorAll('#jp-main-statusbar .jp-StatusBar-TextItem')]
                    .some(item => item.textContent.trim().endsWith('| Idle'));
                const settled = idle && readouts.every((value, i) => Math.abs(value - expected[i]) < 1e-9);
                const now = performance.now();
                if (!settled) { window.hwlibSettledSince = null; return false; }
                window.hwlibSettledSince ??= now;
                return now - window.hwlibSettledSince >= settledMs;
            }""",
            arg=[panel.element_handle(), list(THETA_LABELS), list(expected), SETTLED_MS],
            timeout=WIDGET_TIMEOUT_MS,
            polling=100,
        )
    except PlaywrightTimeout:
        pass  # the assertion below says what the panel shows
    assert read_params(panel) == pytest.approx(expected), what + console_summary(panel.page)


FETCH_IMAGE_JS = """async (img) => {
    const response = await fetch(img.src);
    const bytes = new Uint8Array(await response.arrayBuffer());
    let binary = '';
    for (let i = 0; i < bytes.length; i += 0x8000) binary += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
    return btoa(binary);
}"""


def panel_pixels(panel):
    """The panel's figure as an RGBA array, decoded from the PNG the page shows."""
    import matplotlib.image

    image = panel.locator("img.hwlib-episode")
    for _ in range(20):  # the kernel may replace (and revoke) the image's blob URL while we fetch it
        try:
            png = base64.b64decode(image.evaluate(FETCH_IMAGE_JS))
            break
        except Exception:  # noqa: BLE001
            time.sleep(0.1)
    else:
        pytest.fail("could not read the panel's image from the page")
    assert png.startswith(b"\x89PNG"), "the panel's image is not a PNG"
    return matplotlib.image.imread(io.BytesIO(png))


def opaque_pixels(pixels):
    return int(np.count_nonzero(pixels[..., 3] > 0)) if pixels.shape[2] == 4 else pixels.shape[0] * pixels.shape[1]


def expected_pixels(params, step):
    import matplotlib.image

    from hwlib.widgets import DEFAULT_SEED, render_panel

    return matplotlib.image.imread(io.BytesIO(render_panel(params, DEFAULT_SEED, step=step).png))


def check_panel_shows(panel, params, what, step=None):
    """The panel shows ``params`` with the kit's reward, and a figure with content: exactly the
    figure of these params, at the time step the slider shows (``step``, if given, must be it)."""
    wait_for_params(panel, params, f"{what}: the θ readouts")
    reward = wait_for_reward(panel, params, what)
    if step is not None:
        from playwright.sync_api import expect

        expect(slider(panel, TIME_STEP_LABEL).locator(".widget-readout")).to_have_text(str(step), timeout=WIDGET_TIMEOUT_MS)
    # The label and the image arrive in two messages: wait for the image to catch up.
    deadline = time.monotonic() + WIDGET_TIMEOUT_MS / 1000
    while True:
        shown, at = panel_pixels(panel), read_step(panel)
        if at <= reward:  # (the time step may still show the previous episode's)
            expected = expected_pixels(params, at)
            if shown.shape == expected.shape and np.array_equal(shown, expected):
                break
        if time.monotonic() > deadline:
            opaque = opaque_pixels(shown)
            pytest.fail(
                f"{what}: the panel's image ({shown.shape[1]}x{shown.shape[0]}, {opaque} non-transparent pixels) is not "
                f"the figure of {params} at step {at}" + console_summary(panel.page)
            )
        time.sleep(0.2)
    total = shown.shape[0] * shown.shape[1]
    assert opaque_pixels(shown) == total, f"{what}: the panel's image has transparent pixels (a blank figure has no others)"
    return reward


def click_presets(panel, names, in_one_go=False):
    """Click the preset buttons in this order, as fast as Playwright clicks or (``in_one_go``)
    all within one JavaScript task, with no wait for the kernel in between."""
    if in_one_go:
        panel.evaluate(
            """(element, names) => {
                const buttons = [...element.querySelectorAll('button.widget-button')];
                for (const name of names) buttons.find(b => b.textContent.trim() === name).click();
            }""",
            names,
        )
        return
    for name in names:
        panel.locator("button.widget-button", has_text=re.compile(rf"^\s*{re.escape(name)}\s*$")).click()


# --- the tests -------------------------------------------------------------------------------------


def test_p1_runs_in_jupyterlab(p1):
    page, state = p1
    with screenshot_on_failure(page, "p1"):
        check_ran_cleanly(page, state, P1_NOTEBOOK)


def test_p1_slider_panel_in_jupyterlab(p1):
    page, _ = p1
    with screenshot_on_failure(page, "p1-panel"):
        panel = find_panel(page)
        check_layout(page, panel)
        check_names_and_tooltips(panel)
        check_slider_and_presets(panel)
        check_play(panel)
        problems = output_problems(page, f".jp-NotebookPanel .jp-OutputArea-output:has({PANEL})")
        assert not problems, problems


def find_panel(page):
    panels = page.locator(f".jp-NotebookPanel .jp-OutputArea-output {PANEL}")
    count = panels.count()
    if count != 1:
        pytest.fail(f"expected one slider panel in the notebook's outputs, found {count}; "
                    f"outputs with errors: {output_problems(page)}" + console_summary(page))
    panel = panels.first
    panel.evaluate("element => element.closest('.jp-Cell').scrollIntoView({block: 'start'})")
    panel.locator("img.hwlib-episode").wait_for(state="attached")
    return panel


def check_layout(page, panel):
    """At 1280 x 720 with the file browser open, the whole panel fits the notebook area."""
    file_browser = page.locator("#filebrowser")
    if not file_browser.is_visible():
        page.locator(".jp-SideBar .lm-TabBar-tab[data-id='filebrowser']").click()
    assert file_browser.is_visible(), "the file browser should be open beside the notebook"
    assert page.viewport_size == VIEWPORT

    # Scroll the panel to the top of the notebook area: all of it must be in view at once.
    panel.evaluate("element => element.scrollIntoView({block: 'start'})")
    page.wait_for_timeout(300)
    notebook = page.locator(".jp-NotebookPanel:visible .jp-WindowedPanel-outer, .jp-NotebookPanel:visible .jp-Notebook").first
    area, box = notebook.bounding_box(), panel.bounding_box()
    save_page = ARTIFACTS / "p1_panel_1280x720.png"
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(save_page))
    where = f"panel {box}, notebook area {area} (screenshot {save_page.relative_to(KIT_ROOT)})"
    assert box["x"] >= area["x"] - 1 and box["x"] + box["width"] <= area["x"] + area["width"] + 1, f"the panel is wider than the notebook: {where}"
    assert box["height"] <= area["height"], f"the panel is taller than the notebook area: {where}"
    assert box["y"] >= area["y"] - 1 and box["y"] + box["height"] <= area["y"] + area["height"] + 1, f"the panel is not all in view: {where}"
    overflowing = panel.evaluate(
        """element => [element, ...element.querySelectorAll('*')]
            .filter(e => e.scrollWidth > e.clientWidth + 1 && getComputedStyle(e).overflowX !== 'visible')
            .map(e => e.className)"""
    )
    assert not overflowing, f"parts of the panel scroll sideways: {overflowing}"
    cut = panel.evaluate(
        """element => [...element.querySelectorAll('label.widget-label, button.widget-button')]
            .filter(e => e.offsetParent !== null && e.scrollWidth > e.clientWidth + 1)
            .map(e => e.textContent)"""
    )
    assert not cut, f"labels cut off: {cut}"
    save_screenshot(panel, "p1_slider_panel.png")


def check_names_and_tooltips(panel):
    labels = panel.locator("label.widget-label:visible").all_inner_texts()
    for label in (*THETA_LABELS, TIME_STEP_LABEL, "seed"):
        assert label in [text.strip() for text in labels], f"no control labelled {label!r} (labels: {labels})"
    titles = panel.evaluate(
        """element => {
            const controls = [...element.querySelectorAll(
                '.widget-hslider, .widget-text, .widget-button, .widget-play, .widget-html')];
            return {
                nulls: [...element.querySelectorAll('[title]')].filter(e => ['null', 'undefined', ''].includes(e.title.trim()))
                    .map(e => e.outerHTML.slice(0, 120)),
                untitled: controls.filter(c => ![c, ...c.querySelectorAll('[title]')].some(e => e.title && e.title !== 'null'))
                    .map(c => c.outerHTML.slice(0, 120)),
                count: controls.length,
            };
        }"""
    )
    assert not titles["nulls"], f"tooltips reading null or nothing: {titles['nulls']}"
    assert not titles["untitled"], f"controls without a tooltip: {titles['untitled']}"
    assert titles["count"] == 4 + 1 + 2 + 1 + 1 + 1 + 1  # θ sliders, seed, presets, landscape, reward, play, time step


def check_slider_and_presets(panel):
    from hwlib.widgets import DEFAULT_PARAMS, PRESETS

    # As the cell leaves it: the default weights (a policy that fails), seed 0.
    check_panel_shows(panel, DEFAULT_PARAMS, "the panel as displayed")

    # A student moves the weight on the pole's angular velocity: focus its handle and press
    # ArrowLeft 20 times (0.01 each), from 0.00 to -0.20. The cart then runs off the track after
    # 142 steps, a reward unlike either preset's.
    before = shown_reward(panel)
    handle = slider(panel, THETA_LABELS[3]).locator(".noUi-handle")
    handle.focus()
    for _ in range(20):
        handle.press("ArrowLeft")
    moved = (*DEFAULT_PARAMS[:3], -0.2)
    reward = check_panel_shows(panel, moved, "after 20 presses of ArrowLeft on θ₄")
    assert reward != before, f"moving θ₄ to -0.20 should change the reward (it stayed {before})"
    assert read_step(panel) == reward, "a new episode is shown at its last step"
    save_screenshot(panel, "p1_slider_panel_moved.png")

    # The presets, clicked in quick succession in the orders that once left the figure blank,
    # each run ending on a preset other than the one before.
    left, right = "always left", "always right"
    runs = [
        ([right], False),
        ([left, right, left], False),
        ([right, left, right, left, right], False),
        ([left, right] * 4, True),
        ([left, right, left, right, left, right, left], True),
        ([right, right, left, left, right], False),
    ]
    for names, in_one_go in runs:
        click_presets(panel, names, in_one_go)
        what = f"after clicking {' → '.join(names)}" + (" in one go" if in_one_go else "")
        check_panel_shows(panel, PRESETS[names[-1]], what)
    save_screenshot(panel, "p1_slider_panel_after_presets.png")


def check_play(panel):
    """▶ moves the time step from 0 through the episode to its end, and the figure follows."""
    from playwright.sync_api import expect

    from hwlib.widgets import PRESETS

    click_presets(panel, ["always left"])
    check_panel_shows(panel, PRESETS["always left"], "after clicking always left, before pressing play")
    handle = slider(panel, THETA_LABELS[3]).locator(".noUi-handle")
    handle.focus()
    for _ in range(20):
        handle.press("ArrowLeft")
    params = (*PRESETS["always left"][:3], -0.2)  # 142 steps: ~7 s of play
    end = check_panel_shows(panel, params, "before pressing play")
    readout = slider(panel, TIME_STEP_LABEL).locator(".widget-readout")
    panel.evaluate(
        """(element) => {
            const readout = [...element.querySelectorAll('.widget-hslider')]
                .find(s => s.querySelector('label.widget-label')?.textContent === 'time step').querySelector('.widget-readout');
            window.hwlibSteps = [];
            window.hwlibImages = 0;
            new MutationObserver(() => window.hwlibSteps.push(readout.textContent.trim()))
                .observe(readout, {childList: true, characterData: true, subtree: true});
            new MutationObserver(() => window.hwlibImages++)
                .observe(element.querySelector('img.hwlib-episode'), {attributes: true, attributeFilter: ['src']});
        }"""
    )
    panel.locator(".widget-play button").first.click()
    panel.page.wait_for_function(
        f"() => window.hwlibSteps.length > 5 && window.hwlibSteps[window.hwlibSteps.length - 1] === '{end}'",
        timeout=PLAY_TIMEOUT_MS,
    )
    steps = [int(parse_number(text)) for text in panel.page.evaluate("window.hwlibSteps")]
    playing = [step for step in steps if step < end]
    assert playing and playing[0] <= 2, f"play should start the episode over from step 0: {steps}"
    assert len(set(playing)) >= 10 and playing == sorted(playing), f"the time step should advance while playing: {steps}"
    assert panel.page.evaluate("window.hwlibImages") >= 3, "the figure should follow the time step while playing"
    expect(readout).to_have_text(str(end))
    check_panel_shows(panel, params, "after playing the episode", step=end)
    save_screenshot(panel, "p1_slider_panel_played.png")

    # Presets clicked while the episode plays: the time step's redraws (one kernel thread) and the
    # presets' (another) arrive together. The panel ends on the last preset, at whatever step the
    # slider shows, with that figure.
    panel.page.evaluate("window.hwlibSteps = []")
    panel.locator(".widget-play button").first.click()
    panel.page.wait_for_function("() => new Set(window.hwlibSteps).size > 3", timeout=PLAY_TIMEOUT_MS)
    click_presets(panel, ["always right", "always left", "always right"])
    check_panel_shows(panel, PRESETS["always right"], "after clicking presets while the episode played")


def test_p2_runs_in_jupyterlab(page, lab):
    with screenshot_on_failure(page, "p2"):
        check_p2_runs(page, lab)


def check_p2_runs(page, lab):
    open_notebook(page, lab, P2_NOTEBOOK)
    state = run_all_cells(page)
    check_ran_cleanly(page, state, P2_NOTEBOOK)
    figures = page.locator(".jp-NotebookPanel .jp-OutputArea-output img")
    assert figures.count() >= 2, f"expected at least the training curve and the confusion matrix, found {figures.count()} figures"
    first_figure = page.locator(".jp-NotebookPanel .jp-OutputArea-output", has=page.locator("img")).first
    first_figure.scroll_into_view_if_needed()
    assert first_figure.locator("img").evaluate("img => img.complete && img.naturalWidth > 0"), "the figure did not load"
    save_screenshot(first_figure, "p2_first_figure.png")
