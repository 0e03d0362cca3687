"""Chapter 9 — closed-loop metrics: the checks of their inputs and the box geometry.

Trajectories are ego poses ``(S, T, 3) = [x, y, yaw]`` in the world frame at the
log's rate (``DT = 0.5`` s), one row per validation scene (:func:`check_poses`);
ados are boxes ``(S, T, A, 5) = [x, y, yaw, length, width]`` on the same clock with
a validity mask ``(S, T, A)`` (:func:`check_ados`). The ego's box is
4.727 m × 1.907 m (:data:`~minimanc.world.geometry.EGO_LENGTH` ×
:data:`~minimanc.world.geometry.EGO_WIDTH`, as in the authors' environment;
:func:`ego_boxes`). The gap between two boxes is the edge-to-edge distance between
the oriented rectangles, 0 when they overlap (:func:`box_gap`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc.world.geometry import EGO_LENGTH, EGO_WIDTH, box_corners, boxes_overlap

__all__ = [
    "check_poses",
    "check_ego_and_human",
    "check_ados",
    "check_maps",
    "ego_boxes",
    "box_gap",
    "ado_gaps",
]


# --------------------------------------------------------------------------- checks


def check_poses(ego: Any, name: str = "ego") -> np.ndarray:
    """``ego`` as finite float64 poses ``(S, T, 3) = [x, y, yaw]`` with ``T >= 1``.

    Raises ``ValueError`` naming ``name`` for another shape or a non-finite value.
    """
    arr = np.asarray(ego, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (S, T, 3) [x, y, yaw]; got shape {arr.shape}")
    if arr.shape[1] < 1:
        raise ValueError(f"{name} must have at least one step; got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite; got {int(np.sum(~np.isfinite(arr)))} bad values")
    return arr


def check_ego_and_human(ego: Any, human: Any) -> tuple[np.ndarray, np.ndarray]:
    """The policy's and the human's poses (:func:`check_poses`), which must share their shape."""
    e = check_poses(ego)
    h = check_poses(human, "human")
    if e.shape != h.shape:
        raise ValueError(f"ego and human must have the same shape; got {e.shape} and {h.shape}")
    return e, h


def check_ados(ado: Any, ado_valid: Any, ego: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ado boxes ``(S, T, A, 5)`` (float64) and their mask ``(S, T, A)`` (bool) for the
    checked poses ``ego (S, T, 3)``; ``ValueError`` naming ``ado`` or ``ado_valid``."""
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


def check_maps(maps: Sequence[Any], n_scenes: int) -> Sequence[Any]:
    """``maps``, which must hold one map per scene (``n_scenes``); ``ValueError`` otherwise."""
    if len(maps) != n_scenes:
        raise ValueError(f"maps must hold one map per scene ({n_scenes}); got {len(maps)}")
    return maps


# --------------------------------------------------------------------------- geometry


def ego_boxes(ego: Any) -> np.ndarray:
    """Ego boxes ``(..., 5) = [x, y, yaw, EGO_LENGTH, EGO_WIDTH]`` from poses ``(..., 3)``.

    Parameters
    ----------
    ego : array, shape (..., 3)
        Poses ``[x, y, yaw]`` (m, m, rad) in the world frame.

    Returns
    -------
    ndarray, shape (..., 5)
        Boxes ``[x, y, yaw, length, width]`` (m, m, rad, m, m), centred on the poses.

    Raises
    ------
    ValueError
        If the last dimension of ``ego`` is not 3 (stating its shape).
    """
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

    Parameters
    ----------
    a, b : array, shape (..., 5)
        Boxes ``[x, y, yaw, length, width]`` (m, m, rad, m, m), broadcasting against each other.

    Returns
    -------
    ndarray, shape broadcast(a, b).shape[:-1]
        The gap in m (≥ 0).
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
    """Gap ``(S, T, A)`` between the ego box and every ado box; ``inf`` where the ado is invalid.

    The ego's box is :func:`ego_boxes` of its pose; the gap is :func:`box_gap`.

    Parameters
    ----------
    ego : array, shape (S, T, 3)
        Ego poses ``[x, y, yaw]`` (m, m, rad), finite.
    ado : array, shape (S, T, A, 5)
        Ado boxes ``[x, y, yaw, length, width]`` on the same clock.
    ado_valid : array of bool, shape (S, T, A)
        Which ado boxes exist.

    Returns
    -------
    ndarray, shape (S, T, A)
        The edge-to-edge gap in m; ``inf`` where ``ado_valid`` is False.

    Raises
    ------
    ValueError
        If ``ego``, ``ado`` or ``ado_valid`` has another shape or ``ego`` is not finite
        (:func:`check_poses`, :func:`check_ados`).
    """
    e = check_poses(ego)
    a, v = check_ados(ado, ado_valid, e)
    gaps = np.full(v.shape, np.inf)
    si, ti, ki = np.nonzero(v)  # only the boxes that exist are measured
    gaps[si, ti, ki] = box_gap(ego_boxes(e[si, ti]), a[si, ti, ki])
    return gaps

