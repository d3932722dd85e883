"""Trajectory plots: in a moving field each body is drawn where an agent met it (not at t = 0,
where the lines visibly missed the targets they captured), no agent is drawn in a body's grey or
orange, and the legends never outgrow the field or the figure."""

from __future__ import annotations

import colorsys
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest
from matplotlib.colors import to_rgb

from agents.experiments import evaluation as ev
from agents.experiments.evaluation.plots import (
    AGENT_COLOURS,
    agent_style,
    body_track,
    episode_figure,
    meeting_steps,
)
from debris_gym.envs.rendering import TARGET_OPEN

EASY = "DebrisGym/Rendezvous2D-Easy-v2"


@pytest.fixture(scope="module")
def moving_field():
    env = gym.make(EASY)
    env.reset(seed=3)
    scenario = env.unwrapped.scenario
    env.close()
    assert scenario.moving
    return scenario


def test_body_tracks_follow_the_field_s_own_motion(moving_field):
    track = body_track(moving_field, 120)
    for k in (0, 7, 119):
        np.testing.assert_allclose(
            track[k], moving_field.body_positions(k * moving_field.dt), rtol=1e-9, atol=1e-6
        )


def test_each_body_is_drawn_where_an_agent_came_closest(moving_field):
    """Regression: bodies were drawn at t = 0 only, so a line that captured a moving target
    ended far from the target drawn."""
    track = body_track(moving_field, 100)
    positions = np.full((100, 2), 1e4)  # far from everything ...
    positions[60] = track[60, 0] + [moving_field.targets[0].radius + 1.0, 0.0]  # ... but here
    far = SimpleNamespace(trajectory=SimpleNamespace(positions=positions))
    met = meeting_steps(moving_field, [far], track)
    assert met[0] == 60
    assert np.linalg.norm(track[60, 0] - track[0, 0]) > 10.0  # t = 0 would be the wrong place
    frozen = SimpleNamespace(moving=False, bodies=moving_field.bodies)
    assert not meeting_steps(frozen, [far]).any()


def _grey(colour: str) -> bool:
    h, s, v = colorsys.rgb_to_hsv(*to_rgb(colour))
    return s < 0.25 and v > 0.15  # black reads as an agent's line, mid greys as debris


def _orange(colour: str) -> bool:
    h, s, _ = colorsys.rgb_to_hsv(*to_rgb(colour))
    target, _, _ = colorsys.rgb_to_hsv(*to_rgb(TARGET_OPEN))
    return s > 0.5 and abs(h - target) * 360 < 20


def test_no_agent_is_drawn_in_a_body_s_grey_or_orange():
    """Regression: the ninth agent (the shipped learned policy in the default run) was drawn in
    the grey of the bodies' paths."""
    for i in range(len(AGENT_COLOURS) + 3):
        colour, style = agent_style(i)
        assert not _grey(colour) and not _orange(colour), (i, colour)
        assert style == ("-" if i < len(AGENT_COLOURS) else "--")
    assert len(set(AGENT_COLOURS)) == len(AGENT_COLOURS) >= 9


def test_the_legends_fit_the_figure_and_never_outgrow_the_field():
    """Regression: with many agents with long labels the legend ran off the figure."""
    agents = {f"agent-{i:02d}-" + "with-a-very-long-name" * 3: "zero" for i in range(12)}
    res = ev.evaluate_agents(EASY, agents, episodes=1, seed=0, progress=False, max_episode_steps=4)
    fig = episode_figure(res, 0)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    figure_box = fig.bbox
    axes_box = fig.axes[0].get_window_extent(renderer)
    legend_height = 0.0
    for legend in fig.legends:
        box = legend.get_window_extent(renderer)
        assert figure_box.x0 <= box.x0 and box.x1 <= figure_box.x1 + 0.5, (box, figure_box)
        assert box.y0 >= figure_box.y0 - 0.5 and box.y1 <= axes_box.y0  # below the field
        legend_height += box.height
    assert legend_height <= axes_box.height
