"""Chapter 9 — closed-loop safety metrics: close encounters, collisions and who is at fault, TTC.

Ego poses ``(S, T, 3)`` and ado boxes ``(S, T, A, 5)`` with their mask ``(S, T, A)``
(:mod:`minimanc.metrics.boxes`); only valid ados count.

* **% close encounters** (:func:`close_encounters`, the paper's Table I safety
  metric): the share of the steps of a scene at which some valid ado's *box* is
  closer than :data:`CLOSE_GAP` = 1.0 m to the ego's box (edge-to-edge gap between
  the oriented rectangles, 0 when they overlap, :func:`~minimanc.metrics.boxes.box_gap`;
  ego box 4.727 m × 1.907 m as in the authors' environment).  Box gap, not centre
  distance, so that a car passing in the next lane (gap ≈ 1.6 m on 3.5 m
  lanes) does not count while a cut-in or tail-gating does.  Reported in %.
* **collision** (:func:`collisions`, an honesty check the paper does not report):
  the ego box overlaps a valid ado box at some step of the scene (a scene-level 0/1).

Beyond the paper (nuPlan's closed-loop metrics are the anchor):

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
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from minimanc.checks import check_dt
from minimanc.metrics.boxes import (
    ado_gaps,
    check_ados,
    check_maps,
    check_poses,
    ego_boxes,
)
from minimanc.world.geometry import DT, EGO_LENGTH, EGO_WIDTH, boxes_overlap, wrap_angle
from minimanc.world.lanes import LANE_WIDTH

__all__ = [
    "CLOSE_GAP",
    "V_STOPPED",
    "IN_LANE",
    "TTC_THRESHOLD",
    "TTC_STEP",
    "COLLISION_TYPES",
    "AT_FAULT",
    "close_encounters",
    "collisions",
    "CollisionEvent",
    "ego_in_lane",
    "collision_events",
    "at_fault_collisions",
    "time_to_collision",
    "ttc_rate",
]

CLOSE_GAP: float = 1.0
"""Box-to-box gap (m) below which an ado counts as a close encounter."""

V_STOPPED: float = 0.05
"""Speed (m/s) at or below which a vehicle counts as stopped (nuPlan's ego threshold)."""

IN_LANE: float = (LANE_WIDTH - EGO_WIDTH) / 2
"""Largest distance (m) of the ego's centre from a lane centreline for the ego to be inside
that lane: its box then stays within the lane's edges (0.80 m on 3.5 m lanes)."""

TTC_THRESHOLD: float = 1.0
"""Time-to-collision bound (s) of :func:`ttc_rate`."""

TTC_STEP: float = 0.1
"""Time step (s) of the constant-velocity projection of :func:`time_to_collision`."""

COLLISION_TYPES: tuple[str, ...] = ("stopped_ego", "stopped_ado", "rear", "front", "lateral")
"""The classes of :func:`collision_events` (nuPlan's, in its order)."""

AT_FAULT: frozenset[str] = frozenset({"stopped_ado", "front"})
"""Classes always at fault; ``lateral`` is at fault when the ego is not inside a lane."""

_BEHIND_ANGLE = np.deg2rad(150.0)
_SUBSTEPS = 8


# --------------------------------------------------------------------------- the paper's check


def close_encounters(
    ego: Any, ado: Any, ado_valid: Any, gap: float = CLOSE_GAP
) -> np.ndarray:
    """Per scene, the share of steps (in [0, 1]) with a valid ado box within ``gap`` m of the ego.

    A step counts once however many ados are close; the gap is
    :func:`~minimanc.metrics.boxes.box_gap`.

    Parameters
    ----------
    ego : array, shape (S, T, 3)
        Ego poses ``[x, y, yaw]`` (m, m, rad) in the world frame, finite.
    ado : array, shape (S, T, A, 5)
        Ado boxes ``[x, y, yaw, length, width]`` (m, m, rad, m, m) on the same clock.
    ado_valid : array of bool, shape (S, T, A)
        Which ado boxes exist (only valid ones count).
    gap : float
        The close-encounter distance in m between box edges (finite, >= 0).

    Returns
    -------
    ndarray, shape (S,)
        The share of close steps per scene, in [0, 1].

    Raises
    ------
    ValueError
        If ``gap`` is not finite and >= 0, ``ego``, ``ado`` or ``ado_valid`` has another
        shape, or ``ego`` is not finite.
    """
    if not np.isfinite(gap) or gap < 0:
        raise ValueError(f"gap must be a finite number >= 0; got gap = {gap!r}")
    gaps = ado_gaps(ego, ado, ado_valid)
    close = np.any(gaps < gap, axis=-1) if gaps.shape[-1] else np.zeros(gaps.shape[:2], bool)
    return close.mean(axis=1)


def collisions(ego: Any, ado: Any, ado_valid: Any) -> np.ndarray:
    """Per scene, 1.0 if the ego box overlaps a valid ado box at some step, else 0.0.

    Parameters
    ----------
    ego : array, shape (S, T, 3)
        Ego poses ``[x, y, yaw]`` (m, m, rad) in the world frame, finite.
    ado : array, shape (S, T, A, 5)
        Ado boxes ``[x, y, yaw, length, width]`` (m, m, rad, m, m) on the same clock.
    ado_valid : array of bool, shape (S, T, A)
        Which ado boxes exist (only valid ones count).

    Returns
    -------
    ndarray, shape (S,)
        1.0 for a scene with a collision, else 0.0.

    Raises
    ------
    ValueError
        If ``ego``, ``ado`` or ``ado_valid`` has another shape, or ``ego`` is not finite.
    """
    e = check_poses(ego)
    a, v = check_ados(ado, ado_valid, e)
    return _overlaps(e, a, v).reshape(e.shape[0], -1).any(axis=1).astype(np.float64)


def _overlaps(e: np.ndarray, a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(S, T, A)``: the ego box at the poses ``e`` overlaps the valid ado box (checked
    inputs); the separating-axis test is made only where the circumscribed circles meet."""
    si, ti, ki = np.nonzero(v)
    ab, ep = a[si, ti, ki], e[si, ti]
    reach = (np.hypot(ab[:, 3], ab[:, 4]) + np.hypot(EGO_LENGTH, EGO_WIDTH)) / 2 + 1e-6
    near = np.hypot(ab[:, 0] - ep[:, 0], ab[:, 1] - ep[:, 1]) <= reach
    hit = np.zeros(v.shape, dtype=bool)
    hit[si[near], ti[near], ki[near]] = boxes_overlap(ego_boxes(ep[near]), ab[near])
    return hit


# --------------------------------------------------------------------------- who is at fault


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
    and ``is_drivable(points)`` (a :class:`minimanc.world.lanes.Map`).

    Parameters
    ----------
    poses : array, shape (N, 3) (any array of ``3 N`` values is reshaped to it)
        Ego poses ``[x, y, yaw]`` (m, m, rad).
    m : Map
        The scene's map.

    Returns
    -------
    ndarray of bool, shape (N,)
        True where the ego is inside a lane.
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

    Parameters
    ----------
    ego : array, shape (S, T, 3)
        Ego poses ``[x, y, yaw]`` (m, m, rad) in the world frame, finite.
    ado : array, shape (S, T, A, 5)
        Ado boxes ``[x, y, yaw, length, width]`` (m, m, rad, m, m) on the same clock.
    ado_valid : array of bool, shape (S, T, A)
        Which ado boxes exist (only valid ones count).
    maps : sequence of Map, length S, or None
        The scene's :class:`minimanc.world.lanes.Map`, for the in-lane test of lateral
        contacts.
    dt : float
        Time between logged steps in seconds (finite, > 0).

    Returns
    -------
    list of CollisionEvent
        One per colliding ado, ordered by scene then ado slot.

    Raises
    ------
    ValueError
        If ``ego``, ``ado`` or ``ado_valid`` has another shape, ``ego`` is not finite,
        ``dt`` is not finite and > 0, or ``maps`` does not hold one map per scene.
    """
    e = check_poses(ego)
    a, v = check_ados(ado, ado_valid, e)
    dt = check_dt(dt)
    if maps is not None:
        check_maps(maps, e.shape[0])
    hit = _overlaps(e, a, v)  # (S, T, A)
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
    else 0.0.

    Parameters
    ----------
    ego : array, shape (S, T, 3)
        Ego poses ``[x, y, yaw]`` (m, m, rad) in the world frame, finite.
    ado : array, shape (S, T, A, 5)
        Ado boxes ``[x, y, yaw, length, width]`` (m, m, rad, m, m) on the same clock.
    ado_valid : array of bool, shape (S, T, A)
        Which ado boxes exist (only valid ones count).
    maps : sequence of Map, length S, or None
        The scene's :class:`minimanc.world.lanes.Map`, for the in-lane test of lateral
        contacts.
    dt : float
        Time between logged steps in seconds (finite, > 0).

    Returns
    -------
    ndarray, shape (S,)
        1.0 for a scene with an at-fault collision, else 0.0.

    Raises
    ------
    ValueError
        As :func:`collision_events`.
    """
    e = check_poses(ego)
    out = np.zeros(e.shape[0])
    for ev in collision_events(e, ado, ado_valid, maps, dt):
        if ev.at_fault:
            out[ev.scene] = 1.0
    return out


# --------------------------------------------------------------------------- time-to-collision


def time_to_collision(ego: Any, ado: Any, ado_valid: Any, horizon: float = TTC_THRESHOLD,
                      dt: float = DT) -> np.ndarray:
    """Per scene and step, the time-to-collision in s; see the module docstring.

    Both boxes move on at their constant current velocity; the times tried are
    ``0, TTC_STEP, …`` up to ``horizon`` (:data:`TTC_STEP` s apart).

    Parameters
    ----------
    ego : array, shape (S, T, 3)
        Ego poses ``[x, y, yaw]`` (m, m, rad) in the world frame, finite.
    ado : array, shape (S, T, A, 5)
        Ado boxes ``[x, y, yaw, length, width]`` (m, m, rad, m, m) on the same clock.
    ado_valid : array of bool, shape (S, T, A)
        Which ado boxes exist (only valid ones count).
    horizon : float
        The longest time looked ahead in s (finite, >= 0).
    dt : float
        Time between logged steps in seconds (finite, > 0).

    Returns
    -------
    ndarray, shape (S, T)
        The time-to-collision in s; ``inf`` where none is within ``horizon``.

    Raises
    ------
    ValueError
        If ``horizon`` is not finite and >= 0, ``dt`` is not finite and > 0, or
        ``ego``, ``ado`` or ``ado_valid`` has another shape.
    """
    e = check_poses(ego)
    a, v = check_ados(ado, ado_valid, e)
    dt = check_dt(dt)
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
    """Per scene, the share of steps whose time-to-collision is ``<= threshold`` s.

    The time-to-collision is :func:`time_to_collision` with ``horizon = threshold``.

    Parameters
    ----------
    ego : array, shape (S, T, 3)
        Ego poses ``[x, y, yaw]`` (m, m, rad) in the world frame, finite.
    ado : array, shape (S, T, A, 5)
        Ado boxes ``[x, y, yaw, length, width]`` (m, m, rad, m, m) on the same clock.
    ado_valid : array of bool, shape (S, T, A)
        Which ado boxes exist (only valid ones count).
    threshold : float
        The time-to-collision bound in s (finite, >= 0).
    dt : float
        Time between logged steps in seconds (finite, > 0).

    Returns
    -------
    ndarray, shape (S,)
        The share of steps per scene, in [0, 1].

    Raises
    ------
    ValueError
        As :func:`time_to_collision` (``threshold`` is its ``horizon``).
    """
    return (time_to_collision(ego, ado, ado_valid, threshold, dt) <= threshold).mean(axis=1)
