"""The slider panel for hand-tuning the CartPole policy (handout 1.1.2).

Four sliders set the policy's weights θ₁..θ₄, a number box sets the episode's seed, and a
*time step* slider (with a ▶ Play control) moves through the episode. Every change ends in
``render_panel``, a plain function that plays the episode and draws it; the widgets only pass
values in and show what comes back, so the panel's logic is tested without a browser.

**The panel ends on what was clicked.** The browser sends each control's changes on its own
channel and holds a slider's next value while one is in flight, so a held value could land
after a preset and overwrite half of it. The order is therefore kept in the browser, by a small
front-end part (``PanelControls``, an anywidget, in ``hwlib/machinery/panel_controls.py``): it
sets the sliders to a preset there and sends the whole state (θ, seed, time step, numbered) after
every action on one channel, so the last state the kernel draws is the state of the last action. A
change made from Python (``set_params``, a slider's value set in code) is drawn as before;
without the front-end part the panel draws the controls' values.

Redraws never overlap and never go stale (``LatestOnly``): a change that arrives while a frame is
being drawn is only noted, and the drawing thread draws once more, with the latest state, before it
stops. A new episode costs about 60 ms (play it, draw its curves); a new time step only redraws the
cursor and the cart (about 10 ms, ``EpisodeView.frame_png``). While ▶ Play runs, the browser draws
the steps itself: the kernel sends the episode's picture without the moving parts and where they go
at every step (``EpisodeView.overlay``) once, and the browser draws the cursor and the cart over it,
20 frames per second whatever the kernel is doing; when the play stops, the kernel's own frame of
that step replaces it.

**The layout never moves.** Every part has a fixed size: the status line (reward and why the episode
ended, or what went wrong) has two lines and clips the rest (its tooltip holds all of it).

**Only θ's direction matters**: ``c θ`` with ``c > 0`` pushes the cart the same way as ``θ`` in every
state. When a change leaves θ pointing where it pointed (θ₃ moved alone while the others are 0,
say), the status line says so under the reward, so the unchanged episode does not look frozen.

If the policy raises ``NotImplementedError`` with a ``todo`` attribute (``TodoNotDone``, "TODO 1.1.1
is not done yet"), the status line says which TODO and what to do, in place of the reward; the
panel works as soon as the TODO is done and the cell is run again.
"""

from __future__ import annotations

import html
import math
import re
import threading
from dataclasses import dataclass, replace

import ipywidgets as widgets
import numpy as np

from hwlib.cartpole import (
    ALWAYS_LEFT_PARAMS,
    ALWAYS_RIGHT_PARAMS,
    MAX_EPISODE_REWARD,
    OBSERVATION_NAMES,
    SEED_BOUND,
    CartPoleLinearPolicy,
    Episode,
    play_episode,
)
from hwlib.machinery.latest_only import LatestOnly
from hwlib.machinery.panel_controls import (
    LANDSCAPE_BUTTON_LABEL,  # noqa: F401 - the button's label, read with the panel's other texts
    STATUS_LINES,
    PanelControls,
)
from hwlib.machinery.validation import check_params, check_seed
from hwlib.plots.cartpole import EpisodeView, how_it_ended, message_png
from hwlib.plots.landscape import format_theta

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


DEFAULT_SEED = 0
PLAY_INTERVAL_MS = 50  # one animation frame every 0.05 s (20 frames per second) ...
PLAY_FRAMES = 250  # ... and at most 250 frames per episode (so any episode plays in at most 12.5 s)
FIGURE_DPI, FIGURE_WIDTH, FIGURE_HEIGHT = 80, 9.0, 4.4  # the panel's picture: 720 x 352 px


# The two presets: neither balances the pole (finding weights that do is handout 1.1.2).
PRESETS = {
    "always left": grid_params(ALWAYS_LEFT_PARAMS),
    "always right": grid_params(ALWAYS_RIGHT_PARAMS),
}
DEFAULT_PARAMS = PRESETS["always left"]  # θ = 0: the panel starts from a policy that fails quickly


