"""The slider panel without a browser: ``render_panel``, the presets, and ``SliderPanel`` driven
through its widgets' values and buttons, from one thread or two at once."""

import contextlib
import io
import threading

import ipywidgets as widgets
import matplotlib.image
import numpy as np
import pytest

from hwlib.cartpole import ALWAYS_LEFT_PARAMS, ALWAYS_RIGHT_PARAMS, MAX_EPISODE_REWARD
from hwlib.machinery.episodes import run_episodes
from hwlib.machinery.latest_only import LatestOnly
from hwlib.plots.cartpole import EpisodeView
from hwlib.widgets import (
    DEFAULT_PARAMS,
    LANDSCAPE_BUTTON_LABEL,
    PRESETS,
    SLIDER_LABELS,
    SLIDER_MAX,
    SLIDER_MIN,
    PLAY_INTERVAL_MS,
    PanelControls,
    SliderPanel,
    episode_description,
    render_panel,
    reward_text,
    simulate_episode,
    slider_grid_value,
    slider_panel,
    todo_message,
)

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def kit_reward(params, seed):
    """The reward from the kit's batch engine, which does not run the student's 1.1.1."""
    return int(run_episodes(np.array([params], dtype=float), [seed])[0])


def pixels(png):
    return matplotlib.image.imread(io.BytesIO(bytes(png)))


def opaque_share(png):
    """The share of the image's pixels that are not fully transparent (a blank figure has 0)."""
    image = pixels(png)
    return float(np.mean(image[..., 3] > 0)) if image.shape[2] == 4 else 1.0


def shows_state(panel):
    """The panel's image and reward line are those of its controls' current values."""
    params, seed, step = panel.params, panel.seed_box.value, panel.step_slider.value
    expected = render_panel(params, seed, step=step)
    assert np.array_equal(pixels(panel.image.value), pixels(expected.png)), f"the image is not that of {params}, seed {seed}, step {step}"
    assert f"Total reward: {kit_reward(params, seed)} " in panel.reward_label.value
    return True


# --- render_panel, the plain function -------------------------------------------------------


@pytest.mark.todo("1.1.1")
def test_render_panel_plays_the_episode_and_draws_it(balancing_params):
    frame = render_panel(balancing_params, seed=0)
    assert frame.episode.total_reward == MAX_EPISODE_REWARD and frame.step == MAX_EPISODE_REWARD
    assert frame.reward_text == f"Total reward: {MAX_EPISODE_REWARD} (the maximum)"
    assert frame.png.startswith(PNG_SIGNATURE) and opaque_share(frame.png) == 1.0


@pytest.mark.todo("1.1.1")
@pytest.mark.parametrize(("params", "seed"), [((0.5, -0.3, -1.2, 0.4), 4), (ALWAYS_RIGHT_PARAMS, 0), ((0.0, 0.0, 0.0, -0.2), 0)])
def test_render_panel_reward_is_the_kits_reward(params, seed):
    frame = render_panel(params, seed=seed)
    assert frame.reward_text.startswith(f"Total reward: {kit_reward(params, seed)} (")


@pytest.mark.todo("1.1.1")
def test_render_panel_redraws_the_same_view_differently_for_other_params(balancing_params):
    view = EpisodeView()
    balanced = render_panel(balancing_params, seed=0, view=view)
    falling = render_panel(ALWAYS_LEFT_PARAMS, seed=0, view=view)
    assert balanced.png != falling.png
    assert balanced.episode.num_steps == MAX_EPISODE_REWARD and falling.episode.num_steps < 20
    # The reused view draws what a new one draws.
    assert np.array_equal(pixels(falling.png), pixels(render_panel(ALWAYS_LEFT_PARAMS, seed=0).png))


