"""Chapter 9 — closed-loop metrics of the ego's own trajectory: comfort, similarity, progress.

Poses ``(S, T, 3) = [x, y, yaw]`` at ``DT = 0.5`` s (:mod:`minimanc.metrics.boxes`);
every per-scene metric returns an ``(S,)`` array.

* **Max |acceleration|** (:func:`max_acceleration`, comfort, a Table I metric): the
  largest magnitude over a scene of the *total* planar acceleration
  ``sqrt(a_lon² + a_lat²)`` with ``a_lon[t] = (v[t+1] − v[t]) / DT`` (speed
  differences) and ``a_lat[t] = v[t] · ω[t]`` (centripetal), where
  ``v, ω`` are the unicycle controls that move pose ``t`` to ``t+1``
  (:func:`minimanc.world.geometry.controls_from_poses`).  ``kind =
  "longitudinal"`` gives ``max |a_lon|`` alone.  m/s².
* **ADE** (:func:`ade`, the paper's "human driving similarity", a Table I metric): the
  mean over the ``T`` steps of the Euclidean distance between the policy's and the
  logged human's ego positions (same start pose, synchronised time).  m.
  :func:`along_cross_track` splits each step's displacement into its
  component along the human's heading (ahead > 0: speed or timing) and
  across it (left > 0: steering), ``along² + cross² = ‖p − p_human‖²``.
* **Goal distance** (:func:`goal_distance`, a Table I metric): the distance between
  the ego's position at the last step and the goal, the final human position.  m.
* **off-road** (:func:`off_road`, an honesty check the paper does not report): the
  ego's centre leaves the drivable area of the scene's map at some step (scene-level
  0/1).
* **route progress** (:func:`route_progress`, beyond the paper, as nuPlan's
  closed-loop metrics): the distance the ego advanced along the scene's route
  (:func:`minimanc.world.maps.project_to_route`, first to last step) divided by the
  human's; 1 when the human advanced less than :data:`PROGRESS_MIN` = 1 m (nothing to
  compare with). Above 1: further than the human.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc.checks import check_dt
from minimanc.metrics.boxes import check_ego_and_human, check_maps, check_poses
from minimanc.world.geometry import DT, controls_from_poses
from minimanc.world.maps import project_to_route

__all__ = [
    "PROGRESS_MIN",
    "max_acceleration",
    "ade",
    "along_cross_track",
    "goal_distance",
    "off_road",
    "route_progress",
]

PROGRESS_MIN: float = 1.0
"""Human progress (m) below which :func:`route_progress` is 1 (nothing to compare with)."""


def max_acceleration(ego: Any, dt: float = DT, kind: str = "total") -> np.ndarray:
    """Per scene, the maximum acceleration magnitude (m/s²).

    From the unicycle controls ``v[t], ω[t]`` that move pose ``t`` to
    ``t + 1`` (``T − 1`` of them):  ``a_lon[t] = (v[t+1] − v[t]) / dt`` for
    ``t = 0 … T−3`` and ``a_lat[t] = v[t] ω[t]``.  ``kind="total"`` returns
    ``max_t sqrt(a_lon[t]² + a_lat[t]²)``, ``kind="longitudinal"``
    returns ``max_t |a_lon[t]|``.  Scenes with fewer than 3 poses give 0.

    Parameters
    ----------
    ego : array, shape (S, T, 3)
        Ego poses ``[x, y, yaw]`` (m, m, rad), finite.
    dt : float
        Time between poses in seconds (finite, > 0).
    kind : str
        ``"total"`` or ``"longitudinal"``.

    Returns
    -------
    ndarray, shape (S,)
        The maximum acceleration per scene in m/s².

    Raises
    ------
    ValueError
        If ``kind`` is neither ``"total"`` nor ``"longitudinal"``, ``dt`` is not finite and
        > 0, or ``ego`` is not finite poses of shape ``(S, T, 3)``.
    """
    e = check_poses(ego)
    dt = check_dt(dt)
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

    Only the positions enter.

    Parameters
    ----------
    ego, human : array, shape (S, T, 3)
        The policy's and the logged human's poses ``[x, y, yaw]`` (m, m, rad) on the same
        clock.

    Returns
    -------
    ndarray, shape (S,)
        The ADE per scene in m.

    Raises
    ------
    ValueError
        If a pose array is not finite of shape ``(S, T, 3)``, or the two shapes differ.
    """
    e, h = check_ego_and_human(ego, human)
    return np.linalg.norm(e[..., :2] - h[..., :2], axis=-1).mean(axis=1)


