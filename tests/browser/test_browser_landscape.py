"""The landscape explorer as a student sees it: JupyterLab in headless Chromium, driven by Playwright.

The test runs the problem 1 notebook if it holds the explorer (a cell calling
``LandscapeExplorer(``), otherwise a notebook made of the landscape section's cells below (the
cells to insert into the problem 1 notebook after training), with a stand-in for the training run
they read. It switches the horizontal axis in its dropdown and sees the picture and its caption
change, then picks the other dropdown's coordinate and sees the two swap. In the problem 1
notebook it also clicks the slider panel's "Show θ in the landscape" button and sees the explorer
redrawn through the panel's θ. Each redraw is timed end to end as the browser sees it: from the
change event (or click) until the new picture has loaded and the caption names the new axes or θ.
The times are printed and written to ``test-artifacts/landscape_redraw.txt`` (a row of
benchmarks/RESULTS.md); no wall-clock assertion.

JupyterLab and Chromium are started as in ``tests/browser/test_browser.py`` (``tests/browser/lab_under_test.py``),
whose fixtures and notebook helpers this module uses.
"""

from __future__ import annotations

import json
import shutil

import nbformat
import pytest

from lab_under_test import running_jupyterlab
from test_browser import (  # noqa: F401  (browser, chromium and page are fixtures used by name)
    ARTIFACTS,
    NOTEBOOKS,
    P1_NOTEBOOK,
    WIDGET_TIMEOUT_MS,
    browser,
    check_ran_cleanly,
    chromium,
    console_summary,
    open_notebook,
    output_problems,
    page,
    run_all_cells,
    save_screenshot,
    screenshot_on_failure,
)

pytestmark = [pytest.mark.browser, pytest.mark.timeout(900)]

EXPLORER_CALL = "LandscapeExplorer("
CELLS_NOTEBOOK = "landscape_section.ipynb"

# The landscape section of the problem 1 notebook, to go after training (it reads `np` and
# `settings` from the first cell, `panel`, the slider panel of 1.1.2, and `run`), as (cell type, source).
LANDSCAPE_CELLS = [
    ("markdown", """\
### Seeing the reward landscape

$g(\\theta)$ depends on four numbers, too many to draw, but we can draw a **slice** of it: let two coordinates of $\\theta$
run over a grid and hold the other two fixed. Each cell of the pictures below is the mean reward of 5 episodes, and every
cell plays the *same* 5 start states, so two cells differ only because their policies act differently. The 41 × 41 cells
(8,405 episodes) are played in one batch of the vectorised CartPole, in a fraction of a second
(code: `reward_slice` in `hwlib/landscape.py`; the figure: `plot_reward_landscape` in `hwlib/plots/landscape.py`).

First the slice through the origin: $\\theta_1 = \\theta_2 = 0$ held, and the weights on the pole angle ($\\theta_3$) and on its
angular velocity ($\\theta_4$) varying."""),
    ("code", """\
from hwlib.landscape import LandscapeExplorer, reward_slice
from hwlib.plots import plot_reward_landscape

origin_slice = reward_slice(np.zeros(4), axes=(2, 3))
print(f"{np.mean(origin_slice.mean_rewards == 500):.0%} of the {origin_slice.mean_rewards.size} cells "
      f"score 500 on all {origin_slice.num_episodes} episodes")
plot_reward_landscape(origin_slice)"""),
    ("markdown", """\
Two things stand out.

* **Rays from the origin.** Every border between two colours is a straight line through $(0, 0)$. The policy only
  sees the sign of $\\theta^\\top s$, and for any $c > 0$ the sign of $(c\\theta)^\\top s$ is the same, so $\\pi_{c\\theta} = \\pi_\\theta$,
  $g(c\\theta) = g(\\theta)$, and $g$ is constant along every ray that leaves the origin. Only the direction of $\\theta$
  matters, which is also why all the borders meet at the origin: a tiny $\\theta$ can point anywhere. (Here the held
  coordinates are 0, so each ray lies inside the picture. When they are not 0, as in the next slice, the rays leave
  the plane, and the borders are only nearly straight far from the centre, where the held weights matter less.)
* **Flat plateaus.** Large regions have one colour: the whole upper half, where every policy loses the pole within
  about ten steps, and the yellow region, where every episode lasts all 500 steps. Inside a plateau, a finite
  difference compares two equal rewards and returns exactly zero. Only a step $h$ long enough to reach across a
  border sees any slope, which is why the training uses $h = 0.5$ and not something like $10^{-4}$."""),
    ("markdown", """\
Now the slice through the $\\theta$ that training found, with $\\theta_1$ and $\\theta_2$ held at their trained values. The
red dots are the training path: dot $t$ is $\\theta$ after $t$ updates (`run.params_history`), projected onto the slice
(the path also moves in $\\theta_1$ and $\\theta_2$, which this picture cannot show). The white circles around the star
are $\\theta \\pm h$ along the two axes: the points the finite difference evaluates in these two directions."""),
    ("code", """\
trained_slice = reward_slice(run.policy.params, axes=(2, 3))
plot_reward_landscape(trained_slice, path=run.params_history, fd_step=settings.FD_STEP)"""),
    ("markdown", """\
The path climbs out of the dark plateau around the origin into the yellow one. Once $\\theta + h e_i$ and
$\\theta - h e_i$ score the same on the episodes of an iteration (for instance 500 on every one), the finite difference
along $e_i$ is exactly zero and that coordinate stops moving: that is where the dots pile up, and one label then covers
the run of iterations, first–last. (Training scores each iteration on 20 fresh episodes, the picture on 5 fixed ones,
so the borders training saw are close to these, not identical.) The picture also shows how a learning rate can be too
large: one long step can jump across a border into a plateau where every neighbour scores the same, and from then on
the gradient is zero, whether the plateau is a good one or not.

**Explore.** The dropdowns below choose which two coordinates vary; the other two stay at the current $\\theta$. The
slider panel of 1.1.2 has a button that sends its $\\theta$ here, so you can tune a policy by hand and then see where it
sits in the landscape. Each redraw plays 8,405 episodes and takes about half a second."""),
    ("code", """\
# NBVAL_IGNORE_OUTPUT
explorer = LandscapeExplorer(run.policy.params, path=run.params_history, fd_step=settings.FD_STEP)
explorer.widget"""),
    ("code", """\
# The slider panel's "Show θ in the landscape" button (1.1.2) now sends its θ to the explorer.
panel.on_send_params(explorer.set_params);"""),
]