@pytest.mark.todo("1.1.1")
def test_step_moves_only_the_picture():
    episode = simulate_episode(ALWAYS_LEFT_PARAMS, 0)
    view = EpisodeView()
    start = render_panel(ALWAYS_LEFT_PARAMS, 0, step=0, view=view, episode=episode)
    end = render_panel(ALWAYS_LEFT_PARAMS, 0, view=view, episode=episode)
    assert start.reward_text == end.reward_text
    assert (start.step, end.step) == (0, episode.num_steps)
    assert start.png != end.png


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"params": [1, 2, 3], "seed": 0}, ValueError, "params must have shape"),
        ({"params": [0, 0, np.nan, 0], "seed": 0}, ValueError, "params must hold only finite"),
        ({"params": "abcd", "seed": 0}, TypeError, "params must be an array of numbers"),
        ({"params": ALWAYS_LEFT_PARAMS, "seed": -1}, ValueError, "seed must be a non-negative integer"),
        ({"params": ALWAYS_LEFT_PARAMS, "seed": 1.5}, ValueError, "seed must be a non-negative integer"),
        ({"params": ALWAYS_LEFT_PARAMS, "seed": 0, "step": 12}, ValueError, "step must be None or a whole number from 0 to 11"),
        ({"params": ALWAYS_LEFT_PARAMS, "seed": 0, "step": -1}, ValueError, "step must be None or a whole number"),
        ({"params": ALWAYS_LEFT_PARAMS, "seed": 0, "step": 2.5}, ValueError, "step must be None or a whole number"),
        ({"params": ALWAYS_LEFT_PARAMS, "seed": 0, "view": "figure"}, TypeError, "view must be an hwlib.plots.cartpole.EpisodeView"),
        ({"params": ALWAYS_LEFT_PARAMS, "seed": 0, "episode": [1, 2]}, TypeError, "episode must be an hwlib.cartpole.Episode"),
    ],
)
def test_render_panel_rejects_bad_controls(kwargs, error, message):
    with pytest.raises(error, match=message):
        render_panel(**kwargs)


@pytest.mark.todo("1.1.1")
def test_reward_text_says_why_the_episode_ended(balancing_params):
    assert reward_text(simulate_episode(ALWAYS_LEFT_PARAMS, 0)) == "Total reward: 11 (the pole fell past ±0.21 rad = ±12°)"
    assert reward_text(simulate_episode((0.0, 0.0, 0.0, -0.2), 0)) == "Total reward: 142 (the cart ran off the track past ±2.4 m)"
    assert reward_text(simulate_episode(balancing_params, 0)) == f"Total reward: {MAX_EPISODE_REWARD} (the maximum)"
    with pytest.raises(TypeError, match="episode must be"):
        reward_text(500)


# --- presets and the sliders' grid ---------------------------------------------------------------


def test_presets_are_the_two_that_fail_and_none_balances():
    assert PRESETS == {"always left": (0.0, 0.0, 0.0, 0.0), "always right": (0.0, -1.0, 0.0, 1.0)}
    seeds = list(range(5))
    for name, params in PRESETS.items():
        rewards = run_episodes(np.repeat([params], len(seeds), axis=0), seeds)
        assert rewards.max() < MAX_EPISODE_REWARD, f"the preset {name!r} balances the pole: it hands over 1.1.2's answer"
    assert kit_reward(DEFAULT_PARAMS, 0) < MAX_EPISODE_REWARD


def test_presets_lie_on_the_sliders_grid():
    for params in PRESETS.values():
        assert all(slider_grid_value(value) == value for value in params)


def test_slider_grid_value_is_what_the_browser_sends_back():
    # ipywidgets' slider (noUiSlider) turns -0.1 into 47.5 % of [-2, 2] and back into 1.9 - 2.
    assert slider_grid_value(-0.1) == 1.9 - 2 == -0.10000000000000009
    assert slider_grid_value(0.123) == slider_grid_value(0.12)
    grid = [slider_grid_value(SLIDER_MIN + k * 0.01) for k in range(401)]
    assert grid[0] == SLIDER_MIN and grid[-1] == SLIDER_MAX and np.all(np.diff(grid) > 0.0099)
    assert all(slider_grid_value(value) == value for value in grid), "a grid value must stay where it is"


# --- the panel -----------------------------------------------------------------------------------


def walk(widget):
    yield widget
    for child in getattr(widget, "children", ()):
        yield from walk(child)


