"""Chapter 9 — reactive traffic (minimanc.rollout.reactive): the human's controls give back the
log, a policy's ego is seen by the ados, arrivals are the log's."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from minimanc import metrics, rollout, world
from minimanc.rollout import reactive

ADO_TOL = 1e-4
"""Oracle tolerance (m, rad): the reactive human replay starts from the dataset's float32
pose and applies its float32 controls, so it can differ from the float64 run that was
logged by float32 rounding, amplified over 40 steps (measured: 1.5e-5)."""


@pytest.fixture(scope="module")
def ds():
    return world.generate(16, seed=3, raster=world.RasterConfig(size=32), workers=1)


class Still:
    """A policy that stands still from the first step on."""

    model = None
    setting = "paper"
    keys = ("motion",)

    def initial_state(self, scenes):
        return None

    def __call__(self, obs, state, t, scenes):
        return np.zeros((len(scenes), 2)), state, {}


def test_human_controls_reproduce_the_logged_ados(ds):
    run = rollout.human(ds, agents="reactive")
    assert isinstance(run, rollout.Rollout) and run.agents == "reactive"
    assert run.ado.shape == ds.ado.shape
    # the same ados exist at the same steps, arrivals included
    np.testing.assert_array_equal(run.ado_valid, ds.ado_valid)
    assert (ds.ado_valid[:, -1].sum(axis=-1) > ds.ado_valid[:, 0].sum(axis=-1)).any()  # arrivals
    v = ds.ado_valid[..., None]
    dev = np.abs(np.where(v, run.ado - ds.ado, 0.0))
    dev[..., 2] = np.abs(np.where(v[..., 0], world.wrap_angle(run.ado[..., 2] - ds.ado[..., 2]),
                                  0.0))
    assert dev.max() < ADO_TOL
    np.testing.assert_allclose(run.ego, rollout.human(ds).ego, atol=ADO_TOL)
    assert metrics.collisions(run.ego, run.ado, run.ado_valid).sum() == 0.0
    res = metrics.evaluate(run, ds)
    assert res["collision_rate"] == 0.0 and res["at_fault_collision_rate"] == 0.0
    # the fixture exercises the replayed lane walks of cut-ins that gave up
    assert any(reactive.record_human(ds, i).walks for i in range(len(ds)))


def test_followers_stop_behind_an_ego_that_stands_still(ds):
    still = rollout.simulate(Still(), ds, progress=False, agents="reactive")
    replay = rollout.simulate(Still(), ds, progress=False)
    hits_replay = metrics.collisions(replay.ego, ds.ado, ds.ado_valid)
    hits_reactive = metrics.collisions(still.ego, still.ado, still.ado_valid)
    assert hits_replay.sum() >= 4  # the log's ados drive through it
    assert hits_reactive.sum() == 0  # the reactive ones stop
    # some ado ends up waiting right behind the ego, stopped, in its direction
    ego = still.ego[:, -1]
    rel = world.to_ego_frame(still.ado[:, -1, :, :2], ego[:, None, :])
    behind = (still.ado_valid[:, -1] & (rel[..., 0] < -3.0) & (rel[..., 0] > -12.0)
              & (np.abs(rel[..., 1]) < 1.0))
    moved = np.linalg.norm(still.ado[:, -1, :, :2] - still.ado[:, -2, :, :2], axis=-1)
    assert (behind & (moved < 1e-6)).any()


def test_arrivals_are_the_logs_whatever_the_policy(ds):
    """Slot k holds the same vehicle (its size) under any policy; arrivals enter when clear."""
    still = rollout.simulate(Still(), ds, progress=False, agents="reactive")
    both = still.ado_valid & ds.ado_valid
    np.testing.assert_allclose(still.ado[..., 3:][both], ds.ado[..., 3:][both], atol=1e-5)
    # every ado of the log appears, an arrival whose entry is blocked a little later
    seen_log, seen = ds.ado_valid.any(axis=1), still.ado_valid.any(axis=1)
    assert np.all(seen[seen_log])
    first_log, first = ds.ado_valid.argmax(axis=1), still.ado_valid.argmax(axis=1)
    assert np.all(first[seen_log] >= first_log[seen_log])
    assert np.any(first[seen_log] > first_log[seen_log])  # one waits behind the still ego


def test_batching_and_save_load(ds, tmp_path):
    a = rollout.simulate(Still(), ds, scenes=[2, 5, 7], batch_size=2, progress=False,
                         agents="reactive")
    b = rollout.simulate(Still(), ds, scenes=[5], progress=False, agents="reactive")
    np.testing.assert_array_equal(a.ado[1], b.ado[0])
    np.testing.assert_array_equal(a.ego[1], b.ego[0])
    back = rollout.Rollout.load(a.save(tmp_path / "r.npz"))
    np.testing.assert_array_equal(back.ado, a.ado)
    assert back.agents == "reactive" and list(back.scenes) == [2, 5, 7]
    with pytest.raises(ValueError, match="holds the ados it simulated"):
        rollout.Rollout("x", "paper", a.ego, a.controls, agents="reactive")


def test_simulator_protocol_directly(ds):
    sim = reactive.ReactiveSim(ds, [0, 1])
    with pytest.raises(ValueError, match="reset"):
        sim.observe()
    m0 = sim.reset()
    assert m0.shape == (2, 2)
    scene = sim.observe()
    np.testing.assert_array_equal(scene.pose, np.asarray(ds.ego[[0, 1], 0], np.float64))
    with pytest.raises(ValueError, match="controls"):
        sim.step(np.full((2, 2), np.nan))
    sim.step(np.asarray(ds.controls[[0, 1], 0], np.float64))
    assert sim.trajectory().shape == (2, 2, 3)
    assert sim.ado_trajectory()[0].shape == (2, 2, ds.ado.shape[2], 5)


def test_refuses_datasets_it_cannot_regenerate(ds):
    with pytest.raises(ValueError, match="meta"):
        reactive.ReactiveSim(SimpleNamespace(ego=ds.ego, controls=ds.controls, ado=ds.ado,
                                             ado_valid=ds.ado_valid, maps=ds.maps, meta={}))
    with pytest.raises(ValueError, match="scenes"):
        reactive.ReactiveSim(ds, [99])
    other = dataclasses.replace(ds, meta=dict(ds.meta, seed=4))
    with pytest.raises(ValueError, match="another version"):
        reactive.ReactiveSim(other, [0])
    moved = dataclasses.replace(ds, ego=ds.ego + np.float32(1.0))
    with pytest.raises(ValueError, match="does not regenerate"):
        reactive.record_human(moved, 3)
    with pytest.raises(ValueError, match="steps"):
        rollout.simulate(Still(), ds, steps=0, progress=False, agents="reactive")


def test_a_split_regenerates_from_its_scene_index(ds):
    _, val = ds.split(10)
    run = rollout.human(val, scenes=[0, 3], agents="reactive")
    np.testing.assert_array_equal(run.ado_valid, val.ado_valid[[0, 3]])


def test_simulate_dispatches_on_agents(ds):
    rep = rollout.simulate(Still(), ds, scenes=[1], progress=False, agents="replay")
    rea = rollout.simulate(Still(), ds, scenes=[1], progress=False, agents="reactive")
    assert rep.agents == "replay" and rep.ado is None
    assert rea.agents == "reactive" and rea.ado.shape[:2] == rea.ego.shape[:2]
    np.testing.assert_array_equal(rep.ego, rea.ego)  # a still ego does not see the ados
    with pytest.raises(ValueError, match="agents"):
        rollout.simulate(Still(), ds, progress=False, agents="ghost")
