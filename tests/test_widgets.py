import numpy as np
import pytest

from hwlib import CartPoleLinearPolicy, run_policy
from hwlib.cartpole import ALWAYS_LEFT_PARAMS, BALANCING_PARAMS
from hwlib.plots.cartpole import EpisodeView
from hwlib.widgets import PRESETS, SliderPanel, render_panel, reward_text, simulate_episode

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.mark.todo("1.1.1")
def test_render_panel_plays_the_episode_and_draws_it():
    frame = render_panel(BALANCING_PARAMS, seed=0)
    assert frame.episode.total_reward == 500
    assert frame.reward_text == "Total reward: 500 (the maximum)"
    assert frame.png.startswith(PNG_SIGNATURE)


@pytest.mark.todo("1.1.1")
def test_render_panel_reward_is_the_librarys_reward():
    params = (0.5, -0.3, -1.2, 0.4)
    frame = render_panel(params, seed=4)
    expected = run_policy(CartPoleLinearPolicy(params), seed=4)
    assert frame.reward_text == f"Total reward: {int(expected)}"


@pytest.mark.todo("1.1.1")
def test_render_panel_redraws_the_same_view_differently_for_other_params():
    view = EpisodeView()
    balanced = render_panel(BALANCING_PARAMS, seed=0, view=view)
    falling = render_panel(ALWAYS_LEFT_PARAMS, seed=0, view=view)
    assert balanced.png != falling.png
    assert balanced.episode.num_steps == 500 and falling.episode.num_steps < 20


@pytest.mark.todo("1.1.1")
def test_step_moves_only_the_picture():
    episode = simulate_episode(ALWAYS_LEFT_PARAMS, 0)
    view = EpisodeView()
    start = render_panel(ALWAYS_LEFT_PARAMS, 0, step=0, view=view, episode=episode)
    end = render_panel(ALWAYS_LEFT_PARAMS, 0, view=view, episode=episode)
    assert start.reward_text == end.reward_text
    assert start.png != end.png


@pytest.mark.parametrize(("params", "seed"), [([1, 2, 3], 0), ([0, 0, np.nan, 0], 0), (BALANCING_PARAMS, -1)])
def test_render_panel_rejects_bad_controls(params, seed):
    with pytest.raises(ValueError, match="params must|seed must"):
        render_panel(params, seed)


@pytest.mark.todo("1.1.1")
def test_reward_text_marks_only_the_maximum():
    falling = simulate_episode(ALWAYS_LEFT_PARAMS, 0)
    assert reward_text(falling) == f"Total reward: {int(falling.total_reward)}"
    assert reward_text(simulate_episode(BALANCING_PARAMS, 0)) == "Total reward: 500 (the maximum)"


@pytest.mark.todo("1.1.1")
def test_panel_responds_to_sliders_seed_and_presets():
    panel = SliderPanel(BALANCING_PARAMS, seed=0)
    assert "Total reward: 500" in panel.reward_label.value
    assert bytes(panel.image.value).startswith(PNG_SIGNATURE)

    panel.param_sliders[2].value = 1.0  # the pole-angle weight flipped: the pole falls
    expected = run_policy(CartPoleLinearPolicy(panel.params), seed=0)
    assert f"Total reward: {int(expected)}" in panel.reward_label.value and expected < 500

    panel.seed_box.value = 3
    assert f"Total reward: {int(run_policy(CartPoleLinearPolicy(panel.params), seed=3))}" in panel.reward_label.value

    left_button = next(button for button in panel.preset_buttons if button.description == "always left")
    left_button.click()
    assert panel.params == PRESETS["always left"]
    assert f"Total reward: {int(run_policy(CartPoleLinearPolicy(ALWAYS_LEFT_PARAMS), seed=3))}" in panel.reward_label.value


@pytest.mark.todo("1.1.1")
def test_panel_step_slider_spans_the_episode_and_redraws():
    panel = SliderPanel(ALWAYS_LEFT_PARAMS, seed=0)
    assert panel.step_slider.max == panel.episode.num_steps == panel.step_slider.value
    before = panel.image.value
    panel.step_slider.value = 0
    assert panel.image.value != before


@pytest.mark.todo("1.1.1")
def test_sliders_cover_at_least_minus_two_to_two():
    panel = SliderPanel()
    assert all(slider.min <= -2 and slider.max >= 2 for slider in panel.param_sliders)