def test_panel_names_every_control_and_gives_each_a_tooltip():
    panel = SliderPanel()
    assert [slider.description for slider in panel.param_sliders] == list(SLIDER_LABELS) == [
        "θ₁ · cart position [m]", "θ₂ · cart velocity [m/s]", "θ₃ · pole angle [rad]", "θ₄ · pole angular velocity [rad/s]",
    ]
    assert panel.step_slider.description == "time step"
    assert panel.controls.landscape_label == LANDSCAPE_BUTTON_LABEL == "Show θ in the landscape"
    shown = list(walk(panel.widget))
    # Every widget but the boxes, the image (ipywidgets 8 cannot show an Image with a tooltip) and
    # the front-end part, which draws the preset and landscape buttons: θ sliders, seed, reward,
    # play, time step; then the buttons the front-end part draws: two presets, the landscape.
    assert panel.controls in shown
    controls = [w for w in shown if not isinstance(w, (widgets.Box, widgets.Image, PanelControls))]
    buttons = [(preset["name"], preset["tooltip"]) for preset in panel.controls.presets]
    buttons.append((panel.controls.landscape_label, panel.controls.landscape_tooltip))
    assert len(controls) + len(buttons) == 4 + 1 + 2 + 1 + 1 + 1 + 1
    assert [name for name, _ in buttons] == [*PRESETS, LANDSCAPE_BUTTON_LABEL]
    for control in controls:
        # A missing tooltip reads "null" in the browser.
        assert isinstance(control.tooltip, str) and len(control.tooltip) > 10, f"{type(control).__name__}: tooltip {control.tooltip!r}"
    for name, tooltip in buttons:
        assert isinstance(tooltip, str) and len(tooltip) > 10, f"button {name!r}: tooltip {tooltip!r}"
    assert [preset["params"] for preset in panel.controls.presets] == [list(values) for values in PRESETS.values()]
    assert panel.play.description == "", "a Play shows its tooltip only without a description"
    assert panel.image.tooltip is None
    assert all(slider.min <= -2 and slider.max >= 2 and slider.step == 0.01 for slider in panel.param_sliders)


@pytest.mark.todo("1.1.1")
def test_the_picture_is_described_in_words_a_screen_reader_reads(monkeypatch):
    """The picture's alternative text (the front-end part sets it as the image's ``alt``) says what it shows,
    its numbers rounded as the readouts show them; ▶ Play's icon buttons get names; the status line is live."""
    params = (0.0, 0.0, 0.0, slider_grid_value(-0.3))
    assert params[3] != -0.3
    frame = render_panel(params, 0, step=71)
    reward = kit_reward(params, 0)
    assert frame.description == episode_description(params, 0, frame.episode, 71) == (
        f"The episode of θ = (0.00, 0.00, 0.00, -0.30) from seed 0: total reward {reward} (the cart ran off the track past "
        f"±2.4 m). The plots show the cart position and the pole angle over its {reward} steps with their limits; the "
        f"drawing shows the cart and pole at step 71 of {reward}.")
    panel = SliderPanel(params)
    assert panel.controls.image_alt == render_panel(params, 0).description
    panel.step_slider.value = 10
    assert panel.controls.image_alt.endswith(f"at step 10 of {reward}.")
    with monkeypatch.context() as patch:
        patch.setattr("hwlib.widgets.simulate_episode", lambda params, seed: 1 / 0)
        panel.param_sliders[0].value = 0.5
        assert panel.controls.image_alt == "The picture says: Could not play the episode ZeroDivisionError: division by zero"
    assert set(panel.controls.button_names) == {"fa-play", "fa-pause", "fa-stop", "fa-retweet"}
    assert all(len(name) > 3 for name in panel.controls.button_names.values())
    from hwlib.machinery.panel_controls import PANEL_CSS, PANEL_ESM

    script = PANEL_ESM.read_text(encoding="utf-8")
    for made in ('"aria-label"', '"aria-valuetext"', '"aria-live", "polite"', '"alt"'):
        assert made in script, f"the front-end part no longer sets {made}"
    assert ":focus-visible" in PANEL_CSS and "outline: 3px solid" in PANEL_CSS


@pytest.mark.todo("1.1.1")  # the episode's length is the student's policy's
def test_play_is_linked_to_the_time_step_in_the_browser():
    panel = SliderPanel(ALWAYS_RIGHT_PARAMS)
    link = panel.play_link
    assert type(link).__name__ == "Link", "the Play control must move the time step slider by a jslink (in the browser)"
    assert link.source == (panel.play, "value") and link.target == (panel.step_slider, "value")
    assert isinstance(panel.play, widgets.Play) and panel.play in list(walk(panel.widget))
    assert panel.play.min == 0 and panel.play.max == panel.step_slider.max == panel.episode.num_steps == 8