@dataclass(frozen=True)
class PanelFrame:
    """What the panel shows for one setting of the controls (``description``: the picture in words,
    its alternative text for a screen reader)."""

    episode: Episode
    step: int
    reward_text: str
    png: bytes
    description: str


def reward_text(episode):
    """The panel's reward line, e.g. 'Total reward: 11 (the pole fell past ±0.21 rad = ±12°)'."""
    if not isinstance(episode, Episode):
        raise TypeError(f"episode must be an hwlib.cartpole.Episode, got {type(episode).__name__}")
    return f"Total reward: {int(episode.total_reward)} ({_ending(episode)})"


def _ending(episode):
    return "the maximum" if episode.total_reward >= MAX_EPISODE_REWARD else how_it_ended(episode)


def episode_description(params, seed, episode, step):
    """The panel's picture in words (its alternative text): the weights as the readouts show them, the seed,
    the reward and why the episode ended, and the step the cart is drawn at."""
    if not isinstance(episode, Episode):
        raise TypeError(f"episode must be an hwlib.cartpole.Episode, got {type(episode).__name__}")
    return (f"The episode of θ = {format_theta(check_params(params, 'params'))} from seed {check_seed(seed, 'seed')}: total reward "
            f"{int(episode.total_reward)} ({_ending(episode)}). The plots show the cart position and the pole angle over its "
            f"{episode.num_steps} steps with their limits; the drawing shows the cart and pole at step {step} of {episode.num_steps}.")


def same_direction(before, after):
    """Whether ``after`` is ``before`` times a number > 0 (and not ``before`` itself): the same policy,
    since only θ's direction matters. Both are 4 weights; a zero vector has no direction."""
    before, after = np.asarray(before, dtype=np.float64), np.asarray(after, dtype=np.float64)
    if not before.any() or not after.any() or np.array_equal(before, after):
        return False
    scale = np.abs(before).max() * np.abs(after).max()
    parallel = np.abs(np.outer(before, after) - np.outer(after, before)).max() <= 1e-12 * scale
    return bool(parallel and np.dot(before, after) > 0)


DIRECTION_NOTE = "θ points as before: only its direction matters (c·θ acts as θ for any c > 0), so the episode is the same."


def simulate_episode(params, seed):
    """One episode of the linear policy with ``params`` from ``reset(seed=seed)``."""
    return play_episode(CartPoleLinearPolicy(check_params(params, "params")), seed=check_seed(seed, "seed"))


def render_panel(params, seed, step=None, view=None, episode=None):
    """The panel's callback: play the episode (unless ``episode`` is given) and draw it.

    ``params`` are the 4 weights, ``seed`` the episode's seed. ``episode``, if given, must be the
    episode of these params and seed (the panel passes the one it already played when only the
    time step moves). ``view`` is the ``EpisodeView`` to redraw (a new one if None); ``step``
    picks the step the cart is drawn at (None: the last). Returns a ``PanelFrame``.
    """
    params = check_params(params, "params")
    seed = check_seed(seed, "seed")
    if view is not None and not isinstance(view, EpisodeView):
        raise TypeError(f"view must be an hwlib.plots.cartpole.EpisodeView or None, got {type(view).__name__}")
    if episode is None:
        episode = simulate_episode(params, seed)
    elif not isinstance(episode, Episode):
        raise TypeError(f"episode must be an hwlib.cartpole.Episode or None, got {type(episode).__name__}")
    view = EpisodeView(FIGURE_DPI, FIGURE_WIDTH, FIGURE_HEIGHT) if view is None else view
    png = view.frame_png(episode, step)  # checks step
    step = episode.num_steps if step is None else int(step)
    return PanelFrame(episode, step, reward_text(episode), png, episode_description(params, seed, episode, step))


