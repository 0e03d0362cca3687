"""Chapter 7 — procedural road maps: roads, intersections, roundabouts and the ego's route.

A map is built in two steps, so that it can be stored as a few numbers:

1. ``random_recipe(rng)`` draws a small JSON-able dict (the *recipe*): the map
   kind, road shapes as ``(length, curvature)`` pieces, lanes per direction,
   arm angles, the roundabout radius, and the ego's route choice.
2. ``build_map(recipe)`` turns it, deterministically, into a :class:`Map`:
   lane centrelines as polylines (1 m spacing) with headings, lane
   connectors through junctions (cubic Bézier curves tangent to the lanes),
   drivable area primitives (road strips, junction polygon, roundabout disc
   and island), walkways, pedestrian crossings, the conflict table between
   junction lanes (where paths cross or merge), and the ego's route (a lane
   sequence and its concatenated centreline).

Map kinds (right-hand traffic): ``straight`` and ``curved`` roads,
``intersection`` (three or four arms, 1–2 lanes per direction) and
``roundabout`` (single-lane ring driven counter-clockwise, 3–4 arms).

The drivable area is also rasterised once per map into a world-aligned class
grid (0 nothing, 1 drivable, 2 pedestrian crossing, 3 walkway) that the BEV
rasteriser samples; see :func:`class_grid`.
"""

from __future__ import annotations

import hashlib
import json
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
from PIL import Image, ImageDraw

from minimanc.world.geometry import (
    arclength,
    headings,
    interp_polyline,
    resample,
    to_ego_frame,
    wrap_angle,
)

LANE_WIDTH = 3.5
"""Width of a road lane (m)."""
RING_WIDTH = 5.0
"""Width of the single roundabout ring lane (m)."""
TARGET_SPACING = 4.0
"""Spacing of the moving lane target points along the route (m)."""
K_TARGETS = 10
"""Default number of lane target points (10 x 4 m = the 40 m the raster shows ahead)."""
ROUTE_AHEAD = 430.0
"""Route length available ahead of the ego's start (m): 20 s at the fastest style plus margin."""

KINDS = ("straight", "curved", "intersection", "roundabout")
KIND_PROBS = (0.15, 0.25, 0.32, 0.28)

CLASS_NONE, CLASS_DRIVABLE, CLASS_CROSSING, CLASS_WALKWAY = 0, 1, 2, 3


@dataclass
class Lane:
    """One lane centreline: ``points (N, 2)`` every ~1 m, ``heads (N,)``, arc length ``s (N,)``."""

    id: int
    points: np.ndarray
    heads: np.ndarray
    s: np.ndarray
    kind: str  # "road" | "connector" | "ring"
    width: float
    successors: list[int] = field(default_factory=list)
    predecessors: list[int] = field(default_factory=list)
    junction: int = -1  # junction index for connectors / ring lanes
    left: int = -1  # same-direction neighbour lane on the left (-1: none)
    right: int = -1
    turn: str = ""  # connectors: "straight" | "left" | "right" | "enter" | "exit"

    @property
    def length(self) -> float:
        return float(self.s[-1])


