"""Chapter 7 — BEV raster conventions: heading up, pixel positions, nuScenes colours."""

import colorsys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.path import Path as MplPath

from minimanc import world
from minimanc.world import raster

YELLOW = np.array(raster.VEHICLE)
RED = np.array(raster.EGO)


def straight_map(rotation=0.0, lanes=1):
    recipe = {"kind": "straight", "rotation": rotation, "lanes": lanes,
              "pieces": [[500.0, 0.0]], "ego": {"lane": 0, "start_s": 50.0}}
    return world.build_map(recipe)


def test_default_config_has_nuscenes_proportions():
    cfg = world.RasterConfig()
    assert cfg.shape == (64, 64, 3)
    assert cfg.res_row == cfg.res_col == pytest.approx(50 / 64)
    # devkit: 500 px at 0.1 m/px, agent at row 400, column 250; authors: 250 px at 0.2 m/px
    big = world.RasterConfig(size=500)
    assert big.resolution == pytest.approx(0.1) and big.ego_pixel == (400, 250)
    assert world.RasterConfig(size=250).resolution == pytest.approx(0.2)
    assert cfg.ego_pixel == (51, 32)


def test_config_rejects_bad_values():
    for kw, name in [({"size": 4}, "size"), ({"metres_ahead": -1.0}, "metres_ahead"),
                     ({"metres_side": 0.0}, "metres_side"),
                     ({"metres_behind": -2.0}, "metres_behind")]:
        with pytest.raises(ValueError, match=name):
            world.RasterConfig(**kw)


@settings(max_examples=30, deadline=None)
@given(x=st.floats(-300, 300), y=st.floats(-300, 300), yaw=st.floats(-4, 4),
       dyaw=st.floats(-0.3, 0.3))
def test_vehicle_ten_metres_ahead_is_straight_up(x, y, yaw, dyaw):
    """A vehicle 10 m ahead of the ego lands at row floor((40 - 10) / 0.78125) = 38, col 32."""
    m = straight_map()
    cfg = world.RasterConfig()
    pose = np.array([x, y, yaw])
    ahead = np.array([[x + 10 * np.cos(yaw), y + 10 * np.sin(yaw), yaw + dyaw, 4.5, 1.9]])
    left = np.array([[x - 10 * np.sin(yaw), y + 10 * np.cos(yaw), yaw, 4.5, 1.9]])
    img = world.rasterize(m, pose, np.concatenate([ahead, left]), np.array([True, True]), cfg)
    assert img.shape == (64, 64, 3) and img.dtype == np.uint8
    np.testing.assert_array_equal(img[38, 32], YELLOW)
    # the box is 4.5 m long (about 5.8 px) and 1.9 m wide: not drawn 6 rows away
    assert not np.array_equal(img[38 - 5, 32], YELLOW)
    assert not np.array_equal(img[38, 32 + 3], YELLOW)
    # 10 m to the ego's left: same row as the ego (51), col floor((25 - 10) / 0.78125) = 19
    np.testing.assert_array_equal(img[51, 19], YELLOW)
    # the ego is drawn red at its pixel, box 4.727 m x 1.907 m
    np.testing.assert_array_equal(img[51, 32], RED)
    np.testing.assert_array_equal(img[48, 31], RED)
    assert not np.array_equal(img[51, 35], RED)


def test_invalid_ados_are_not_drawn():
    m = straight_map()
    pose = np.array([70.0, -1.75, 0.0])
    ado = np.array([[80.0, -1.75, 0.0, 4.5, 1.9]])
    img = world.rasterize(m, pose, ado, np.array([False]))
    assert not np.array_equal(img[38, 32], YELLOW)


def test_layer_colours_on_a_straight_road():
    """Road along +x, lanes at y = -1.75 (forward) and +1.75 (backward), crossing at x = 90."""
    m = straight_map()
    cfg = world.RasterConfig()
    img = world.rasterize(m, np.array([70.0, -1.75, 0.0]), None, None, cfg)
    # own lane centreline (same direction): cyan, straight up the ego's column
    for r in (2, 10, 30, 45):
        np.testing.assert_array_equal(img[r, 32], (0, 255, 255))
    # opposite lane 3.5 m to the left: red, column floor((25 - 3.5) / 0.78125) = 27
    np.testing.assert_array_equal(img[10, 27], (255, 0, 0))
    # drivable area white, walkway blue beyond the kerb (2 m to the right), background black
    np.testing.assert_array_equal(img[10, 30], raster.DRIVABLE)
    np.testing.assert_array_equal(img[10, 35], raster.WALKWAY)
    np.testing.assert_array_equal(img[10, 60], raster.BACKGROUND)
    # pedestrian crossing 20 m ahead (rows 24 to 27)
    np.testing.assert_array_equal(img[25, 30], raster.PED_CROSSING)
    # layers can be switched off
    plain = world.rasterize(m, np.array([70.0, -1.75, 0.0]), None, None,
                            world.RasterConfig(draw_lanes=False, draw_walkways=False,
                                               draw_crossings=False))
    np.testing.assert_array_equal(plain[10, 32], raster.DRIVABLE)
    np.testing.assert_array_equal(plain[10, 35], raster.BACKGROUND)
    np.testing.assert_array_equal(plain[25, 30], raster.DRIVABLE)