@pytest.mark.todo("1.1.1")
def test_panel_starts_from_a_failing_policy():
    panel = SliderPanel()
    assert panel.params == DEFAULT_PARAMS
    assert f"Total reward: {kit_reward(DEFAULT_PARAMS, 0)} (" in panel.reward_label.value
    assert kit_reward(DEFAULT_PARAMS, 0) < MAX_EPISODE_REWARD
    assert bytes(panel.image.value).startswith(PNG_SIGNATURE) and shows_state(panel)


@pytest.mark.todo("1.1.1")
def test_panel_responds_to_sliders_seed_and_presets():
    panel = SliderPanel(ALWAYS_LEFT_PARAMS, seed=0)
    panel.param_sliders[3].value = -0.2  # the weight on the pole's angular velocity: the cart now runs off
    assert "Total reward: 142 " in panel.reward_label.value and shows_state(panel)

    panel.seed_box.value = 3
    assert shows_state(panel)

    panel.apply_preset("always right")
    assert panel.params == PRESETS["always right"] and shows_state(panel)


@pytest.mark.todo("1.1.1")
def test_panel_time_step_spans_the_episode_and_redraws():
    panel = SliderPanel(ALWAYS_LEFT_PARAMS, seed=0)
    assert panel.step_slider.max == panel.episode.num_steps == panel.step_slider.value == 11
    before = panel.image.value
    panel.step_slider.value = 0
    assert panel.image.value != before and shows_state(panel)
    panel.param_sliders[3].value = -0.2  # a new episode is shown at its end, and the time step spans it
    assert panel.step_slider.value == panel.step_slider.max == panel.play.max == 142 and shows_state(panel)
    assert panel.play.step == 1 and panel.play.interval == PLAY_INTERVAL_MS == 50  # every step, 20 frames per second


def test_panel_validates_its_arguments():
    with pytest.raises(ValueError, match=r"params must lie within the sliders' range \[-2, 2\]"):
        SliderPanel((0.0, 0.0, 3.0, 0.0))
    with pytest.raises(ValueError, match="params must have shape"):
        SliderPanel((0.0, 0.0))
    with pytest.raises(ValueError, match="seed must be"):
        SliderPanel(seed=-3)
    with pytest.raises(ValueError, match="seed must be below"):
        SliderPanel(seed=2**31)
    panel = SliderPanel()
    with pytest.raises(ValueError, match="params must lie within"):
        panel.set_params((0.0, -2.5, 0.0, 0.0))
    with pytest.raises(TypeError, match="callback must be callable"):
        panel.on_send_params("landscape")


@pytest.mark.todo("1.1.1")
def test_panel_puts_given_params_on_the_grid():
    panel = SliderPanel((0.123, -0.1, 0.0, 1.0))
    assert panel.params == (slider_grid_value(0.12), slider_grid_value(-0.1), 0.0, 1.0)


@pytest.mark.todo("1.1.1")
def test_a_preset_replays_the_episode_once(monkeypatch):
    panel = SliderPanel(ALWAYS_RIGHT_PARAMS)
    played = []
    monkeypatch.setattr("hwlib.widgets.simulate_episode", lambda params, seed: played.append(params) or simulate_episode(params, seed))
    panel.apply_preset("always left")
    assert played == [PRESETS["always left"]] and shows_state(panel)


@pytest.mark.todo("1.1.1")
def test_an_error_in_a_callback_is_shown_and_the_panel_recovers(monkeypatch):
    panel = SliderPanel()

    def broken(params, seed):
        raise NotImplementedError("TODO 1.1.1")

    with monkeypatch.context() as patch:
        patch.setattr("hwlib.widgets.simulate_episode", broken)
        panel.param_sliders[0].value = 0.5
        assert "Could not play the episode" in panel.reward_label.value and "TODO 1.1.1" in panel.reward_label.value
    panel.param_sliders[0].value = 0.25
    assert shows_state(panel)


# --- the browser's state: the last action decides ---------------------------------------------


