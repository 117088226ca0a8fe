"""The slider panel for hand-tuning the CartPole policy (handout 1.1.2).

Four sliders set the policy's weights θ₁..θ₄, a number box sets the episode's seed, and a
*time step* slider (with a ▶ Play control) moves through the episode. Every change ends in
``render_panel``, a plain function that plays the episode and draws it; the widgets only pass
values in and show what comes back, so the panel's logic is tested without a browser.

Redraws never overlap and never go stale. A change can arrive on more than one thread (the
kernel may handle widget messages outside its main thread), and a figure drawn by two threads
at once can end up blank for good. So the panel draws one frame at a time: a change that
arrives while a frame is being drawn is only noted, and the drawing thread draws once more,
with the controls' latest values, before it stops (many quick changes cost one extra frame,
not one each). The presets lie on the sliders' grid, so the browser has nothing to snap and
echo back when a preset is clicked.
"""

from __future__ import annotations

import contextlib
import html
import math
import threading
from dataclasses import dataclass

import ipywidgets as widgets

from hwlib._checks import check_params, check_seed
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
from hwlib.plots.cartpole import EpisodeView, figure_png, how_it_ended

SLIDER_MIN, SLIDER_MAX, SLIDER_STEP = -2.0, 2.0, 0.01
SLIDER_RANGE = (SLIDER_MIN, SLIDER_MAX)
OBSERVATION_UNITS = ("m", "m/s", "rad", "rad/s")
SUBSCRIPTS = "₁₂₃₄"
SLIDER_LABELS = tuple(
    f"θ{SUBSCRIPTS[index]} · {name} [{unit}]" for index, (name, unit) in enumerate(zip(OBSERVATION_NAMES, OBSERVATION_UNITS))
)
DEFAULT_SEED = 0
PLAY_INTERVAL_MS = 100  # one animation frame every 0.1 s ...
PLAY_FRAMES = 100  # ... and at most ~100 frames per episode (a 500-step episode plays in ~10 s)
LANDSCAPE_BUTTON_LABEL = "Show θ in the landscape"


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


# The two presets: neither balances the pole (finding weights that do is handout 1.1.2).
PRESETS = {
    "always left": grid_params(ALWAYS_LEFT_PARAMS),
    "always right": grid_params(ALWAYS_RIGHT_PARAMS),
}
PRESET_TOOLTIPS = {
    "always left": "θ = (0, 0, 0, 0): θ·s is never negative, so the cart is pushed left at every step",
    "always right": "θ = (0, −1, 0, 1): once the cart is pushed right, θ·s only gets more negative, so it keeps being pushed right",
}
DEFAULT_PARAMS = PRESETS["always left"]  # θ = 0: the panel starts from a policy that fails quickly

SLIDER_TOOLTIP = (
    "Weight θ{sub} on the {name} [{unit}]. The policy pushes the cart right when "
    "θ₁·x + θ₂·ẋ + θ₃·φ + θ₄·φ̇ < 0, otherwise left. Drag, or click the handle and use the arrow keys (0.01 per press)."
)
SEED_TOOLTIP = "Seed of the episode's start state, reset(seed=...): the same seed always gives the same start"
STEP_TOOLTIP = "The time step the cart is drawn at (the grey line in the plots). Drag to move through the episode, or press ▶"
PLAY_TOOLTIP = "Play the episode: moves the time step from 0 to the end (press again to pause)"
REWARD_TOOLTIP = f"Total reward of the episode: +1 for every step the pole stays up, {MAX_EPISODE_REWARD} at most"
LANDSCAPE_TOOLTIP_CONNECTED = "Mark the current θ in the reward landscape view"
LANDSCAPE_TOOLTIP_UNCONNECTED = "No landscape view is connected to this panel (connect one with panel.on_send_params)"


@dataclass(frozen=True)
class PanelFrame:
    """What the panel shows for one setting of the controls."""

    episode: Episode
    step: int
    reward_text: str
    png: bytes


