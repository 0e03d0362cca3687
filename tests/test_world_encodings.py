"""Chapter 7 — the raster's two encodings (minimanc.world.raster, minimanc.world.encodings): the
RGB raster unchanged, each binary channel drawn where it should be (boxes, past boxes, lanes
by direction, the route), a non-square view, reading back, the dataset and the closed loop."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import world
from minimanc.rollout import reactive
from minimanc.rollout.driver import observation
from minimanc.rollout.log import LogReplay
from minimanc.world import raster
from minimanc.world.datawriter import DatasetWriter
from minimanc.world.fileformat import ARRAY_FIELDS, DatasetFileError
from minimanc.world.history import History

CHANNELS = world.RasterConfig(encoding="channels", route=True, history=2)


def straight_map():
    return world.build_map({"kind": "straight", "rotation": 0.0, "lanes": 1,
                            "pieces": [[500.0, 0.0]], "ego": {"lane": 0, "start_s": 50.0}})


def plane(img, cfg, name):
    return world.planes(img, cfg)[..., cfg.channel_names.index(name)]


def test_rgb_raster_is_unchanged():
    """A fixed frame (straight road, heading 0, two ados, faded history, goal raster) hashes
    as it did before the channels encoding was added."""
    m = straight_map()
    cfg = world.RasterConfig(history=2)
    pose = np.array([70.0, -1.75, 0.0])
    ado = np.array([[80.0, -1.75, 0.0, 4.5, 1.9], [60.0, 1.75, np.pi, 4.5, 1.9]])
    past = History(np.array([[[66.0, -1.75, 0.0], [62.0, -1.75, 0.0]]]), np.ones((1, 2), bool),
                   np.stack([ado - [[4.0, 0, 0, 0, 0], [-4.0, 0, 0, 0, 0]],
                             ado - [[8.0, 0, 0, 0, 0], [-8.0, 0, 0, 0, 0]]])[None],
                   np.ones((1, 2, 2), bool))
    img = world.rasterize(m, pose, ado, np.ones(2, bool), cfg, history=past)
    goal = world.rasterize_goal(m, np.array([120.0, -1.75, 0.0]))
    digest = hashlib.sha256(img.tobytes() + goal.tobytes()).hexdigest()[:16]
    assert digest == "4f4c7fcf7d0ed879"


def test_channel_names_follow_the_layers():
    assert CHANNELS.channel_names == (
        "drivable", "crossing", "walkway", "lane_same", "lane_opposite", "route",
        "ego", "ego_t-1", "ego_t-2", "vehicles", "vehicles_t-1", "vehicles_t-2")
    assert CHANNELS.input_shape == (64, 64, 12) and CHANNELS.shape == (64, 64, 2)
    bare = world.RasterConfig(encoding="channels", draw_lanes=False, draw_walkways=False,
                              draw_crossings=False)
    assert bare.channel_names == ("drivable", "ego", "vehicles") and bare.shape == (64, 64, 1)
    assert world.RasterConfig().channel_names == ("red", "green", "blue")


def test_boxes_and_past_boxes_light_their_own_planes():
    """An ado 10 m ahead at t, 16 m and 20 m ahead one and two steps before (in the ego
    frame at t); the ego's own past boxes 5 m and 10 m back (that of t - 2 is read 8 m back,
    its front half: its centre is on the raster's edge)."""
    m = straight_map()
    cfg = CHANNELS
    pose = np.array([70.0, -1.75, 0.0])
    now = np.array([[80.0, -1.75, 0.0, 4.5, 1.9]])
    past = History(np.array([[[65.0, -1.75, 0.0], [60.0, -1.75, 0.0]]]), np.ones((1, 2), bool),
                   np.array([[[[86.0, -1.75, 0.0, 4.5, 1.9]], [[90.0, -1.75, 0.0, 4.5, 1.9]]]]),
                   np.ones((1, 2, 1), bool))
    img = world.rasterize(m, pose, now, np.ones(1, bool), cfg, history=past)
    assert img.shape == cfg.shape and img.dtype == np.uint8
    P = world.planes(img, cfg)
    assert set(np.unique(P)) <= {0, 1}
    k = {n: i for i, n in enumerate(cfg.channel_names)}
    col = 32  # the ego's column (y = 0 -> floor(25 / 0.78125) = 32)
    for name, x in (("vehicles", 10.0), ("vehicles_t-1", 16.0), ("vehicles_t-2", 20.0),
                    ("ego", 0.0), ("ego_t-1", -5.0), ("ego_t-2", -10.0 + 2.0)):
        row = int(np.floor((40.0 - x) / cfg.res_row))
        assert P[row, col, k[name]] == 1, (name, row)
    # each plane holds one box: the vehicles' at t is 4.5 m long (5 or 6 rows), nowhere else
    rows = np.nonzero(P[:, col, k["vehicles"]])[0]
    assert 5 <= len(rows) <= 7 and abs(rows.mean() - (40 - 10) / cfg.res_row) < 1.0
    rows1 = np.nonzero(P[:, col, k["vehicles_t-1"]])[0]
    assert abs(rows1.mean() - (40 - 16) / cfg.res_row) < 1.0
    assert not P[:, :, k["vehicles_t-1"]][rows].any()  # the past box is not where the car is
    # the ego at t is the fixed box at the ego pixel; its past boxes lie behind it
    np.testing.assert_array_equal(P[..., k["ego"]] > 0, raster._ego_mask(cfg))
    assert np.nonzero(P[:, col, k["ego_t-1"]])[0].mean() > cfg.ego_pixel[0]
    # without a past (the first step), the past planes are empty
    none = History(np.zeros((1, 2, 3)), np.zeros((1, 2), bool), np.zeros((1, 2, 1, 5)),
                   np.zeros((1, 2, 1), bool))
    first = world.planes(world.rasterize(m, pose, now, np.ones(1, bool), cfg, history=none), cfg)
    for name in ("ego_t-1", "ego_t-2", "vehicles_t-1", "vehicles_t-2"):
        assert not first[..., k[name]].any()


