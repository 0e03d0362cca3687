"""Chapter 10 — the map adapter: highway-env's road network as a chapter-7 ``Map``.

Each lane of the road network is sampled once per episode with
``lane.position(s, 0)`` (every ~1 m) and ``lane.width_at(s)`` into an
explicit recipe (:func:`map_recipe`) and built into a
:class:`minimanc.world.lanes.Map` (:func:`explicit_map`, :func:`road_map`):
lane centrelines, one drivable strip per lane (half width = half the lane
width, so "off-road" means what highway-env's ``on_road`` means) and the
ego's route. :class:`RouteTracker` moves the lane target with the ego's own
lane. The chapter-7 rasteriser then draws the map unchanged.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np
from highway_env.road.lane import CircularLane, SineLane, StraightLane

from minimanc.highway.env import ENV_IDS, ego_pose, scenario_of, to_world
from minimanc.world.lanes import K_TARGETS, Lane, Map
from minimanc.world.maps import lane_targets, project_to_route
from minimanc.world.roads import EXPLICIT_KIND, build_map, concat_lanes


def _lane_table(network) -> list[tuple]:
    """Lane indices ``(from, to, id)`` in the network's (deterministic) order: Map lane ids."""
    return list(network.lanes_dict().keys())


def _lane_kind(lane, scenario: str) -> str:
    if isinstance(lane, CircularLane):
        return "ring" if scenario == "roundabout" else "connector"
    if isinstance(lane, SineLane):
        return "connector"
    return "road"


def _lane_points(lane, s_lo: float, s_hi: float, spacing: float) -> tuple[np.ndarray, float]:
    """World-frame centreline samples of a highway-env lane between arc lengths ``s_lo, s_hi``.

    Straight lanes need only their two ends (the Map resamples them); curved
    ones are sampled every ``spacing`` m with ``lane.position(s, 0)``. Also
    returns the mean ``lane.width_at(s)``.
    """
    straight = isinstance(lane, StraightLane) and not isinstance(lane, SineLane)
    n = 1 if straight else max(int(np.ceil((s_hi - s_lo) / spacing)), 1)
    s = np.linspace(s_lo, s_hi, n + 1)
    pts = np.array([lane.position(si, 0.0) for si in s], dtype=np.float64)
    width = float(np.mean([lane.width_at(si) for si in np.linspace(s_lo, s_hi, 5)]))
    return to_world(pts), width


def route_edges(network, start: tuple, destination: str | None, max_lanes: int = 32) -> list:
    """The road edges ``(from, to)`` from the ego's lane to ``destination``.

    Without a destination the route follows the road ahead: at each node the
    next road whose lane starts closest to the current lane's end
    (highway-env's own rule for vehicles without a plan).
    """
    edges = [tuple(start[:2])]
    if destination is not None:
        path = network.shortest_path(start[1], destination)
        edges += [(path[i], path[i + 1]) for i in range(len(path) - 1)]
        return edges
    current = start
    for _ in range(max_lanes):
        lane = network.get_lane(current)
        nxt = network.next_lane(current, route=None, position=lane.position(lane.length, 0.0))
        if tuple(nxt[:2]) in edges or nxt == current:
            break
        edges.append(tuple(nxt[:2]))
        current = nxt
    return edges


def _chain(network, first: tuple, edges: Sequence[tuple]) -> list[tuple]:
    """Lane indices along ``edges`` starting with lane ``first`` (on ``edges[0]``).

    Each next lane is the one of the next road whose start is closest to the
    current lane's end (the same id when the lanes line up).
    """
    chain = [tuple(first)]
    for a, b in edges[1:]:
        end = network.get_lane(chain[-1])
        end_pt = end.position(end.length, 0.0)
        lanes = network.graph[a][b]
        d = [np.linalg.norm(ln.position(0.0, 0.0) - end_pt) for ln in lanes]
        chain.append((a, b, int(np.argmin(d))))
    return chain


def _route_fields(lanes: list[Lane], route: list[int]) -> dict:
    """``route, route_points, route_heads, route_s`` of a lane sequence (as ``build_map``)."""
    rp, rh, rs, _ = concat_lanes(lanes, route)
    return {"route": [int(r) for r in route], "route_points": rp, "route_heads": rh,
            "route_s": rs}


def explicit_map(recipe: dict) -> Map:
    """The :class:`Map` of an explicit recipe (:func:`map_recipe`), via :func:`world.build_map`.

    Explicit recipes carry the geometry itself (lane polylines and widths,
    drivable strips, the route as lane ids) as JSON-able numbers, which is
    what lets :func:`minimanc.world.load` rebuild the maps of highway-env
    demonstrations without highway-env (see :mod:`minimanc.world.maps`).
    """
    if not isinstance(recipe, dict) or recipe.get("kind") != EXPLICIT_KIND:
        raise ValueError(f"recipe must be a dict with kind={EXPLICIT_KIND!r}, "
                         f"got {str(recipe)[:200]}")
    return build_map(recipe)


def _round(a: np.ndarray) -> list:
    return np.round(np.asarray(a, dtype=np.float64), 3).tolist()