def browser_state(panel, seq, params, seed=0, step=None):
    """What the kernel gets when the panel's front-end part sends its state (ipywidgets' set_state)."""
    panel.controls.set_state({"state": {"seq": seq, "params": list(params), "seed": seed, "step": step}})


def from_browser(control, value):
    """A control's own message from the browser, as ipywidgets handles it."""
    control.set_state({"value": value})


def browser_click(panel, params):
    """A click of "Show θ in the landscape" in the browser, which carries the θ the sliders show there."""
    panel.controls._handle_custom_msg({"event": "send_params", "params": list(params)}, [])


@pytest.mark.todo("1.1.1")
def test_a_slider_value_held_in_the_browser_cannot_overwrite_a_later_preset():
    # The order that mixed two settings: θ₄ moved by keys (its first value sent, the next held by the
    # browser), then "always right" clicked; the held slider value reached the kernel last.
    panel = SliderPanel()
    panel.controls._handle_custom_msg({"event": "connected"}, [])
    browser_state(panel, 1, (0.0, 0.0, 0.0, -0.01))
    from_browser(panel.param_sliders[3], -0.01)
    browser_state(panel, 2, PRESETS["always right"])  # the browser applied the preset to its sliders
    for index, value in enumerate(PRESETS["always right"]):
        from_browser(panel.param_sliders[index], value)
    from_browser(panel.param_sliders[3], -0.2)  # a slider message that arrives late, from before the click
    assert panel.params == PRESETS["always right"] and panel.state.step is None
    assert panel.controls.drawn == 2
    assert np.array_equal(pixels(panel.image.value), pixels(render_panel(PRESETS["always right"], 0).png))
    assert f"Total reward: {kit_reward(PRESETS['always right'], 0)} " in panel.reward_label.value


@pytest.mark.todo("1.1.1")
def test_the_time_step_is_the_last_one_set_and_a_new_episode_starts_at_its_end():
    panel = SliderPanel()
    moved = (0.0, 0.0, 0.0, -0.2)  # 142 steps
    browser_state(panel, 1, moved)
    assert panel.step_slider.max == panel.step_slider.value == 142 and shows_state(panel)
    from_browser(panel.step_slider, 30)  # the browser sends the slider's value, and its state
    browser_state(panel, 2, moved, step=30)
    assert panel.step_slider.value == 30 and shows_state(panel)
    from_browser(panel.step_slider, 142)  # the slider's own message, from before: the state decides
    assert panel.step_slider.value == 142  # (the control's value is the browser's; the picture is the state's)
    assert np.array_equal(pixels(panel.image.value), pixels(render_panel(moved, 0, step=30).png))
    browser_state(panel, 3, PRESETS["always right"])
    assert panel.step_slider.value == panel.episode.num_steps == 8 and shows_state(panel)
    browser_state(panel, 4, PRESETS["always right"], seed=3, step=400)  # past the end: the end
    from_browser(panel.seed_box, 3)
    assert panel.step_slider.value == panel.episode.num_steps and shows_state(panel)
    assert panel.controls.drawn == 4


@pytest.mark.todo("1.1.1")
def test_a_step_the_browser_asked_for_is_never_written_back():
    moved = (0.0, 0.0, 0.0, -0.2)
    panel = SliderPanel(moved)
    from_browser(panel.step_slider, 40)  # ▶ Play has moved on to step 40 in the browser ...
    browser_state(panel, 1, moved, step=30)  # ... when the kernel draws the state of step 30
    assert panel.step_slider.value == 40, "writing 30 back would pull ▶ Play back to a step it has passed"
    assert np.array_equal(pixels(panel.image.value), pixels(render_panel(moved, 0, step=30).png))


