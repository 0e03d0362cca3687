"""Chapter 7 — faded history in the raster (minimanc.world.history): the past boxes are the
track's, a vehicle that does not move looks the same with and without history, the current
boxes are drawn on top, and the closed loop draws the image the dataset stored."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimanc import world
from minimanc.rollout import reactive
from minimanc.rollout.driver import observation
from minimanc.rollout.log import LogReplay
from minimanc.world.history import MAX_HISTORY, History, fade, history_of, latest_history
from minimanc.world.raster import EGO, VEHICLE, rasterize_batch


@pytest.fixture(scope="module")
def ds():
    return world.generate(3, seed=3, raster=world.RasterConfig(size=32, history=2), workers=1)


@given(st.integers(1, MAX_HISTORY))
def test_fade_dims_the_older_boxes(steps):
    f = fade(steps)
    assert f.shape == (steps,) and np.all(np.diff(f) < 0) and 0 < f[-1] and f[0] < 1


def test_fade_refuses_out_of_range():
    with pytest.raises(ValueError):
        fade(0)
    with pytest.raises(ValueError):
        fade(MAX_HISTORY + 1)


def test_history_of_reads_the_track(ds):
    ego, ado, valid = np.asarray(ds.ego[0], np.float64), ds.ado[0], ds.ado_valid[0]
    h = history_of(ego, ado, valid, 3)
    T = len(ego)
    assert h.ego.shape == (T, 3, 3) and h.ado.shape == (T, 3) + ado.shape[1:]
    # frame t sees min(t, 3) past steps, j + 1 steps back
    np.testing.assert_array_equal(h.ego_valid.sum(1), np.minimum(np.arange(T), 3))
    np.testing.assert_array_equal(h.ego[10, 0], ego[9])
    np.testing.assert_array_equal(h.ego[10, 2], ego[7])
    np.testing.assert_array_equal(h.ado_valid[10, 1], valid[8])
    assert not h.ado_valid[0].any()
    last = latest_history(ego[None, :11], ado[None, :11], valid[None, :11], 3)
    np.testing.assert_array_equal(last.ego, h.ego[10:11])
    np.testing.assert_array_equal(last.ado_valid, h.ado_valid[10:11])


def test_history_refuses_bad_shapes():
    with pytest.raises(ValueError, match="History needs"):
        History(np.zeros((2, 3, 3)), np.ones((2, 2), bool), np.zeros((2, 3, 1, 5)),
                np.ones((2, 3, 1), bool))
    with pytest.raises(ValueError, match="finite"):
        History(np.full((1, 1, 3), np.nan), np.ones((1, 1), bool), np.zeros((1, 1, 1, 5)),
                np.ones((1, 1, 1), bool))
    with pytest.raises(ValueError, match="frames"):
        history_of(np.zeros((4, 3)), np.zeros((4, 1, 5)), np.ones((4, 1), bool), 2, frames=[4])


def test_a_vehicle_that_does_not_move_looks_the_same(ds):
    """The past boxes of a standing scene lie under the current ones: nothing changes."""
    m = ds.maps[0]
    pose = np.asarray(ds.ego[0, 5], np.float64)[None]
    ado, valid = np.asarray(ds.ado[0, 5], np.float64)[None], ds.ado_valid[0, 5][None]
    plain = rasterize_batch(m, pose, ado, valid, world.RasterConfig(size=32))
    still = History(np.repeat(pose[:, None], 2, 1), np.ones((1, 2), bool),
                    np.repeat(ado[:, None], 2, 1), np.repeat(valid[:, None], 2, 1))
    drawn = rasterize_batch(m, pose, ado, valid, ds.raster, history=still)
    np.testing.assert_array_equal(drawn, plain)


def test_history_draws_faded_boxes_under_the_current_ones(ds):
    plain = world.generate(3, seed=3, raster=world.RasterConfig(size=32), workers=1)
    np.testing.assert_array_equal(plain.ego, ds.ego)
    a, b = plain.bev, ds.bev
    changed = np.any(a != b, axis=-1)
    assert changed.any()
    # the current boxes are unchanged (the ados' and the ego's, at its centre pixel; a red
    # pixel elsewhere may be an oncoming lane), and every changed pixel holds a faded colour
    on = np.all(a == VEHICLE, axis=-1)
    np.testing.assert_array_equal(b[on], a[on])
    r, c = ds.raster.ego_pixel
    assert np.all(b[:, :, r, c] == EGO)
    faded = {tuple(np.round(np.array(c) * f).astype(np.uint8)) for c in (VEHICLE, EGO)
             for f in fade(2)}
    assert {tuple(p) for p in b[changed]} <= faded
    assert not changed[:, 0].any()  # no past at the first step


def test_the_raster_asks_for_the_history_it_draws(ds):
    m, pose = ds.maps[0], np.asarray(ds.ego[0, :1], np.float64)
    ado, valid = np.asarray(ds.ado[0, :1], np.float64), ds.ado_valid[0, :1]
    with pytest.raises(ValueError, match="history="):
        rasterize_batch(m, pose, ado, valid, ds.raster)
    past = history_of(np.asarray(ds.ego[0], np.float64), ds.ado[0], ds.ado_valid[0], 2,
                      frames=[0])
    with pytest.raises(ValueError, match="draws none"):
        rasterize_batch(m, pose, ado, valid, world.RasterConfig(size=32), history=past)
    three = history_of(np.asarray(ds.ego[0], np.float64), ds.ado[0], ds.ado_valid[0], 3,
                       frames=[0])
    with pytest.raises(ValueError, match="2 steps"):
        rasterize_batch(m, pose, ado, valid, ds.raster, history=three)
    with pytest.raises(ValueError, match="history"):
        world.RasterConfig(history=MAX_HISTORY + 1)


def test_metadata_names_the_history_only_when_drawn(ds, tmp_path):
    assert "history" not in world.RasterConfig().as_meta()
    assert ds.meta["raster"]["history"] == 2
    back = world.load(world.save(ds, tmp_path / "h.npz"))
    assert back.raster.history == 2
    np.testing.assert_array_equal(back.bev, ds.bev)


class _Bev:
    model, setting, keys = None, "paper", ("bev",)


@pytest.mark.parametrize("make", [LogReplay, reactive.ReactiveSim])
def test_the_closed_loop_draws_the_stored_image(ds, make):
    """Driving the human's controls, both simulators render the dataset's own rasters."""
    sim = make(ds, np.arange(3))
    sim.reset()
    steps = 6 if make is LogReplay else 3
    for t in range(steps):
        obs = observation(_Bev(), sim.observe(), np.zeros((3, 2), np.float32), sim.raster,
                          sim.k_targets)
        np.testing.assert_array_equal(np.round(obs["bev"] * 255).astype(np.uint8),
                                      ds.bev[:, t])
        sim.step(np.asarray(ds.controls[:, t], dtype=np.float64))