class SliderPanel:
    """The ipywidgets panel. Display it (or ``panel.widget``) in a notebook.

    ``params``: the weights the sliders start at (default: all zero, the "always left" preset),
    within [-2, 2]; they are moved to the sliders' 0.01 grid. ``seed``: the episode's seed.
    """

    def __init__(self, params=None, seed=DEFAULT_SEED):
        params = DEFAULT_PARAMS if params is None else grid_params(params, "params")
        seed = check_seed(seed, "seed")
        if seed >= SEED_BOUND:
            raise ValueError(f"seed must be below {SEED_BOUND}, got {seed}")
        self.view = EpisodeView(FIGURE_DPI, FIGURE_WIDTH, FIGURE_HEIGHT)
        self.episode = None
        self.not_done = None  # the TodoNotDone the policy raised, while it does
        self._episode_key = None
        self._listeners = []
        self._writing = threading.local()  # set while the panel itself moves the time step
        self._params_lock = threading.Lock()  # one set_params at a time
        self._state_lock = threading.Lock()
        self._state = PanelState(tuple(params), seed)
        self._frontend = False  # True once the browser's part speaks: it then sends the state
        self._drawn_params = None  # the weights of the last episode drawn
        self._direction_note = ""  # the line under the reward when they point where the weights before them did
        self._overlay_key = None  # the (params, seed) whose overlay the browser has for ▶ Play

        self.param_sliders = [
            widgets.FloatSlider(
                value=value, min=SLIDER_MIN, max=SLIDER_MAX, step=SLIDER_STEP, description=label,
                tooltip=SLIDER_TOOLTIP.format(sub=SUBSCRIPTS[index], name=name, unit=unit),
                continuous_update=True, readout_format=".2f",
                style={"description_width": "17em"}, layout=widgets.Layout(width="36em"),
            )
            for index, (value, label, name, unit) in enumerate(zip(params, SLIDER_LABELS, OBSERVATION_NAMES, OBSERVATION_UNITS))
        ]
        self.seed_box = widgets.BoundedIntText(
            value=seed, min=0, max=SEED_BOUND - 1, description="seed", tooltip=SEED_TOOLTIP,
            style={"description_width": "3em"}, layout=widgets.Layout(width="13em"),
        )
        self.reward_label = widgets.HTML(
            tooltip=REWARD_TOOLTIP,
            layout=widgets.Layout(width="auto", align_self="stretch", height=f"{1.4 * STATUS_LINES + 0.4:.1f}em", overflow="hidden"),
        )
        self.reward_label.add_class("hwlib-reward")
        self.reward_label.add_class("hwlib-status")
        self.step_slider = widgets.IntSlider(
            value=0, min=0, max=0, description="time step", tooltip=STEP_TOOLTIP, continuous_update=True,
            style={"description_width": "5em"}, layout=widgets.Layout(width="36em"),
        )
        # No description: ipywidgets 8 shows a Play's tooltip only when its description is empty.
        self.play = widgets.Play(value=0, min=0, max=0, interval=PLAY_INTERVAL_MS, tooltip=PLAY_TOOLTIP, show_repeat=False)
        self.play_link = widgets.jslink((self.play, "value"), (self.step_slider, "value"))  # runs in the browser
        self.controls = PanelControls(
            controls=[*self.param_sliders, self.seed_box, self.step_slider, self.play],
            presets=[{"name": name, "params": list(values), "tooltip": PRESET_TOOLTIPS[name]} for name, values in PRESETS.items()],
        )
        # No tooltip on the image: ipywidgets 8's Image view fails to render with one. Its size is
        # fixed (the figure's), so nothing below or beside it moves while an error is shown.
        width, height = round(FIGURE_DPI * FIGURE_WIDTH), round(FIGURE_DPI * FIGURE_HEIGHT)
        self.image = widgets.Image(
            format="png", layout=widgets.Layout(width=f"{width}px", height=f"{height}px", align_self="flex-start", flex="0 0 auto"),
        )
        self.image.add_class("hwlib-episode")

        self.widget = widgets.VBox([
            widgets.HBox(
                [
                    widgets.VBox(self.param_sliders, layout=widgets.Layout(flex="0 0 auto")),
                    widgets.VBox([self.seed_box, self.controls], layout=widgets.Layout(flex="0 0 auto")),
                ],
                layout=widgets.Layout(flex_flow="row nowrap"),
            ),
            widgets.HBox([self.play, self.step_slider], layout=widgets.Layout(flex_flow="row nowrap")),
            self.reward_label,
            self.image,
        ])
        self.widget.add_class("hwlib-slider-panel")

        self._draw(raise_errors=True)  # a broken policy fails here, in the cell, with its traceback
        self._redraws = LatestOnly(self._draw)
        for control in [*self.param_sliders, self.seed_box, self.step_slider]:
            control.observe(self._on_control_change, names="value")
        self.controls.observe(self._on_frontend_state, names="state")
        self.play.observe(lambda _change: self._redraws.request(), names="playing")
        self.controls.on_msg(self._on_frontend_message)

    def _repr_mimebundle_(self, **kwargs):
        return self.widget._repr_mimebundle_(**kwargs)

    @property
    def params(self):
        """The four weights the panel shows, as a tuple of floats."""
        return tuple(float(value) for value in self._state.params)

    @property
    def state(self):
        """The ``PanelState`` the panel shows (or is about to show)."""
        return self._state

    def set_params(self, params):
        """Move the sliders to ``params`` (within [-2, 2], put on the 0.01 grid) and redraw once."""
        params = grid_params(params, "params")
        # One redraw for the four sliders, not four; and never half of one preset and half of another.
        with self._redraws.held(), self._params_lock:
            for slider, value in zip(self.param_sliders, params):
                slider.value = value
            with self._state_lock:
                self._state = replace(self._state, params=params, step=None, seq=0)

    def apply_preset(self, name):
        """Move the sliders to the preset ``name`` ("always left" or "always right"), as its button does."""
        if name not in PRESETS:
            raise ValueError(f"name must be one of the presets {list(PRESETS)}, got {name!r}")
        self.set_params(PRESETS[name])

    def on_send_params(self, callback):
        """Call ``callback(params)`` (a tuple of 4 floats) whenever "Show θ in the landscape" is clicked.

        Enables the button. Returns ``callback``, so this also works as a decorator.
        """
        if not callable(callback):
            raise TypeError(f"callback must be callable as callback(params), got {type(callback).__name__}")
        self._listeners.append(callback)
        self.controls.landscape_enabled = True
        self.controls.landscape_tooltip = LANDSCAPE_TOOLTIP_CONNECTED
        return callback

    def send_params(self, params=None):
        """Call every listener registered with ``on_send_params`` with ``params`` (default: the panel's weights).

        Every listener is called even if one raises; the first error is raised afterwards.
        """
        params = self.params if params is None else grid_params(params, "params")
        first_error = None
        for listener in list(self._listeners):
            try:
                listener(params)
            except Exception as error:  # noqa: BLE001 (re-raised below, after the other listeners)
                first_error = first_error or error
        if first_error is not None:
            raise first_error

    # --- what the browser and the kernel change ---------------------------------------------------

    def _on_control_change(self, change):
        if getattr(self._writing, "active", False):
            return  # the panel's own move of the time step, already part of the frame being drawn
        control = change.owner
        if self._frontend and "value" in control._property_lock:
            return  # the control's own message from the browser: the browser's state carries it, in order
        with self._state_lock:
            state = self._state
            if control is self.step_slider:
                self._state = replace(state, step=int(change.new), seq=0)
            elif control is self.seed_box:
                self._state = replace(state, seed=int(change.new), step=None, seq=0)
            else:
                params = list(state.params)
                params[self.param_sliders.index(control)] = float(change.new)
                self._state = replace(state, params=tuple(params), step=None, seq=0)
        self._redraws.request()

    def _on_frontend_state(self, change):
        if change.new is None:
            return
        try:
            state = parse_frontend_state(change.new)
        except (TypeError, ValueError):
            return  # not a state the panel's front end sends: leave the panel as it is
        self._frontend = True
        with self._state_lock:
            self._state = state
        self._redraws.request()

    def _on_frontend_message(self, _widget, content, _buffers):
        if not isinstance(content, dict):
            return
        if content.get("event") == "connected":
            self._frontend = True
        elif content.get("event") == "send_params":
            self.send_params(content.get("params"))

    # --- drawing ------------------------------------------------------------------------------

    def _draw(self, raise_errors=False):
        """Draw one frame for the panel's current state (only ever one thread at a time)."""
        with self._state_lock:
            state = self._state
        params, seed = state.params, state.seed
        try:
            if self.episode is None or self._episode_key != (params, seed):
                self.episode, self._episode_key = None, None
                episode = simulate_episode(params, seed)
                self.episode, self._episode_key = episode, (params, seed)
                self._move_time_step(episode.num_steps)
            step = self.episode.num_steps if state.step is None else min(state.step, self.episode.num_steps)
            frame = render_panel(params, seed, step=step, view=self.view, episode=self.episode)
        except Exception as error:
            lines = todo_message(error)
            if raise_errors and lines is None:
                raise
            self._show_error(error, lines)
            return
        self.not_done = None
        # The time step slider shows the step drawn when the panel chose it (a new episode's end, or the
        # end of one shorter than the step asked for). A step the browser asked for is its own value
        # already: writing it back late would pull ▶ Play back to a step it has passed.
        if (state.step is None or state.step != step) and self.step_slider.value != step:
            self._writing.active = True
            try:
                self.step_slider.value = step
            finally:
                self._writing.active = False
        note = ""
        if self._drawn_params is not None and same_direction(self._drawn_params, params):
            note = f"<br>{html.escape(DIRECTION_NOTE)}"
        if self._drawn_params != params:
            self._drawn_params = params
            self._direction_note = note
        self.reward_label.value = f"<b>{html.escape(frame.reward_text)}</b>{self._direction_note}"
        self.reward_label.tooltip = REWARD_TOOLTIP + (f"\n{DIRECTION_NOTE}" if self._direction_note else "")
        self.image.value = frame.png
        self.controls.image_alt = frame.description
        if self.play.playing and self._overlay_key != (params, seed):
            # ▶ plays: the browser draws the steps over the episode's picture, with this
            data = self.view.overlay(self.episode)
            self.controls.overlay = {**data, "params": list(params), "seed": seed}
            self.controls.overlay_png = self.view.background_png(self.episode)
            self._overlay_key = (params, seed)
        self.controls.drawn = max(self.controls.drawn, state.seq)

    def _show_error(self, error, todo_lines):
        """Say what went wrong in the status line, and in the picture, whose size stays."""
        self.episode, self._episode_key = None, None
        if todo_lines is not None:
            self.not_done = error
            lines = todo_lines
            text = "<br>".join(f"<b>{html.escape(line)}</b>" if index == 0 else html.escape(line) for index, line in enumerate(lines))
        else:
            lines = ["Could not play the episode", f"{type(error).__name__}: {error}"]
            text = f"<b>Could not play the episode</b>: {html.escape(type(error).__name__)}: {html.escape(str(error))}"
        self.reward_label.value = text
        self.reward_label.tooltip = "\n".join(lines)  # all of it, however long
        self.image.value = message_png(lines, self.view.figure.get_size_inches(), self.view.figure.dpi)
        self.controls.image_alt = "The picture says: " + " ".join(lines)

    def _move_time_step(self, num_steps):
        self._writing.active = True
        try:
            for control in (self.step_slider, self.play):
                control.max = num_steps  # first the max, so the value is never clamped to the old one
            self.play.step = max(1, math.ceil(num_steps / PLAY_FRAMES))
        finally:
            self._writing.active = False


def slider_panel(params=None, seed=DEFAULT_SEED):
    """Build the panel; the notebook displays what this returns.

    Returns the ``SliderPanel`` (it displays as its widget); keep it to connect a listener,
    e.g. ``panel = slider_panel()`` then ``panel.on_send_params(...)``.
    """
    return SliderPanel(params, seed)
