"""The slider panel's parts (``hwlib/widgets.py`` builds the panel from them; students need not read this).

- The sliders' grid (``slider_grid_value``, ``grid_params``) and the panel's texts (labels, tooltips,
  ``todo_message``); the state the browser sends (``PanelState``, ``parse_frontend_state``).
- ``PanelControls``: the panel's small front-end part (an anywidget), with its JavaScript
  (``panel_controls.js``) and style (``PANEL_CSS``). It draws the preset and landscape buttons, sets the
  sliders to a preset in the browser, and sends the whole state after every action on one
  channel, numbered, so the last state the kernel receives is the state of the last action; while
  ▶ Play runs it draws the time steps over the episode's picture itself.
- ``LatestOnly``: redraws one at a time, and always once more after the last request, so a
  burst of changes from several threads ends on the latest state.
"""

from __future__ import annotations

import contextlib
import math
import pathlib
import re
import threading
from dataclasses import dataclass

import anywidget
import ipywidgets as widgets
import traitlets

from hwlib._checks import check_params, check_seed
from hwlib.cartpole import MAX_EPISODE_REWARD, OBSERVATION_NAMES, SEED_BOUND

SLIDER_MIN, SLIDER_MAX, SLIDER_STEP = -2.0, 2.0, 0.01
OBSERVATION_UNITS = ("m", "m/s", "rad", "rad/s")
SUBSCRIPTS = "₁₂₃₄"
SLIDER_LABELS = tuple(
    f"θ{SUBSCRIPTS[index]} · {name} [{unit}]" for index, (name, unit) in enumerate(zip(OBSERVATION_NAMES, OBSERVATION_UNITS))
)


def slider_grid_value(value):
    """``value`` moved to the sliders' grid, computed exactly as the browser's slider does it.

    ipywidgets 8 draws a FloatSlider with noUiSlider, which snaps a value to the grid in percent
    of the range and sends the snapped value back to the kernel whenever it differs from the
    model's. Values this function returns are left as they are (they are the snapped values), so
    displaying them sends nothing back. ``value`` must lie within the sliders' range.
    """
    span = SLIDER_MAX - SLIDER_MIN
    percent = (value - SLIDER_MIN) * 100 / span
    percent_step = SLIDER_STEP * 100 / span
    snapped = math.floor(percent / percent_step + 0.5) * percent_step  # JavaScript's Math.round
    if snapped >= 100:
        return SLIDER_MAX
    return snapped * span / 100 + SLIDER_MIN


def grid_params(params, name="params"):
    """Four weights within the sliders' range, on the sliders' grid, as a tuple of floats."""
    params = check_params(params, name)
    if params.min() < SLIDER_MIN or params.max() > SLIDER_MAX:
        raise ValueError(f"{name} must lie within the sliders' range [{SLIDER_MIN:g}, {SLIDER_MAX:g}], got {params.tolist()}")
    return tuple(slider_grid_value(float(value)) for value in params)


PRESET_TOOLTIPS = {
    "always left": "θ = (0, 0, 0, 0): θ·s is never negative, so the cart is pushed left at every step",
    "always right": "θ = (0, −1, 0, 1): once the cart is pushed right, θ·s only gets more negative, so it keeps being pushed right",
}
SLIDER_TOOLTIP = (
    "Weight θ{sub} on the {name} [{unit}]. The policy pushes the cart right when "
    "θ₁·x + θ₂·ẋ + θ₃·φ + θ₄·φ̇ < 0, otherwise left. Drag, or click the handle and use the arrow keys (0.01 per press)."
)
SEED_TOOLTIP = "Seed of the episode's start state, reset(seed=...): the same seed always gives the same start"
STEP_TOOLTIP = "The time step the cart is drawn at (the grey line in the plots). Drag to move through the episode, or press ▶"
PLAY_TOOLTIP = "Play the episode: moves the time step from 0 to the end (press again to pause)"
REWARD_TOOLTIP = f"Total reward of the episode: +1 for every step the pole stays up, {MAX_EPISODE_REWARD} at most"
LANDSCAPE_TOOLTIP_CONNECTED = "Mark the current θ in the reward landscape view"
LANDSCAPE_BUTTON_LABEL = "Show θ in the landscape"
STATUS_LINES = 2  # the status line's height, in lines of text
LANDSCAPE_TOOLTIP_UNCONNECTED = "No landscape view is connected to this panel (connect one with panel.on_send_params)"


