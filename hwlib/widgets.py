"""The slider panel for hand-tuning the CartPole policy (handout 1.1.2).

Four sliders set the policy parameters, a number box sets the episode's seed, and a step
slider scrubs through the episode. Every change calls ``render_panel``, a plain function
that plays the episode and draws it; the widgets only pass values in and show what comes
back, so the whole panel logic is tested without a browser.
"""

from __future__ import annotations

from dataclasses import dataclass

import ipywidgets as widgets

from hwlib._checks import check_params, check_seed
from hwlib.cartpole import (
    ALWAYS_LEFT_PARAMS,
    ALWAYS_RIGHT_PARAMS,
    BALANCING_PARAMS,
    OBSERVATION_NAMES,
    CartPoleLinearPolicy,
    Episode,
    play_episode,
)
from hwlib.plots.cartpole import EpisodeView, figure_png

PRESETS = {
    "always left": ALWAYS_LEFT_PARAMS,
    "always right": ALWAYS_RIGHT_PARAMS,
    "balancing (hand-tuned)": BALANCING_PARAMS,
}
SLIDER_RANGE = (-2.0, 2.0)
DEFAULT_SEED = 0


@dataclass(frozen=True)
class PanelFrame:
    """What the panel shows for one setting of the controls."""

    episode: Episode
    reward_text: str
    png: bytes


def reward_text(episode):
    """The panel's reward line, e.g. 'Total reward: 500 (the maximum)'."""
    reward = int(episode.total_reward)
    suffix = " (the maximum)" if reward == 500 else ""
    return f"Total reward: {reward}{suffix}"


def simulate_episode(params, seed):
    """One episode of the linear policy with ``params`` from ``reset(seed=seed)``."""
    return play_episode(CartPoleLinearPolicy(check_params(params, "params")), seed=check_seed(seed, "seed"))


def render_panel(params, seed, step=None, view=None, episode=None):
    """The panel's callback: play the episode (unless ``episode`` is given) and draw it.

    ``view`` is the ``EpisodeView`` to redraw (a new one if None); ``step`` picks the step
    the cart is drawn at (default: the last). Returns a ``PanelFrame``.
    """
    if episode is None:
        episode = simulate_episode(params, seed)
    view = EpisodeView() if view is None else view
    view.show(episode, step)
    return PanelFrame(episode, reward_text(episode), figure_png(view.figure))


class SliderPanel:
    """The ipywidgets panel. Display ``panel.widget`` in a notebook."""

    def __init__(self, params=BALANCING_PARAMS, seed=DEFAULT_SEED):
        params = check_params(params, "params")
        self.view = EpisodeView()
        self.episode = None
        self.param_sliders = [
            widgets.FloatSlider(
                value=float(value), min=SLIDER_RANGE[0], max=SLIDER_RANGE[1], step=0.01,
                description=f"θ{index + 1}", tooltip=f"weight on the {name}", continuous_update=True,
                readout_format=".2f",
            )
            for index, (value, name) in enumerate(zip(params, OBSERVATION_NAMES))
        ]
        self.seed_box = widgets.BoundedIntText(value=check_seed(seed, "seed"), min=0, max=2**31 - 1, description="seed")
        self.step_slider = widgets.IntSlider(value=0, min=0, max=0, description="step")
        self.preset_buttons = [widgets.Button(description=name, layout=widgets.Layout(width="auto")) for name in PRESETS]
        self.reward_label = widgets.HTML(layout=widgets.Layout(min_width="20em"))
        self.reward_label.add_class("hwlib-reward")
        self.image = widgets.Image(format="png")

        for control in [*self.param_sliders, self.seed_box]:
            control.observe(self._on_episode_change, names="value")
        self.step_slider.observe(self._on_step_change, names="value")
        for button in self.preset_buttons:
            button.on_click(self._on_preset)

        self.widget = widgets.VBox([
            widgets.HBox(self.preset_buttons),
            widgets.HBox([widgets.VBox(self.param_sliders), widgets.VBox([self.seed_box, self.reward_label])]),
            self.step_slider,
            self.image,
        ])
        self.refresh()

    @property
    def params(self):
        return tuple(slider.value for slider in self.param_sliders)

    def set_params(self, params):
        """Move the sliders to ``params`` and redraw once."""
        params = check_params(params, "params")
        for slider, value in zip(self.param_sliders, params):
            slider.unobserve(self._on_episode_change, names="value")  # one replay for all four, not four
            slider.value = float(value)
            slider.observe(self._on_episode_change, names="value")
        self.refresh()

    def refresh(self):
        """Play the episode for the current controls and redraw everything."""
        self.episode = simulate_episode(self.params, self.seed_box.value)
        self.step_slider.unobserve(self._on_step_change, names="value")
        self.step_slider.max = self.episode.num_steps
        self.step_slider.value = self.episode.num_steps
        self.step_slider.observe(self._on_step_change, names="value")
        self._show(render_panel(self.params, self.seed_box.value, view=self.view, episode=self.episode))

    def _show(self, frame):
        self.reward_label.value = f"<b>{frame.reward_text}</b>"
        self.image.value = frame.png

    def _on_episode_change(self, _change):
        self.refresh()

    def _on_step_change(self, change):
        self._show(render_panel(self.params, self.seed_box.value, step=change["new"], view=self.view, episode=self.episode))

    def _on_preset(self, button):
        self.set_params(PRESETS[button.description])


def slider_panel(params=BALANCING_PARAMS, seed=DEFAULT_SEED):
    """Build the panel and return the widget to display."""
    return SliderPanel(params, seed).widget
