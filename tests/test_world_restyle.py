"""Chapter 7 — the human of another style in the same scene (SceneRun.restyle)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from minimanc.world.driver import SceneRun, simulate_scene
from minimanc.world.generation import draw_scene

T = 20


def scene(index: int):
    rng, _, m = draw_scene(3, index)
    return m, rng


@pytest.mark.parametrize("index", [0, 1, 2])
def test_restyle_with_the_drawn_style_changes_nothing(index):
    m, rng = scene(index)
    base = simulate_scene(m, rng, T=T)
    m, rng = scene(index)
    style = SceneRun(m, rng).style  # the style this scene draws
    m, rng = scene(index)
    again = simulate_scene(m, rng, T=T, style=style)
    np.testing.assert_array_equal(again.ego, base.ego)
    np.testing.assert_array_equal(again.controls, base.controls)
    np.testing.assert_array_equal(again.ado, base.ado)


def test_restyle_keeps_the_start_and_changes_the_driving():
    m, rng = scene(0)
    base = simulate_scene(m, rng, T=T)
    m, rng = scene(0)
    drawn = SceneRun(m, rng).style
    slow = replace(drawn, v0=0.5 * drawn.v0, a_max=0.5 * drawn.a_max)
    m, rng = scene(0)
    run = SceneRun(m, rng)
    start_pose, start_v = run.pose.copy(), run.ego.v
    run.restyle(slow)
    assert run.ego.v0 == slow.v0 and run.driver.style is slow
    np.testing.assert_array_equal(run.pose, start_pose)
    assert run.ego.v == start_v  # the logged start state is kept
    m, rng = scene(0)
    log = simulate_scene(m, rng, T=T, style=slow)
    np.testing.assert_array_equal(log.ego[0], base.ego[0])
    travelled = lambda e: np.linalg.norm(np.diff(e[:, :2], axis=0), axis=-1).sum()  # noqa: E731
    assert travelled(log.ego) < travelled(base.ego), "a slower style should travel less"
