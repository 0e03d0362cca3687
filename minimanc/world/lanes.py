"""Chapter 7 — the road map's data: lanes, lane samples, the :class:`Map` and its class grid.

What :func:`minimanc.world.roads.build_map` produces: lane centrelines as
polylines with headings (:class:`Lane`), the drivable area primitives, the
conflict table and the ego's route (:class:`Map`), dense lane samples bucketed
in tiles (:class:`LaneSamples`), and the world-aligned class grid (0 nothing,
1 drivable, 2 pedestrian crossing, 3 walkway) that the BEV rasteriser samples
(:func:`class_grid`).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from minimanc.world.geometry import (
    headings,
    interp_polyline,
)

__all__ = [
    "CLASS_CROSSING",
    "CLASS_DRIVABLE",
    "CLASS_NONE",
    "CLASS_WALKWAY",
    "KINDS",
    "KIND_PROBS",
    "K_TARGETS",
    "LANE_WIDTH",
    "Lane",
    "LaneSamples",
    "Map",
    "RING_WIDTH",
    "ROUTE_AHEAD",
    "TARGET_SPACING",
    "class_grid",
    "offset_polyline",
]

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
    """A built map; see :mod:`minimanc.world.maps`. ``recipe`` rebuilds it exactly."""

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
    holes: list[np.ndarray] = field(default_factory=list)  # holes cut from the drivable area
    walkway_polygons: list[np.ndarray] = field(default_factory=list)  # under the drivable area

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
            _lru_put(_SAMPLE_CACHE, (self.key, spacing), c, CACHED_MAPS)
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

CACHED_MAPS = 64
"""How many maps' class grids and lane samples a process keeps (least recently used first
out): a closed loop and its scoring visit the same validation maps again and again, and a
grid at 0.25 m is about 2 MB."""
_GRID_CACHE: OrderedDict = OrderedDict()
_SAMPLE_CACHE: OrderedDict = OrderedDict()


def _lru_put(cache: OrderedDict, key, value, size: int) -> None:
    cache[key] = value
    cache.move_to_end(key)
    while len(cache) > size:
        cache.popitem(last=False)


def offset_polyline(points: np.ndarray, heads: np.ndarray, d: float) -> np.ndarray:
    """Offset a polyline by ``d`` to its left (negative: right)."""
    n = np.stack([-np.sin(heads), np.cos(heads)], axis=1)
    return points + d * n



# --------------------------------------------------------------------------- class grid


def class_grid(m: Map, res: float) -> tuple[np.ndarray, np.ndarray, float]:
    """World-aligned class grid of the map at ``res`` m/cell (cached: the last :data:`CACHED_MAPS`).

    Returns ``(grid (H, W) uint8, origin (2,), res)``; cell ``[iy, ix]`` covers
    ``origin + res * ([ix, iy] + [0, 1))``. Drawn with Pillow in the nuScenes
    layer order: walkway, drivable area (strips, polygons, discs), crossings.
    """
    # Pillow, loaded when a grid is first drawn: importing the world loads no imaging library
    from PIL import Image, ImageDraw

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
        edges = [offset_polyline(p, hd, hw), offset_polyline(p, hd, -hw)[::-1]]
        draw.polygon(px(np.concatenate(edges)), fill=val)
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
    for poly in m.holes:
        draw.polygon(px(poly), fill=CLASS_NONE)
    if m.walkway_polygons:  # recorded maps: walkways where nothing drivable is drawn
        walk = Image.new("L", (W, H), 0)
        wdraw = ImageDraw.Draw(walk)
        for poly in m.walkway_polygons:
            wdraw.polygon(px(poly), fill=1)
        arr = np.asarray(img, dtype=np.uint8).copy()
        arr[(np.asarray(walk) > 0) & (arr == CLASS_NONE)] = CLASS_WALKWAY
        img = Image.fromarray(arr)
        draw = ImageDraw.Draw(img)
    for poly in m.crossings:
        draw.polygon(px(poly), fill=CLASS_CROSSING)
    grid = np.asarray(img, dtype=np.uint8).copy()
    out = (grid, origin, float(res))
    _lru_put(_GRID_CACHE, key, out, CACHED_MAPS)
    return out
