"""Chapter 7 — frames, kinematics and polylines of the driving world.

Conventions used by the whole ``minimanc.world`` package:

* **World frame**: x east, y north (metres); yaw measured counter-clockwise
  from +x (radians), wrapped to (-pi, pi].
* **Ego frame**: origin at the ego's centre, +x forward, +y to the ego's left.
  ``to_ego_frame`` maps world points into it; ``goal_in_ego_frame`` maps a
  whole pose (position and yaw).
* **Kinematics**: the paper's environment moves the ego as a unicycle with
  controls ``[speed (m/s), yaw rate (rad/s)]`` integrated by explicit Euler
  at ``DT = 0.5`` s (nuScenes' 2 Hz)::

      x' = x + v cos(yaw) dt,  y' = y + v sin(yaw) dt,  yaw' = yaw + w dt

  (the position uses the *old* yaw). Logged human controls reproduce the
  logged trajectory exactly under this rule.

Polylines are ``(N, 2)`` float arrays; helpers below give their arc length,
headings, resampling, interpolation at arc lengths and projection of query
points (nearest point on the segments, not just on the vertices).
"""

from __future__ import annotations

import numpy as np

from minimanc.dmp.params import DT as DT  # the control period (chapter 3) is the logs' step

EGO_LENGTH = 4.727
"""Length of the ego box (m), as in the authors' environment."""
EGO_WIDTH = 1.907
"""Width of the ego box (m), as in the authors' environment."""


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap angles to (-pi, pi]."""
    a = np.asarray(a, dtype=np.float64)
    w = np.mod(a + np.pi, 2.0 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


def _check_last(arr: np.ndarray, n: int, name: str) -> np.ndarray:
    arr = np.asarray(arr)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise ValueError(f"{name} must have last dimension {n}, got shape {arr.shape}")
    return arr


def to_ego_frame(points_world: np.ndarray, ego_pose: np.ndarray) -> np.ndarray:
    """Express world points ``(..., 2)`` in the frame of ``ego_pose = [x, y, yaw]``.

    ``p_ego = R(-yaw) (p - [x, y])``: +x is the ego's forward direction, +y its
    left. ``ego_pose`` may also be batched ``(..., 3)`` if it broadcasts against
    the points' leading dimensions.
    """
    p = _check_last(points_world, 2, "points_world").astype(np.float64)
    e = _check_last(ego_pose, 3, "ego_pose").astype(np.float64)
    c, s = np.cos(e[..., 2]), np.sin(e[..., 2])
    dx = p[..., 0] - e[..., 0]
    dy = p[..., 1] - e[..., 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


def from_ego_frame(points_ego: np.ndarray, ego_pose: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_ego_frame`: ego-frame points ``(..., 2)`` to world."""
    p = _check_last(points_ego, 2, "points_ego").astype(np.float64)
    e = _check_last(ego_pose, 3, "ego_pose").astype(np.float64)
    c, s = np.cos(e[..., 2]), np.sin(e[..., 2])
    x = e[..., 0] + c * p[..., 0] - s * p[..., 1]
    y = e[..., 1] + s * p[..., 0] + c * p[..., 1]
    return np.stack([x, y], axis=-1)


def goal_in_ego_frame(goal_pose_world: np.ndarray, ego_pose: np.ndarray) -> np.ndarray:
    """Re-express a world pose ``(..., 3)`` in the ego frame(s) ``(..., 3)``.

    Returns ``[x, y, yaw]`` with the position from :func:`to_ego_frame` and the
    relative yaw ``wrap(yaw_goal - yaw_ego)``. This is the goal input the models
    receive at every step (final human pose, seen from the current ego pose).
    """
    g = _check_last(goal_pose_world, 3, "goal_pose_world").astype(np.float64)
    e = _check_last(ego_pose, 3, "ego_pose").astype(np.float64)
    xy = to_ego_frame(g[..., :2], e)
    yaw = wrap_angle(g[..., 2] - e[..., 2])
    return np.concatenate([xy, yaw[..., None]], axis=-1)


def unicycle_step(pose: np.ndarray, controls: np.ndarray, dt: float = DT) -> np.ndarray:
    """One explicit-Euler step of the unicycle: ``pose (..., 3)``, ``controls (..., 2)``.

    ``controls = [speed, yaw_rate]``; the position moves along the *current*
    yaw, then the yaw turns by ``yaw_rate * dt`` (wrapped to (-pi, pi]). The
    result has the dtype of ``pose`` promoted with ``controls``.
    """
    p = _check_last(pose, 3, "pose")
    u = _check_last(controls, 2, "controls")
    if not np.isfinite(dt) or dt <= 0:
        raise ValueError(f"dt must be a positive finite number, got {dt!r}")
    dtype = np.result_type(p.dtype, u.dtype, np.float32)
    p = p.astype(dtype)
    u = u.astype(dtype)
    v, w = u[..., 0], u[..., 1]
    yaw = p[..., 2]
    x = p[..., 0] + v * np.cos(yaw) * dtype.type(dt)
    y = p[..., 1] + v * np.sin(yaw) * dtype.type(dt)
    yaw_new = wrap_angle(yaw + w * dtype.type(dt)).astype(dtype)
    return np.stack([x, y, yaw_new], axis=-1)


