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

Every per-scene metric returns an ``(S,)`` array; :func:`evaluate` averages
over the scenes and :func:`aggregate` turns one dict per training seed into
``mean ± std`` (population std over seeds, ``ddof = 0``; 0 for one seed).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.world.geometry import (
    DT,
    EGO_LENGTH,
    EGO_WIDTH,
    box_corners,
    boxes_overlap,
    controls_from_poses,
)

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
    "evaluate",
    "aggregate",
]

CLOSE_GAP: float = 1.0
"""Box-to-box gap (m) below which an ado counts as a close encounter."""

TABLE_METRICS: tuple[str, ...] = ("close_encounters", "max_acceleration", "ade", "goal_distance")
"""The paper's four Table I metrics, in its order."""

METRICS: tuple[str, ...] = TABLE_METRICS + ("collision_rate", "off_road_rate")
"""Every key :func:`evaluate` returns."""


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


# --------------------------------------------------------------------------- summaries


def evaluate(traj: Any, ds: Any, gap: float = CLOSE_GAP) -> dict[str, float]:
    """All metrics of one rollout, averaged over its scenes.

    ``traj`` has ``.ego`` (S, T, 3) (a :class:`minimanc.rollout.Rollout`);
    ``ds`` is the validation dataset it was rolled out on (``ego``, ``ado``,
    ``ado_valid``, ``maps``).  Keys: :data:`METRICS`; ``close_encounters``,
    ``collision_rate`` and ``off_road_rate`` in percent, the rest in m or
    m/s².
    """
    ego = _traj(traj.ego)
    human = _traj(ds.ego, "ds.ego")
    if ego.shape != human.shape:
        raise ValueError(
            f"traj.ego must have the dataset's shape {human.shape}; got {ego.shape}"
        )
    return {
        "close_encounters": 100.0 * float(close_encounters(ego, ds.ado, ds.ado_valid, gap).mean()),
        "max_acceleration": float(max_acceleration(ego).mean()),
        "ade": float(ade(ego, human).mean()),
        "goal_distance": float(goal_distance(ego, human[:, -1]).mean()),
        "collision_rate": 100.0 * float(collisions(ego, ds.ado, ds.ado_valid).mean()),
        "off_road_rate": 100.0 * float(off_road(ego, ds.maps).mean()),
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