def test_heading_up_is_rotation_invariant():
    """The same road rotated in the world, seen from the same relative pose: same raster."""
    cfg = world.RasterConfig()
    a = world.rasterize(straight_map(0.0), np.array([70.0, -1.0, 0.1]), None, None, cfg)
    rot = 1.1
    c, s = np.cos(rot), np.sin(rot)
    pose = np.array([c * 70.0 - s * -1.0, s * 70.0 + c * -1.0, 0.1 + rot])
    b = world.rasterize(straight_map(rot), pose, None, None, cfg)
    same = np.all(a == b, axis=-1).mean()
    assert same > 0.97, same  # only pixels on layer boundaries may flip (grid sampling)


def test_any_pose_far_off_the_map():
    m = straight_map()
    img = world.rasterize(m, np.array([5000.0, -3000.0, 2.0]))
    mask = world.rasterize(m, np.array([5000.0, -3000.0, 2.0]), draw_ego=False)
    assert np.all(mask == 0)
    assert np.array_equal(img[51, 32], RED)
    with pytest.raises(ValueError, match="ego_pose"):
        world.rasterize(m, np.array([np.nan, 0.0, 0.0]))


def test_rasterize_batch_matches_single_frames():
    rng = np.random.default_rng(3)
    m = world.random_map(rng, "roundabout")
    poses = np.stack([m.route_pose(s)[0] for s in (m.start_s, m.start_s + 30.0)])
    heads = np.array([m.route_pose(s)[1] for s in (m.start_s, m.start_s + 30.0)])
    poses = np.concatenate([poses, heads[:, None]], axis=1)
    ado = np.zeros((2, 3, 5))
    ado[:, :, :2] = poses[:, None, :2] + rng.normal(0, 10, (2, 3, 2))
    ado[:, :, 3:] = (4.5, 1.9)
    valid = np.array([[True, False, True], [True, True, True]])
    batch = world.rasterize_batch([m, m], poses, ado, valid)
    for i in range(2):
        np.testing.assert_array_equal(batch[i], world.rasterize(m, poses[i], ado[i], valid[i]))
    with pytest.raises(ValueError, match="ego_poses"):
        world.rasterize_batch(m, np.zeros((2, 2)))


@pytest.mark.parametrize("cfg", [world.RasterConfig(),
                                 world.RasterConfig(encoding="channels", route=True)])
def test_a_batch_of_several_maps_draws_each_frame_as_alone(cfg):
    """Frames of different maps in one batch (the closed loop's) are drawn as each is alone;
    no frame is an empty batch of the raster's shape."""
    rng = np.random.default_rng(5)
    maps = [world.random_map(rng, kind) for kind in ("roundabout", "intersection", "curved")]
    poses = np.array([[*m.route_pose(m.start_s + 10.0 * i)[0], m.route_pose(m.start_s)[1]]
                      for i, m in enumerate(maps)])
    batch = world.rasterize_batch(maps, poses, cfg=cfg)
    for m, pose, img in zip(maps, poses, batch):
        np.testing.assert_array_equal(img, world.rasterize(m, pose, cfg=cfg))
    assert world.rasterize_batch([], np.zeros((0, 3)), cfg=cfg).shape == (0, *cfg.shape)


@settings(max_examples=40, deadline=None)
@given(rel=st.floats(-10, 10))
def test_hue_matches_colorsys(rel):
    """Lane colour = devkit color_by_yaw: hsv((wrap(agent - lane) + pi) / 2pi, 1, 1)."""
    wrapped = (rel + np.pi) % (2 * np.pi) - np.pi
    want = np.array(colorsys.hsv_to_rgb((wrapped + np.pi) / (2 * np.pi), 1.0, 1.0)) * 255
    got = world.hue_colours(np.array(rel))
    np.testing.assert_allclose(got, want, atol=1.0)
    # the look-up table used by the rasteriser is within one unit of the exact colour
    q = int(np.floor(np.mod(rel, 2 * np.pi) * raster._N_HUE / (2 * np.pi)))
    np.testing.assert_allclose(raster._HUE_LUT[min(q, raster._N_HUE - 1)], want, atol=2.0)


@settings(max_examples=30, deadline=None)
@given(x=st.floats(-20, 20), y=st.floats(-20, 20), yaw=st.floats(-4, 4),
       length=st.floats(1, 12), width=st.floats(0.5, 3))
def test_box_mask_matches_polygon_oracle(x, y, yaw, length, width):
    cfg = world.RasterConfig()
    X, Y = cfg.pixel_centres()
    box = np.array([x, y, yaw, length, width])
    got = world.box_mask(X, Y, box)
    corners = world.box_corners(box)
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    # points clearly inside/outside (shrunk/grown polygon) must agree
    inner = world.box_corners(np.array([x, y, yaw, length - 0.02, width - 0.02]))
    outer = world.box_corners(np.array([x, y, yaw, length + 0.02, width + 0.02]))
    surely_in = MplPath(inner).contains_points(pts).reshape(X.shape)
    maybe_in = MplPath(outer).contains_points(pts).reshape(X.shape)
    assert np.all(got[surely_in])
    assert not np.any(got[~maybe_in])
    assert corners.shape == (4, 2)
