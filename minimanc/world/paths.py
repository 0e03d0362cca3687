"""Chapter 7 — paths along lanes and the vehicles on them.

A :class:`Path` is a sequence of lanes concatenated into one polyline (with
its curvature and junction lanes); a :class:`PathBank` stacks a scene's paths
for vectorised look-ups; :func:`corridor_leaders` finds each vehicle's leader
in its corridor; :class:`Vehicle` is one vehicle on a path, and
:func:`random_vehicle_size`, :func:`random_lane_walk` draw new ones
(:mod:`minimanc.world.traffic` moves them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from minimanc.world.lanes import Map
from minimanc.world.roads import concat_lanes

__all__ = [
    "Path",
    "PathBank",
    "Vehicle",
    "corridor_leaders",
    "random_lane_walk",
    "random_vehicle_size",
]

def _lane_kappa(lane) -> np.ndarray:
    """Smoothed curvature of a lane centreline (cached on the lane)."""
    k = getattr(lane, "_kappa", None)
    if k is None:
        hu = np.unwrap(lane.heads)
        ds = np.maximum(np.gradient(lane.s), 1e-6) if len(lane.s) > 1 else np.ones(1)
        k = np.gradient(hu) / ds if len(hu) > 1 else np.zeros(1)
        k = np.convolve(np.pad(k, 2, mode="edge"), np.ones(5) / 5, mode="valid")
        lane._kappa = k
    return k


def _joined(m: Map, ids: list[int], j: int) -> bool:
    """Whether lane ``ids[j]`` starts where ``ids[j - 1]`` ends (its first point is shared)."""
    if j == 0:
        return False
    a, b = m.lanes[ids[j - 1]], m.lanes[ids[j]]
    return bool(np.linalg.norm(b.points[0] - a.points[-1]) < 1e-6)


@dataclass
class Path:
    """Lanes ``lanes`` concatenated; ``starts`` are their start arc lengths on the path."""

    lanes: list[int]
    points: np.ndarray
    heads: np.ndarray
    s: np.ndarray
    starts: np.ndarray
    kappa: np.ndarray
    junction_lanes: list[tuple[int, float]]  # (lane id, start arc length) of junction lanes

    @classmethod
    def from_lanes(cls, m: Map, ids: list[int]) -> Path:
        p, h, s, starts = concat_lanes(m.lanes, ids)
        k = np.concatenate([_lane_kappa(m.lanes[i])[1 if j else 0:] if _joined(m, ids, j)
                            else _lane_kappa(m.lanes[i]) for j, i in enumerate(ids)])
        jl = [(lid, float(st)) for lid, st in zip(ids, starts) if m.lanes[lid].junction >= 0]
        return cls(list(ids), p, h, s, starts, k, jl)

    @property
    def length(self) -> float:
        return float(self.s[-1])

    def pose(self, s: float) -> tuple[np.ndarray, float]:
        """Position and heading at arc length ``s`` (clamped to the path)."""
        s = min(max(s, 0.0), self.length)
        i = min(max(int(np.searchsorted(self.s, s)) - 1, 0), len(self.s) - 2)
        f = (s - self.s[i]) / max(self.s[i + 1] - self.s[i], 1e-9)
        xy = self.points[i] + f * (self.points[i + 1] - self.points[i])
        h0 = float(self.heads[i])
        dh = (float(self.heads[i + 1]) - h0 + math.pi) % (2 * math.pi) - math.pi
        h = (h0 + f * dh + math.pi) % (2 * math.pi) - math.pi
        return xy, h

    def window(self, s0: float, s1: float) -> slice:
        i0 = max(int(np.searchsorted(self.s, s0)) - 1, 0)
        i1 = min(int(np.searchsorted(self.s, s1)) + 1, len(self.s))
        return slice(i0, i1)



class PathBank:
    """All paths of a scene concatenated, so that every vehicle is queried in one call.

    Path ``k`` occupies global arc lengths ``[base[k], base[k] + length_k]``;
    consecutive paths are separated by a jump of 1 km, so ``np.interp`` on the
    global arc length never mixes two paths.
    """

    def __init__(self) -> None:
        self.paths: list[Path] = []
        self._dirty = True

    def add(self, path: Path) -> int:
        self.paths.append(path)
        self._dirty = True
        return len(self.paths) - 1

    def _build(self) -> None:
        base, acc = [], 0.0
        for p in self.paths:
            base.append(acc)
            acc += p.length + 1000.0
        self.base = np.array(base)
        self.lengths = np.array([p.length for p in self.paths])
        self.gs = np.concatenate([b + p.s for b, p in zip(base, self.paths)])
        pts = np.concatenate([p.points for p in self.paths])
        hd = np.concatenate([p.heads for p in self.paths])
        self.x, self.y = pts[:, 0], pts[:, 1]
        self.c, self.sn = np.cos(hd), np.sin(hd)
        self.h = hd
        self.xy = pts
        self.k = np.abs(np.concatenate([p.kappa for p in self.paths]))
        sizes = np.array([len(p.s) for p in self.paths])
        self.first = np.concatenate([[0], np.cumsum(sizes)[:-1]])  # first vertex of each path
        self.last = self.first + sizes - 1
        self._dirty = False

    def window(self, pid: np.ndarray, s: np.ndarray, n: int,
               stride: int) -> tuple[np.ndarray, ...]:
        """Path vertices ahead of each vehicle: every ``stride``-th vertex from just behind ``s``.

        Gathers (no interpolation): returns points ``(N, n, 2)``, headings, arc
        lengths and |curvature| ``(N, n)``, and ``inside (N, n)`` — False past
        the path's end (those samples repeat the last vertex).
        """
        if self._dirty:
            self._build()
        g = self.base[pid] + np.clip(s, 0.0, self.lengths[pid])
        k0 = np.maximum(np.searchsorted(self.gs, g) - 1, self.first[pid])
        idx = k0[:, None] + stride * np.arange(n)[None, :]
        inside = idx <= self.last[pid][:, None]
        idx = np.minimum(idx, self.last[pid][:, None])
        return (self.xy[idx], self.h[idx], self.gs[idx] - self.base[pid][:, None],
                self.k[idx], inside)

    def query(self, pid: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, ...]:
        """Position ``(..., 2)``, heading, |curvature| at arc lengths ``s`` of paths ``pid``.

        Beyond a path's ends the position is extended straight.
        """
        if self._dirty:
            self._build()
        pid = np.asarray(pid)
        L = self.lengths[pid]
        sc = np.clip(s, 0.0, L)
        g = self.base[pid] + sc
        c = np.interp(g, self.gs, self.c)
        sn = np.interp(g, self.gs, self.sn)
        h = np.arctan2(sn, c)
        extra = s - sc
        x = np.interp(g, self.gs, self.x) + extra * np.cos(h)
        y = np.interp(g, self.gs, self.y) + extra * np.sin(h)
        return np.stack([x, y], axis=-1), h, np.interp(g, self.gs, self.k)


def corridor_leaders(
    win: np.ndarray,
    win_h: np.ndarray,
    win_s: np.ndarray,
    win_ok: np.ndarray,
    s: np.ndarray,
    length: np.ndarray,
    width: np.ndarray,
    boxes: np.ndarray,
    speeds: np.ndarray,
    active: np.ndarray,
    spacing: float,
    margin: float = 0.45,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every vehicle, the nearest vehicle whose box overlaps its corridor ahead.

    ``win (N, P, 2)`` are points sampled every ``spacing`` m along each
    vehicle's path (``win_h`` headings, ``win_s`` arc lengths, ``win_ok``
    which samples are inside its look-ahead). A box ``j`` overlaps vehicle
    ``i``'s corridor when its centre lies within ``w_i/2 + (extent of j
    across the path) + margin`` of the path and ahead of ``i``'s centre.
    Returns ``gap (N,)`` (front of ``i`` to the near extent of the leader,
    ``inf`` if free), the leader's speed along the path ``(N,)`` and its index
    ``(N,)`` (-1 if free).
    """
    N, P = win_ok.shape
    gap_out = np.full(N, np.inf)
    vl_out = np.zeros(N)
    who_out = np.full(N, -1)
    # candidate pairs: j near i's corridor at all (cheap pre-filter on centres)
    reach = spacing * win_ok.sum(axis=1) + 12.0
    d = np.hypot(boxes[None, :, 0] - boxes[:, None, 0], boxes[None, :, 1] - boxes[:, None, 1])
    cand = (d < reach[:, None]) & active[None, :] & active[:, None]
    np.fill_diagonal(cand, False)
    ii, jj = np.nonzero(cand)
    if len(ii) == 0:
        return gap_out, vl_out, who_out
    rx = boxes[jj, 0, None] - win[ii, :, 0]  # (K, P)
    ry = boxes[jj, 1, None] - win[ii, :, 1]
    d2 = np.where(win_ok[ii], rx * rx + ry * ry, np.inf)
    k = np.argmin(d2, axis=1)
    kk = np.arange(len(ii))
    hk = win_h[ii, k]
    ch, sh = np.cos(hk), np.sin(hk)
    tx, ty = rx[kk, k], ry[kk, k]
    tt = tx * ch + ty * sh  # along the path from the nearest sample
    lat = np.abs(-tx * sh + ty * ch)  # across the path
    dpsi = boxes[jj, 2] - hk
    cs, sn = np.abs(np.cos(dpsi)), np.abs(np.sin(dpsi))
    perp = sn * boxes[jj, 3] / 2 + cs * boxes[jj, 4] / 2
    along = cs * boxes[jj, 3] / 2 + sn * boxes[jj, 4] / 2
    ds = win_s[ii, k] + tt - s[ii]
    inside = (lat < width[ii] / 2 + perp + margin) & (np.abs(tt) <= 0.75 * spacing + 0.5)
    inside &= ds > 0.0
    gap = np.where(inside, ds - length[ii] / 2 - along, np.inf)
    order = np.lexsort((gap, ii))  # per i, the smallest gap first
    first = np.ones(len(order), bool)
    first[1:] = ii[order][1:] != ii[order][:-1]
    sel = order[first]
    g = gap[sel]
    hit = np.isfinite(g)
    sel, g = sel[hit], g[hit]
    gap_out[ii[sel]] = g
    vl_out[ii[sel]] = np.maximum(speeds[jj[sel]] * np.cos(dpsi[sel]), 0.0)
    who_out[ii[sel]] = jj[sel]
    return gap_out, vl_out, who_out