def map_recipe(
    env,
    scenario: str | None = None,
    destination: str | None = None,
    spacing: float = 1.0,
    window: tuple[float, float] = (150.0, 1500.0),
    max_lane_length: float = 2000.0,
) -> dict:
    """The explicit recipe (:func:`explicit_map`) of the env's road network and the ego's route.

    Every lane is sampled with ``lane.position(s, 0)`` every ``spacing`` m
    (straight lanes: their two ends) and mirrored into the world frame
    (:func:`to_world`); its width is the mean of ``lane.width_at(s)``. Lanes
    longer than ``max_lane_length`` (the 10 km highway) are cropped to
    ``window = (behind, ahead)`` metres around the ego's position along them.
    The drivable area is one strip per lane (its centreline, half its width:
    "off-road" then means what highway-env's ``on_road`` means). The route
    starts on the ego's lane and runs along the roads to ``destination``
    (default: the env's ``destination``, else the road ahead); its roads are
    kept in ``recipe["source"]["edges"]``. highway-env has no walkways,
    crossings or junction polygons.
    """
    u = env.unwrapped
    scenario = scenario or scenario_of(u)
    if not (np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing must be positive, got {spacing!r}")
    net = u.road.network
    table = _lane_table(net)
    lookup = {index: i for i, index in enumerate(table)}
    ego = u.vehicle
    specs = []
    for index in table:
        lane = net.get_lane(index)
        s_lo, s_hi = 0.0, float(lane.length)
        if s_hi > max_lane_length:
            s_ego = float(lane.local_coordinates(ego.position)[0])
            s_lo = float(np.clip(s_ego - window[0], 0.0, s_hi - 1.0))
            s_hi = float(np.clip(s_ego + window[1], s_lo + 1.0, s_hi))
        pts, width = _lane_points(lane, s_lo, s_hi, spacing)
        a, b, k = index
        succ = []
        for nb, group in net.graph.get(b, {}).items():
            for nk, nxt in enumerate(group):
                if np.linalg.norm(nxt.position(0.0, 0.0) - lane.position(lane.length, 0.0)) < 3.0:
                    succ.append(lookup[(b, nb, nk)])
        side = net.graph[a][b]
        specs.append({
            "points": _round(pts), "width": round(width, 4), "kind": _lane_kind(lane, scenario),
            "successors": succ, "left": lookup[(a, b, k - 1)] if k > 0 else -1,
            "right": lookup[(a, b, k + 1)] if k + 1 < len(side) else -1,
        })
    if destination is None:
        destination = getattr(u, "destination", None)
    start = tuple(ego.lane_index)
    edges = route_edges(net, start, destination)
    route = [lookup[i] for i in _chain(net, start, edges)]
    kind = {"roundabout": "roundabout", "intersection": "intersection"}.get(scenario, "straight")
    return {
        "kind": EXPLICIT_KIND,
        "map_kind": kind,
        "lanes": specs,
        "strips": [{"lane": i, "half_width": sp["width"] / 2.0} for i, sp in enumerate(specs)],
        "route": route,
        "start_s": 0.0,
        "source": {"simulator": "highway-env", "scenario": scenario,
                   "env_id": ENV_IDS.get(scenario), "destination": destination,
                   "edges": [list(e) for e in edges], "lane_index": [list(i) for i in table]},
    }


def road_map(env, scenario: str | None = None, destination: str | None = None,
             **kwargs: Any) -> Map:
    """The env's road network as a chapter-7 :class:`Map`: ``explicit_map(map_recipe(env))``.

    Sampled once per episode; ``start_s`` is the ego's arc length on the
    route. Keyword arguments go to :func:`map_recipe`.
    """
    recipe = map_recipe(env, scenario, destination, **kwargs)
    m = explicit_map(recipe)
    pose = ego_pose(env)
    recipe["start_s"] = round(float(project_to_route(m, pose[:2], float(pose[2]))[0]), 3)
    m.start_s = recipe["start_s"]
    return m


class RouteTracker:
    """The moving lane target on highway-env's road, from the ego's *own* position.

    The route's roads are fixed per episode (``Map.recipe["edges"]``); the lane
    on them is the one the ego is in now (highway-env's lane distance with
    heading), continued along the remaining roads. So after a lane change the
    target follows the new lane. :meth:`map_for` returns the episode map with
    that lane sequence as its route (same geometry and cache key, so the
    rasteriser's caches still hit), and :meth:`lane_targets` the chapter-7
    targets (:func:`minimanc.world.maps.lane_targets`) on it.
    """

    def __init__(self, env, m: Map) -> None:
        self.env = env.unwrapped
        self.map = m
        self.edges = [tuple(e) for e in m.recipe["source"]["edges"]]
        self.table = _lane_table(self.env.road.network)
        self.lookup = {index: i for i, index in enumerate(self.table)}
        self._cache: dict[tuple[int, ...], Map] = {tuple(m.route): m}

    def current_lane(self, pose: np.ndarray) -> tuple:
        """highway-env lane index of the route lane nearest to the world ``pose``."""
        net = self.env.road.network
        xy, heading = to_world(np.asarray(pose[:2]), float(pose[2]))
        best, best_d, best_e = None, np.inf, 0
        for e_i, (a, b) in enumerate(self.edges):
            for k, lane in enumerate(net.graph[a][b]):
                d = lane.distance_with_heading(xy, float(heading))
                if d < best_d - 1e-9:
                    best, best_d, best_e = (a, b, k), d, e_i
        self._edge = best_e
        return best

    def map_for(self, pose: np.ndarray) -> Map:
        """The episode map whose route runs from the ego's current lane to the destination."""
        first = self.current_lane(pose)
        chain = _chain(self.env.road.network, first, self.edges[self._edge:])
        key = tuple(self.lookup[i] for i in chain)
        m = self._cache.get(key)
        if m is None:
            m = dataclasses.replace(self.map, **_route_fields(self.map.lanes, list(key)))
            self._cache[key] = m
        return m

    def lane_targets(self, pose: np.ndarray, k: int = K_TARGETS) -> np.ndarray:
        """``(k, 2)`` lane target points every 4 m ahead, in the ego frame of ``pose``."""
        return lane_targets(self.map_for(pose), np.asarray(pose, dtype=np.float64), k)