# What the made-up notebook runs first, in place of the problem 1 notebook's earlier cells.
STAND_IN_CELL = """\
import numpy as np
from types import SimpleNamespace

from hwlib import CartPoleLinearPolicy, settings

# Stands in for the notebook's training run: a straight path from the origin.
params_history = np.linspace(np.zeros(4), [0.3, -0.4, 0.8, 0.2], 8)
run = SimpleNamespace(policy=CartPoleLinearPolicy(params_history[-1]), params_history=params_history)"""


def notebook_has_explorer(path):
    notebook = json.loads(path.read_text())
    return any(cell["cell_type"] == "code" and EXPLORER_CALL in "".join(cell["source"]) for cell in notebook["cells"])


def landscape_section_notebook():
    """The landscape section's cells after the stand-in, without the cell wiring the slider panel
    (the made-up notebook has no panel)."""
    cells = [nbformat.v4.new_code_cell(STAND_IN_CELL)]
    for kind, source in LANDSCAPE_CELLS:
        if "panel." in source:
            continue
        cells.append(nbformat.v4.new_markdown_cell(source) if kind == "markdown" else nbformat.v4.new_code_cell(source))
    notebook = nbformat.v4.new_notebook(cells=cells)
    notebook.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3 (ipykernel)", "language": "python"}
    return notebook


@pytest.fixture(scope="module")
def notebook_name():
    return P1_NOTEBOOK if notebook_has_explorer(NOTEBOOKS / P1_NOTEBOOK) else CELLS_NOTEBOOK


@pytest.fixture(scope="module")
def lab(chromium, notebook_name, tmp_path_factory):
    """JupyterLab serving a copy of the kit's notebooks, plus the made-up one when the real one lacks the explorer."""
    root = tmp_path_factory.mktemp("lab-root")
    (root / "notebooks").mkdir()
    for notebook in NOTEBOOKS.glob("*.ipynb"):
        shutil.copy2(notebook, root / "notebooks" / notebook.name)
    if notebook_name == CELLS_NOTEBOOK:
        nbformat.write(landscape_section_notebook(), root / "notebooks" / CELLS_NOTEBOOK)
    with running_jupyterlab(root, tmp_path_factory.mktemp("lab-state")) as server:
        yield server


# ipywidgets shows the spaces of option labels as no-break spaces.
OPTION_TEXT_JS = "option => option.textContent.replace(/\\u00a0/g, ' ').trim()"

# Do what a student does to `control`: pick the option labelled `label` in a <select>, or click
# it (a button) when `label` is null. Resolve with the milliseconds until the image has a new,
# loaded source and the caption contains `expected`.
TIMED_REDRAW_JS = """async ([control, image, caption, label, expected]) => {
    const oldSource = image.src;
    let start;
    if (label === null) {
        start = performance.now();
        control.click();
    } else {
        const text = %s;
        const option = [...control.options].find(option => text(option) === label);
        if (!option) throw new Error(`no option ${label} in ${[...control.options].map(text)}`);
        start = performance.now();
        control.value = option.value;
        control.dispatchEvent(new Event('change', {bubbles: true}));
    }
    await new Promise((resolve, reject) => {
        const check = () => {
            if (image.src !== oldSource && image.complete && image.naturalWidth > 0
                && caption.textContent.includes(expected)) {
                resolve();
            } else if (performance.now() - start > %d) {
                reject(new Error(`no redraw: the caption reads ${caption.textContent.trim()}`));
            } else {
                setTimeout(check, 5);
            }
        };
        check();
    });
    return performance.now() - start;
}""" % (OPTION_TEXT_JS, WIDGET_TIMEOUT_MS)