@dataclass
class LaneSamples:
    """Lane centreline samples sorted by square tile, for fast look-up around a point."""

    points: np.ndarray  # (P, 2) float64, sorted by tile
    heads: np.ndarray  # (P,)
    origin: np.ndarray  # (2,) corner of tile (0, 0)
    tile: float  # tile size (m)
    shape: tuple[int, int]  # (ny, nx) tiles
    starts: np.ndarray  # (ny * nx + 1,) CSR offsets into the sorted samples

    @classmethod
    def build(cls, points: np.ndarray, heads: np.ndarray, bounds, tile: float = 16.0):
        origin = np.array(bounds[:2], dtype=np.float64)
        nx = int(np.ceil((bounds[2] - bounds[0]) / tile)) + 1
        ny = int(np.ceil((bounds[3] - bounds[1]) / tile)) + 1
        ix = np.clip(((points[:, 0] - origin[0]) // tile).astype(np.int64), 0, nx - 1)
        iy = np.clip(((points[:, 1] - origin[1]) // tile).astype(np.int64), 0, ny - 1)
        cell = iy * nx + ix
        order = np.argsort(cell, kind="stable")
        starts = np.searchsorted(cell[order], np.arange(ny * nx + 1))
        return cls(points[order], heads[order], origin, tile, (ny, nx), starts)

    def near(self, xy: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Samples in the tiles that overlap the square of half side ``radius`` around ``xy``."""
        ny, nx = self.shape
        x0 = int(max((xy[0] - radius - self.origin[0]) // self.tile, 0))
        x1 = int(min((xy[0] + radius - self.origin[0]) // self.tile, nx - 1))
        y0 = int(max((xy[1] - radius - self.origin[1]) // self.tile, 0))
        y1 = int(min((xy[1] + radius - self.origin[1]) // self.tile, ny - 1))
        if x1 < x0 or y1 < y0:
            return self.points[:0], self.heads[:0]
        rows = np.arange(y0, y1 + 1) * nx
        lo = self.starts[rows + x0]
        hi = self.starts[rows + x1 + 1]  # tiles of a row are contiguous
        idx = np.concatenate([np.arange(a, b) for a, b in zip(lo, hi)])
        return self.points[idx], self.heads[idx]


@dataclass
class Map:
    """A built map; see the module docstring. ``recipe`` rebuilds it exactly."""

    recipe: dict
    kind: str
    lanes: list[Lane]
    strips: list[tuple[np.ndarray, float]]  # drivable strips (centre polyline, half width)
    polygons: list[np.ndarray]  # drivable polygons
    discs: list[tuple[float, float, float, int]]  # (cx, cy, radius, class) drawn in order
    walkways: list[tuple[np.ndarray, float]]  # walkway strips (centre polyline, half width)
    crossings: list[np.ndarray]  # (4, 2) pedestrian crossing polygons
    route: list[int]
    route_points: np.ndarray
    route_heads: np.ndarray
    route_s: np.ndarray
    start_s: float  # ego's start along the route (m)
    conflicts: dict[tuple[int, int], tuple[float, float]]  # (a, b) -> (s_in, s_out) on a
    bounds: tuple[float, float, float, float]
    key: str = ""

    @property
    def has_junction(self) -> bool:
        return self.kind == "intersection"

    @property
    def has_roundabout(self) -> bool:
        return self.kind == "roundabout"

    def lane_samples(self, spacing: float) -> LaneSamples:
        """Dense samples of all lane centrelines, bucketed in square tiles (cached)."""
        c = _SAMPLE_CACHE.get((self.key, spacing))
        if c is None:
            pts, hds = [], []
            for lane in self.lanes:
                n = max(int(np.ceil(lane.length / spacing)), 1)
                sq = np.linspace(0.0, lane.length, n + 1)
                p, h = interp_polyline(lane.points, lane.s, lane.heads, sq)
                pts.append(p)
                hds.append(h)
            c = LaneSamples.build(np.concatenate(pts), np.concatenate(hds), self.bounds)
            _lru_put(_SAMPLE_CACHE, (self.key, spacing), c, 16)
        return c

    def is_drivable(self, points: np.ndarray) -> np.ndarray:
        """Whether world points ``(..., 2)`` lie on the drivable area (crossings included)."""
        grid, origin, res = class_grid(self, 0.25)
        p = np.asarray(points, dtype=np.float64)
        ix = np.floor((p[..., 0] - origin[0]) / res).astype(np.int64)
        iy = np.floor((p[..., 1] - origin[1]) / res).astype(np.int64)
        inside = (ix >= 0) & (iy >= 0) & (ix < grid.shape[1]) & (iy < grid.shape[0])
        cls = grid[np.clip(iy, 0, grid.shape[0] - 1), np.clip(ix, 0, grid.shape[1] - 1)]
        return inside & ((cls == CLASS_DRIVABLE) | (cls == CLASS_CROSSING))

    def route_pose(self, s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Position and heading on the route at arc length(s) ``s``."""
        return interp_polyline(self.route_points, self.route_s, self.route_heads, s)


# --------------------------------------------------------------------------- caches

_GRID_CACHE: OrderedDict = OrderedDict()
_SAMPLE_CACHE: OrderedDict = OrderedDict()


def _lru_put(cache: OrderedDict, key, value, size: int) -> None:
    cache[key] = value
    cache.move_to_end(key)
    while len(cache) > size:
        cache.popitem(last=False)


# --------------------------------------------------------------------------- recipes


def _pieces(rng: np.random.Generator, total: float, curvy: bool, first_straight: float = 0.0):
    """Random (length, curvature) pieces of a road of ``total`` metres."""
    pieces: list[list[float]] = []
    if first_straight > 0:
        pieces.append([first_straight, 0.0])
    done = first_straight
    while done < total:
        if curvy and rng.random() < 0.6:
            radius = float(rng.uniform(45.0, 160.0))
            angle = float(rng.uniform(0.35, 1.3))
            length = min(radius * angle, total - done + 1.0)
            k = float(rng.choice([-1.0, 1.0])) / radius
        else:
            length = min(float(rng.uniform(25.0, 110.0)), total - done + 1.0)
            k = 0.0
        pieces.append([round(length, 3), round(k, 6)])
        done += length
    return pieces


def random_recipe(rng: np.random.Generator, kind: str | None = None) -> dict:
    """Draw a map recipe (a JSON-able dict). ``kind`` forces the map kind."""
    if kind is None:
        kind = str(rng.choice(KINDS, p=KIND_PROBS))
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    rot = float(rng.uniform(-np.pi, np.pi))
    if kind in ("straight", "curved"):
        n = int(rng.choice([1, 2], p=[0.4, 0.6]))
        start = float(rng.uniform(40.0, 60.0))
        total = start + ROUTE_AHEAD
        pieces = _pieces(rng, total, curvy=(kind == "curved"))
        if kind == "straight" and rng.random() < 0.3:  # one gentle bend
            i = int(rng.integers(len(pieces)))
            pieces[i][1] = round(float(rng.choice([-1, 1]) / rng.uniform(250, 500)), 6)
        return {
            "kind": kind,
            "rotation": rot,
            "lanes": n,
            "pieces": pieces,
            "ego": {"lane": int(rng.integers(n)), "start_s": start},
        }
    if kind == "intersection":
        n_arms = 4 if rng.random() < 0.75 else 3
        angles = [0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi]
        if n_arms == 3:
            angles.pop(int(rng.integers(4)))
        angles = [float(a + rng.uniform(-0.12, 0.12)) for a in angles]
        n_main = int(rng.choice([1, 2], p=[0.4, 0.6]))
        n_side = int(rng.choice([1, 2], p=[0.6, 0.4]))
        arm_in = int(rng.integers(n_arms))
        arm_out = int((arm_in + rng.integers(1, n_arms)) % n_arms)
        start_dist = float(rng.uniform(8.0, 130.0))
        arms = []
        for k, a in enumerate(angles):
            main = (round(a / (0.5 * np.pi)) % 2) == 0
            if k == arm_in:
                length = start_dist + 45.0
            elif k == arm_out:
                length = ROUTE_AHEAD - start_dist + 10.0
            else:
                length = float(rng.uniform(90.0, 150.0))
            arms.append(
                {
                    "angle": a,
                    "lanes": n_main if main else n_side,
                    "pieces": _pieces(rng, length, rng.random() < 0.4, first_straight=30.0),
                }
            )
        return {
            "kind": kind,
            "rotation": rot,
            "arms": arms,
            "ego": {"arm_in": arm_in, "arm_out": arm_out, "start_dist": start_dist,
                    "lane_pick": float(rng.random())},
        }
    # roundabout
    n_arms = 4 if rng.random() < 0.7 else 3
    base = np.linspace(0.0, 2 * np.pi, n_arms, endpoint=False)
    jitter = 0.15 if n_arms == 4 else 0.25
    angles = [float(a + rng.uniform(-jitter, jitter)) for a in base]
    radius = float(rng.uniform(15.0, 24.0))
    arm_in = int(rng.integers(n_arms))
    exits = int(rng.integers(1, n_arms))
    start_dist = float(rng.uniform(8.0, 110.0))
    arm_out = (arm_in + exits) % n_arms
    arms = []
    for k, a in enumerate(angles):
        if k == arm_in:
            length = start_dist + 45.0
        elif k == arm_out:
            length = ROUTE_AHEAD - start_dist + 10.0
        else:
            length = float(rng.uniform(90.0, 150.0))
        arms.append(
            {"angle": a, "lanes": 1,
             "pieces": _pieces(rng, length, rng.random() < 0.4, first_straight=25.0)}
        )
    return {
        "kind": kind,
        "rotation": rot,
        "radius": radius,
        "arms": arms,
        "ego": {"arm_in": arm_in, "exits": exits, "start_dist": start_dist},
    }


# --------------------------------------------------------------------------- geometry helpers


def _reference(x0: float, y0: float, h0: float, pieces) -> tuple[np.ndarray, np.ndarray]:
    """Integrate (length, curvature) pieces from a start pose: points and exact headings."""
    xs, ys, hs = [np.array([x0])], [np.array([y0])], [np.array([h0])]
    x, y, h = x0, y0, h0
    for length, k in pieces:
        n = max(int(np.ceil(length / 1.0)), 1)
        s = np.arange(1, n + 1) * (length / n)
        if abs(k) < 1e-9:
            px, py, ph = x + s * np.cos(h), y + s * np.sin(h), np.full(n, h)
        else:
            ph = h + k * s
            px = x + (np.sin(ph) - np.sin(h)) / k
            py = y - (np.cos(ph) - np.cos(h)) / k
        xs.append(px)
        ys.append(py)
        hs.append(ph)
        x, y, h = float(px[-1]), float(py[-1]), float(ph[-1])
    return np.stack([np.concatenate(xs), np.concatenate(ys)], axis=1), np.concatenate(hs)


def _offset(points: np.ndarray, heads: np.ndarray, d: float) -> np.ndarray:
    """Offset a polyline by ``d`` to its left (negative: right)."""
    n = np.stack([-np.sin(heads), np.cos(heads)], axis=1)
    return points + d * n


def _bezier(p0, h0, p1, h1, k0: float = 0.4, k1: float = 0.4) -> np.ndarray:
    """Cubic Bézier from pose (p0, h0) to (p1, h1), resampled every ~1 m."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    dist = float(np.linalg.norm(p1 - p0))
    c0 = p0 + k0 * dist * np.array([np.cos(h0), np.sin(h0)])
    c1 = p1 - k1 * dist * np.array([np.cos(h1), np.sin(h1)])
    t = np.linspace(0.0, 1.0, 200)[:, None]
    pts = (1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * c0 + 3 * (1 - t) * t**2 * c1 + t**3 * p1
    return resample(pts, 1.0)


def _arc(c, r: float, a0: float, a1: float) -> np.ndarray:
    """Counter-clockwise arc of radius r from angle a0 to a1 (a1 > a0), every ~1 m."""
    n = max(int(np.ceil(r * (a1 - a0))), 2)
    a = np.linspace(a0, a1, n + 1)
    return np.stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a)], axis=1)


class _Builder:
    def __init__(self) -> None:
        self.lanes: list[Lane] = []
        self.strips: list[tuple[np.ndarray, float]] = []
        self.polygons: list[np.ndarray] = []
        self.discs: list[tuple[float, float, float, int]] = []
        self.walkways: list[tuple[np.ndarray, float]] = []
        self.crossings: list[np.ndarray] = []

    def lane(self, points, kind, width=LANE_WIDTH, heads=None, junction=-1, turn="") -> int:
        points = np.asarray(points, dtype=np.float64)
        if heads is None:
            heads = headings(points)
        lid = len(self.lanes)
        self.lanes.append(
            Lane(lid, points, wrap_angle(heads), arclength(points), kind, width,
                 junction=junction, turn=turn)
        )
        return lid

    def link(self, a: int, b: int) -> None:
        self.lanes[a].successors.append(b)
        self.lanes[b].predecessors.append(a)

    def road(self, ref: np.ndarray, heads: np.ndarray, n_fwd: int, n_bwd: int):
        """Lanes of a two-way road along ``ref``: forward lanes on the right."""
        fwd, bwd = [], []
        for i in range(n_fwd):
            fwd.append(self.lane(_offset(ref, heads, -(i + 0.5) * LANE_WIDTH), "road",
                                 heads=heads))
        for i in range(n_bwd):
            p = _offset(ref, heads, (i + 0.5) * LANE_WIDTH)[::-1]
            bwd.append(self.lane(p, "road", heads=wrap_angle(heads[::-1] + np.pi)))
        for group in (fwd, bwd):  # index 0 is the innermost lane
            for i in range(len(group) - 1):
                inner, outer = self.lanes[group[i]], self.lanes[group[i + 1]]
                inner.right, outer.left = outer.id, inner.id
        hw = max(n_fwd, n_bwd) * LANE_WIDTH
        self.strips.append((ref, hw + 0.5))
        self.walkways.append((ref, hw + 2.75))
        return fwd, bwd

    def crossing(self, centre, heading: float, half_width: float, depth: float = 3.0) -> None:
        u = np.array([np.cos(heading), np.sin(heading)])
        n = np.array([-u[1], u[0]])
        c = np.asarray(centre, float)
        hd = depth / 2
        self.crossings.append(
            np.array([c - hd * u - half_width * n, c + hd * u - half_width * n,
                      c + hd * u + half_width * n, c - hd * u + half_width * n])
        )


# --------------------------------------------------------------------------- builders


def _build_road(recipe: dict, b: _Builder) -> tuple[list[int], float]:
    n = int(recipe["lanes"])
    ref, hd = _reference(0.0, 0.0, 0.0, recipe["pieces"])
    fwd, _ = b.road(ref, hd, n, n)
    ego = recipe["ego"]
    lane = fwd[min(int(ego["lane"]), n - 1)]
    # a few crossings along the road
    s = arclength(ref)
    for sc in np.arange(90.0, s[-1] - 30.0, 160.0):
        p, h = interp_polyline(ref, s, hd, sc)
        b.crossing(p, float(h), n * LANE_WIDTH)
    return [lane], float(ego["start_s"])


def _arm_lanes(b: _Builder, arm: dict, r0: float, centre=(0.0, 0.0)):
    a = float(arm["angle"])
    x0, y0 = centre[0] + r0 * np.cos(a), centre[1] + r0 * np.sin(a)
    ref, hd = _reference(x0, y0, a, arm["pieces"])
    n = int(arm["lanes"])
    out_lanes, in_lanes = b.road(ref, hd, n, n)
    return ref, hd, out_lanes, in_lanes


def _build_intersection(recipe: dict, b: _Builder) -> tuple[list[int], float]:
    arms = recipe["arms"]
    hw_max = max(a["lanes"] for a in arms) * LANE_WIDTH
    r0 = hw_max / np.cos(0.25) + 6.0
    refs, outs, ins = [], [], []
    for arm in arms:
        ref, hd, o, i = _arm_lanes(b, arm, r0)
        refs.append((ref, hd))
        outs.append(o)
        ins.append(i)
        hw = arm["lanes"] * LANE_WIDTH
        b.crossing(ref[0] + 2.5 * np.array([np.cos(hd[0]), np.sin(hd[0])]), float(hd[0]), hw)
        # walkway reaches into the corners of the junction
        wref = np.array([[0.0, 0.0], ref[0]])
        b.walkways.append((wref, hw + 2.75))
    # junction polygon: hull of the arms' mouth corners
    corners = []
    for arm, (ref, hd) in zip(arms, refs):
        hw = arm["lanes"] * LANE_WIDTH + 0.5
        for side in (-1, 1):
            corners.append(_offset(ref[:1], hd[:1], side * hw)[0])
    corners = np.array(corners)
    order = np.argsort(np.arctan2(corners[:, 1], corners[:, 0]))
    b.polygons.append(corners[order])
    # connectors
    conn: dict[tuple[int, int], list[tuple[int, int, int]]] = {}
    for ai in range(len(arms)):
        for ao in range(len(arms)):
            if ai == ao:
                continue
            h_in = float(wrap_angle(arms[ai]["angle"] + np.pi))
            h_out = float(arms[ao]["angle"])
            turn_ang = float(wrap_angle(h_out - h_in))
            if abs(turn_ang) < 0.6:
                turn = "straight"
            elif turn_ang > 0:
                turn = "left"
            else:
                turn = "right"
            n_in, n_out = len(ins[ai]), len(outs[ao])
            if turn == "straight":
                pairs = [(i, min(i, n_out - 1)) for i in range(n_in)]
            elif turn == "left":
                pairs = [(0, 0)]
            else:
                pairs = [(n_in - 1, n_out - 1)]
            for li, lo in pairs:
                lane_in, lane_out = b.lanes[ins[ai][li]], b.lanes[outs[ao][lo]]
                k = 0.33 if turn == "straight" else 0.39  # 0.39: a quarter circle
                pts = _bezier(lane_in.points[-1], lane_in.heads[-1], lane_out.points[0],
                              lane_out.heads[0], k, k)
                cid = b.lane(pts, "connector", junction=0, turn=turn)
                b.link(lane_in.id, cid)
                b.link(cid, lane_out.id)
                conn.setdefault((ai, ao), []).append((li, lo, cid))
                b.strips.append((pts, LANE_WIDTH / 2 + 1.0))
    ego = recipe["ego"]
    ai, ao = int(ego["arm_in"]), int(ego["arm_out"])
    options = conn[(ai, ao)]
    li, lo, cid = options[min(int(ego["lane_pick"] * len(options)), len(options) - 1)]
    route = [ins[ai][li], cid, outs[ao][lo]]
    start = b.lanes[ins[ai][li]].length - float(ego["start_dist"])
    return route, start


def _build_roundabout(recipe: dict, b: _Builder) -> tuple[list[int], float]:
    arms = recipe["arms"]
    R = float(recipe["radius"])
    r0 = R + RING_WIDTH / 2 + 7.0
    delta = 8.0 / R
    refs, outs, ins = [], [], []
    for arm in arms:
        ref, hd, o, i = _arm_lanes(b, arm, r0)
        refs.append((ref, hd))
        outs.append(o[0])
        ins.append(i[0])
        b.crossing(ref[0] + 3.0 * np.array([np.cos(hd[0]), np.sin(hd[0])]), float(hd[0]),
                   LANE_WIDTH)
    c = np.zeros(2)
    b.discs.append((0.0, 0.0, R + RING_WIDTH / 2 + 3.0, CLASS_WALKWAY))
    b.discs.append((0.0, 0.0, R + RING_WIDTH / 2 + 0.25, CLASS_DRIVABLE))
    b.discs.append((0.0, 0.0, R - RING_WIDTH / 2 - 0.25, CLASS_NONE))
    # attach points counter-clockwise: diverge (exit) before merge (entry) at each arm
    attach = []
    for k, arm in enumerate(arms):
        a = float(arm["angle"])
        attach.append((a - delta, "exit", k))
        attach.append((a + delta, "enter", k))
    attach.sort(key=lambda t: np.mod(t[0], 2 * np.pi))
    angs = [np.mod(t[0], 2 * np.pi) for t in attach]
    ring_ids = []
    for j in range(len(attach)):
        a0 = angs[j]
        a1 = angs[(j + 1) % len(attach)]
        if a1 <= a0:
            a1 += 2 * np.pi
        pts = _arc(c, R, a0, a1)
        hd = np.linspace(a0, a1, len(pts)) + np.pi / 2
        ring_ids.append(b.lane(pts, "ring", width=RING_WIDTH, heads=hd, junction=0))
    for j in range(len(ring_ids)):
        b.link(ring_ids[j], ring_ids[(j + 1) % len(ring_ids)])
    enter_conn, exit_conn, seg_after, seg_before = {}, {}, {}, {}
    for j, (_, what, k) in enumerate(attach):
        seg_after[(what, k)] = ring_ids[j]
        seg_before[(what, k)] = ring_ids[j - 1]
        ang = angs[j]
        p_ring = np.array([R * np.cos(ang), R * np.sin(ang)])
        h_ring = ang + np.pi / 2
        if what == "enter":
            lane_in = b.lanes[ins[k]]
            pts = _bezier(lane_in.points[-1], lane_in.heads[-1], p_ring, h_ring, 0.45, 0.45)
            cid = b.lane(pts, "connector", junction=0, turn="enter")
            b.link(lane_in.id, cid)
            b.link(cid, ring_ids[j])
            enter_conn[k] = cid
        else:
            lane_out = b.lanes[outs[k]]
            pts = _bezier(p_ring, h_ring, lane_out.points[0], lane_out.heads[0], 0.45, 0.45)
            cid = b.lane(pts, "connector", junction=0, turn="exit")
            b.link(ring_ids[j - 1], cid)
            b.link(cid, lane_out.id)
            exit_conn[k] = cid
        b.strips.append((pts, LANE_WIDTH / 2 + 1.0))
    ego = recipe["ego"]
    ai = int(ego["arm_in"])
    ao = (ai + int(ego["exits"])) % len(arms)
    route = [ins[ai], enter_conn[ai]]
    seg = seg_after[("enter", ai)]
    guard = 0
    while True:
        route.append(seg)
        nxt = [s for s in b.lanes[seg].successors if s == exit_conn[ao]]
        if nxt:
            break
        seg = [s for s in b.lanes[seg].successors if b.lanes[s].kind == "ring"][0]
        guard += 1
        if guard > 3 * len(ring_ids):
            raise ValueError(f"recipe: no ring path from arm {ai} to arm {ao}")
    route += [exit_conn[ao], outs[ao]]
    start = b.lanes[ins[ai]].length - float(ego["start_dist"])
    return route, start


def _conflicts(lanes: list[Lane], threshold: float = 2.6) -> dict:
    """Crossing and merging conflicts between junction lanes.

    For lanes ``a`` and ``b`` of the same junction whose centrelines come
    closer than ``threshold``, store the arc-length interval of ``a`` inside
    that zone. Pairs that only touch because one follows the other, or that
    diverge from a common start, are skipped.
    """
    out: dict[tuple[int, int], tuple[float, float]] = {}
    jl = [ln for ln in lanes if ln.junction >= 0]
    lo = [ln.points.min(axis=0) - threshold for ln in jl]
    hi = [ln.points.max(axis=0) + threshold for ln in jl]
    for i, a in enumerate(jl):
        for k, b in enumerate(jl[i + 1:], start=i + 1):
            if np.any(lo[i] > hi[k]) or np.any(lo[k] > hi[i]):
                continue  # bounding boxes apart
            if b.id in a.successors or a.id in b.successors:
                continue
            d = np.linalg.norm(a.points[:, None, :] - b.points[None, :, :], axis=-1)
            if d.min() >= threshold:
                continue
            near_a = np.nonzero(d.min(axis=1) < threshold)[0]
            near_b = np.nonzero(d.min(axis=0) < threshold)[0]
            if near_a[0] == 0 and near_b[0] == 0 and np.linalg.norm(
                    a.points[0] - b.points[0]) < 0.5:
                continue  # diverging from a common start: handled by car following
            out[(a.id, b.id)] = (float(a.s[near_a[0]]), float(a.s[near_a[-1]]))
            out[(b.id, a.id)] = (float(b.s[near_b[0]]), float(b.s[near_b[-1]]))
    return out


def _transform_all(b: _Builder, rot: float) -> None:
    c, s = np.cos(rot), np.sin(rot)
    R = np.array([[c, -s], [s, c]])
    for ln in b.lanes:
        ln.points = ln.points @ R.T
        ln.heads = wrap_angle(ln.heads + rot)
    b.strips = [(p @ R.T, w) for p, w in b.strips]
    b.walkways = [(p @ R.T, w) for p, w in b.walkways]
    b.polygons = [p @ R.T for p in b.polygons]
    b.crossings = [p @ R.T for p in b.crossings]
    # discs are centred at the origin: rotation-invariant


def concat_lanes(
    lanes: list[Lane], ids: list[int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Concatenate lane centrelines ``ids`` into one polyline.

    Returns ``(points (P, 2), headings (P,), arc length (P,), lane start arc
    lengths (len(ids),))``; shared joint points are kept once.
    """
    pts, hds, first = [], [], []
    n = 0
    for lid in ids:
        p, h = lanes[lid].points, lanes[lid].heads
        if pts and np.linalg.norm(p[0] - pts[-1][-1]) < 1e-6:
            p, h = p[1:], h[1:]
            first.append(n - 1)  # the joint point, kept from the previous lane
        else:
            first.append(n)
        pts.append(p)
        hds.append(h)
        n += len(p)
    rp = np.concatenate(pts)
    rs = arclength(rp)
    # headings: the lanes' own (exact for arcs and offsets)
    return rp, np.concatenate(hds), rs, rs[np.array(first)]


EXPLICIT_KIND = "explicit"
"""Recipe kind of a map given by its geometry (e.g. taken from another simulator)."""


def _explicit_map(recipe: dict) -> Map:
    """A :class:`Map` from an *explicit* recipe: the geometry itself, as JSON-able numbers.

    ::

        {"kind": "explicit", "map_kind": "roundabout" | "intersection" | "straight" | ...,
         "lanes": [{"points": [[x, y], ...], "width": w, "kind": "road"|"connector"|"ring",
                    "successors": [ids], "left": id | -1, "right": id | -1,
                    "junction": -1, "turn": ""}, ...],
         "strips": [{"lane": id, "half_width": hw} | {"points": [...], "half_width": hw}],
         "polygons": [[[x, y], ...]], "walkways": [{"points": ..., "half_width": hw}],
         "crossings": [[[x, y] x 4]], "discs": [[cx, cy, r, class]],
         "route": [lane ids], "start_s": s0}

    Lanes are resampled every 1 m with headings from the polyline; the key
    hashes the geometry only (the format of :func:`minimanc.highway.explicit_map`).
    """
    lanes: list[Lane] = []
    for i, spec in enumerate(recipe["lanes"]):
        raw = np.asarray(spec["points"], dtype=np.float64)
        if raw.ndim != 2 or raw.shape[1] != 2 or len(raw) < 2:
            raise ValueError(f"recipe lane {i}: points must be (N >= 2, 2), got {raw.shape}")
        pts = resample(raw, 1.0)
        lanes.append(Lane(
            i, pts, wrap_angle(headings(pts)), arclength(pts), str(spec.get("kind", "road")),
            float(spec["width"]), successors=[int(j) for j in spec.get("successors", [])],
            junction=int(spec.get("junction", -1)), left=int(spec.get("left", -1)),
            right=int(spec.get("right", -1)), turn=str(spec.get("turn", "")),
        ))
    for ln in lanes:
        for j in ln.successors:
            lanes[j].predecessors.append(ln.id)

    def strip(spec: dict) -> tuple[np.ndarray, float]:
        pts = (lanes[int(spec["lane"])].points if "lane" in spec
               else np.asarray(spec["points"], dtype=np.float64))
        return pts, float(spec["half_width"])

    strips = [strip(sp) for sp in recipe.get("strips", [])]
    walkways = [strip(sp) for sp in recipe.get("walkways", [])]
    polygons = [np.asarray(p, dtype=np.float64) for p in recipe.get("polygons", [])]
    crossings = [np.asarray(p, dtype=np.float64) for p in recipe.get("crossings", [])]
    discs = [(float(d[0]), float(d[1]), float(d[2]), int(d[3])) for d in recipe.get("discs", [])]
    route = [int(r) for r in recipe["route"]]
    rp, rh, rs, _ = concat_lanes(lanes, route)
    allp = np.concatenate([ln.points for ln in lanes] + [p for p, _ in walkways] + polygons)
    margin = 12.0
    bounds = (float(allp[:, 0].min() - margin), float(allp[:, 1].min() - margin),
              float(allp[:, 0].max() + margin), float(allp[:, 1].max() + margin))
    geometry = {k: recipe.get(k, []) for k in ("lanes", "strips", "polygons", "walkways",
                                                "crossings", "discs")}
    key = hashlib.sha256(json.dumps(geometry, sort_keys=True).encode()).hexdigest()[:16]
    return Map(
        recipe=recipe, kind=str(recipe.get("map_kind", "straight")), lanes=lanes,
        strips=strips, polygons=polygons, discs=discs, walkways=walkways, crossings=crossings,
        route=route, route_points=rp, route_heads=rh, route_s=rs,
        start_s=float(recipe.get("start_s", 0.0)), conflicts=_conflicts(lanes),
        bounds=bounds, key="x-" + key,
    )


def build_map(recipe: dict) -> Map:
    """Build the :class:`Map` described by ``recipe`` (deterministic).

    ``recipe["kind"]`` is one of :data:`KINDS` (procedural, from
    :func:`random_recipe`) or ``"explicit"`` (geometry given as numbers).
    """
    if isinstance(recipe, dict) and recipe.get("kind") == EXPLICIT_KIND:
        try:
            return _explicit_map(recipe)
        except (KeyError, TypeError, IndexError) as e:
            raise ValueError(f"recipe: invalid explicit map: {e!r}") from e
    if not isinstance(recipe, dict) or recipe.get("kind") not in KINDS:
        raise ValueError(f"recipe must be a dict with kind in {KINDS + (EXPLICIT_KIND,)}, "
                         f"got {recipe!r:.200}")
    b = _Builder()
    kind = recipe["kind"]
    if kind in ("straight", "curved"):
        route, start = _build_road(recipe, b)
    elif kind == "intersection":
        route, start = _build_intersection(recipe, b)
    else:
        route, start = _build_roundabout(recipe, b)
    _transform_all(b, float(recipe.get("rotation", 0.0)))
    rp, rh, rs, _ = concat_lanes(b.lanes, route)
    allp = [ln.points for ln in b.lanes] + [p for p, _ in b.walkways]
    allp += [p for p in b.polygons]
    allp = np.concatenate(allp)
    margin = 12.0
    bounds = (float(allp[:, 0].min() - margin), float(allp[:, 1].min() - margin),
              float(allp[:, 0].max() + margin), float(allp[:, 1].max() + margin))
    key = hashlib.sha256(json.dumps(recipe, sort_keys=True).encode()).hexdigest()[:16]
    return Map(
        recipe=recipe, kind=kind, lanes=b.lanes, strips=b.strips, polygons=b.polygons,
        discs=b.discs, walkways=b.walkways, crossings=b.crossings, route=route,
        route_points=rp, route_heads=rh, route_s=rs, start_s=float(start),
        conflicts=_conflicts(b.lanes), bounds=bounds, key=key,
    )


def random_map(rng: np.random.Generator, kind: str | None = None) -> Map:
    """``build_map(random_recipe(rng, kind))``."""
    return build_map(random_recipe(rng, kind))


# --------------------------------------------------------------------------- class grid


def class_grid(m: Map, res: float) -> tuple[np.ndarray, np.ndarray, float]:
    """World-aligned class grid of the map at ``res`` m/cell (cached, LRU of 8).

    Returns ``(grid (H, W) uint8, origin (2,), res)``; cell ``[iy, ix]`` covers
    ``origin + res * ([ix, iy] + [0, 1))``. Drawn with Pillow in the nuScenes
    layer order: walkway, drivable area (strips, polygons, discs), crossings.
    """
    if not (res > 0):
        raise ValueError(f"res must be positive, got {res!r}")
    key = (m.key, float(res))
    hit = _GRID_CACHE.get(key)
    if hit is not None:
        _GRID_CACHE.move_to_end(key)
        return hit
    x0, y0, x1, y1 = m.bounds
    W = int(np.ceil((x1 - x0) / res))
    H = int(np.ceil((y1 - y0) / res))
    img = Image.new("L", (W, H), CLASS_NONE)
    draw = ImageDraw.Draw(img)
    origin = np.array([x0, y0])

    def px(p: np.ndarray) -> list[tuple[float, float]]:
        q = (np.asarray(p) - origin) / res
        return [tuple(v) for v in q.tolist()]

    def strip(p: np.ndarray, hw: float, val: int) -> None:
        # a strip is the polygon between its two offset edges, with round caps
        hd = headings(p)
        draw.polygon(px(np.concatenate([_offset(p, hd, hw), _offset(p, hd, -hw)[::-1]])),
                     fill=val)
        r = hw / res
        for cx, cy in px(p[[0, -1]]):
            draw.ellipse([cx - r, cy - r, cx + r, cy + r], fill=val)

    for p, hw in m.walkways:
        strip(p, hw, CLASS_WALKWAY)
    discs_first = [d for d in m.discs if d[3] == CLASS_WALKWAY]
    for cx, cy, r, val in discs_first:
        c = px(np.array([[cx, cy]]))[0]
        rr = r / res
        draw.ellipse([c[0] - rr, c[1] - rr, c[0] + rr, c[1] + rr], fill=val)
    for p, hw in m.strips:
        strip(p, hw, CLASS_DRIVABLE)
    for poly in m.polygons:
        draw.polygon(px(poly), fill=CLASS_DRIVABLE)
    for cx, cy, r, val in m.discs:
        if val == CLASS_WALKWAY:
            continue
        c = px(np.array([[cx, cy]]))[0]
        rr = r / res
        draw.ellipse([c[0] - rr, c[1] - rr, c[0] + rr, c[1] + rr], fill=val)
    for poly in m.crossings:
        draw.polygon(px(poly), fill=CLASS_CROSSING)
    grid = np.asarray(img, dtype=np.uint8).copy()
    out = (grid, origin, float(res))
    _lru_put(_GRID_CACHE, key, out, 8)
    return out


# --------------------------------------------------------------------------- route queries


def project_to_route(m: Map, xy: np.ndarray, yaw: np.ndarray | float | None = None):
    """Arc length and signed lateral offset of world point(s) ``xy (..., 2)`` on the route.

    The nearest point on the route's segments. If ``yaw`` is given, parts of
    the route heading more than 90 degrees away from it are ignored (so a
    route passing near itself is not confused), unless nothing else is left.
    Returns ``(s, lateral)`` with the shape of ``xy[..., 0]`` (floats for one point).
    """
    q = np.asarray(xy, dtype=np.float64)
    single = q.ndim == 1
    q = q.reshape(-1, 2)
    p, rs, rh = m.route_points, m.route_s, m.route_heads
    a, d = p[:-1], p[1:] - p[:-1]
    d2 = (q[:, None, 0] - a[None, :, 0]) ** 2 + (q[:, None, 1] - a[None, :, 1]) ** 2
    if yaw is not None:
        y = np.broadcast_to(np.asarray(yaw, dtype=np.float64).reshape(-1), (len(q),))
        ok = np.cos(rh[None, :-1] - y[:, None]) > 0.0
        ok[~ok.any(axis=1)] = True
        d2 = np.where(ok, d2, np.inf)
    k = np.argmin(d2, axis=1)
    # exact projection on the segments around the nearest vertex
    seg = np.clip(k[:, None] + np.arange(-3, 4)[None, :], 0, len(a) - 1)  # (Q, 7)
    A, D = a[seg], d[seg]
    L2 = np.maximum(np.sum(D * D, axis=-1), 1e-12)
    rel = q[:, None, :] - A
    tt = np.clip(np.sum(rel * D, axis=-1) / L2, 0.0, 1.0)
    foot = A + tt[..., None] * D
    dist2 = np.sum((q[:, None, :] - foot) ** 2, axis=-1)
    j = np.argmin(dist2, axis=1)
    rows = np.arange(len(q))
    sg = seg[rows, j]
    s = rs[sg] + tt[rows, j] * np.sqrt(L2[rows, j])
    cross = D[rows, j, 0] * rel[rows, j, 1] - D[rows, j, 1] * rel[rows, j, 0]
    lat = np.sign(cross) * np.sqrt(dist2[rows, j])
    if single:
        return float(s[0]), float(lat[0])
    return s.reshape(np.shape(xy)[:-1]), lat.reshape(np.shape(xy)[:-1])


def lane_targets(
    m: Map, ego_pose: np.ndarray, k: int = K_TARGETS, spacing: float = TARGET_SPACING
) -> np.ndarray:
    """Moving lane target: ``k`` route centreline points ahead of the ego, in the ego frame.

    From the ego's *own* position (never the human's time index — that would
    leak the human's speed): project the ego on the route, then take the
    points at ``s_ego + spacing * (1, 2, ..., k)``. Past the route's end the
    centreline is extended straight. ``ego_pose`` is ``(3,)`` or a batch
    ``(N, 3)``; returns ``(k, 2)`` or ``(N, k, 2)`` float64.
    """
    pose = np.asarray(ego_pose, dtype=np.float64)
    if pose.ndim not in (1, 2) or pose.shape[-1] != 3 or not np.all(np.isfinite(pose)):
        raise ValueError(f"ego_pose must be finite with shape (3,) or (N, 3), got {pose.shape}")
    if int(k) < 1:
        raise ValueError(f"k must be >= 1, got {k!r}")
    if not spacing > 0:
        raise ValueError(f"spacing must be positive, got {spacing!r}")
    P = pose.reshape(-1, 3)
    s, _ = project_to_route(m, P[:, :2], P[:, 2])
    sq = s[:, None] + spacing * np.arange(1, int(k) + 1)[None, :]
    pts, _ = m.route_pose(sq)
    out = to_ego_frame(pts, P[:, None, :])
    return out[0] if pose.ndim == 1 else out