@pytest.mark.parametrize(
    "state",
    [
        {"seq": 5, "params": [0.0, 0.0, 3.0, 0.0], "seed": 0, "step": None},
        {"seq": 5, "params": [0.0, 0.0, 0.0], "seed": 0, "step": None},
        {"seq": 5, "params": [0.0, 0.0, float("nan"), 0.0], "seed": 0, "step": None},
        {"seq": 5, "params": [0.0, 0.0, 0.0, 0.0], "seed": -1, "step": None},
        {"seq": 5, "params": [0.0, 0.0, 0.0, 0.0], "seed": 0, "step": -2},
        {"seq": 5, "params": [0.0, 0.0, 0.0, 0.0], "seed": 0, "step": True},
        {"seq": "5", "params": [0.0, 0.0, 0.0, 0.0], "seed": 0, "step": None},
        "state",
    ],
)
def test_a_state_the_front_end_never_sends_changes_nothing(state):
    panel = SliderPanel(ALWAYS_RIGHT_PARAMS)
    before = (panel.state, bytes(panel.image.value))
    panel.controls.set_state({"state": state})
    assert (panel.state, bytes(panel.image.value)) == before


@pytest.mark.todo("1.1.1")
def test_without_its_front_end_part_the_panel_draws_the_controls_values():
    # A front end without anywidget: only the controls' own messages arrive, and they decide.
    panel = SliderPanel()
    from_browser(panel.param_sliders[3], -0.2)
    assert panel.params == (0.0, 0.0, 0.0, -0.2) and panel.step_slider.value == 142


class NotDoneYet(NotImplementedError):
    """Stands in for hwlib.machinery.todos.TodoNotDone: a NotImplementedError that names its TODO."""

    def __init__(self, todo):
        super().__init__(todo)
        self.todo = todo

    def _render_traceback_(self):
        return [f"\x1b[31mTODO {self.todo} is not done yet:\x1b[0m CartPoleLinearPolicy.__call__ in hwlib/cartpole.py",
                "Write it between ### BEGIN TODO and ### END TODO, then run this cell again."]


def not_done_errors():
    errors = [NotDoneYet("1.1.1")]
    with contextlib.suppress(ImportError):
        from hwlib.machinery.todos import TodoNotDone

        errors.append(TodoNotDone("1.1.1"))
    return errors


@pytest.mark.todo("1.1.1")
@pytest.mark.parametrize("error", not_done_errors(), ids=lambda error: type(error).__name__)
def test_a_todo_not_done_is_named_in_the_panel_and_the_panel_recovers(monkeypatch, error):
    def not_done(params, seed):
        raise error

    with monkeypatch.context() as patch:
        patch.setattr("hwlib.widgets.simulate_episode", not_done)
        panel = SliderPanel()  # no traceback: the panel is shown, and says what to do
        assert panel.not_done is error
        assert "TODO 1.1.1 is not done yet" in panel.reward_label.value and "Could not play" not in panel.reward_label.value
        assert "\x1b" not in panel.reward_label.value and "TODO 1.1.1 is not done yet" in panel.reward_label.tooltip
        picture = pixels(panel.image.value)
        assert picture.shape == (352, 720, 4), "the picture keeps its size, so nothing moves"
        panel.param_sliders[0].value = 0.5
        assert panel.not_done is error
    panel.param_sliders[0].value = 0.25  # the TODO done (and the cell run again): the panel plays
    assert panel.not_done is None and shows_state(panel)


def test_todo_message_names_the_todo_only_for_a_todo_not_done():
    assert todo_message(NotImplementedError("TODO 1.1.1")) is None, "a plain NotImplementedError names no TODO"
    assert todo_message(ValueError("bad")) is None
    plain = NotImplementedError("write the linear policy")
    plain.todo = "1.1.1"
    assert todo_message(plain) == ["TODO 1.1.1 is not done yet: write the linear policy"]
    assert todo_message(NotDoneYet("1.1.1")) == [
        "TODO 1.1.1 is not done yet: CartPoleLinearPolicy.__call__ in hwlib/cartpole.py",
        "Write it between ### BEGIN TODO and ### END TODO, then run this cell again.",
    ]


def test_a_broken_policy_fails_in_the_cell(monkeypatch):
    def broken(params, seed):
        raise ZeroDivisionError("in the student's policy")

    monkeypatch.setattr("hwlib.widgets.simulate_episode", broken)
    with pytest.raises(ZeroDivisionError, match="in the student's policy"):
        SliderPanel()


