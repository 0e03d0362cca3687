"""Chapter 9 — closed-loop metrics of the paper's Table I (section V-A), defined precisely.

The paper names four metrics ("all metrics are the lower the better") without
formulas; these are ours, stated exactly so that every number in
``table1.md`` can be recomputed by hand.  Trajectories are ego poses
``(S, T, 3) = [x, y, yaw]`` in the world frame at the log's rate
(``DT = 0.5`` s), one row per validation scene.

* **% close encounters** (:func:`close_encounters`, safety): the share of the
  steps of a scene at which some valid ado's *box* is closer than
  :data:`CLOSE_GAP` = 1.0 m to the ego's box (edge-to-edge gap between the
  oriented rectangles, 0 when they overlap; ego box
  4.727 m × 1.907 m as in the authors' environment).  Box gap, not centre
  distance, so that a car passing in the next lane (gap ≈ 1.6 m on 3.5 m
  lanes) does not count while a cut-in or tail-gating does.  Reported in %.
* **Max |acceleration|** (:func:`max_acceleration`, comfort): the largest
  magnitude over a scene of the *total* planar acceleration
  ``sqrt(a_lon² + a_lat²)`` with ``a_lon[t] = (v[t+1] − v[t]) / DT`` (speed
  differences) and ``a_lat[t] = v[t] · ω[t]`` (centripetal), where
  ``v, ω`` are the unicycle controls that move pose ``t`` to ``t+1``
  (:func:`minimanc.world.geometry.controls_from_poses`).  ``kind =
  "longitudinal"`` gives ``max |a_lon|`` alone.  m/s².
* **ADE** (:func:`ade`, the paper's "human driving similarity"): the mean
  over the ``T`` steps of the Euclidean distance between the policy's and the
  logged human's ego positions (same start pose, synchronised time).  m.
  :func:`along_cross_track` splits each step's displacement into its
  component along the human's heading (ahead > 0: speed or timing) and
  across it (left > 0: steering), ``along² + cross² = ‖p − p_human‖²``.
* **Goal distance** (:func:`goal_distance`): the distance between the ego's
  position at the last step and the goal, the final human position.  m.

Two honesty checks the paper does not report:

* **collision** (:func:`collisions`): the ego box overlaps a valid ado box at
  some step of the scene (a scene-level 0/1);
* **off-road** (:func:`off_road`): the ego's centre leaves the drivable area
  of the scene's map at some step (scene-level 0/1).

Safety and progress beyond the paper (nuPlan's closed-loop metrics are the anchor):

* **at-fault collision** (:func:`at_fault_collisions`, scene-level 0/1): a
  collision the ego could have avoided. Each ado counts once, at its first
  contact (the first of 8 sub-steps between two logged steps, positions and
  headings interpolated linearly, at which the boxes overlap), classified as
  nuPlan does (:func:`collision_events`):

  1. ``stopped_ego`` — the ego's speed is ≤ :data:`V_STOPPED` → *not* at fault;
  2. ``stopped_ado`` — the ado's speed is ≤ :data:`V_STOPPED` → at fault;
  3. ``rear`` — the ado's centre is more than 150° off the ego's heading, seen
     from the ego's centre (it came from behind) → *not* at fault;
  4. ``front`` — the ego's front edge touches the ado's box → at fault;
  5. ``lateral`` — any other contact → at fault when the ego was *not inside a
     lane* (:func:`ego_in_lane`: its centre more than :data:`IN_LANE` m from
     every lane centreline heading within 45° of it, or off the drivable area):
     the ego drove into a vehicle beside it; not at fault when it was in its
     lane (a vehicle cutting in drove into it).

  Where this differs from nuPlan: speeds are finite differences of the 2 Hz
  positions over the step that led to the contact (nuPlan reads the tracked
  velocities); the angle is seen from the box centre (our unicycle has no rear
  axle); "inside a lane" is a distance to the centrelines (nuPlan intersects the
  ego's corners with the lane polygons); both stopped thresholds are
  :data:`V_STOPPED` = 0.05 m/s (nuPlan uses 0.005 m/s for the tracks); there
  are no pedestrians or static objects.
* **time-to-collision** (:func:`time_to_collision`, :func:`ttc_rate`): at each
  step, the first time ``τ`` in ``0, 0.1, …, TTC_THRESHOLD`` s at which the ego
  box and a valid ado box, both moved on at their constant current velocity
  (finite differences of positions, headings kept), overlap; ``inf`` when
  none does, when the ego is stopped, or for ados behind the ego (as above:
  those are not the ego's to avoid). :func:`ttc_rate` is the share of steps
  with ``τ ≤`` :data:`TTC_THRESHOLD` = 1.0 s (nuPlan's bound is 0.95 s), in %.
* **route progress** (:func:`route_progress`): the distance the ego advanced
  along the scene's route (:func:`minimanc.world.maps.project_to_route`, first
  to last step) divided by the human's; 1 when the human advanced less than
  :data:`PROGRESS_MIN` = 1 m (nothing to compare with). Above 1: further than
  the human.

Every per-scene metric returns an ``(S,)`` array; :func:`evaluate` averages
over the scenes and :func:`aggregate` turns one dict per training seed into
``mean ± std`` (population std over seeds, ``ddof = 0``; 0 for one seed).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from minimanc.world.geometry import (
    DT,
    EGO_LENGTH,
    EGO_WIDTH,
    box_corners,
    boxes_overlap,
    controls_from_poses,
    wrap_angle,
)
from minimanc.world.lanes import LANE_WIDTH

__all__ = [
    "CLOSE_GAP",
    "METRICS",
    "TABLE_METRICS",
    "ego_boxes",
    "box_gap",
    "ado_gaps",
    "close_encounters",
    "max_acceleration",
    "ade",
    "along_cross_track",
    "goal_distance",
    "collisions",
    "off_road",
    "ALL_METRICS",
    "COLLISION_TYPES",
    "IN_LANE",
    "PROGRESS_MIN",
    "SAFETY_METRICS",
    "TTC_THRESHOLD",
    "V_STOPPED",
    "AT_FAULT",
    "CollisionEvent",
    "at_fault_collisions",
    "collision_events",
    "ego_in_lane",
    "route_progress",
    "time_to_collision",
    "ttc_rate",
    "evaluate",
    "aggregate",
]

CLOSE_GAP: float = 1.0
"""Box-to-box gap (m) below which an ado counts as a close encounter."""

TABLE_METRICS: tuple[str, ...] = ("close_encounters", "max_acceleration", "ade", "goal_distance")
"""The paper's four Table I metrics, in its order."""

