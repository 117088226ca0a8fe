"""The slider panel's small front-end part (``hwlib/widgets.py`` builds the panel with it).

``PanelControls`` is an anywidget with its JavaScript (``panel_controls.js``) and style
(``PANEL_CSS``). It draws the preset and landscape buttons, sets the sliders to a preset in the
browser, and sends the whole state after every action on one channel, numbered, so the last state
the kernel receives is the state of the last action (ipywidgets alone sends each control's
changes on its own channel, and a held slider value can land after a preset's); while ▶ Play
runs it draws the time steps over the episode's picture itself.

It also makes the panel usable with a keyboard and a screen reader, where ipywidgets leaves gaps:
every slider's handle is named by its label and reads its value as the readout shows it ("-0.30",
not -0.30000000000000004), ▶ Play's buttons are named, the picture's alternative text says what it
shows (``image_alt``, from the kernel), the status line is a live region (a new reward or error is
announced), and a focused control has a visible outline.
"""

from __future__ import annotations

import pathlib

import anywidget
import ipywidgets as widgets
import traitlets

STATUS_LINES = 2  # the panel's status line's height, in lines of text
LANDSCAPE_BUTTON_LABEL = "Show θ in the landscape"
LANDSCAPE_TOOLTIP_UNCONNECTED = "No landscape view is connected to this panel (connect one with panel.on_send_params)"
# The names a screen reader gives ▶ Play's buttons (ipywidgets draws them as icons only), by their icon.
PLAY_BUTTON_NAMES = {"fa-play": "Play the episode", "fa-pause": "Pause the episode", "fa-stop": "Stop: back to step 0",
                     "fa-retweet": "Play again and again"}

PANEL_ESM = pathlib.Path(__file__).with_name("panel_controls.js")  # the JavaScript, read by anywidget

PANEL_CSS = f"""
.hwlib-slider-panel {{ position: relative; }}
.hwlib-play-overlay {{ position: absolute; display: none; pointer-events: none; }}
.hwlib-panel-controls {{ display: flex; flex-direction: column; gap: 4px; }}
.hwlib-presets {{ display: flex; gap: 4px; }}
.hwlib-panel-controls .widget-button {{ width: auto; margin: 0; }}
.hwlib-slider-panel :is(.noUi-handle, button, input, select, [contenteditable]):focus-visible {{
  outline: 3px solid var(--jp-brand-color1, #1976d2) !important; outline-offset: 2px !important;  /* over ipywidgets' "none" */
}}
.hwlib-status .widget-html-content {{
  display: -webkit-box; -webkit-box-orient: vertical; -webkit-line-clamp: {STATUS_LINES};
  overflow: hidden; white-space: normal; line-height: 1.4em; height: {1.4 * STATUS_LINES}em;
}}
"""


class PanelControls(anywidget.AnyWidget):
    """The panel's front-end part: the preset and landscape buttons, and the state as the browser has it.

    ``controls``: the four θ sliders, the seed box, the time step slider and the Play (their browser
    models are followed). ``overlay`` and ``overlay_png``: what the browser draws ▶ Play with (see
    ``EpisodeView.overlay``), for the ``params`` and ``seed`` they name. ``state`` (browser → kernel): ``{"seq", "params", "seed", "step"}`` after each
    action, ``step`` None for "the end of the episode". ``drawn``: the ``seq`` of the last state the
    kernel has drawn (the browser shows it as ``data-drawn``, and the state it sent as ``data-sent``).
    ``image_alt``: the episode picture's alternative text; ``button_names``: ▶ Play's buttons' names.
    """

    _esm = PANEL_ESM
    _css = PANEL_CSS
    controls = traitlets.List(trait=traitlets.Instance(widgets.Widget)).tag(sync=True, **widgets.widget_serialization)
    presets = traitlets.List().tag(sync=True)
    landscape_label = traitlets.Unicode(LANDSCAPE_BUTTON_LABEL).tag(sync=True)
    landscape_tooltip = traitlets.Unicode(LANDSCAPE_TOOLTIP_UNCONNECTED).tag(sync=True)
    landscape_enabled = traitlets.Bool(False).tag(sync=True)
    state = traitlets.Any(None).tag(sync=True, echo_update=False)  # hwlib/widgets.py checks it (parse_frontend_state)
    drawn = traitlets.Int(0).tag(sync=True)
    overlay = traitlets.Dict(allow_none=True, default_value=None).tag(sync=True)
    overlay_png = traitlets.Bytes(b"").tag(sync=True)
    image_alt = traitlets.Unicode("").tag(sync=True)
    button_names = traitlets.Dict(PLAY_BUTTON_NAMES).tag(sync=True)
