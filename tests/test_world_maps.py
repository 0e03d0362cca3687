"""Chapter 7 — procedural maps, routes and the moving lane target."""

import json

import numpy as np
import pytest

from minimanc import world
from minimanc.world import lanes


@pytest.fixture(scope="module")
def some_maps():
    out = []
    for i, kind in enumerate(lanes.KINDS * 3):
        out.append(world.random_map(np.random.default_rng([7, i]), kind))
    return out


def test_every_kind_builds_with_a_long_continuous_route(some_maps):
    for m in some_maps:
        assert m.kind in lanes.KINDS
        # the route is one continuous polyline, ~1 m spacing, long enough for 20 s of driving
        steps = np.linalg.norm(np.diff(m.route_points, axis=0), axis=1)
        assert steps.max() < 1.3 and steps.min() > 0.05
        assert m.route_s[-1] - m.start_s >= lanes.ROUTE_AHEAD - 1.0
        # headings agree with the polyline's direction
        d = np.diff(m.route_points, axis=0)
        dirs = np.arctan2(d[:, 1], d[:, 0])
        err = np.abs(world.wrap_angle(dirs - m.route_heads[:-1]))
        assert np.percentile(err, 99) < 0.15
        # the whole route lies on the drivable area
        assert m.is_drivable(m.route_points).all()
        # lane successors join end to start
        for ln in m.lanes:
            for nxt in ln.successors:
                assert np.linalg.norm(ln.points[-1] - m.lanes[nxt].points[0]) < 1e-6


def test_junction_maps_have_junction_lanes_and_conflicts(some_maps):
    for m in some_maps:
        kinds = {m.lanes[i].kind for i in m.route}
        if m.kind == "intersection":
            assert "connector" in kinds and m.has_junction
            assert len(m.conflicts) > 0
        elif m.kind == "roundabout":
            assert "ring" in kinds and m.has_roundabout
            assert len(m.conflicts) > 0
        else:
            assert kinds == {"road"} and not m.conflicts
        # conflict table is symmetric with intervals inside each lane
        for (a, b), (s_in, s_out) in m.conflicts.items():
            assert (b, a) in m.conflicts
            assert 0.0 <= s_in <= s_out <= m.lanes[a].length + 1e-9


def test_recipe_round_trips_through_json(some_maps):
    for m in some_maps[:4]:
        again = world.build_map(json.loads(json.dumps(m.recipe)))
        np.testing.assert_array_equal(again.route_points, m.route_points)
        assert again.key == m.key and len(again.lanes) == len(m.lanes)


def test_lane_targets_every_four_metres_from_the_egos_own_position(some_maps):
    m = some_maps[2]  # an intersection
    for s in (m.start_s, m.start_s + 37.0, m.start_s + 80.0):
        p, h = m.route_pose(s)
        for lat in (0.0, 0.8):
            pose = np.array([p[0] - lat * np.sin(h), p[1] + lat * np.cos(h), h + 0.05])
            lt = world.lane_targets(m, pose, k=10)
            assert lt.shape == (10, 2)
            # consecutive targets are 4 m apart along the route (chords of curves are shorter)
            gaps = np.linalg.norm(np.diff(lt, axis=0), axis=1)
            assert np.all(gaps <= 4.0 + 1e-6) and np.all(gaps > 3.0)
            # the first one is 4 m ahead of the projection of the ego on the route
            first = world.to_ego_frame(m.route_pose(s + 4.0)[0], pose)
            np.testing.assert_allclose(lt[0], first, atol=0.05)
    # no dependence on time: the same pose gives the same targets
    pose = np.array([*m.route_pose(m.start_s + 10)[0], m.route_pose(m.start_s + 10)[1]])
    np.testing.assert_array_equal(world.lane_targets(m, pose), world.lane_targets(m, pose))


def test_lane_targets_bad_input(some_maps):
    m = some_maps[0]
    with pytest.raises(ValueError, match="ego_pose"):
        world.lane_targets(m, np.zeros(2))
    with pytest.raises(ValueError, match="k"):
        world.lane_targets(m, np.zeros(3), k=0)


def test_bad_recipe_raises():
    with pytest.raises(ValueError, match="recipe"):
        world.build_map({"kind": "spaghetti"})
    with pytest.raises(ValueError, match="kind"):
        world.random_recipe(np.random.default_rng(0), kind="spaghetti")


def test_explicit_recipe_builds_the_given_geometry():
    recipe = {"kind": "explicit", "map_kind": "straight", "start_s": 5.0,
              "lanes": [{"points": [[0.0, 0.0], [100.0, 0.0]], "width": 3.5,
                         "successors": [1]},
                        {"points": [[100.0, 0.0], [100.0, 50.0]], "width": 3.5}],
              "strips": [{"lane": 0, "half_width": 2.0}, {"lane": 1, "half_width": 2.0}],
              "route": [0, 1]}
    m = world.build_map(recipe)
    assert m.kind == "straight" and m.key.startswith("x-") and m.start_s == 5.0
    assert m.lanes[1].predecessors == [0]
    assert m.route_s[-1] == pytest.approx(150.0)
    assert m.is_drivable(np.array([[50.0, 1.5], [100.0, 30.0]])).all()
    assert not m.is_drivable(np.array([[50.0, 3.0]])).any()
    again = world.build_map(json.loads(json.dumps(recipe)))
    assert again.key == m.key
    with pytest.raises(ValueError, match="recipe"):
        world.build_map({"kind": "explicit", "lanes": [{"points": [[0, 0]], "width": 3}],
                         "route": [0]})