@settings(max_examples=25, deadline=None)
@given(x=st.floats(-300, 300), y=st.floats(-300, 300), yaw=st.floats(-4, 4),
       ahead=st.floats(-5, 35), left=st.floats(-15, 15))
def test_a_box_lights_the_pixels_box_mask_says(x, y, yaw, ahead, left):
    """The vehicles plane is the inverse-mapping box test of chapter 7 (box_mask), any pose."""
    m = straight_map()
    cfg = world.RasterConfig(encoding="channels")
    c, s = np.cos(yaw), np.sin(yaw)
    box = np.array([x + c * ahead - s * left, y + s * ahead + c * left, yaw + 0.3, 4.5, 1.9])
    img = world.rasterize(m, np.array([x, y, yaw]), box[None], np.ones(1, bool), cfg)
    X, Y = cfg.pixel_centres()
    want = world.box_mask(X, Y, np.array([ahead, left, 0.3, 4.5, 1.9]))
    got = plane(img, cfg, "vehicles") > 0
    assert (got != want).sum() <= 2  # a pixel centre on the box's edge may go either way


def test_map_planes_match_the_rgb_layers():
    """Both encodings sample the same class grid: white/slate/blue ⇔ the map's planes."""
    m = straight_map()
    pose = np.array([70.0, -1.0, 0.2])
    off = dict(draw_lanes=False)
    rgb = world.rasterize(m, pose, cfg=world.RasterConfig(**off), draw_ego=False)
    ch = world.rasterize(m, pose, cfg=world.RasterConfig(encoding="channels", **off),
                         draw_ego=False)
    cfg = world.RasterConfig(encoding="channels", **off)
    is_ = lambda c: np.all(rgb == np.array(c), axis=-1)  # noqa: E731
    np.testing.assert_array_equal(plane(ch, cfg, "drivable") > 0,
                                  is_(raster.DRIVABLE) | is_(raster.PED_CROSSING))
    np.testing.assert_array_equal(plane(ch, cfg, "crossing") > 0, is_(raster.PED_CROSSING))
    np.testing.assert_array_equal(plane(ch, cfg, "walkway") > 0, is_(raster.WALKWAY))
    assert (plane(ch, cfg, "crossing") > 0).any() and (plane(ch, cfg, "walkway") > 0).any()


def test_lanes_split_by_direction():
    """Own lane (same direction) straight up the ego's column; the opposite lane 3.5 m left."""
    m = straight_map()
    cfg = world.RasterConfig(encoding="channels")
    img = world.rasterize(m, np.array([70.0, -1.75, 0.0]), cfg=cfg)
    same, opp = plane(img, cfg, "lane_same"), plane(img, cfg, "lane_opposite")
    for r in (2, 10, 30, 45):
        assert same[r, 32] == 1 and opp[r, 32] == 0
        assert opp[r, 27] == 1 and same[r, 27] == 0
    # seen from the other carriageway the roles swap
    back = world.rasterize(m, np.array([70.0, 1.95, np.pi]), cfg=cfg)  # lane 0.2 m left
    assert plane(back, cfg, "lane_same")[10, 31] == 1
    assert plane(back, cfg, "lane_opposite")[10, 27] == 1


