"""Chapter 7 — nuScenes' map expansion as the world's explicit map: lanes, areas and the route.

:class:`MapExpansion` reads ``DATAROOT/maps/expansion/<location>.json`` (the devkit's
``NuScenesMap`` layers ``drivable_area``, ``ped_crossing``, ``walkway``, ``lane``,
``lane_connector``, their ``polygon``/``node`` geometry, ``arcline_path_3`` and
``connectivity``). Lane centrelines are the arcline paths discretised as the devkit's
``arcline_path_utils.discretize_lane`` does (each path a sequence of three arcs or straight
pieces of curvature ``sign / radius``; :func:`discretize_arcline`). :meth:`local_recipe`
cuts what a scene sees (its ego track plus :data:`MARGIN`) into an *explicit* map recipe
(:func:`minimanc.world.roads.build_map`): lanes (connectors marked as junction lanes; their
points thinned to within :data:`SIMPLIFY` by :func:`simplify_polyline`, since every scene's
recipe is kept in the dataset's header) with
their successors, the drivable polygons and their holes, walkways and pedestrian crossings
(polygons clipped to the scene's box, :func:`clip_polygon`), and the route.

**The route** (:func:`route_of`) is the lanes the logged ego drove: at each keyframe the
nearest lane point heading within 90 degrees of the ego (closer than :data:`MATCH_RADIUS`);
consecutive lanes are joined by the shortest path in the lane graph. At a lane change (the
next lane is not reachable ahead) the route follows the lane changed into, back through its
predecessors to the route so far, so the route is always one connected lane chain and the
lane target (the points every 4 m ahead on it) is defined exactly as on the world. A lane
matched at one keyframe that is connected neither way to the route while a later matched lane
is reachable ahead (at the end of a junction, where connectors from several arms converge on
one lane, the nearest can be another arm's) is passed over. The route is then extended ahead
through the straightest successors, up to :data:`ROUTE_EXTENSION`.
"""

from __future__ import annotations

import math
from collections import deque
from pathlib import Path

import numpy as np

from minimanc.world.geometry import wrap_angle
from minimanc.world.lanes import LANE_WIDTH
from minimanc.world.nuscenes.tables import NuScenesError, read_json

__all__ = ["LOCATIONS", "MARGIN", "MATCH_RADIUS", "ROUTE_EXTENSION", "SIMPLIFY", "MapExpansion",
           "clip_polygon", "discretize_arcline", "route_of", "simplify_polyline"]

LOCATIONS: tuple[str, ...] = ("boston-seaport", "singapore-onenorth",
                              "singapore-hollandvillage", "singapore-queenstown")
"""The four map locations of nuScenes."""
MARGIN = 70.0
"""Metres kept around the ego's track (the raster's 47 m reach plus the 40 m lane target)."""
MATCH_RADIUS = 5.0
"""The farthest a lane centreline may be from the ego to count as the lane it drives (m)."""
ROUTE_EXTENSION = 60.0
"""Route length added ahead of the ego's last keyframe through successor lanes (m)."""
RESOLUTION = 1.0
"""Discretisation of the arcline centrelines (m), the world's lane spacing."""
SIMPLIFY = 0.01
"""Largest distance (m) a lane point left out of a recipe lies from the polyline kept."""


def simplify_polyline(points: np.ndarray, tol: float = SIMPLIFY) -> np.ndarray:
    """The points ``(N, 2)`` without those within ``tol`` of the polyline through the rest
    (Douglas–Peucker; the ends are kept). A recipe's lanes are resampled every metre when
    the map is built, so a straight lane needs its two ends only."""
    p = np.asarray(points, dtype=np.float64)
    keep = np.zeros(len(p), dtype=bool)
    keep[[0, -1]] = True
    todo = [(0, len(p) - 1)]
    while todo:
        a, b = todo.pop()
        if b - a < 2:
            continue
        d = p[b] - p[a]
        rel = p[a + 1:b] - p[a]
        n = math.hypot(d[0], d[1])
        dist = (np.abs(d[0] * rel[:, 1] - d[1] * rel[:, 0]) / n if n > 1e-12
                else np.hypot(rel[:, 0], rel[:, 1]))
        k = int(np.argmax(dist))
        if dist[k] > tol:
            keep[a + 1 + k] = True
            todo += [(a, a + 1 + k), (a + 1 + k, b)]
    return p[keep]