METRICS: tuple[str, ...] = TABLE_METRICS + ("collision_rate", "off_road_rate")
"""The paper's metrics and the two honesty checks (keys of :func:`evaluate`)."""

SAFETY_METRICS: tuple[str, ...] = ("at_fault_collision_rate", "ttc_rate", "route_progress")
"""At-fault collisions (%), time-to-collision below the bound (% of steps) and the progress
along the route relative to the human (a ratio), also returned by :func:`evaluate`."""

ALL_METRICS: tuple[str, ...] = METRICS + SAFETY_METRICS
"""Every key :func:`evaluate` returns."""

V_STOPPED: float = 0.05
"""Speed (m/s) at or below which a vehicle counts as stopped (nuPlan's ego threshold)."""

IN_LANE: float = (LANE_WIDTH - EGO_WIDTH) / 2
"""Largest distance (m) of the ego's centre from a lane centreline for the ego to be inside
that lane: its box then stays within the lane's edges (0.80 m on 3.5 m lanes)."""

TTC_THRESHOLD: float = 1.0
"""Time-to-collision bound (s) of :func:`ttc_rate`."""

TTC_STEP: float = 0.1
"""Time step (s) of the constant-velocity projection of :func:`time_to_collision`."""

PROGRESS_MIN: float = 1.0
"""Human progress (m) below which :func:`route_progress` is 1 (nothing to compare with)."""

COLLISION_TYPES: tuple[str, ...] = ("stopped_ego", "stopped_ado", "rear", "front", "lateral")
"""The classes of :func:`collision_events` (nuPlan's, in its order)."""