SEND_BUTTON_TEXT = "Show θ in the landscape"  # the slider panel's button that sends its θ to the explorer


def dropdown(explorer, description):
    return explorer.locator(".widget-dropdown", has=explorer.page.locator(f"label:text-is('{description}')")).locator("select")


def selected_label(select):
    return select.evaluate(f"select => ({OPTION_TEXT_JS})(select.options[select.selectedIndex])")


def timed_redraw(explorer, control, label, expected_caption, what):
    """Pick ``label`` in the dropdown ``control`` (or click the button ``control`` if ``label`` is
    None); return the redraw time in ms as the browser sees it."""
    try:
        return explorer.page.evaluate(
            TIMED_REDRAW_JS,
            [control.element_handle(), explorer.locator("img.hwlib-landscape").element_handle(),
             explorer.locator(".hwlib-landscape-caption").element_handle(), label, expected_caption],
        )
    except Exception as error:
        pytest.fail(f"{what}: {error}" + console_summary(explorer.page))


def test_landscape_explorer_switches_axes_in_jupyterlab(page, lab, notebook_name):
    with screenshot_on_failure(page, "landscape"):
        check_landscape_explorer(page, lab, notebook_name)


def check_landscape_explorer(page, lab, notebook_name):
    from hwlib.landscape import AXIS_LABELS

    open_notebook(page, lab, f"notebooks/{notebook_name}")
    state = run_all_cells(page)
    check_ran_cleanly(page, state, notebook_name)

    explorers = page.locator(".jp-NotebookPanel .jp-OutputArea-output", has=page.locator(".hwlib-landscape-caption"))
    assert explorers.count() == 1, f"expected one landscape explorer, found {explorers.count()}" + console_summary(page)
    explorer = explorers.first
    explorer.scroll_into_view_if_needed()
    image = explorer.locator("img.hwlib-landscape")
    caption = explorer.locator(".hwlib-landscape-caption")
    page.wait_for_function("img => img.complete && img.naturalWidth > 0", arg=image.element_handle())
    assert caption.inner_text().startswith("θ₃ across, θ₄ up;"), caption.inner_text()
    assert (selected_label(dropdown(explorer, "across")), selected_label(dropdown(explorer, "up"))) == AXIS_LABELS[2:4]
    before = image.screenshot()
    save_screenshot(explorer, "landscape_explorer.png")

    # Across: θ₃ -> θ₁. The picture is redrawn with the new axis.
    times = {"θ₃ -> θ₁ across": timed_redraw(explorer, dropdown(explorer, "across"), AXIS_LABELS[0], "θ₁ across, θ₄ up;",
                                             "picking θ₁ across")}
    after = image.screenshot()
    assert after != before, "the picture did not change when the horizontal axis went from θ₃ to θ₁"
    save_screenshot(explorer, "landscape_explorer_theta1_across.png")

    # Up: θ₄ -> θ₁, the coordinate shown across: the two swap.
    times["swap"] = timed_redraw(explorer, dropdown(explorer, "up"), AXIS_LABELS[0], "θ₄ across, θ₁ up;", "picking θ₁ up")
    assert selected_label(dropdown(explorer, "across")) == AXIS_LABELS[3], "choosing the other dropdown's axis should swap the two"
    assert caption.inner_text().startswith("θ₄ across, θ₁ up;"), caption.inner_text()
    assert image.screenshot() not in (before, after)
    save_screenshot(explorer, "landscape_explorer_swapped.png")

    if notebook_name == P1_NOTEBOOK:  # the real notebook wires the slider panel to the explorer
        times["θ sent from the panel"] = check_panel_sends_theta(page, explorer)
    assert not output_problems(page), output_problems(page)

    report = (f"landscape explorer redraw, end to end in Chromium ({notebook_name}): "
              + ", ".join(f"{ms:.0f} ms ({what})" for what, ms in times.items()))
    print(report)
    ARTIFACTS.mkdir(exist_ok=True)
    (ARTIFACTS / "landscape_redraw.txt").write_text(report + "\n")


def check_panel_sends_theta(page, explorer):
    """The slider panel's button redraws the explorer through the θ the panel shows."""
    from hwlib.landscape import format_theta
    from test_browser import read_params  # the panel's own test knows how to read its sliders

    panel = page.locator(".jp-NotebookPanel .jp-OutputArea-output", has=page.locator(".hwlib-slider-panel")).first
    panel.scroll_into_view_if_needed()
    expected = f"through θ = {format_theta(read_params(panel))};"
    button = panel.locator("button", has_text=SEND_BUTTON_TEXT)
    if expected in explorer.locator(".hwlib-landscape-caption").inner_text():
        pytest.fail(f"the panel shows the θ the explorer already shows ({expected}): the check would prove nothing")
    sent_ms = timed_redraw(explorer, button, None, expected, f"clicking {SEND_BUTTON_TEXT!r}")
    explorer.scroll_into_view_if_needed()
    save_screenshot(explorer, "landscape_explorer_from_panel.png")
    return sent_ms
