"""Chapter 7 — frames, unicycle and box geometry of minimanc.world."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import world

finite = st.floats(-200, 200, allow_nan=False)
angle = st.floats(-10, 10, allow_nan=False)


@settings(max_examples=40, deadline=None)
@given(x=finite, y=finite, yaw=angle, px=finite, py=finite)
def test_to_ego_frame_round_trip_and_isometry(x, y, yaw, px, py):
    pose = np.array([x, y, yaw])
    p = np.array([[px, py], [px + 1.0, py - 2.0]])
    q = world.to_ego_frame(p, pose)
    np.testing.assert_allclose(world.from_ego_frame(q, pose), p, atol=1e-9)
    # distances are preserved, and the ego's own position maps to the origin
    np.testing.assert_allclose(np.linalg.norm(q[0] - q[1]), np.linalg.norm(p[0] - p[1]))
    np.testing.assert_allclose(world.to_ego_frame(pose[:2], pose), [0.0, 0.0], atol=1e-9)


def test_to_ego_frame_axes():
    # ego at (1, 2) facing north: a point further north is straight ahead (+x),
    # a point to the west is on the ego's left (+y)
    pose = np.array([1.0, 2.0, np.pi / 2])
    np.testing.assert_allclose(world.to_ego_frame(np.array([1.0, 12.0]), pose), [10, 0],
                               atol=1e-12)
    np.testing.assert_allclose(world.to_ego_frame(np.array([-4.0, 2.0]), pose), [0, 5],
                               atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(x=finite, y=finite, yaw=angle, gx=finite, gy=finite, gyaw=angle)
def test_goal_in_ego_frame(x, y, yaw, gx, gy, gyaw):
    ego = np.array([x, y, yaw])
    goal = np.array([gx, gy, gyaw])
    g = world.goal_in_ego_frame(goal, ego)
    np.testing.assert_allclose(g[:2], world.to_ego_frame(goal[:2], ego), atol=1e-9)
    assert -np.pi < g[2] <= np.pi
    np.testing.assert_allclose(np.cos(g[2]), np.cos(gyaw - yaw), atol=1e-9)
    np.testing.assert_allclose(np.sin(g[2]), np.sin(gyaw - yaw), atol=1e-9)
    np.testing.assert_allclose(world.goal_in_ego_frame(ego, ego), 0.0, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(x=finite, y=finite, yaw=angle, v=st.floats(0, 20), w=st.floats(-1.5, 1.5))
def test_unicycle_step_is_explicit_euler(x, y, yaw, v, w):
    dt = world.DT
    out = world.unicycle_step(np.array([x, y, yaw]), np.array([v, w]), dt)
    # position moves along the *old* yaw; then the yaw turns
    np.testing.assert_allclose(out[:2], [x + v * np.cos(yaw) * dt, y + v * np.sin(yaw) * dt],
                               atol=1e-9)
    np.testing.assert_allclose(np.cos(out[2]), np.cos(yaw + w * dt), atol=1e-9)
    np.testing.assert_allclose(np.sin(out[2]), np.sin(yaw + w * dt), atol=1e-9)
    # and controls_from_poses inverts it
    back = world.controls_from_poses(np.stack([np.array([x, y, yaw]), out]))
    np.testing.assert_allclose(back[0], [v, w], atol=1e-7)


def test_unicycle_step_batched_and_dtype():
    poses = np.zeros((4, 3), np.float32)
    ctl = np.tile(np.array([[2.0, 0.1]], np.float32), (4, 1))
    out = world.unicycle_step(poses, ctl)
    assert out.shape == (4, 3) and out.dtype == np.float32
    np.testing.assert_allclose(out[:, 0], 1.0)


def test_bad_input_raises():
    with pytest.raises(ValueError, match="pose"):
        world.unicycle_step(np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError, match="controls"):
        world.unicycle_step(np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="dt"):
        world.unicycle_step(np.zeros(3), np.zeros(2), dt=0.0)
    with pytest.raises(ValueError, match="ego_pose"):
        world.to_ego_frame(np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError, match="points_world"):
        world.to_ego_frame(np.zeros(3), np.zeros(3))


def test_wrap_angle_range():
    a = np.linspace(-20, 20, 1001)
    w = world.wrap_angle(a)
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-12)
    assert world.wrap_angle(-np.pi) == np.pi


def _inside_box(points, box):
    c, s = np.cos(box[2]), np.sin(box[2])
    d = points - box[:2]
    u = c * d[:, 0] + s * d[:, 1]
    v = -s * d[:, 0] + c * d[:, 1]
    return (np.abs(u) <= box[3] / 2) & (np.abs(v) <= box[4] / 2)


@settings(max_examples=40, deadline=None)
@given(x=st.floats(-6, 6), y=st.floats(-6, 6), ya=angle, yb=angle,
       la=st.floats(1, 8), wa=st.floats(0.5, 3), lb=st.floats(1, 8), wb=st.floats(0.5, 3))
def test_boxes_overlap_matches_sampling(x, y, ya, yb, la, wa, lb, wb):
    a = np.array([0.0, 0.0, ya, la, wa])
    b = np.array([x, y, yb, lb, wb])
    got = bool(world.boxes_overlap(a, b))
    # oracle: dense samples of box a's area tested against box b (and vice versa)
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, 61), np.linspace(-0.5, 0.5, 61))
    def samples(box):
        c, s = np.cos(box[2]), np.sin(box[2])
        px = box[0] + c * u.ravel() * box[3] - s * v.ravel() * box[4]
        py = box[1] + s * u.ravel() * box[3] + c * v.ravel() * box[4]
        return np.stack([px, py], 1)
    hit = _inside_box(samples(a), b).any() or _inside_box(samples(b), a).any()
    if hit:
        assert got
    if np.hypot(x, y) > (np.hypot(la, wa) + np.hypot(lb, wb)) / 2:
        assert not got  # farther apart than the circumscribed circles
    if got:  # a real overlap is found by the sampling once the boxes are grown a little
        grown = _inside_box(samples(np.array([0, 0, ya, la + 0.3, wa + 0.3])),
                            np.array([x, y, yb, lb + 0.3, wb + 0.3])).any()
        assert grown or _inside_box(samples(b), np.array([0, 0, ya, la + 0.3, wa + 0.3])).any()
    # corners of each box lie on the box boundary
    ca = world.box_corners(a)
    np.testing.assert_allclose(np.linalg.norm(ca[0] - ca[2]), np.hypot(la, wa))

