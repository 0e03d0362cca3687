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

The recipe and the route queries (:func:`project_to_route`, :func:`lane_targets`) live
here; the data types (:class:`~minimanc.world.lanes.Map`, :class:`~minimanc.world.lanes.Lane`,
the class grid and its constants) in :mod:`minimanc.world.lanes` and the construction
(:func:`~minimanc.world.roads.build_map`) in :mod:`minimanc.world.roads`: import each from
where it is defined (the package :mod:`minimanc.world` gathers the public ones).
"""

from __future__ import annotations

import numpy as np

from minimanc.checks import check_int
from minimanc.world.geometry import to_ego_frame
from minimanc.world.lanes import (
    K_TARGETS,
    KIND_PROBS,
    KINDS,
    ROUTE_AHEAD,
    TARGET_SPACING,
    Map,
)
from minimanc.world.roads import build_map

__all__ = ["lane_targets", "project_to_route", "random_map", "random_recipe"]


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


def _arm_length(rng: np.random.Generator, k: int, arm_in: int, arm_out: int,
                start_dist: float) -> float:
    """Length of arm ``k`` of a junction: the ego's entry arm is long enough for its start,
    its exit arm for the route ahead, any other arm is drawn from ``rng``."""
    if k == arm_in:
        return start_dist + 45.0
    if k == arm_out:
        return ROUTE_AHEAD - start_dist + 10.0
    return float(rng.uniform(90.0, 150.0))


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
            length = _arm_length(rng, k, arm_in, arm_out, start_dist)
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
        length = _arm_length(rng, k, arm_in, arm_out, start_dist)
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


def random_map(rng: np.random.Generator, kind: str | None = None) -> Map:
    """``build_map(random_recipe(rng, kind))``."""
    return build_map(random_recipe(rng, kind))


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
    k = check_int("k", k, 1)
    if not spacing > 0:
        raise ValueError(f"spacing must be positive, got {spacing!r}")
    P = pose.reshape(-1, 3)
    s, _ = project_to_route(m, P[:, :2], P[:, 2])
    sq = s[:, None] + spacing * np.arange(1, int(k) + 1)[None, :]
    pts, _ = m.route_pose(sq)
    out = to_ego_frame(pts, P[:, None, :])
    return out[0] if pose.ndim == 1 else out