def test_route_plane_follows_the_route_through_a_junction():
    """The route's points ahead (the lane targets) lie on the route plane, and every route
    pixel is within the band of the route; at a turn the plane turns with the route."""
    rng = np.random.default_rng(0)
    while True:
        m = world.random_map(rng, "intersection")
        if any(m.lanes[k].turn in ("left", "right") for k in m.route):
            break
    cfg = world.RasterConfig.from_extent(60.0, 20.0, 0.5, encoding="channels", route=True)
    i = next(i for i, k in enumerate(m.route) if m.lanes[k].turn in ("left", "right"))
    s_turn = sum(m.lanes[k].length for k in m.route[:i])  # where the route enters the turn
    turned = False
    for before in (45.0, 25.0, 5.0):
        (xy, h) = m.route_pose(s_turn - before)
        pose = np.array([xy[0], xy[1], h])
        img = world.rasterize(m, pose, cfg=cfg)
        route = plane(img, cfg, "route") > 0
        pts = world.lane_targets(m, pose, 14, spacing=4.0)
        r, c = cfg.ego_to_pixel(pts)
        inside = (r >= 0) & (r < cfg.size) & (c >= 0) & (c < cfg.width)
        assert inside.sum() >= 5 and route[r[inside], c[inside]].all()
        X, Y = cfg.pixel_centres()
        samples = world.to_ego_frame(m.route_pose(np.arange(m.start_s - 20.0, m.route_s[-1],
                                                            0.25))[0], pose)
        d = np.min(np.hypot(X[route][:, None] - samples[None, :, 0],
                            Y[route][:, None] - samples[None, :, 1]), axis=1)
        assert d.max() <= np.sqrt(2) * (raster.ROUTE_WIDTH / 2 + cfg.resolution)  # square stamps
        # only the route *ahead*: nothing drawn behind the ego's own position
        assert not route[cfg.ego_pixel[0] + 2:, :].any()
        turned |= bool(np.any(np.abs(Y[route]) > 10.0))
    assert turned  # the plane turns with the route, off the lane straight ahead


def test_non_square_view():
    cfg = world.RasterConfig.from_extent(90.0, 15.0, 0.5, encoding="channels", history=2)
    assert (cfg.size, cfg.width) == (200, 60) and cfg.res_row == cfg.res_col == 0.5
    assert cfg.ego_pixel == (180, 30) and cfg.input_shape == (200, 60, 11)
    m = straight_map()
    pose = np.array([70.0, -1.75, 0.0])
    ado = np.array([[155.0, -1.75, 0.0, 4.5, 1.9], [80.0, 8.0, 0.0, 4.5, 1.9]])
    past = History(np.zeros((1, 2, 3)), np.zeros((1, 2), bool), np.zeros((1, 2, 2, 5)),
                   np.zeros((1, 2, 2), bool))
    v = plane(world.rasterize(m, pose, ado, np.ones(2, bool), cfg, history=past), cfg,
              "vehicles")
    assert v[int((90 - 85) / 0.5), 30] == 1  # 85 m ahead: beyond the square raster's 40 m
    assert v[int((90 - 10) / 0.5), int((15 - 9.75) / 0.5)] == 1  # 9.75 m left
    rgb = world.rasterize(m, pose, ado, np.ones(2, bool), world.RasterConfig.from_extent(
        90.0, 15.0, 0.5))
    assert rgb.shape == (200, 60, 3)
    np.testing.assert_array_equal(rgb[10, 30], raster.VEHICLE)


@pytest.mark.parametrize("kw, name", [
    ({"encoding": "hsv"}, "encoding"), ({"route": True}, "route"),
    ({"cols": 4}, "cols"), ({"encoding": "channels", "route": "yes"}, "route"),
    ({"draw_lanes": 1}, "draw_lanes"), ({"history": -1}, "history")])
def test_bad_configs_are_refused(kw, name):
    with pytest.raises(ValueError, match=name):
        world.RasterConfig(**kw)


def test_from_extent_refuses_a_bad_resolution():
    with pytest.raises(ValueError, match="resolution"):
        world.RasterConfig.from_extent(60.0, 15.0, 0.0)


def test_metadata_names_new_fields_only_when_set():
    assert world.RasterConfig().as_meta() == {
        "size": 64, "metres_ahead": 40.0, "metres_behind": 10.0, "metres_side": 25.0,
        "lane_width_m": 0.5, "draw_lanes": True, "draw_walkways": True, "draw_crossings": True,
        "ego_length": world.EGO_LENGTH, "ego_width": world.EGO_WIDTH}
    meta = CHANNELS.as_meta()
    assert meta["encoding"] == "channels" and meta["route"] is True and "cols" not in meta
    assert world.RasterConfig(**meta) == CHANNELS