def test_no_control_can_move_whatever_the_texts_say():
    """Every part has a fixed size: the status line two lines (it clips the rest), the picture the
    figure's; the rows never wrap."""
    panel = SliderPanel()
    status = panel.reward_label.layout
    assert status.height.endswith("em") and status.overflow == "hidden" and status.align_self == "stretch"
    assert (panel.image.layout.width, panel.image.layout.height) == ("720px", "352px")
    rows = [child for child in panel.widget.children if isinstance(child, widgets.HBox)]
    assert len(rows) == 2 and all(row.layout.flex_flow == "row nowrap" for row in rows)
    assert "-webkit-line-clamp: 2" in panel.controls._css


# --- no race: one redraw at a time, and always one after the last change -------------------------


def count_draws(panel, on_draw=None):
    """Wrap the panel's figure so every draw is counted, and overlapping draws are caught."""
    state = {"draws": 0, "inside": 0, "most_inside": 0}
    lock = threading.Lock()
    show = panel.view.show

    def counted_show(episode, step=None):
        with lock:
            state["draws"] += 1
            state["inside"] += 1
            state["most_inside"] = max(state["most_inside"], state["inside"])
        try:
            if on_draw is not None:
                on_draw(state["draws"])
            return show(episode, step)
        finally:
            with lock:
                state["inside"] -= 1

    panel.view.show = counted_show
    return state