AT_FAULT: frozenset[str] = frozenset({"stopped_ado", "front"})
"""Classes always at fault; ``lateral`` is at fault when the ego is not inside a lane."""

_BEHIND_ANGLE = np.deg2rad(150.0)
_SUBSTEPS = 8


# --------------------------------------------------------------------------- checks


def _traj(ego: Any, name: str = "ego") -> np.ndarray:
    arr = np.asarray(ego, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (S, T, 3) [x, y, yaw]; got shape {arr.shape}")
    if arr.shape[1] < 1:
        raise ValueError(f"{name} must have at least one step; got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite; got {int(np.sum(~np.isfinite(arr)))} bad values")
    return arr


def _ados(ado: Any, ado_valid: Any, ego: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(ado, dtype=np.float64)
    v = np.asarray(ado_valid, dtype=bool)
    S, T = ego.shape[:2]
    if a.ndim != 4 or a.shape[:2] != (S, T) or a.shape[-1] != 5:
        raise ValueError(
            f"ado must have shape (S, T, A, 5) = ({S}, {T}, A, 5) [x, y, yaw, length, width]; "
            f"got shape {a.shape}"
        )
    if v.shape != a.shape[:3]:
        raise ValueError(f"ado_valid must have shape {a.shape[:3]}; got shape {v.shape}")
    return a, v


def _check_dt(dt: float) -> float:
    if not np.isfinite(dt) or dt <= 0:
        raise ValueError(f"dt must be a positive finite number; got dt = {dt!r}")
    return float(dt)


# --------------------------------------------------------------------------- geometry


def ego_boxes(ego: Any) -> np.ndarray:
    """Ego boxes ``(..., 5) = [x, y, yaw, EGO_LENGTH, EGO_WIDTH]`` from poses ``(..., 3)``."""
    e = np.asarray(ego, dtype=np.float64)
    if e.ndim == 0 or e.shape[-1] != 3:
        raise ValueError(f"ego must have last dimension 3 [x, y, yaw]; got shape {e.shape}")
    size = np.broadcast_to([EGO_LENGTH, EGO_WIDTH], e.shape[:-1] + (2,))
    return np.concatenate([e, size], axis=-1)


def _point_segment_dist(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    L2 = np.maximum(np.sum(d * d, axis=-1), 1e-12)
    t = np.clip(np.sum((p - a) * d, axis=-1) / L2, 0.0, 1.0)
    foot = a + t[..., None] * d
    return np.linalg.norm(p - foot, axis=-1)


def box_gap(a: Any, b: Any) -> np.ndarray:
    """Edge-to-edge distance between oriented boxes ``a (..., 5)`` and ``b (..., 5)`` (broadcast).

    0 where the rectangles overlap (separating-axis test,
    :func:`minimanc.world.geometry.boxes_overlap`); otherwise the smallest
    distance from a corner of one box to an edge of the other, which is the
    exact distance between two disjoint convex polygons.
    """
    ca = box_corners(a)  # (..., 4, 2)
    cb = box_corners(b)
    ca, cb = np.broadcast_arrays(ca, cb)
    ea0, ea1 = ca, np.roll(ca, -1, axis=-2)  # edges of a: corner k -> k+1
    eb0, eb1 = cb, np.roll(cb, -1, axis=-2)
    # corners of b (index i) against edges of a (index k), and vice versa
    d_ba = _point_segment_dist(cb[..., :, None, :], ea0[..., None, :, :], ea1[..., None, :, :])
    d_ab = _point_segment_dist(ca[..., :, None, :], eb0[..., None, :, :], eb1[..., None, :, :])
    gap = np.minimum(d_ba.min(axis=(-2, -1)), d_ab.min(axis=(-2, -1)))
    return np.where(boxes_overlap(a, b), 0.0, gap)


def ado_gaps(ego: Any, ado: Any, ado_valid: Any) -> np.ndarray:
    """Gap ``(S, T, A)`` between the ego box and every ado box; ``inf`` where the ado is invalid."""
    e = _traj(ego)
    a, v = _ados(ado, ado_valid, e)
    gaps = box_gap(ego_boxes(e)[:, :, None, :], a)
    return np.where(v, gaps, np.inf)


# --------------------------------------------------------------------------- metrics


def close_encounters(
    ego: Any, ado: Any, ado_valid: Any, gap: float = CLOSE_GAP
) -> np.ndarray:
    """Per scene, the share of steps (in [0, 1]) with a valid ado box within ``gap`` m of the ego.

    ``ego`` (S, T, 3); ``ado`` (S, T, A, 5) ``[x, y, yaw, length, width]``
    (world frame, the logged replay); ``ado_valid`` (S, T, A).  A step counts
    once however many ados are close.  Returns ``(S,)``.
    """
    if not np.isfinite(gap) or gap < 0:
        raise ValueError(f"gap must be a finite number >= 0; got gap = {gap!r}")
    gaps = ado_gaps(ego, ado, ado_valid)
    close = np.any(gaps < gap, axis=-1) if gaps.shape[-1] else np.zeros(gaps.shape[:2], bool)
    return close.mean(axis=1)


def max_acceleration(ego: Any, dt: float = DT, kind: str = "total") -> np.ndarray:
    """Per scene, the maximum acceleration magnitude (m/s²).

    From the unicycle controls ``v[t], ω[t]`` that move pose ``t`` to
    ``t + 1`` (``T − 1`` of them):  ``a_lon[t] = (v[t+1] − v[t]) / dt`` for
    ``t = 0 … T−3`` and ``a_lat[t] = v[t] ω[t]``.  ``kind="total"`` returns
    ``max_t sqrt(a_lon[t]² + a_lat[t]²)``, ``kind="longitudinal"``
    returns ``max_t |a_lon[t]|``.  Scenes with fewer than 3 poses give 0.
    Returns ``(S,)``.
    """
    e = _traj(ego)
    dt = _check_dt(dt)
    if kind not in ("total", "longitudinal"):
        raise ValueError(f"kind must be 'total' or 'longitudinal'; got kind = {kind!r}")
    S, T = e.shape[:2]
    if T < 3:
        return np.zeros(S)
    u = np.stack([controls_from_poses(e[s], dt) for s in range(S)])  # (S, T-1, 2)
    v, w = u[..., 0], u[..., 1]
    a_lon = np.diff(v, axis=1) / dt  # (S, T-2)
    if kind == "longitudinal":
        return np.abs(a_lon).max(axis=1)
    a_lat = v[:, :-1] * w[:, :-1]
    return np.sqrt(a_lon**2 + a_lat**2).max(axis=1)


def ade(ego: Any, human: Any) -> np.ndarray:
    """Per scene, the average displacement error ``mean_t ‖p[t] − p_human[t]‖`` (m).

    ``ego`` and ``human`` are ``(S, T, 3)`` poses on the same clock; only the
    positions enter.  Returns ``(S,)``.
    """
    e = _traj(ego)
    h = _traj(human, "human")
    if e.shape != h.shape:
        raise ValueError(f"ego and human must have the same shape; got {e.shape} and {h.shape}")
    return np.linalg.norm(e[..., :2] - h[..., :2], axis=-1).mean(axis=1)


def along_cross_track(ego: Any, human: Any) -> tuple[np.ndarray, np.ndarray]:
    """Per scene and step, the displacement from the human split along and across its heading (m).

    With ``d[t] = p[t] − p_human[t]`` (the policy's position minus the logged
    human's at the same time) and the human's heading ``ψ[t]``:
    ``along[t] = d[t] · (cos ψ[t], sin ψ[t])`` (positive when the policy is
    ahead of the human) and ``cross[t] = d[t] · (−sin ψ[t], cos ψ[t])``
    (positive when it is to the human's left).  A rotation, so
    ``along² + cross² = ‖d‖²`` and ``mean_t sqrt(along² + cross²)`` is
    :func:`ade`.  ``ego`` and ``human`` are ``(S, T, 3)`` poses on the same
    clock (the policy's yaw does not enter).  Returns ``(along, cross)``,
    each ``(S, T)``.
    """
    e = _traj(ego)
    h = _traj(human, "human")
    if e.shape != h.shape:
        raise ValueError(f"ego and human must have the same shape; got {e.shape} and {h.shape}")
    d = e[..., :2] - h[..., :2]
    c, s = np.cos(h[..., 2]), np.sin(h[..., 2])
    along = d[..., 0] * c + d[..., 1] * s
    cross = -d[..., 0] * s + d[..., 1] * c
    return along, cross


def goal_distance(ego: Any, goal: Any) -> np.ndarray:
    """Per scene, ``‖p[T−1] − g‖``: last ego position to the goal position ``goal (S, 2|3)`` (m)."""
    e = _traj(ego)
    g = np.asarray(goal, dtype=np.float64)
    if g.ndim != 2 or g.shape[0] != e.shape[0] or g.shape[1] not in (2, 3):
        raise ValueError(f"goal must have shape ({e.shape[0]}, 2 or 3); got shape {g.shape}")
    return np.linalg.norm(e[:, -1, :2] - g[:, :2], axis=-1)


def collisions(ego: Any, ado: Any, ado_valid: Any) -> np.ndarray:
    """Per scene, 1.0 if the ego box overlaps a valid ado box at some step, else 0.0. ``(S,)``."""
    e = _traj(ego)
    a, v = _ados(ado, ado_valid, e)
    hit = boxes_overlap(ego_boxes(e)[:, :, None, :], a) & v
    return hit.reshape(e.shape[0], -1).any(axis=1).astype(np.float64)


def off_road(ego: Any, maps: Sequence[Any]) -> np.ndarray:
    """Per scene, 1.0 if the ego centre leaves the map's drivable area at some step. ``(S,)``.

    ``maps[s].is_drivable(points (N, 2)) -> bool (N,)`` decides (the
    :class:`minimanc.world.maps.Map`; pedestrian crossings count as drivable).
    """
    e = _traj(ego)
    if len(maps) != e.shape[0]:
        raise ValueError(f"maps must hold one map per scene ({e.shape[0]}); got {len(maps)}")
    out = np.zeros(e.shape[0])
    for s, m in enumerate(maps):
        out[s] = float(not np.all(m.is_drivable(e[s, :, :2])))
    return out


# --------------------------------------------------------------------------- safety and progress


def _speeds(xy: np.ndarray, valid: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Per step, the speed over the step that led there (backward difference; forward at a
    first valid step; 0 when valid alone) and the velocity over the next one (forward
    difference; backward at a last valid step; 0 alone). ``xy (S, T, ..., 2)``."""
    d = np.diff(xy, axis=1) / dt  # (S, T-1, ..., 2)
    ok = valid[:, 1:] & valid[:, :-1]
    zero = np.zeros_like(xy[:, :1])
    fwd = np.concatenate([d, zero], axis=1)
    bwd = np.concatenate([zero, d], axis=1)
    f_ok = np.concatenate([ok, np.zeros_like(ok[:, :1])], axis=1)
    b_ok = np.concatenate([np.zeros_like(ok[:, :1]), ok], axis=1)
    into = np.where(b_ok[..., None], bwd, np.where(f_ok[..., None], fwd, 0.0))
    ahead = np.where(f_ok[..., None], fwd, np.where(b_ok[..., None], bwd, 0.0))
    return np.linalg.norm(into, axis=-1), ahead


def _behind(ego: np.ndarray, other_xy: np.ndarray) -> np.ndarray:
    """Whether ``other_xy (..., 2)`` is more than 150° off the heading of ``ego (..., 3)``."""
    rel = other_xy - ego[..., :2]
    ang = np.arctan2(rel[..., 1], rel[..., 0]) - ego[..., 2]
    return np.abs(wrap_angle(ang)) > _BEHIND_ANGLE


def _front_edge(ego: np.ndarray) -> np.ndarray:
    """The ego's front edge as a box of zero length ``(..., 5)``."""
    e = np.asarray(ego, dtype=np.float64)
    c, s = np.cos(e[..., 2]), np.sin(e[..., 2])
    x = e[..., 0] + c * EGO_LENGTH / 2
    y = e[..., 1] + s * EGO_LENGTH / 2
    return np.stack([x, y, e[..., 2], np.zeros_like(x), np.full_like(x, EGO_WIDTH)], axis=-1)


def _lerp_pose(a: np.ndarray, b: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Poses (or boxes) between ``a`` and ``b`` at fractions ``f (K,)``: ``(K, n)``."""
    out = a[None, :] + f[:, None] * (b - a)[None, :]
    out[:, 2] = a[2] + f * wrap_angle(b[2] - a[2])
    return out


@dataclass(frozen=True)
class CollisionEvent:
    """The first contact of the ego with one ado: scene row, step (the logged step at or
    before which the contact happened), ado slot, class (:data:`COLLISION_TYPES`), whether the
    ego was inside a lane (``None`` when no map was given) and whether it is at fault."""

    scene: int
    step: int
    ado: int
    kind: str
    in_lane: bool | None
    at_fault: bool


def ego_in_lane(poses: Any, m: Any) -> np.ndarray:
    """Whether the ego at ``poses (N, 3)`` is inside a lane of map ``m``: ``(N,)`` bool.

    Inside: the centre is on the drivable area and within :data:`IN_LANE` m of a lane
    centreline sample (every 0.25 m) whose heading is within 45° of the ego's.
    ``m`` needs ``lane_samples(spacing)`` (a :class:`minimanc.world.lanes.LaneSamples`)
    and ``is_drivable(points)`` (a :class:`minimanc.world.maps.Map`).
    """
    P = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    samples = m.lane_samples(0.25)
    out = np.asarray(m.is_drivable(P[:, :2]), dtype=bool).copy()
    for k, (x, y, h) in enumerate(P):
        if not out[k]:
            continue
        pts, hds = samples.near(np.array([x, y]), IN_LANE + 0.5)
        ok = np.cos(hds - h) > np.cos(np.pi / 4)
        d2 = (pts[:, 0] - x) ** 2 + (pts[:, 1] - y) ** 2
        out[k] = bool(np.any(ok & (d2 <= IN_LANE**2)))
    return out


def collision_events(ego: Any, ado: Any, ado_valid: Any, maps: Sequence[Any] | None = None,
                     dt: float = DT) -> list[CollisionEvent]:
    """Every ego–ado collision of the rollout, each ado once at its first contact, classified.

    See the module docstring for the classes and the at-fault rule. ``maps`` (one per
    scene) decide whether the ego was inside a lane for ``lateral`` contacts; without
    them a lateral contact counts as at fault (the conservative choice).
    """
    e = _traj(ego)
    a, v = _ados(ado, ado_valid, e)
    dt = _check_dt(dt)
    if maps is not None and len(maps) != e.shape[0]:
        raise ValueError(f"maps must hold one map per scene ({e.shape[0]}); got {len(maps)}")
    hit = boxes_overlap(ego_boxes(e)[:, :, None, :], a) & v  # (S, T, A)
    S, T, A = hit.shape
    first = np.where(hit.any(axis=1), hit.argmax(axis=1), -1)  # (S, A)
    v_ego, _ = _speeds(e[..., :2], np.ones((S, T), bool), dt)
    v_ado, _ = _speeds(a[..., :2], v, dt)
    f = (np.arange(1, _SUBSTEPS + 1) / _SUBSTEPS)
    events = []
    for s_, k in zip(*np.nonzero(first >= 0)):
        t = int(first[s_, k])
        pe, pa = e[s_, t], a[s_, t, k]
        if t > 0 and v[s_, t - 1, k]:  # the first sub-step of (t-1, t] in contact
            es = _lerp_pose(e[s_, t - 1], e[s_, t], f)
            as_ = _lerp_pose(a[s_, t - 1, k], a[s_, t, k], f)
            j = int(np.argmax(boxes_overlap(ego_boxes(es), as_)))
            pe, pa = es[j], as_[j]
        if v_ego[s_, t] <= V_STOPPED:
            kind = "stopped_ego"
        elif v_ado[s_, t, k] <= V_STOPPED:
            kind = "stopped_ado"
        elif _behind(pe, pa[:2]):
            kind = "rear"
        elif bool(boxes_overlap(_front_edge(pe), pa)):
            kind = "front"
        else:
            kind = "lateral"
        in_lane = None
        if kind == "lateral" and maps is not None:
            in_lane = bool(ego_in_lane(pe[None], maps[s_])[0])
        fault = kind in AT_FAULT or (kind == "lateral" and not in_lane)
        events.append(CollisionEvent(int(s_), t, int(k), kind, in_lane, bool(fault)))
    return events


def at_fault_collisions(ego: Any, ado: Any, ado_valid: Any, maps: Sequence[Any] | None = None,
                        dt: float = DT) -> np.ndarray:
    """Per scene, 1.0 if the ego is at fault in some collision (:func:`collision_events`),
    else 0.0. ``(S,)``."""
    e = _traj(ego)
    out = np.zeros(e.shape[0])
    for ev in collision_events(e, ado, ado_valid, maps, dt):
        if ev.at_fault:
            out[ev.scene] = 1.0
    return out


def time_to_collision(ego: Any, ado: Any, ado_valid: Any, horizon: float = TTC_THRESHOLD,
                      dt: float = DT) -> np.ndarray:
    """Per scene and step, the time-to-collision ``(S, T)`` in s (``inf``: none within
    ``horizon``); see the module docstring. Sampled every :data:`TTC_STEP` s."""
    e = _traj(ego)
    a, v = _ados(ado, ado_valid, e)
    dt = _check_dt(dt)
    if not np.isfinite(horizon) or horizon < 0:
        raise ValueError(f"horizon must be a finite number >= 0; got horizon = {horizon!r}")
    S, T, A = v.shape
    taus = np.arange(int(np.floor(horizon / TTC_STEP + 1e-9)) + 1) * TTC_STEP  # 0 ... horizon
    _, vel_e = _speeds(e[..., :2], np.ones((S, T), bool), dt)
    _, vel_a = _speeds(a[..., :2], v, dt)
    moving = np.linalg.norm(vel_e, axis=-1) > V_STOPPED  # (S, T)
    cand = v & moving[..., None] & ~_behind(e[:, :, None, :], a[..., :2])
    # centres that cannot meet within the horizon are skipped
    rel_p = a[..., :2] - e[:, :, None, :2]
    rel_v = vel_a - vel_e[:, :, None, :]
    reach = (np.hypot(a[..., 3], a[..., 4]) + np.hypot(EGO_LENGTH, EGO_WIDTH)) / 2
    cand &= np.linalg.norm(rel_p, axis=-1) <= reach + np.linalg.norm(rel_v, axis=-1) * horizon
    ttc = np.full((S, T), np.inf)
    si, ti, ki = np.nonzero(cand)
    if len(si) == 0:
        return ttc
    eb = ego_boxes(e[si, ti])  # (N, 5)
    ab = a[si, ti, ki]
    move = np.zeros((len(taus), len(si), 5))
    ego_k = eb[None] + move
    ego_k[..., :2] += taus[:, None, None] * vel_e[si, ti][None]
    ado_k = ab[None] + move
    ado_k[..., :2] += taus[:, None, None] * vel_a[si, ti, ki][None]
    over = boxes_overlap(ego_k, ado_k)  # (K, N)
    tau = np.where(over.any(axis=0), taus[np.argmax(over, axis=0)], np.inf)
    np.minimum.at(ttc, (si, ti), tau)
    return ttc


def ttc_rate(ego: Any, ado: Any, ado_valid: Any, threshold: float = TTC_THRESHOLD,
             dt: float = DT) -> np.ndarray:
    """Per scene, the share of steps (in [0, 1]) whose time-to-collision is ``<= threshold``
    s (:func:`time_to_collision` with ``horizon = threshold``). ``(S,)``."""
    return (time_to_collision(ego, ado, ado_valid, threshold, dt) <= threshold).mean(axis=1)


def route_progress(ego: Any, human: Any, maps: Sequence[Any]) -> np.ndarray:
    """Per scene, the ego's progress along the route over the human's (module docstring).

    ``ego`` and ``human`` ``(S, T, 3)``; ``maps[s]`` the scene's
    :class:`minimanc.world.maps.Map` (its route). ``(S,)``.
    """
    from minimanc.world.maps import project_to_route

    e = _traj(ego)
    h = _traj(human, "human")
    if e.shape != h.shape:
        raise ValueError(f"ego and human must have the same shape; got {e.shape} and {h.shape}")
    if len(maps) != e.shape[0]:
        raise ValueError(f"maps must hold one map per scene ({e.shape[0]}); got {len(maps)}")
    out = np.ones(e.shape[0])
    for k, m in enumerate(maps):
        ends = np.stack([e[k, 0], e[k, -1], h[k, 0], h[k, -1]])
        s, _ = project_to_route(m, ends[:, :2], ends[:, 2])
        human_ds = s[3] - s[2]
        if human_ds >= PROGRESS_MIN:
            out[k] = (s[1] - s[0]) / human_ds
    return out


# --------------------------------------------------------------------------- summaries


def evaluate(traj: Any, ds: Any, gap: float = CLOSE_GAP) -> dict[str, float]:
    """All metrics of one rollout, averaged over its scenes.

    ``traj`` has ``.ego`` (S, T, 3) (a :class:`minimanc.rollout.Rollout`);
    ``ds`` is the validation dataset it was rolled out on (``ego``, ``ado``,
    ``ado_valid``, ``maps``). The ados are the rollout's own when it holds them
    (``traj.ado``, ``traj.ado_valid``: the reactive protocol,
    :class:`minimanc.world.reactive.ReactiveRollout`), else the dataset's log.
    Keys: :data:`ALL_METRICS`; ``close_encounters``, ``collision_rate``,
    ``off_road_rate``, ``at_fault_collision_rate`` and ``ttc_rate`` in percent,
    ``route_progress`` a ratio, the rest in m or m/s².
    """
    ego = _traj(traj.ego)
    human = _traj(ds.ego, "ds.ego")
    if ego.shape != human.shape:
        raise ValueError(
            f"traj.ego must have the dataset's shape {human.shape}; got {ego.shape}"
        )
    ado, valid = ds.ado, ds.ado_valid
    if getattr(traj, "ado", None) is not None:
        ado, valid = traj.ado, traj.ado_valid
    return {
        "close_encounters": 100.0 * float(close_encounters(ego, ado, valid, gap).mean()),
        "max_acceleration": float(max_acceleration(ego).mean()),
        "ade": float(ade(ego, human).mean()),
        "goal_distance": float(goal_distance(ego, human[:, -1]).mean()),
        "collision_rate": 100.0 * float(collisions(ego, ado, valid).mean()),
        "off_road_rate": 100.0 * float(off_road(ego, ds.maps).mean()),
        "at_fault_collision_rate": 100.0 * float(
            at_fault_collisions(ego, ado, valid, ds.maps).mean()),
        "ttc_rate": 100.0 * float(ttc_rate(ego, ado, valid).mean()),
        "route_progress": float(route_progress(ego, human, ds.maps).mean()),
    }


def aggregate(per_seed: Sequence[Mapping[str, float]]) -> dict[str, dict[str, float]]:
    """``[{metric: value} per seed]`` → ``{metric: {"mean", "std", "n", "values"}}``.

    ``std`` is the population standard deviation over seeds (``ddof = 0``; NaN
    when a seed's value is infinite, e.g. a closed loop that blew up).
    Only the numeric keys present in every seed's dict are kept.
    """
    if len(per_seed) == 0:
        raise ValueError("per_seed must hold at least one dict of metrics; got an empty sequence")
    def numeric(v: Any) -> bool:
        return isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool)

    keys = [k for k in per_seed[0] if all(k in d and numeric(d[k]) for d in per_seed)]
    out: dict[str, dict[str, Any]] = {}
    for k in keys:
        vals = np.array([float(d[k]) for d in per_seed])
        out[k] = {
            "mean": float(vals.mean()),
            "std": float(vals.std()) if np.all(np.isfinite(vals)) else float("nan"),
            "n": len(vals),
            "values": [float(x) for x in vals],
        }
    return out