def controls_from_poses(poses: np.ndarray, dt: float = DT) -> np.ndarray:
    """Controls that move ``poses[t]`` to ``poses[t+1]`` under :func:`unicycle_step`.

    Exact when the displacement lies along the heading (as for logged human
    trajectories); otherwise the speed is the projection on the heading.
    Returns ``(T-1, 2)``.
    """
    p = _check_last(poses, 3, "poses").astype(np.float64)
    d = p[1:, :2] - p[:-1, :2]
    c, s = np.cos(p[:-1, 2]), np.sin(p[:-1, 2])
    v = (d[:, 0] * c + d[:, 1] * s) / dt
    w = wrap_angle(p[1:, 2] - p[:-1, 2]) / dt
    return np.stack([v, w], axis=-1)


# --------------------------------------------------------------------------- polylines


def arclength(points: np.ndarray) -> np.ndarray:
    """Cumulative arc length ``(N,)`` of a polyline ``(N, 2)`` (starts at 0)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)])


def headings(points: np.ndarray) -> np.ndarray:
    """Heading of a polyline at each vertex (central differences, one-sided at the ends)."""
    d = np.gradient(points, axis=0) if len(points) > 2 else np.diff(points, axis=0)[[0, -1]]
    return np.arctan2(d[:, 1], d[:, 0])


def resample(points: np.ndarray, spacing: float = 1.0) -> np.ndarray:
    """Resample a polyline at (almost) uniform arc-length ``spacing``, keeping both ends."""
    s = arclength(points)
    n = max(int(np.ceil(s[-1] / spacing)), 1)
    sq = np.linspace(0.0, s[-1], n + 1)
    return np.stack([np.interp(sq, s, points[:, 0]), np.interp(sq, s, points[:, 1])], axis=1)


def interp_polyline(
    points: np.ndarray, s: np.ndarray, heads: np.ndarray, s_query: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray]:
    """Position ``(..., 2)`` and heading ``(...)`` at arc lengths ``s_query``.

    Beyond the ends the polyline is extended straight along its end headings.
    """
    sq = np.asarray(s_query, dtype=np.float64)
    x = np.interp(sq, s, points[:, 0])
    y = np.interp(sq, s, points[:, 1])
    # unwrap headings for interpolation, then wrap back
    hu = np.unwrap(heads)
    h = np.interp(sq, s, hu)
    before = np.minimum(sq - s[0], 0.0)
    after = np.maximum(sq - s[-1], 0.0)
    x = x + before * np.cos(hu[0]) + after * np.cos(hu[-1])
    y = y + before * np.sin(hu[0]) + after * np.sin(hu[-1])
    return np.stack([x, y], axis=-1), wrap_angle(h)


def project_to_polyline(
    points: np.ndarray, s: np.ndarray, query: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Project query points ``(M, 2)`` onto a polyline: arc length and signed lateral offset.

    Uses the nearest point on the *segments*. Lateral offset is positive to
    the left of the polyline's direction. Returns ``(s_proj (M,), lat (M,))``.
    """
    q = np.atleast_2d(np.asarray(query, dtype=np.float64))
    a = points[:-1]
    d = points[1:] - a
    L2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
    rel = q[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("mij,ij->mi", rel, d) / L2, 0.0, 1.0)
    foot = a[None] + t[..., None] * d[None]
    dist2 = np.sum((q[:, None, :] - foot) ** 2, axis=-1)
    k = np.argmin(dist2, axis=1)
    rows = np.arange(len(q))
    seglen = np.sqrt(L2[k])
    sp = s[k] + t[rows, k] * seglen
    cross = d[k, 0] * rel[rows, k, 1] - d[k, 1] * rel[rows, k, 0]
    lat = np.sign(cross) * np.sqrt(dist2[rows, k])
    return sp, lat


# --------------------------------------------------------------------------- boxes


def box_corners(boxes: np.ndarray) -> np.ndarray:
    """Corners ``(..., 4, 2)`` of oriented boxes ``(..., 5) = [x, y, yaw, length, width]``."""
    b = _check_last(boxes, 5, "boxes").astype(np.float64)
    c, s = np.cos(b[..., 2]), np.sin(b[..., 2])
    hl, hw = b[..., 3] / 2, b[..., 4] / 2
    sx = np.array([1.0, 1.0, -1.0, -1.0])
    sy = np.array([1.0, -1.0, -1.0, 1.0])
    lx = sx * hl[..., None]
    ly = sy * hw[..., None]
    x = b[..., 0, None] + c[..., None] * lx - s[..., None] * ly
    y = b[..., 1, None] + s[..., None] * lx + c[..., None] * ly
    return np.stack([x, y], axis=-1)


def boxes_overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Separating-axis test between oriented boxes ``a (..., 5)`` and ``b (..., 5)`` (broadcast).

    Returns a boolean array: True where the two rectangles intersect.
    """
    ca = box_corners(a)
    cb = box_corners(b)
    ca, cb = np.broadcast_arrays(ca, cb)
    ya = np.asarray(a)[..., 2]
    yb = np.asarray(b)[..., 2]
    ya, yb = np.broadcast_arrays(ya, yb)
    overlap = np.ones(ya.shape, dtype=bool)
    for yaw in (ya, yb):
        for ang in (yaw, yaw + np.pi / 2):
            ax = np.stack([np.cos(ang), np.sin(ang)], axis=-1)[..., None, :]
            pa = np.sum(ca * ax, axis=-1)
            pb = np.sum(cb * ax, axis=-1)
            sep = (pa.max(-1) < pb.min(-1)) | (pb.max(-1) < pa.min(-1))
            overlap &= ~sep
    return overlap
