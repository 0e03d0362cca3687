"""Tests for minimanc.metrics: hand-made trajectories with known answers."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import checks, metrics
from minimanc.world.geometry import (
    EGO_LENGTH,
    EGO_WIDTH,
    box_corners,
    boxes_overlap,
    unicycle_step,
)

DT = 0.5


def drive(start, controls, dt=DT):
    """Poses (S, T, 3) from a start (S, 3) and controls (S, T-1, 2) by the unicycle."""
    poses = [np.asarray(start, dtype=float)]
    for t in range(controls.shape[1]):
        poses.append(unicycle_step(poses[-1], controls[:, t], dt))
    return np.stack(poses, axis=1)


def straight(speed=10.0, T=10, y=0.0):
    u = np.tile([[speed, 0.0]], (1, T - 1, 1))
    return drive(np.array([[0.0, y, 0.0]]), u)


# --------------------------------------------------------------------------- box gap


def test_box_gap_known_values():
    a = np.array([0.0, 0.0, 0.0, 4.0, 2.0])
    assert metrics.box_gap(a, [0.0, 5.0, 0.0, 4.0, 2.0]) == pytest.approx(3.0)
    assert metrics.box_gap(a, [10.0, 0.0, np.pi / 2, 4.0, 2.0]) == pytest.approx(7.0)
    assert metrics.box_gap(a, [1.0, 0.5, 0.3, 4.0, 2.0]) == 0.0  # overlap
    sq = np.array([0.0, 0.0, 0.0, 2.0, 2.0])
    assert metrics.box_gap(sq, [4.0, 4.0, 0.0, 2.0, 2.0]) == pytest.approx(np.sqrt(8.0))
    # a box rotated 45 degrees whose corner points at the other's edge
    d = 1.0 + np.sqrt(2.0) + 0.5  # half-size + half-diagonal + gap 0.5
    assert metrics.box_gap(sq, [d, 0.0, np.pi / 4, 2.0, 2.0]) == pytest.approx(0.5)


def _boundary(box, n=150):
    c = box_corners(np.asarray(box))
    t = np.linspace(0, 1, n, endpoint=False)[:, None]
    return np.concatenate([c[k] + t * (c[(k + 1) % 4] - c[k]) for k in range(4)])


coord = st.floats(-8, 8, allow_nan=False)
size = st.floats(0.5, 5, allow_nan=False)
yaw = st.floats(-np.pi, np.pi, allow_nan=False)


@settings(max_examples=40, deadline=None)
@given(coord, coord, yaw, size, size, coord, coord, yaw, size, size)
def test_box_gap_matches_dense_boundary_sampling(x1, y1, h1, l1, w1, x2, y2, h2, l2, w2):
    a = np.array([x1, y1, h1, l1, w1])
    b = np.array([x2, y2, h2, l2, w2])
    gap = float(metrics.box_gap(a, b))
    assert gap == pytest.approx(float(metrics.box_gap(b, a)), abs=1e-9)
    if gap == 0.0:
        return
    pa, pb = _boundary(a), _boundary(b)
    brute = np.sqrt(((pa[:, None] - pb[None]) ** 2).sum(-1)).min()
    # sampling can only overestimate, by at most one sampling step
    assert gap <= brute + 1e-9
    assert brute - gap <= (max(l1, w1, l2, w2) / 150) * 2 + 1e-9


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 1.0))
def test_gaps_and_collisions_measure_the_valid_boxes_alone(seed, share):
    """Measured only where an ado exists (the overlaps only where the circumscribed circles
    meet), the gaps and the collisions are those of every ego and ado box broadcast, masked
    afterwards."""
    rng = np.random.default_rng(seed)
    S, T, A = 2, 5, 6
    ego = np.concatenate([rng.uniform(-6, 6, (S, T, 2)), rng.uniform(-np.pi, np.pi, (S, T, 1))],
                         axis=-1)
    ado = np.concatenate([rng.uniform(-9, 9, (S, T, A, 2)),
                          rng.uniform(-np.pi, np.pi, (S, T, A, 1)),
                          rng.uniform(0.5, 6, (S, T, A, 2))], axis=-1)
    valid = rng.random((S, T, A)) < share
    boxes = metrics.ego_boxes(ego)[:, :, None, :]
    np.testing.assert_array_equal(metrics.ado_gaps(ego, ado, valid),
                                  np.where(valid, metrics.box_gap(boxes, ado), np.inf))
    hit = boxes_overlap(boxes, ado) & valid
    np.testing.assert_array_equal(metrics.collisions(ego, ado, valid),
                                  hit.reshape(S, -1).any(axis=1).astype(float))
    events = metrics.collision_events(ego, ado, valid)
    assert [(e.scene, e.ado) for e in events] == list(zip(*np.nonzero(hit.any(axis=1))))


# --------------------------------------------------------------------------- close encounters


def test_close_encounters_parked_car_next_lane():
    ego = straight(speed=4.0, T=11)  # x = 0, 2, ..., 20
    T = ego.shape[1]
    # one ado parked at x = 10, y = 2.5 (width 1.8): lateral gap 2.5 - 0.9535 - 0.9 = 0.6465
    ado = np.tile(np.array([10.0, 2.5, 0.0, 4.0, 1.8]), (1, T, 1, 1))
    valid = np.ones((1, T, 1), bool)
    share = metrics.close_encounters(ego, ado, valid, gap=1.0)
    # close while the boxes overlap in x (lateral gap < 1) or the corner gap is < 1
    xs = ego[0, :, 0]
    dx = np.maximum(np.abs(xs - 10.0) - (EGO_LENGTH / 2 + 2.0), 0.0)
    lat = 2.5 - EGO_WIDTH / 2 - 0.9
    expected = np.mean(np.hypot(dx, lat) < 1.0)
    assert share[0] == pytest.approx(expected)
    assert 0 < share[0] < 1
    # threshold below the lateral gap: never close; invalid ado: never close
    assert metrics.close_encounters(ego, ado, valid, gap=0.5)[0] == 0.0
    assert metrics.close_encounters(ego, ado, ~valid, gap=1.0)[0] == 0.0


def test_collisions_only_when_boxes_overlap():
    ego = straight(speed=4.0, T=11)
    T = ego.shape[1]
    ado = np.tile(np.array([10.0, 1.0, 0.0, 4.0, 1.8]), (1, T, 1, 1))
    valid = np.ones((1, T, 1), bool)
    assert metrics.collisions(ego, ado, valid)[0] == 1.0
    assert metrics.collisions(ego, ado + [0, 3.0, 0, 0, 0], valid)[0] == 0.0
    assert metrics.collisions(ego, ado, ~valid)[0] == 0.0


# --------------------------------------------------------------------------- acceleration


def test_max_acceleration_constant_speed_is_zero():
    assert metrics.max_acceleration(straight(8.0))[0] == pytest.approx(0.0, abs=1e-9)


def test_max_acceleration_circle_is_centripetal():
    v, w = 6.0, 0.3
    ego = drive(np.zeros((1, 3)), np.tile([[v, w]], (1, 12, 1)))
    assert metrics.max_acceleration(ego)[0] == pytest.approx(v * w, rel=1e-9)
    assert metrics.max_acceleration(ego, kind="longitudinal")[0] == pytest.approx(0.0, abs=1e-9)


def test_max_acceleration_speed_ramp_and_peak():
    speeds = np.array([0.0, 1.0, 2.0, 3.0, 5.0, 5.0, 5.0])  # +2, +2, +2, +4 m/s^2, then 0
    u = np.stack([speeds, np.zeros_like(speeds)], -1)[None]
    ego = drive(np.zeros((1, 3)), u)
    assert metrics.max_acceleration(ego)[0] == pytest.approx(4.0)
    assert metrics.max_acceleration(ego, kind="longitudinal")[0] == pytest.approx(4.0)
    # braking counts by magnitude
    ego_b = drive(np.zeros((1, 3)), u[:, ::-1])
    assert metrics.max_acceleration(ego_b)[0] == pytest.approx(4.0)


def test_max_acceleration_combines_components():
    # speed 4 -> 6 while turning at 0.5 rad/s: a_lon = 4, a_lat = 4 * 0.5 = 2 at that step
    u = np.array([[[4.0, 0.5], [6.0, 0.0], [6.0, 0.0]]])
    ego = drive(np.zeros((1, 3)), u)
    assert metrics.max_acceleration(ego)[0] == pytest.approx(np.hypot(4.0, 2.0))


# --------------------------------------------------------------------------- ade / goal


def test_ade_and_goal_distance():
    human = straight(10.0, T=9)
    shifted = human + np.array([0.0, 3.0, 0.0])
    assert metrics.ade(human, human)[0] == 0.0
    assert metrics.ade(shifted, human)[0] == pytest.approx(3.0)
    slow = straight(5.0, T=9)  # error grows 0, 2.5, ..., 20 -> mean 10
    assert metrics.ade(slow, human)[0] == pytest.approx(10.0)
    goal = human[:, -1]
    assert metrics.goal_distance(human, goal)[0] == 0.0
    assert metrics.goal_distance(slow, goal)[0] == pytest.approx(20.0)
    assert metrics.goal_distance(slow, goal[:, :2])[0] == pytest.approx(20.0)


# --------------------------------------------------------------------------- along / cross track


def test_along_cross_track_constructed_cases():
    human = straight(10.0, T=9)  # heading 0: along = dx, cross = dy
    along, cross = metrics.along_cross_track(human + [0.0, 3.0, 0.0], human)
    assert along.shape == cross.shape == (1, 9)
    assert np.allclose(along, 0.0) and np.allclose(cross, 3.0)  # 3 m to the left
    slow = straight(5.0, T=9)  # falls behind by 2.5 m per step, no lateral error
    along, cross = metrics.along_cross_track(slow, human)
    assert np.allclose(along[0], -2.5 * np.arange(9)) and np.allclose(cross, 0.0)
    # a human heading north (yaw pi/2): +x is to its right, +y ahead
    north = np.array([[[0.0, 0.0, np.pi / 2], [0.0, 5.0, np.pi / 2]]])
    along, cross = metrics.along_cross_track(north + [[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]]], north)
    assert np.allclose(along, [[0.0, 2.0]]) and np.allclose(cross, [[-1.0, 0.0]])
    # the policy's own yaw does not enter
    twisted = north + [[[1.0, 0.0, 1.3], [0.0, 2.0, -0.4]]]
    assert np.allclose(metrics.along_cross_track(twisted, north), (along, cross))
    # batched over scenes: each scene uses its own human's heading
    both = np.concatenate([human[:, :2], north])
    shift = both + [3.0, 4.0, 0.0]
    along, cross = metrics.along_cross_track(shift, both)
    assert np.allclose(along, [[3.0, 3.0], [4.0, 4.0]])
    assert np.allclose(cross, [[4.0, 4.0], [-3.0, -3.0]])


poses = st.lists(st.tuples(coord, coord, yaw), min_size=2, max_size=6)


@settings(max_examples=60, deadline=None)
@given(poses, poses, yaw, coord, coord)
def test_along_cross_track_splits_ade(a, b, turn, tx, ty):
    T = min(len(a), len(b))
    ego = np.array(a[:T])[None]
    human = np.array(b[:T])[None]
    along, cross = metrics.along_cross_track(ego, human)
    d2 = np.sum((ego[..., :2] - human[..., :2]) ** 2, axis=-1)
    assert np.allclose(along**2 + cross**2, d2, atol=1e-9)
    assert np.allclose(np.sqrt(along**2 + cross**2).mean(axis=1), metrics.ade(ego, human))
    # a rigid motion of the whole scene (both trajectories) leaves the split unchanged
    c, s = np.cos(turn), np.sin(turn)

    def move(p):
        xy = p[..., :2] @ np.array([[c, s], [-s, c]]) + [tx, ty]
        return np.concatenate([xy, p[..., 2:] + turn], axis=-1)

    moved = metrics.along_cross_track(move(ego), move(human))
    assert np.allclose(moved[0], along, atol=1e-9) and np.allclose(moved[1], cross, atol=1e-9)
    # with the same headings, swapping policy and human flips both signs
    same = np.concatenate([ego[..., :2], human[..., 2:]], axis=-1)
    back = metrics.along_cross_track(human, same)
    assert np.allclose(back[0], -along, atol=1e-9) and np.allclose(back[1], -cross, atol=1e-9)


def test_off_road_uses_the_map():
    class Strip:  # drivable where |y| < 2
        def is_drivable(self, p):
            return np.abs(np.asarray(p)[..., 1]) < 2.0

    on = straight(5.0, T=6)
    off = drive(np.zeros((1, 3)), np.tile([[5.0, 0.4]], (1, 5, 1)))
    assert metrics.off_road(on, [Strip()])[0] == 0.0
    assert metrics.off_road(off, [Strip()])[0] == 1.0


def test_evaluate_on_fake_dataset():
    class Everywhere:  # drivable everywhere, the route along +x
        route_points = np.stack([np.arange(-50.0, 200.0), np.zeros(250)], -1)
        route_heads = np.zeros(250)
        route_s = np.arange(250.0)

        def is_drivable(self, p):
            return np.ones(np.asarray(p).shape[:-1], bool)

    human = np.concatenate([straight(10.0, T=9), straight(10.0, T=9, y=20.0)])
    T = human.shape[1]
    ado = np.zeros((2, T, 1, 5)) + [500.0, 0, 0, 4, 2]
    ds = SimpleNamespace(ego=human, ado=ado, ado_valid=np.ones((2, T, 1), bool),
                         maps=[Everywhere(), Everywhere()])
    res = metrics.evaluate(SimpleNamespace(ego=human), ds)
    assert set(res) == set(metrics.ALL_METRICS)
    assert metrics.ALL_METRICS[:len(metrics.METRICS)] == metrics.METRICS
    assert res["ade"] == 0.0 and res["goal_distance"] == 0.0
    assert res["close_encounters"] == 0.0 and res["collision_rate"] == 0.0
    assert res["at_fault_collision_rate"] == 0.0 and res["ttc_rate"] == 0.0
    assert res["route_progress"] == pytest.approx(1.0)
    # a rollout that carries its own ados (the reactive protocol) is scored on them
    hit = ado.copy()
    hit[0, :, 0, :3] = human[0, :, :3] + [12.0, 0.0, 0.0]
    hit[0, 5:, 0, :3] = human[0, 5, :3] + [12.0, 0.0, 0.0]  # stops at step 5: rear-ended
    own = SimpleNamespace(ego=human, ado=hit, ado_valid=ds.ado_valid)
    res_own = metrics.evaluate(own, ds)
    assert res_own["collision_rate"] == pytest.approx(50.0)
    assert res_own["at_fault_collision_rate"] == pytest.approx(50.0)  # a stopped ado ahead
    assert metrics.evaluate(SimpleNamespace(ego=human, ado=None), ds) == res
    other = human.copy()
    other[0] += [0.0, 4.0, 0.0]
    res2 = metrics.evaluate(SimpleNamespace(ego=other), ds)
    assert res2["ade"] == pytest.approx(2.0)  # mean over scenes of 4 and 0
    assert res2["goal_distance"] == pytest.approx(2.0)


def test_aggregate_mean_std():
    agg = metrics.aggregate([{"ade": 1.0, "x": 0.0}, {"ade": 3.0, "x": 0.0}, {"ade": 2.0}])
    assert set(agg) == {"ade"}
    assert agg["ade"]["mean"] == pytest.approx(2.0)
    assert agg["ade"]["std"] == pytest.approx(np.std([1.0, 3.0, 2.0]))
    assert agg["ade"]["n"] == 3
    assert metrics.aggregate([{"ade": 5.0}])["ade"]["std"] == 0.0
    assert set(metrics.aggregate([{"ade": 1.0, "error": "blew up"}])) == {"ade"}


# --------------------------------------------------------------------------- bad input


def test_bad_input_raises_value_error_naming_parameter():
    ego = straight()
    with pytest.raises(ValueError, match="ego"):
        metrics.ade(ego[0], ego[0])
    with pytest.raises(ValueError, match="human"):
        metrics.ade(ego, ego[:, :-1])
    with pytest.raises(ValueError, match="kind"):
        metrics.max_acceleration(ego, kind="lateral")
    with pytest.raises(ValueError, match="dt"):
        metrics.max_acceleration(ego, dt=0.0)
    with pytest.raises(ValueError, match="gap"):
        metrics.close_encounters(ego, np.zeros((1, 10, 1, 5)), np.ones((1, 10, 1), bool), gap=-1)
    with pytest.raises(ValueError, match="ado"):
        metrics.close_encounters(ego, np.zeros((1, 9, 1, 5)), np.ones((1, 9, 1), bool))
    with pytest.raises(ValueError, match="goal"):
        metrics.goal_distance(ego, np.zeros((2, 3)))
    with pytest.raises(ValueError, match="ego"):
        metrics.ade(ego * np.nan, ego)
    with pytest.raises(ValueError, match="human"):
        metrics.along_cross_track(ego, ego[:, :-1])
    with pytest.raises(ValueError, match="human"):
        metrics.along_cross_track(ego, ego + np.inf)
    with pytest.raises(ValueError, match="ego"):
        metrics.along_cross_track(ego[0], ego)
    with pytest.raises(ValueError, match="per_seed"):
        metrics.aggregate([])


# --------------------------------------------------------------------------- at-fault collisions


class TwoLanes:
    """A straight two-lane road along +x: lane centrelines at y = 0 and y = 3.5, drivable
    for -1.75 < y < 5.25."""

    def lane_samples(self, spacing):
        from minimanc.world.lanes import LaneSamples

        x = np.arange(-100.0, 300.0, spacing)
        pts = np.concatenate([np.stack([x, 0 * x], -1), np.stack([x, 0 * x + 3.5], -1)])
        return LaneSamples.build(pts, np.zeros(len(pts)), (-100.0, -10.0, 300.0, 10.0))

    def is_drivable(self, p):
        y = np.asarray(p)[..., 1]
        return (y > -1.75) & (y < 5.25)


def _ado_track(x0, y0, vx, vy=0.0, T=10, size=(4.0, 1.8)):
    """One ado moving at constant velocity: boxes (1, T, 1, 5), heading along its velocity."""
    t = np.arange(T) * DT
    yaw = np.arctan2(vy, vx) if (vx or vy) else 0.0
    box = np.stack([x0 + vx * t, y0 + vy * t, np.full(T, yaw), np.full(T, size[0]),
                    np.full(T, size[1])], -1)
    return box[None, :, None, :], np.ones((1, T, 1), bool)


def _kinds(ego, ado, valid, maps=None):
    return [(e.kind, e.at_fault) for e in metrics.collision_events(ego, ado, valid, maps)]


def test_ego_running_into_a_slower_vehicle_ahead_is_at_fault():
    ego = straight(speed=10.0, T=10)  # x = 0, 5, ..., 45
    ado, valid = _ado_track(20.0, 0.0, 3.0)
    assert _kinds(ego, ado, valid) == [("front", True)]
    assert metrics.at_fault_collisions(ego, ado, valid)[0] == 1.0
    assert metrics.collisions(ego, ado, valid)[0] == 1.0


def test_ego_hitting_a_stopped_vehicle_is_at_fault():
    ego = straight(speed=8.0, T=10)
    ado, valid = _ado_track(25.0, 0.5, 0.0)
    assert _kinds(ego, ado, valid) == [("stopped_ado", True)]


def test_vehicle_running_into_a_slower_or_stopped_ego_from_behind_is_not_at_fault():
    slow = straight(speed=3.0, T=10)
    ado, valid = _ado_track(-14.0, 0.0, 10.0)
    assert _kinds(slow, ado, valid) == [("rear", False)]
    assert metrics.at_fault_collisions(slow, ado, valid)[0] == 0.0
    stopped = straight(speed=0.0, T=10)
    assert _kinds(stopped, ado, valid) == [("stopped_ego", False)]
    assert metrics.collisions(stopped, ado, valid)[0] == 1.0  # a collision, not the ego's


def test_ego_drifting_into_a_vehicle_beside_it_is_at_fault_but_not_a_cut_in():
    # the ego steers left into the neighbour lane, where an ado drives at the same speed
    u = np.tile([[10.0, 0.0]], (1, 9, 1))
    u[0, 1, 1], u[0, 3, 1] = 0.35, -0.35  # a lane change to the left
    ego = drive(np.zeros((1, 3)), u)
    ado, valid = _ado_track(-0.5, 3.5, 10.0)
    assert _kinds(ego, ado, valid, [TwoLanes()]) == [("lateral", True)]
    ev = metrics.collision_events(ego, ado, valid, [TwoLanes()])[0]
    assert ev.in_lane is False
    # an ado cutting into the lane of an ego that keeps its lane: not the ego's fault
    ego2 = straight(speed=10.0, T=10)
    cut, valid2 = _ado_track(-0.5, 3.5, 10.0, vy=-1.5)
    assert _kinds(ego2, cut, valid2, [TwoLanes()]) == [("lateral", False)]
    assert metrics.at_fault_collisions(ego2, cut, valid2, [TwoLanes()])[0] == 0.0
    # without a map a lateral contact counts as at fault (conservative)
    assert metrics.at_fault_collisions(ego2, cut, valid2)[0] == 1.0


def test_each_ado_counts_once_and_invalid_ados_never():
    ego = straight(speed=10.0, T=10)
    a1, v1 = _ado_track(20.0, 0.0, 3.0)
    a2, v2 = _ado_track(-10.0, 0.0, 12.0)
    ado, valid = np.concatenate([a1, a2], axis=2), np.concatenate([v1, v2], axis=2)
    assert metrics.collisions(ego, ado, valid)[0] == 1.0
    assert sorted(_kinds(ego, ado, valid)) == [("front", True), ("rear", False)]
    assert [e.ado for e in metrics.collision_events(ego, ado, valid)] == [0, 1]
    assert metrics.collision_events(ego, ado, ~valid) == []
    assert metrics.at_fault_collisions(ego, ado, ~valid)[0] == 0.0


def test_ego_in_lane_uses_the_lane_centrelines():
    m = TwoLanes()
    poses = np.array([[0.0, 0.0, 0.0], [0.0, 0.7, 0.0], [0.0, 1.0, 0.0], [0.0, 3.5, 0.1],
                      [0.0, 3.5, 2.0], [0.0, 6.0, 0.0]])
    assert metrics.ego_in_lane(poses, m).tolist() == [True, True, False, True, False, False]
    assert metrics.IN_LANE == pytest.approx((3.5 - EGO_WIDTH) / 2)


# --------------------------------------------------------------------------- time to collision


def test_time_to_collision_constructed_cases():
    ego = straight(speed=10.0, T=6)  # x = 0 ... 25
    # a stopped ado whose rear is 10.64 m ahead of the ego's front at t = 0: contact at 1.064 s
    ado, valid = _ado_track(15.0, 0.0, 0.0, T=6)
    ttc = metrics.time_to_collision(ego, ado, valid, horizon=2.0)
    assert ttc[0, 0] == pytest.approx(1.1)  # the first 0.1 s sample after contact
    assert ttc[0, 1] == pytest.approx(0.6)
    assert np.isinf(metrics.time_to_collision(ego, ado, valid, horizon=1.0)[0, 0])
    assert ttc[0, 2] == 0.0 or ttc[0, 2] == pytest.approx(0.1)
    # an ado closing in from behind, a stopped ego, an ado in the next lane: no TTC
    behind, vb = _ado_track(-14.0, 0.0, 15.0, T=6)  # closes in, still behind at the end
    assert np.isinf(metrics.time_to_collision(ego, behind, vb, 2.0)).all()
    still = straight(speed=0.0, T=6)
    assert np.isinf(metrics.time_to_collision(still, ado, valid, 2.0)).all()
    side, vs = _ado_track(0.0, 3.5, 10.0, T=6)
    assert np.isinf(metrics.time_to_collision(ego, side, vs, 2.0)).all()
    # the rate: share of steps with TTC <= the bound
    rate = metrics.ttc_rate(ego, ado, valid, threshold=1.0)[0]
    assert rate == pytest.approx(np.mean(metrics.time_to_collision(ego, ado, valid, 1.0) <= 1.0))
    assert 0 < rate < 1
    with pytest.raises(ValueError, match="horizon"):
        metrics.time_to_collision(ego, ado, valid, horizon=-1.0)


@settings(max_examples=30, deadline=None)
@given(st.floats(2.0, 15.0), st.floats(8.0, 40.0), st.floats(0.0, 1.5))
def test_time_to_collision_matches_the_closing_speed(v, gap, v_ado):
    """Head-on into a slower ado ahead: TTC is the gap over the closing speed, rounded up to
    the 0.1 s grid (to within the grid)."""
    ego = straight(speed=v, T=3)
    centre = EGO_LENGTH / 2 + gap + 2.0
    ado, valid = _ado_track(centre, 0.0, v_ado, T=3)
    ttc = metrics.time_to_collision(ego, ado, valid, horizon=10.0)[0, 0]
    exact = gap / (v - v_ado) if v - v_ado > 1e-9 else np.inf
    if exact <= 9.8:
        assert exact - 1e-9 <= ttc <= exact + 0.1 + 1e-9
    elif exact > 10.0:
        assert np.isinf(ttc)


# --------------------------------------------------------------------------- route progress


def test_route_progress_relative_to_the_human():
    from minimanc.world.maps import random_recipe
    from minimanc.world.roads import build_map

    m = build_map(random_recipe(np.random.default_rng(0), kind="straight"))

    def on_route(s):
        xy, h = m.route_pose(np.asarray(s, float))
        return np.concatenate([xy, h[..., None]], -1)[None]

    human = on_route(np.linspace(10.0, 50.0, 9))
    half = on_route(np.linspace(10.0, 30.0, 9))
    assert metrics.route_progress(human, human, [m])[0] == pytest.approx(1.0)
    assert metrics.route_progress(half, human, [m])[0] == pytest.approx(0.5, abs=1e-6)
    assert metrics.route_progress(human, half, [m])[0] == pytest.approx(2.0, abs=1e-6)
    parked = on_route(np.full(9, 10.0))
    assert metrics.route_progress(half, parked, [m])[0] == 1.0  # nothing to compare with
    with pytest.raises(ValueError, match="maps"):
        metrics.route_progress(human, human, [])


@settings(max_examples=40, deadline=None)
@given(st.floats(-30, 30), st.floats(-6, 6), st.floats(-12, 12), st.floats(-4, 4),
       st.floats(0.0, 12.0))
def test_fault_follows_who_was_moving(x0, y0, vx, vy, v_ego):
    """A stopped ego is never at fault; a moving ego that touches a stopped ado always is."""
    ado, valid = _ado_track(x0, y0, vx, vy, T=10)
    still = straight(speed=0.0, T=10)
    assert all(not e.at_fault and e.kind == "stopped_ego"
               for e in metrics.collision_events(still, ado, valid, [TwoLanes()]))
    parked, pv = _ado_track(x0, y0, 0.0, T=10)
    ego = straight(speed=v_ego, T=10)
    for e in metrics.collision_events(ego, parked, pv, [TwoLanes()]):
        assert e.at_fault == (v_ego > metrics.V_STOPPED)


# --------------------------------------------------------------------------- the package


def test_package_reexports_every_public_name_from_the_module_that_owns_it():
    """``minimanc.metrics`` is a package of one concept per module; its API is as before."""
    import importlib
    import inspect

    owners = {"boxes", "trajectory", "safety", "table"}
    assert hasattr(metrics, "__path__")  # a package, not one long module
    for name in metrics.__all__:
        obj = getattr(metrics, name)
        if inspect.isfunction(obj) or inspect.isclass(obj):
            module = obj.__module__
        else:  # a constant: the submodule whose ``__all__`` lists it
            module = next(f"minimanc.metrics.{m}" for m in sorted(owners)
                          if name in importlib.import_module(f"minimanc.metrics.{m}").__all__)
        package, owner = module.rsplit(".", 1)
        assert package == "minimanc.metrics" and owner in owners, (name, module)
        assert getattr(importlib.import_module(module), name) is obj, name
    # reachable by attribute as before, outside ``__all__``
    assert (metrics.DT, metrics.TTC_STEP) == (0.5, 0.1)
    assert (metrics.EGO_LENGTH, metrics.EGO_WIDTH) == (EGO_LENGTH, EGO_WIDTH)
    assert len(set(metrics.__all__)) == len(metrics.__all__)


def test_input_checks_are_public_and_name_the_parameter():
    from minimanc.metrics import boxes

    ego = straight()
    assert boxes.check_poses(ego.tolist()).dtype == np.float64
    for bad, match in [(ego[0], "ego must have shape"), (ego[:, :0], "at least one step"),
                       (ego * np.nan, "ego must be finite")]:
        with pytest.raises(ValueError, match=match):
            boxes.check_poses(bad)
    with pytest.raises(ValueError, match="ds.ego must be finite"):
        boxes.check_poses(ego + np.inf, "ds.ego")
    with pytest.raises(ValueError, match="ego and human must have the same shape"):
        boxes.check_ego_and_human(ego, ego[:, :-1])
    with pytest.raises(ValueError, match="ado_valid must have shape"):
        boxes.check_ados(np.zeros((1, 10, 2, 5)), np.ones((1, 10, 1), bool), ego)
    for dt in (0.0, -0.5, np.inf, np.nan):
        with pytest.raises(ValueError, match="dt must be a positive finite number"):
            checks.check_dt(dt)
    assert checks.check_dt(np.float32(0.5)) == 0.5


@given(st.integers(0, 4), st.integers(0, 4))
def test_every_metric_with_maps_refuses_the_wrong_number_alike(n_maps, n_scenes):
    """One check, one message, in off_road, route_progress and collision_events."""
    from minimanc.metrics import boxes

    maps = [TwoLanes()] * n_maps
    if n_maps == n_scenes:
        assert boxes.check_maps(maps, n_scenes) is maps
        return
    message = f"maps must hold one map per scene ({n_scenes}); got {n_maps}"
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        boxes.check_maps(maps, n_scenes)
    if n_scenes == 0:
        return
    ego = np.repeat(straight(), n_scenes, axis=0)
    ado, valid = np.zeros((n_scenes, 10, 1, 5)), np.zeros((n_scenes, 10, 1), bool)
    for call in (lambda: metrics.off_road(ego, maps),
                 lambda: metrics.route_progress(ego, ego, maps),
                 lambda: metrics.collision_events(ego, ado, valid, maps)):
        with pytest.raises(ValueError) as info:
            call()
        assert str(info.value) == message