def along_cross_track(ego: Any, human: Any) -> tuple[np.ndarray, np.ndarray]:
    """Per scene and step, the displacement from the human split along and across its heading (m).

    With ``d[t] = p[t] − p_human[t]`` (the policy's position minus the logged
    human's at the same time) and the human's heading ``ψ[t]``:
    ``along[t] = d[t] · (cos ψ[t], sin ψ[t])`` (positive when the policy is
    ahead of the human) and ``cross[t] = d[t] · (−sin ψ[t], cos ψ[t])``
    (positive when it is to the human's left).  A rotation, so
    ``along² + cross² = ‖d‖²`` and ``mean_t sqrt(along² + cross²)`` is
    :func:`ade`.  The policy's yaw does not enter.

    Parameters
    ----------
    ego, human : array, shape (S, T, 3)
        The policy's and the logged human's poses ``[x, y, yaw]`` (m, m, rad) on the same
        clock.

    Returns
    -------
    along, cross : ndarray, shape (S, T)
        The components of ``d[t]`` along and across the human's heading, in m.

    Raises
    ------
    ValueError
        If a pose array is not finite of shape ``(S, T, 3)``, or the two shapes differ.
    """
    e, h = check_ego_and_human(ego, human)
    d = e[..., :2] - h[..., :2]
    c, s = np.cos(h[..., 2]), np.sin(h[..., 2])
    along = d[..., 0] * c + d[..., 1] * s
    cross = -d[..., 0] * s + d[..., 1] * c
    return along, cross


def goal_distance(ego: Any, goal: Any) -> np.ndarray:
    """Per scene, ``‖p[T−1] − g‖``: last ego position to the goal position (m).

    Parameters
    ----------
    ego : array, shape (S, T, 3)
        Ego poses ``[x, y, yaw]`` (m, m, rad), finite.
    goal : array, shape (S, 2) or (S, 3)
        The goal per scene, ``[x, y]`` or a pose ``[x, y, yaw]`` (its yaw is ignored).

    Returns
    -------
    ndarray, shape (S,)
        The goal distance per scene in m.

    Raises
    ------
    ValueError
        If ``goal`` has not shape ``(S, 2)`` or ``(S, 3)``, or ``ego`` is not finite poses
        of shape ``(S, T, 3)``.
    """
    e = check_poses(ego)
    g = np.asarray(goal, dtype=np.float64)
    if g.ndim != 2 or g.shape[0] != e.shape[0] or g.shape[1] not in (2, 3):
        raise ValueError(f"goal must have shape ({e.shape[0]}, 2 or 3); got shape {g.shape}")
    return np.linalg.norm(e[:, -1, :2] - g[:, :2], axis=-1)


def off_road(ego: Any, maps: Sequence[Any]) -> np.ndarray:
    """Per scene, 1.0 if the ego centre leaves the map's drivable area at some step. ``(S,)``.

    ``maps[s].is_drivable(points (N, 2)) -> bool (N,)`` decides (the
    :class:`minimanc.world.lanes.Map`; pedestrian crossings count as drivable).

    Parameters
    ----------
    ego : array, shape (S, T, 3)
        Ego poses ``[x, y, yaw]`` (m, m, rad), finite.
    maps : sequence of Map, length S
        The map of each scene.

    Returns
    -------
    ndarray, shape (S,)
        1.0 where the ego left the drivable area, else 0.0.

    Raises
    ------
    ValueError
        If ``ego`` is not finite poses of shape ``(S, T, 3)`` or ``maps`` does not hold
        one map per scene.
    """
    e = check_poses(ego)
    check_maps(maps, e.shape[0])
    out = np.zeros(e.shape[0])
    for s, m in enumerate(maps):
        out[s] = float(not np.all(m.is_drivable(e[s, :, :2])))
    return out


def route_progress(ego: Any, human: Any, maps: Sequence[Any]) -> np.ndarray:
    """Per scene, the ego's progress along the route over the human's (module docstring).

    Progress is measured by projecting the first and last poses onto the route
    (:func:`minimanc.world.maps.project_to_route`); a human progress below
    :data:`PROGRESS_MIN` gives 1.

    Parameters
    ----------
    ego, human : array, shape (S, T, 3)
        The policy's and the logged human's poses ``[x, y, yaw]`` (m, m, rad).
    maps : sequence of Map, length S
        The scene's :class:`minimanc.world.lanes.Map` (its route).

    Returns
    -------
    ndarray, shape (S,)
        The ratio of the ego's to the human's progress along the route (dimensionless).

    Raises
    ------
    ValueError
        If a pose array is not finite of shape ``(S, T, 3)``, the two shapes differ, or
        ``maps`` does not hold one map per scene.
    """
    e, h = check_ego_and_human(ego, human)
    check_maps(maps, e.shape[0])
    out = np.ones(e.shape[0])
    for k, m in enumerate(maps):
        ends = np.stack([e[k, 0], e[k, -1], h[k, 0], h[k, -1]])
        s, _ = project_to_route(m, ends[:, :2], ends[:, 2])
        human_ds = s[3] - s[2]
        if human_ds >= PROGRESS_MIN:
            out[k] = (s[1] - s[0]) / human_ds
    return out