@pytest.mark.todo("1.1.1")
def test_two_threads_at_once_never_draw_together_and_the_last_state_is_shown():
    panel = SliderPanel(ALWAYS_RIGHT_PARAMS)
    # Each draw yields the processor for a moment, so the other thread's changes land mid-draw.
    state = count_draws(panel, on_draw=lambda _draws: threading.Event().wait(0.002))
    start = threading.Barrier(2)
    errors = []

    def clicks():
        start.wait()
        for index in range(30):
            panel.apply_preset(list(PRESETS)[index % 2])

    def moves():
        start.wait()
        rng = np.random.default_rng(0)
        for index in range(30):
            panel.param_sliders[index % 4].value = slider_grid_value(float(rng.uniform(-1, 1)))
            panel.step_slider.value = int(rng.integers(0, panel.step_slider.max + 1))
            panel.seed_box.value = index % 3

    def run(work):
        try:
            work()
        except Exception as error:  # noqa: BLE001 (reported by the main thread)
            errors.append(error)

    threads = [threading.Thread(target=run, args=(work,)) for work in (clicks, moves)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors, errors
    assert state["most_inside"] == 1, "two redraws of the panel overlapped"
    assert state["draws"] > 0
    assert opaque_share(panel.image.value) == 1.0, "the panel's figure went (partly) transparent"
    assert shows_state(panel)


@pytest.mark.todo("1.1.1")
def test_changes_during_a_draw_are_drawn_once_more_with_the_latest_values():
    panel = SliderPanel(ALWAYS_LEFT_PARAMS)
    in_first_draw, release = threading.Event(), threading.Event()

    def hold_first(draws):
        if draws == 1:
            in_first_draw.set()
            assert release.wait(30), "the test never released the first draw"

    state = count_draws(panel, on_draw=hold_first)
    drawer = threading.Thread(target=lambda: setattr(panel.param_sliders[3], "value", -0.2))
    drawer.start()
    assert in_first_draw.wait(30)
    # Three changes while the first draw is under way: each returns at once, none draws.
    panel.seed_box.value = 1
    panel.set_params(ALWAYS_RIGHT_PARAMS)
    panel.seed_box.value = 2
    assert state["draws"] == 1
    release.set()
    drawer.join(30)
    assert state["draws"] == 2, "the three changes should cost one more draw, with the latest values"
    assert (panel.params, panel.seed_box.value) == (PRESETS["always right"], 2) and shows_state(panel)


@pytest.mark.todo("1.1.1")
def test_presets_from_two_threads_never_mix():
    panel = SliderPanel(PRESETS["always left"])
    in_right, left_done = threading.Event(), threading.Event()

    def pause_right_halfway(change):
        # Thread "right" has written θ₂ but not yet θ₄: let thread "left" run its whole preset now.
        if threading.current_thread().name == "right":
            in_right.set()
            left_done.wait(0.5)  # "left" can only finish first if presets can interleave

    panel.param_sliders[1].observe(pause_right_halfway, names="value")
    right = threading.Thread(target=panel.set_params, args=(PRESETS["always right"],), name="right")
    right.start()
    assert in_right.wait(30)
    left = threading.Thread(target=lambda: (panel.set_params(PRESETS["always left"]), left_done.set()), name="left")
    left.start()
    right.join(30)
    left.join(30)
    assert panel.params in PRESETS.values(), f"the sliders show half of one preset and half of the other: {panel.params}"
    assert panel.params == PRESETS["always left"], "the preset set last should be shown"
    assert shows_state(panel)


def test_latest_only_holds_requests_until_the_block_ends():
    draws = []
    redraws = LatestOnly(lambda: draws.append(len(draws)))
    with redraws.held():
        redraws.request()
        redraws.request()
        assert draws == []
    assert draws == [0]
    redraws.request()
    assert draws == [0, 1]


def test_latest_only_recovers_after_a_failing_draw():
    calls = []

    def draw():
        calls.append(None)
        if len(calls) == 1:
            raise RuntimeError("first draw fails")

    redraws = LatestOnly(draw)
    with pytest.raises(RuntimeError, match="first draw fails"):
        redraws.request()
    redraws.request()
    assert len(calls) == 2


# --- the hook for the landscape view -----------------------------------------------------------


def test_show_in_landscape_sends_the_current_params_to_every_listener():
    panel = SliderPanel(ALWAYS_RIGHT_PARAMS)
    assert not panel.controls.landscape_enabled, "with no landscape view connected the button does nothing, so it is disabled"
    first, second = [], []

    def listener(params):
        first.append(params)

    assert panel.on_send_params(listener) is listener
    panel.on_send_params(second.append)
    assert panel.controls.landscape_enabled and "landscape" in panel.controls.landscape_tooltip
    panel.param_sliders[0].value = 0.25
    panel.send_params()
    assert first == second == [(0.25, -1.0, 0.0, 1.0)]
    assert all(type(value) is float for value in first[0])
    # The button's click in the browser carries the θ the sliders show there, which is what is sent.
    browser_click(panel, (0.5, -1.0, 0.0, 1.0))
    assert first == second == [(0.25, -1.0, 0.0, 1.0), (0.5, -1.0, 0.0, 1.0)]


def test_every_listener_is_called_even_if_one_fails():
    panel = SliderPanel()
    called = []

    def failing(params):
        raise RuntimeError("landscape broke")

    panel.on_send_params(failing)
    panel.on_send_params(called.append)
    with pytest.raises(RuntimeError, match="landscape broke"):
        panel.send_params()
    assert called == [DEFAULT_PARAMS]


def test_slider_panel_returns_a_panel_that_displays_as_its_widget():
    panel = slider_panel()
    assert isinstance(panel, SliderPanel)
    bundle = panel._repr_mimebundle_()
    assert bundle["application/vnd.jupyter.widget-view+json"]["model_id"] == panel.widget.model_id


def test_the_panel_says_when_a_change_leaves_theta_pointing_where_it_pointed():
    from hwlib.widgets import DIRECTION_NOTE, same_direction

    assert same_direction((0, 0, -1, 0), (0, 0, -1.5, 0)) and same_direction((0.3, -0.2, 0.8, 0.1), (0.6, -0.4, 1.6, 0.2))
    assert not same_direction((0, 0, -1, 0), (0, 0, 1, 0))  # the sign flips: another policy
    assert not same_direction((0, 0, 0, 0), (0, 0, -1, 0)) and not same_direction((0, 0, -1, 0), (0, 0, -1, 0))
    assert not same_direction((0, 0, -1, 0), (0, 0, -1, 0.01))
    panel = SliderPanel((0.0, 0.0, -1.0, 0.0))
    panel.param_sliders[2].value = -1.5  # θ₃ alone, the same sign: the same policy, the same episode
    assert DIRECTION_NOTE in html_text(panel.reward_label.value) and DIRECTION_NOTE in panel.reward_label.tooltip
    panel.step_slider.value = 3  # moving through the episode keeps the note
    assert DIRECTION_NOTE in html_text(panel.reward_label.value)
    panel.param_sliders[2].value = 1.0  # the sign flips: a new episode, no note
    assert DIRECTION_NOTE not in html_text(panel.reward_label.value)


def html_text(value):
    import html

    return html.unescape(value)
