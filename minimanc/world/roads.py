"""Chapter 7 — building a road map from its recipe: roads, intersections, roundabouts.

:func:`build_map` turns a recipe (:func:`minimanc.world.maps.random_recipe`),
deterministically, into a :class:`~minimanc.world.lanes.Map`: lane centrelines
integrated from ``(length, curvature)`` pieces, lane connectors through
junctions (cubic Bézier curves tangent to the lanes), the drivable area,
walkways, pedestrian crossings, the conflict table between junction lanes and
the ego's route (:func:`concat_lanes`). An *explicit* recipe gives the
geometry itself (:data:`EXPLICIT_KIND`).
"""

from __future__ import annotations

import hashlib
import json

import numpy as np

from minimanc.world.geometry import (
    arclength,
    headings,
    interp_polyline,
    resample,
    wrap_angle,
)
from minimanc.world.lanes import (
    CLASS_DRIVABLE,
    CLASS_NONE,
    CLASS_WALKWAY,
    KINDS,
    LANE_WIDTH,
    RING_WIDTH,
    Lane,
    Map,
    offset_polyline,
)

__all__ = [
    "EXPLICIT_KIND",
    "build_map",
    "concat_lanes",
]

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
            fwd.append(self.lane(offset_polyline(ref, heads, -(i + 0.5) * LANE_WIDTH), "road",
                                 heads=heads))
        for i in range(n_bwd):
            p = offset_polyline(ref, heads, (i + 0.5) * LANE_WIDTH)[::-1]
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
            corners.append(offset_polyline(ref[:1], hd[:1], side * hw)[0])
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
         "holes": [[[x, y], ...]], "walkway_polygons": [[[x, y], ...]],
         "route": [lane ids], "start_s": s0}

    ``holes`` (optional) are cut from the drivable area; ``walkway_polygons`` (optional,
    recorded maps such as nuScenes') are walkways wherever nothing drivable is drawn.

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
    holes = [np.asarray(p, dtype=np.float64) for p in recipe.get("holes", [])]
    walk_polys = [np.asarray(p, dtype=np.float64) for p in recipe.get("walkway_polygons", [])]
    discs = [(float(d[0]), float(d[1]), float(d[2]), int(d[3])) for d in recipe.get("discs", [])]
    route = [int(r) for r in recipe["route"]]
    rp, rh, rs, _ = concat_lanes(lanes, route)
    allp = np.concatenate([ln.points for ln in lanes] + [p for p, _ in walkways] + polygons
                          + walk_polys)
    margin = 12.0
    bounds = (float(allp[:, 0].min() - margin), float(allp[:, 1].min() - margin),
              float(allp[:, 0].max() + margin), float(allp[:, 1].max() + margin))
    geometry = {k: recipe.get(k, []) for k in ("lanes", "strips", "polygons", "walkways",
                                                "crossings", "discs")}
    geometry.update({k: recipe[k] for k in ("holes", "walkway_polygons") if k in recipe})
    key = hashlib.sha256(json.dumps(geometry, sort_keys=True).encode()).hexdigest()[:16]
    return Map(
        recipe=recipe, kind=str(recipe.get("map_kind", "straight")), lanes=lanes,
        strips=strips, polygons=polygons, discs=discs, walkways=walkways, crossings=crossings,
        route=route, route_points=rp, route_heads=rh, route_s=rs,
        start_s=float(recipe.get("start_s", 0.0)), conflicts=_conflicts(lanes),
        bounds=bounds, key="x-" + key, holes=holes, walkway_polygons=walk_polys,
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