def discretize_arcline(path: dict, resolution: float = RESOLUTION) -> np.ndarray:
    """Poses ``(N, 3)`` every ``<= resolution`` metres along one ``arcline_path_3`` record.

    The devkit's ``discretize``: ``shape`` gives the turn sign of the three segments
    (``L`` +1, ``R`` −1, ``S`` 0), of curvature ``sign / radius``, lengths
    ``segment_length``; the start pose is ``start_pose [x, y, yaw]``.
    """
    shape = path["shape"]
    first = 1 if shape in ("LRL", "LSL", "LSR") else -1
    middle = 1 if shape == "RLR" else (-1 if shape == "LRL" else 0)
    last = 1 if shape in ("LRL", "LSL", "RSL") else -1
    signs = (first, middle, last)
    radius = float(path["radius"])
    lengths = [float(v) for v in path["segment_length"]]
    total = sum(lengths)
    n = int(max(math.ceil(total / resolution) + 1.5, 2))
    s = np.linspace(0.0, total, n)
    out = np.empty((n, 3))
    x, y, h = (float(v) for v in path["start_pose"])
    start = 0.0
    for i, (sign, length) in enumerate(zip(signs, lengths, strict=True)):
        stop = start + length
        sel = (s >= start) & ((s <= stop) if i == 2 else (s < stop))
        u = s[sel] - start
        k = sign / radius if radius > 0 else 0.0
        if abs(k) < 1e-9:
            out[sel] = np.stack([x + u * math.cos(h), y + u * math.sin(h), h + 0 * u], axis=1)
            x, y = x + length * math.cos(h), y + length * math.sin(h)
        else:
            out[sel] = np.stack([x + (np.sin(h + k * u) - math.sin(h)) / k,
                                 y - (np.cos(h + k * u) - math.cos(h)) / k, h + k * u], axis=1)
            x, y = x + (math.sin(h + k * length) - math.sin(h)) / k, \
                y - (math.cos(h + k * length) - math.cos(h)) / k
            h = h + k * length
        start = stop
    out[:, 2] = wrap_angle(out[:, 2])
    return out


def clip_polygon(poly: np.ndarray, box: tuple[float, float, float, float]) -> np.ndarray:
    """The polygon ``(N, 2)`` clipped to the box ``(x0, y0, x1, y1)`` (Sutherland–Hodgman).

    Exact for convex polygons; for concave ones the filled area is exact too (the result may
    hold zero-width edges along the box). Returns ``(M, 2)``, ``M = 0`` if nothing is left.
    """
    pts = [tuple(p) for p in np.asarray(poly, dtype=np.float64)]
    x0, y0, x1, y1 = box
    for axis, bound, keep_above in ((0, x0, True), (0, x1, False), (1, y0, True), (1, y1, False)):
        if not pts:
            break
        out = []
        prev = pts[-1]
        for cur in pts:
            cin = cur[axis] >= bound if keep_above else cur[axis] <= bound
            pin = prev[axis] >= bound if keep_above else prev[axis] <= bound
            if cin != pin:
                t = (bound - prev[axis]) / (cur[axis] - prev[axis])
                out.append((prev[0] + t * (cur[0] - prev[0]), prev[1] + t * (cur[1] - prev[1])))
            if cin:
                out.append(cur)
            prev = cur
        pts = out
    return np.asarray(pts, dtype=np.float64).reshape(-1, 2)