@dataclass
class Vehicle:
    """A vehicle on a path. Ados move along it; the ego's pose is set by its driver."""

    pid: int  # path index in the scene's PathBank
    s: float
    v: float
    length: float
    width: float
    v0: float
    T: float
    a_max: float
    b: float
    s0: float
    a_lat: float
    gap_crit: float
    is_ego: bool = False
    active: bool = True
    offset: float = 0.0  # lateral offset from the path (cut-in: adjacent lane)
    offset_rate: float = 0.0
    cut_in: dict | None = None
    stamp: float = np.inf  # arrival time at the junction (first come, first served)
    xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    yaw: float = 0.0

    @property
    def box(self) -> np.ndarray:
        return np.array([self.xy[0], self.xy[1], self.yaw, self.length, self.width])


def random_vehicle_size(rng: np.random.Generator) -> tuple[float, float]:
    """Length and width of an ado: mostly cars, some vans, a few trucks and buses."""
    u = rng.random()
    if u < 0.82:
        return float(rng.uniform(3.9, 4.9)), float(rng.uniform(1.7, 1.95))
    if u < 0.95:
        return float(rng.uniform(5.0, 6.2)), float(rng.uniform(1.95, 2.2))
    return float(rng.uniform(8.0, 11.5)), float(rng.uniform(2.4, 2.55))


def random_lane_walk(m: Map, rng: np.random.Generator, first: int, min_length: float) -> list[int]:
    """A lane sequence from ``first`` following random successors (stops at the map's exits)."""
    ids = [first]
    total = m.lanes[first].length
    while total < min_length:
        succ = m.lanes[ids[-1]].successors
        if not succ:
            break
        nxt = int(succ[int(rng.integers(len(succ)))])
        ids.append(nxt)
        total += m.lanes[nxt].length
        if len(ids) > 40:
            break
    return ids
