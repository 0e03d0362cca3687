"""Chapter 10 — ask the world's driver (minimanc.dagger.expert): the logged controls on the
logged states, sensible answers elsewhere, a clear refusal where it cannot answer."""

from __future__ import annotations

import numpy as np
import pytest

from minimanc import world
from minimanc.dagger.expert import HumanExpert
from minimanc.rollout import reactive

EXACT = 1e-9
"""On the run's own float64 states at t >= 1 the expert is the run's driver: equal to
rounding (measured 0)."""
START = 1e-4
"""At t = 0 the run placed the ego at the route's start arc length, the expert projects the
pose on the route (a lateral offset on a curve moves it by ~1 cm): measured 1e-5."""
LOGGED = 1e-4
"""On the dataset's float32 poses and speeds: measured 9.4e-6 on 640 states."""


@pytest.fixture(scope="module")
def ds():
    return world.generate(8, seed=3, raster=world.RasterConfig(size=32), workers=1)


@pytest.fixture(scope="module")
def expert(ds):
    return HumanExpert(ds)


def test_logged_states_give_the_logged_controls(ds, expert):
    T = ds.ego.shape[1]
    for s in range(len(ds)):
        rec = reactive.record_human(ds, s)
        steps = expert.steps(s)
        for t in range(T):
            u = expert(s, t, rec.ego[t], steps[t].speed)
            np.testing.assert_allclose(u, rec.controls[t], atol=START if t == 0 else EXACT)
            speed = float(ds.controls[s, t - 1, 0]) if t else steps[t].speed
            u32 = expert(s, t, ds.ego[s, t], speed)
            np.testing.assert_allclose(u32, ds.controls[s, t], atol=LOGGED)


def test_asking_does_not_change_the_expert(ds, expert):
    a = expert(2, 10, ds.ego[2, 10], float(ds.controls[2, 9, 0]))
    expert(2, 10, ds.ego[2, 10] + [0.5, 0.3, 0.05], 3.0)
    b = expert(2, 10, ds.ego[2, 10], float(ds.controls[2, 9, 0]))
    np.testing.assert_array_equal(a, b)


def test_experts_of_one_process_share_the_human_runs(ds, expert):
    """An expert of a subset asks about the same scenes: it reuses the runs (the same
    objects) and gives the same answers."""
    other = HumanExpert(ds.subset(np.array([5, 2])))
    assert other.steps(1) is expert.steps(2)
    pose = ds.ego[2, 10] + [0.5, 0.3, 0.05]
    np.testing.assert_array_equal(other(1, 10, pose, 3.0), expert(2, 10, pose, 3.0))


def test_the_ados_of_a_reactive_simulation_step(ds, expert):
    """Driven by the human's controls, the reactive simulation's ados at every step give the
    logged controls too; the live simulation is not changed by asking."""
    sim = reactive.ReactiveSim(ds, [0, 3])
    sim.reset()
    for t in range(ds.ego.shape[1] - 1):
        pose = sim.observe().pose
        speeds = [run.ego.v for run in sim.runs]
        before = [(v.s, v.v, v.stamp) for run in sim.runs for v in run.traffic.vehicles]
        u = expert.label([0, 3], t, pose, speeds, [run.traffic for run in sim.runs])
        assert before == [(v.s, v.v, v.stamp) for run in sim.runs for v in run.traffic.vehicles]
        np.testing.assert_allclose(u, ds.controls[[0, 3], t], atol=LOGGED)
        sim.step(np.asarray(ds.controls[[0, 3], t], np.float64))


def test_off_the_log_the_driver_steers_back_and_speeds_up(ds, expert):
    s, t = 1, 12
    pose, speed = np.asarray(ds.ego[s, t], np.float64), float(ds.controls[s, t - 1, 0])
    here = expert(s, t, pose, speed)
    yaw = pose[2]
    left = pose + [-np.sin(yaw), np.cos(yaw), 0.0]  # 1 m to the left of the human
    right = pose - [-np.sin(yaw), np.cos(yaw), 0.0]
    assert expert(s, t, left, speed)[1] < here[1] < expert(s, t, right, speed)[1]
    slow = expert(s, t, pose, 0.5 * speed)
    assert slow[0] > 0.5 * speed  # far below its desired speed, it accelerates


def test_refuses_a_state_it_cannot_label(ds, expert):
    pose, speed = np.asarray(ds.ego[0, 5], np.float64), float(ds.controls[0, 4, 0])
    with pytest.raises(ValueError, match="pose"):
        expert(0, 5, [np.nan, pose[1], pose[2]], speed)
    with pytest.raises(ValueError, match="pose"):
        expert(0, 5, pose[:2], speed)
    with pytest.raises(ValueError, match="speed"):
        expert(0, 5, pose, -1.0)
    with pytest.raises(ValueError, match="speed"):
        expert(0, 5, pose, float("inf"))
    with pytest.raises(ValueError, match="drivable"):
        expert(0, 5, pose + [0.0, 1e4, 0.0], speed)
    with pytest.raises(ValueError, match="route"):
        expert(0, 5, pose + [0.0, 0.0, np.pi], speed)  # facing back along its route
    with pytest.raises(ValueError, match="t must"):
        expert(0, 40, pose, speed)
    with pytest.raises(ValueError, match="scene"):
        expert(8, 5, pose, speed)
    with pytest.raises(ValueError, match="poses"):
        expert.label([0, 1], 5, pose[None], [speed, speed])
    with pytest.raises(ValueError, match="cache"):
        HumanExpert(ds, cache=0)