class MapExpansion:
    """One location's map expansion, its lanes discretised once (see the module doc)."""

    def __init__(self, dataroot: str | Path, location: str) -> None:
        path = Path(dataroot) / "maps" / "expansion" / f"{location}.json"
        if not path.exists():
            raise NuScenesError(
                f"map expansion {path} is missing: download 'nuScenes-map-expansion-v1.3.zip' "
                "from https://www.nuscenes.org/download (Map expansion) and unzip it into "
                f"{Path(dataroot) / 'maps'}")
        data = read_json(path, "map expansion")
        need = ("node", "polygon", "drivable_area", "ped_crossing", "walkway", "lane",
                "lane_connector", "arcline_path_3", "connectivity")
        missing = [k for k in need if not isinstance(data, dict) or k not in data]
        if missing:
            raise NuScenesError(f"map expansion {path} lacks the layer(s) {', '.join(missing)} "
                                "(version 1.3 of the expansion holds them)")
        self.location = location
        nodes = {n["token"]: (float(n["x"]), float(n["y"])) for n in data["node"]}
        polys = {p["token"]: p for p in data["polygon"]}

        def ring(tokens) -> np.ndarray:
            return np.asarray([nodes[t] for t in tokens], dtype=np.float64).reshape(-1, 2)

        self.drivable: list[tuple[np.ndarray, list[np.ndarray]]] = []
        for area in data["drivable_area"]:
            for pt in area["polygon_tokens"]:
                p = polys[pt]
                self.drivable.append((ring(p["exterior_node_tokens"]),
                                      [ring(h["node_tokens"]) for h in p.get("holes", [])]))
        self.walkways = [ring(polys[w["polygon_token"]]["exterior_node_tokens"])
                         for w in data["walkway"]]
        self.crossings = [ring(polys[c["polygon_token"]]["exterior_node_tokens"])
                          for c in data["ped_crossing"]]
        self.lane_tokens: list[str] = []
        self.lane_kind: list[str] = []
        self.centre: list[np.ndarray] = []
        for layer, kind in (("lane", "road"), ("lane_connector", "connector")):
            for rec in data[layer]:
                paths = data["arcline_path_3"].get(rec["token"])
                if not paths:
                    continue
                poses = [discretize_arcline(p) for p in paths]
                joined = [poses[0]] + [q[1:] if np.linalg.norm(q[0, :2] - prev[-1, :2]) < 1e-6
                                       else q for prev, q in zip(poses[:-1], poses[1:],
                                                                 strict=True)]
                self.lane_tokens.append(rec["token"])
                self.lane_kind.append(kind)
                self.centre.append(np.concatenate(joined))
        index = {t: i for i, t in enumerate(self.lane_tokens)}
        conn = data["connectivity"]
        self.successors = [[index[o] for o in conn.get(t, {}).get("outgoing", []) if o in index]
                           for t in self.lane_tokens]
        self.predecessors: list[list[int]] = [[] for _ in self.lane_tokens]
        for i, succ in enumerate(self.successors):
            for j in succ:
                self.predecessors[j].append(i)
        self._lane_box = np.array([[c[:, 0].min(), c[:, 1].min(), c[:, 0].max(), c[:, 1].max()]
                                   for c in self.centre]).reshape(-1, 4)

    def lanes_in(self, box: tuple[float, float, float, float]) -> list[int]:
        """Indices of the lanes whose centreline's bounding box meets ``box``."""
        b = self._lane_box
        hit = (b[:, 2] >= box[0]) & (b[:, 0] <= box[2]) & (b[:, 3] >= box[1]) & (b[:, 1] <= box[3])
        return [int(i) for i in np.flatnonzero(hit)]

    def local_recipe(self, ego: np.ndarray, map_kind: str = "nuscenes") -> dict:
        """The explicit recipe of the map around the ego track ``ego (T, 3)`` with its route.

        Raises :class:`NuScenesError` if the ego drives on no lane (a car park, say)."""
        box = (float(ego[:, 0].min() - MARGIN), float(ego[:, 1].min() - MARGIN),
               float(ego[:, 0].max() + MARGIN), float(ego[:, 1].max() + MARGIN))
        keep = self.lanes_in(box)
        route = route_of(self, ego, keep)
        if not route:
            raise NuScenesError(f"the ego drives on no lane of {self.location} (within "
                                f"{MATCH_RADIUS} m, heading within 90 degrees)")
        keep = sorted(set(keep) | set(route))
        local = {g: i for i, g in enumerate(keep)}

        def pts(a: np.ndarray) -> list[list[float]]:
            return np.round(a, 2).tolist()

        lanes = [{"points": pts(simplify_polyline(self.centre[g][:, :2])), "width": LANE_WIDTH,
                  "kind": self.lane_kind[g], "junction": 0 if self.lane_kind[g] == "connector"
                  else -1, "successors": [local[j] for j in self.successors[g] if j in local],
                  "token": self.lane_tokens[g]} for g in keep]
        def cut(poly: np.ndarray) -> list[list[float]] | None:
            """``poly`` clipped to the box (as is when inside it, None when outside it)."""
            lo, hi = poly.min(axis=0), poly.max(axis=0)
            if hi[0] < box[0] or lo[0] > box[2] or hi[1] < box[1] or lo[1] > box[3]:
                return None
            inside = lo[0] >= box[0] and hi[0] <= box[2] and lo[1] >= box[1] and hi[1] <= box[3]
            c = poly if inside else clip_polygon(poly, box)
            return pts(c) if len(c) >= 3 else None

        polygons, holes = [], []
        for ext, hs in self.drivable:
            c = cut(ext)
            if c is not None:
                polygons.append(c)
                holes += [h for h in map(cut, hs) if h is not None]
        walk = [c for c in map(cut, self.walkways) if c is not None]
        cross = [c for c in map(cut, self.crossings) if c is not None]
        junction = any(self.lane_kind[g] == "connector" for g in route)
        return {"kind": "explicit", "map_kind": "intersection" if junction else map_kind,
                "source": "nuscenes", "location": self.location, "lanes": lanes,
                "polygons": polygons, "holes": holes, "walkway_polygons": walk,
                "crossings": cross, "route": [local[g] for g in route], "start_s": 0.0}