@given(st.integers(1, 20), st.integers(0, 2**31 - 1))
def test_pack_and_planes_round_trip(c, seed):
    bits = np.random.default_rng(seed).integers(0, 2, (2, 3, 4, c)).astype(np.uint8)
    packed = raster.pack(bits)
    assert packed.shape == (2, 3, 4, -(-c // 8)) and packed.dtype == np.uint8
    np.testing.assert_array_equal(packed, np.packbits(bits, axis=-1, bitorder="little"))
    np.testing.assert_array_equal(
        np.unpackbits(packed, axis=-1, count=c, bitorder="little"), bits)


def test_reading_a_raster_back():
    m = straight_map()
    pose = np.array([70.0, -1.75, 0.0])
    ado = np.array([[80.0, -1.75, 0.0, 4.5, 1.9]])
    cfg = world.RasterConfig(encoding="channels")
    img = world.rasterize(m, pose, ado, cfg=cfg)
    x = world.to_input(img, cfg)
    assert x.dtype == np.float32 and x.shape == cfg.input_shape
    np.testing.assert_array_equal(x, world.planes(img, cfg))
    rgb_cfg = world.RasterConfig()
    rgb = world.rasterize(m, pose, ado, cfg=rgb_cfg)
    np.testing.assert_array_equal(world.to_input(rgb, rgb_cfg), rgb / np.float32(255))
    assert world.to_rgb(rgb, rgb_cfg) is rgb
    # the picture of the channels: the devkit colours where the planes are set
    pic = world.to_rgb(img, cfg)
    assert pic.shape == (64, 64, 3)
    np.testing.assert_array_equal(pic[38, 32], raster.VEHICLE)
    np.testing.assert_array_equal(pic[51, 32], raster.EGO)
    np.testing.assert_array_equal(pic[10, 27], raster.OPPOSITE_LANE)
    np.testing.assert_array_equal(pic[10, 30], raster.DRIVABLE)
    with pytest.raises(ValueError, match="bev must be uint8"):
        world.planes(rgb, cfg)
    with pytest.raises(ValueError, match="bev must be uint8"):
        world.to_input(img.astype(np.float32), cfg)


@pytest.fixture(scope="module")
def ds():
    return world.generate(3, seed=3, raster=world.RasterConfig(size=32, encoding="channels",
                                                               route=True, history=2),
                          workers=1)


def test_dataset_stores_packed_channels_and_round_trips(ds, tmp_path):
    cfg = ds.raster
    assert ds.bev.shape == (3, 40, 32, 32, 2) and ds.bev.dtype == np.uint8
    assert ds.goal_bev.shape == (3, 32, 32, 2)
    back = world.load(world.save(ds, tmp_path / "c.npz"))
    assert back.raster == cfg and back.content_hash() == ds.content_hash()
    np.testing.assert_array_equal(back.bev, ds.bev)
    # the stored frames are the rasteriser's, from the stored poses
    P = world.planes(ds.bev, cfg)
    assert P[..., cfg.channel_names.index("vehicles_t-1")][:, 1:].any()
    assert not P[..., cfg.channel_names.index("vehicles_t-1")][:, 0].any()
    goal = world.planes(ds.goal_bev, cfg)
    assert not goal[..., cfg.channel_names.index("vehicles")].any()
    assert goal[..., cfg.channel_names.index("route")].any()
    # the same scenes in RGB: the same poses, other rasters
    rgb = world.generate(3, seed=3, raster=world.RasterConfig(size=32, history=2), workers=1)
    np.testing.assert_array_equal(rgb.ego, ds.ego)
    assert rgb.content_hash() != ds.content_hash()


def test_rasters_that_disagree_with_their_config_are_refused(ds, tmp_path):
    arrays = {f: getattr(ds, f) for f in ARRAY_FIELDS}
    rgb_meta = dict(ds.meta, raster=world.RasterConfig(size=32, history=2).as_meta())
    with pytest.raises(ValueError, match="bev frames have shape"):
        world.Dataset.build([{f: a[0] for f, a in arrays.items()}],
                            dict(rgb_meta, **{k: rgb_meta[k][:1] for k in
                                              ("recipes", "tags", "attempts", "scene_index")}))
    path = tmp_path / "mixed.npz"
    with DatasetWriter(path) as w:
        w.add(arrays)
        w.finish(rgb_meta)
    with pytest.raises(DatasetFileError, match="bev frames have shape"):
        world.load(path)


class _Bev:
    model, setting, keys = None, "paper", ("bev",)


@pytest.mark.parametrize("make", [LogReplay, reactive.ReactiveSim])
def test_the_closed_loop_draws_the_stored_channels(ds, make):
    """Driving the human's controls, both simulators re-render the dataset's own planes
    from the policy's poses and their recorded history."""
    sim = make(ds, np.arange(3))
    sim.reset()
    assert sim.raster == ds.raster
    for t in range(6 if make is LogReplay else 3):
        obs = observation(_Bev(), sim.observe(), np.zeros((3, 2), np.float32), sim.raster,
                          sim.k_targets)
        np.testing.assert_array_equal(obs["bev"], world.to_input(ds.bev[:, t], ds.raster))
        sim.step(np.asarray(ds.controls[:, t], dtype=np.float64))