def reward_text(episode):
    """The panel's reward line, e.g. 'Total reward: 11 (the pole fell past 12°)'."""
    if not isinstance(episode, Episode):
        raise TypeError(f"episode must be an hwlib.cartpole.Episode, got {type(episode).__name__}")
    reward = int(episode.total_reward)
    reason = "the maximum" if reward >= MAX_EPISODE_REWARD else how_it_ended(episode)
    return f"Total reward: {reward} ({reason})"


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
    view = EpisodeView() if view is None else view
    view.show(episode, step)  # checks step
    step = episode.num_steps if step is None else int(step)
    return PanelFrame(episode, step, reward_text(episode), figure_png(view.figure))


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
        self.view = EpisodeView()
        self.episode = None
        self._episode_key = None
        self._listeners = []
        self._writing = threading.local()  # set while the panel itself moves the time step
        self._params_lock = threading.Lock()  # one set_params at a time

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
        self.preset_buttons = [
            widgets.Button(description=name, tooltip=PRESET_TOOLTIPS[name], layout=widgets.Layout(width="auto"))
            for name in PRESETS
        ]
        self.landscape_button = widgets.Button(
            description=LANDSCAPE_BUTTON_LABEL, tooltip=LANDSCAPE_TOOLTIP_UNCONNECTED, disabled=True, icon="crosshairs",
            layout=widgets.Layout(width="auto"),
        )
        self.reward_label = widgets.HTML(tooltip=REWARD_TOOLTIP, layout=widgets.Layout(min_width="16em"))
        self.reward_label.add_class("hwlib-reward")
        self.step_slider = widgets.IntSlider(
            value=0, min=0, max=0, description="time step", tooltip=STEP_TOOLTIP, continuous_update=True,
            style={"description_width": "5em"}, layout=widgets.Layout(width="36em"),
        )
        # No description: ipywidgets 8 shows a Play's tooltip only when its description is empty.
        self.play = widgets.Play(value=0, min=0, max=0, interval=PLAY_INTERVAL_MS, tooltip=PLAY_TOOLTIP, show_repeat=False)
        self.play_link = widgets.jslink((self.play, "value"), (self.step_slider, "value"))  # runs in the browser
        # No tooltip on the image: ipywidgets 8's Image view fails to render with one.
        self.image = widgets.Image(format="png", layout=widgets.Layout(max_width="100%", height="auto", align_self="flex-start"))
        self.image.add_class("hwlib-episode")

        self.widget = widgets.VBox([
            widgets.HBox(
                [
                    widgets.VBox(self.param_sliders),
                    widgets.VBox([
                        widgets.HBox(self.preset_buttons),
                        self.seed_box,
                        self.reward_label,
                        self.landscape_button,
                    ]),
                ],
                layout=widgets.Layout(flex_flow="row wrap"),
            ),
            widgets.HBox([self.play, self.step_slider]),
            self.image,
        ])
        self.widget.add_class("hwlib-slider-panel")

        self._draw(raise_errors=True)  # a broken policy fails here, in the cell, with its traceback
        self._redraws = LatestOnly(self._draw)
        for control in [*self.param_sliders, self.seed_box, self.step_slider]:
            control.observe(self._on_control_change, names="value")
        for button in self.preset_buttons:
            button.on_click(self._on_preset)
        self.landscape_button.on_click(lambda _button: self.send_params())

    def _repr_mimebundle_(self, **kwargs):
        return self.widget._repr_mimebundle_(**kwargs)

    @property
    def params(self):
        """The four weights the sliders show, as a tuple of floats."""
        return tuple(float(slider.value) for slider in self.param_sliders)

    def set_params(self, params):
        """Move the sliders to ``params`` (within [-2, 2], put on the 0.01 grid) and redraw once."""
        params = grid_params(params, "params")
        # One redraw for the four sliders, not four; and never half of one preset and half of another.
        with self._redraws.held(), self._params_lock:
            for slider, value in zip(self.param_sliders, params):
                slider.value = value

    def refresh(self):
        """Redraw for the controls as they are now (from any thread; see ``LatestOnly``)."""
        self._redraws.request()

    def on_send_params(self, callback):
        """Call ``callback(params)`` (a tuple of 4 floats) whenever "Show θ in the landscape" is clicked.

        Enables the button. Returns ``callback``, so this also works as a decorator.
        """
        if not callable(callback):
            raise TypeError(f"callback must be callable as callback(params), got {type(callback).__name__}")
        self._listeners.append(callback)
        self.landscape_button.disabled = False
        self.landscape_button.tooltip = LANDSCAPE_TOOLTIP_CONNECTED
        return callback

    def send_params(self):
        """Call every listener registered with ``on_send_params`` with the current weights.

        Every listener is called even if one raises; the first error is raised afterwards.
        """
        params = self.params
        first_error = None
        for listener in list(self._listeners):
            try:
                listener(params)
            except Exception as error:  # noqa: BLE001 (re-raised below, after the other listeners)
                first_error = first_error or error
        if first_error is not None:
            raise first_error

    # --- drawing ------------------------------------------------------------------------------

    def _draw(self, raise_errors=False):
        """Draw one frame for the controls' current values (only ever one thread at a time)."""
        params, seed = self.params, int(self.seed_box.value)
        try:
            if self.episode is None or self._episode_key != (params, seed):
                episode = simulate_episode(params, seed)
                self.episode, self._episode_key = episode, (params, seed)
                step = episode.num_steps  # a new episode is shown at its end: where and why it stopped
                self._move_time_step(episode.num_steps, step)
            else:
                step = min(int(self.step_slider.value), self.episode.num_steps)
            frame = render_panel(params, seed, step=step, view=self.view, episode=self.episode)
        except Exception as error:
            if raise_errors:
                raise
            self.episode, self._episode_key = None, None
            self.reward_label.value = (
                f"<b>Could not play the episode</b>: {html.escape(type(error).__name__)}: {html.escape(str(error))}"
            )
            return
        self.reward_label.value = f"<b>{html.escape(frame.reward_text)}</b>"
        self.image.value = frame.png

    def _move_time_step(self, num_steps, step):
        self._writing.active = True
        try:
            for control in (self.step_slider, self.play):
                control.max = num_steps  # first the max, so the value is never clamped to the old one
            self.play.step = max(1, math.ceil(num_steps / PLAY_FRAMES))
            self.step_slider.value = step
        finally:
            self._writing.active = False

    def _on_control_change(self, _change):
        if getattr(self._writing, "active", False):
            return  # the panel's own move of the time step, already part of the frame being drawn
        self._redraws.request()

    def _on_preset(self, button):
        self.set_params(PRESETS[button.description])


def slider_panel(params=None, seed=DEFAULT_SEED):
    """Build the panel; the notebook displays what this returns.

    Returns the ``SliderPanel`` (it displays as its widget); keep it to connect a listener,
    e.g. ``panel = slider_panel()`` then ``panel.on_send_params(...)``.
    """
    return SliderPanel(params, seed)