def _nearest_lane(m: MapExpansion, pose: np.ndarray, lanes: list[int]) -> int:
    best, best_d = -1, MATCH_RADIUS
    for g in lanes:
        c = m.centre[g]
        d = np.hypot(c[:, 0] - pose[0], c[:, 1] - pose[1])
        ok = np.cos(c[:, 2] - pose[2]) > 0.0
        if ok.any():
            k = int(np.argmin(np.where(ok, d, np.inf)))
            if d[k] < best_d:
                best, best_d = g, float(d[k])
    return best


def _path(graph: list[list[int]], a: int, b: int, depth: int = 8) -> list[int] | None:
    """Shortest lane path from ``a`` to ``b`` in ``graph`` (``[a, ..., b]``) or ``None``."""
    prev = {a: -1}
    todo = deque([(a, 0)])
    while todo:
        u, d = todo.popleft()
        if u == b:
            out = [u]
            while prev[out[-1]] != -1:
                out.append(prev[out[-1]])
            return out[::-1]
        if d < depth:
            for v in graph[u]:
                if v not in prev:
                    prev[v] = u
                    todo.append((v, d + 1))
    return None


def route_of(m: MapExpansion, ego: np.ndarray, lanes: list[int]) -> list[int]:
    """The connected lane chain the ego drove (global lane indices; see the module doc)."""
    matched: list[int] = []
    for pose in ego:
        g = _nearest_lane(m, pose, lanes)
        if g >= 0 and (not matched or matched[-1] != g):
            matched.append(g)
    if not matched:
        return []
    route = [matched[0]]
    for i, g in enumerate(matched[1:], start=1):
        if g in route:
            continue
        ahead = _path(m.successors, route[-1], g)
        if ahead is not None:
            route += ahead[1:]
            continue
        back = None  # a lane change: g's predecessors back to the route so far
        for j in range(len(route) - 1, -1, -1):
            p = _path(m.predecessors, g, route[j])
            if p is not None:
                back = route[:j + 1] + p[::-1][1:]
                break
        if back is None and any(_path(m.successors, route[-1], h) is not None
                                for h in matched[i + 1:]):
            continue  # a connector converging on the lane ahead, matched by mistake
        if back is None:
            back, u = [g], g
            while m.predecessors[u] and len(back) < len(route) and m.predecessors[u][0] not in back:
                u = m.predecessors[u][0]
                back.insert(0, u)
        route = back
    # ahead of the last keyframe: the straightest successors
    last = ego[-1]
    c = m.centre[route[-1]]
    k = int(np.argmin(np.hypot(c[:, 0] - last[0], c[:, 1] - last[1])))
    ahead = float(np.sum(np.hypot(*np.diff(c[k:, :2], axis=0).T)))
    while ahead < ROUTE_EXTENSION and m.successors[route[-1]]:
        h = m.centre[route[-1]][-1, 2]
        nxt = [s for s in m.successors[route[-1]] if s not in route]
        if not nxt:
            break
        s = min(nxt, key=lambda j: abs(math.remainder(m.centre[j][-1, 2] - h, 2 * math.pi)))
        route.append(s)
        ahead += float(np.sum(np.hypot(*np.diff(m.centre[s][:, :2], axis=0).T)))
    return route