class LatestOnly:
    """Runs ``draw()`` one call at a time, and always once more after the last ``request()``.

    ``request()`` from any thread: if nobody is drawing, the calling thread draws, and keeps
    drawing until no request arrived during its last draw; if somebody is drawing, the request
    is only noted and the call returns at once. Inside ``with held():`` requests are only noted;
    leaving the block makes one request for all of them.
    """

    def __init__(self, draw):
        self._draw = draw
        self._lock = threading.Lock()
        self._pending = False
        self._drawing = False
        self._holds = 0

    def request(self):
        with self._lock:
            self._pending = True
            if self._drawing or self._holds:
                return
            self._drawing = True
        try:
            while True:
                with self._lock:
                    if not self._pending or self._holds:
                        self._drawing = False
                        return
                    self._pending = False
                self._draw()
        except BaseException:
            with self._lock:
                self._drawing = False
            raise

    @contextlib.contextmanager
    def held(self):
        with self._lock:
            self._holds += 1
        try:
            yield
        finally:
            with self._lock:
                self._holds -= 1
            self.request()


_ANSI_ESCAPE = re.compile(r"\x1b\[[0-9;]*m")


def todo_message(error):
    """The lines that say which TODO is not done yet, if ``error`` says so; otherwise None.

    ``error`` says so when it is a ``NotImplementedError`` with a ``todo`` attribute (the kit's
    ``TodoNotDone``). Its short message (``_render_traceback_``, what IPython shows) is used when
    it has one, else "TODO x.y.z is not done yet: <its message>".
    """
    todo = getattr(error, "todo", None)
    if not isinstance(error, NotImplementedError) or not todo:
        return None
    render = getattr(error, "_render_traceback_", None)
    if callable(render):
        try:
            lines = [_ANSI_ESCAPE.sub("", str(line)).rstrip() for line in render()]
        except Exception:  # noqa: BLE001 (a broken message must not break the panel: use the plain one)
            lines = []
        lines = [line for text in lines for line in text.splitlines() if line.strip()]
        if lines:
            return lines
    detail = str(error).strip()
    return [f"TODO {todo} is not done yet" + (f": {detail}" if detail and detail != str(todo) else "")]


@dataclass(frozen=True)
class PanelState:
    """What the panel shows: the weights, the seed, and the time step (None: the episode's end)."""

    params: tuple
    seed: int
    step: int | None = None
    seq: int = 0  # the browser's number for this state (0: a change made in the kernel)


def parse_frontend_state(state):
    """The ``PanelState`` the browser sent, checked; ValueError if it is not one."""
    if not isinstance(state, dict):
        raise ValueError(f"the panel's state must be a dict, got {type(state).__name__}")
    params = grid_params(state.get("params"), "state['params']")
    seed = check_seed(state.get("seed"), "state['seed']")
    if seed >= SEED_BOUND:
        raise ValueError(f"state['seed'] must be below {SEED_BOUND}, got {seed}")
    step, seq = state.get("step"), state.get("seq", 0)
    if step is not None and (isinstance(step, bool) or not isinstance(step, int) or step < 0):
        raise ValueError(f"state['step'] must be None or a non-negative integer, got {step!r}")
    if isinstance(seq, bool) or not isinstance(seq, int):
        raise ValueError(f"state['seq'] must be an integer, got {seq!r}")
    return PanelState(params, seed, step, seq)



# --- the front-end part -----------------------------------------------------------------------

PANEL_ESM = pathlib.Path(__file__).with_name("panel_controls.js")  # the JavaScript, read by anywidget

PANEL_CSS = f"""
.hwlib-slider-panel {{ position: relative; }}
.hwlib-play-overlay {{ position: absolute; display: none; pointer-events: none; }}
.hwlib-panel-controls {{ display: flex; flex-direction: column; gap: 4px; }}
.hwlib-presets {{ display: flex; gap: 4px; }}
.hwlib-panel-controls .widget-button {{ width: auto; margin: 0; }}
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
    """

    _esm = PANEL_ESM
    _css = PANEL_CSS
    controls = traitlets.List(trait=traitlets.Instance(widgets.Widget)).tag(sync=True, **widgets.widget_serialization)
    presets = traitlets.List().tag(sync=True)
    landscape_label = traitlets.Unicode(LANDSCAPE_BUTTON_LABEL).tag(sync=True)
    landscape_tooltip = traitlets.Unicode(LANDSCAPE_TOOLTIP_UNCONNECTED).tag(sync=True)
    landscape_enabled = traitlets.Bool(False).tag(sync=True)
    state = traitlets.Any(None).tag(sync=True, echo_update=False)  # checked by parse_frontend_state
    drawn = traitlets.Int(0).tag(sync=True)
    overlay = traitlets.Dict(allow_none=True, default_value=None).tag(sync=True)
    overlay_png = traitlets.Bytes(b"").tag(sync=True)
