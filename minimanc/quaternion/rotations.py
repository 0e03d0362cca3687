"""Chapter 4 — conversions of unit quaternions: axis–angle, rotation vector, yaw, rotation
matrix, and rotating vectors. See :mod:`minimanc.quaternion`."""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.checks import (
    check_broadcast,
    is_traced,
)
from minimanc.quaternion.algebra import (
    SMALL_SQUARED,
    check_angle,
    check_unit,
    check_vector,
    components,
    exp,
    log_unchecked,
    shortest,
    unit_unchecked,
    vector_norm,
)

__all__ = [
    "from_axis_angle",
    "from_rotation_vector",
    "from_yaw",
    "rotate",
    "to_axis_angle",
    "to_matrix",
    "to_rotation_vector",
    "to_yaw",
]

# --------------------------------------------------------------------------- conversions


def from_axis_angle(axis: Any, angle: Any, xp: Any = np) -> Any:
    """Rotation by ``angle`` about ``axis``: ``(cos θ/2, sin θ/2 · n)`` with ``n = axis/‖axis‖``.

    Parameters
    ----------
    axis : array-like, shape (..., 3)
        Rotation axes, any non-zero length (normalised here).
    angle : float or array-like, shape (...)
        Angles θ (rad), counter-clockwise about ``axis``; the batch shapes of
        ``axis[..., 0]`` and ``angle`` broadcast.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    q : array, shape (..., 4)
        Unit quaternions.

    Raises
    ------
    TypeError
        If ``axis`` or ``angle`` is not real numbers (concrete input).
    ValueError
        If ``axis`` is not of shape ``(..., 3)``, contains a zero vector, a value
        is not finite, or the batch shapes do not broadcast.
    """
    axis = check_vector("axis", axis, 3)
    angle = check_angle("angle", angle)
    check_broadcast(("axis", axis, 1), ("angle", angle, 0))
    if not is_traced(axis) and np.any(np.linalg.norm(axis, axis=-1) == 0):
        raise ValueError("axis contains a zero vector, which has no direction")
    n = axis / xp.expand_dims(vector_norm(axis, xp), -1)
    half = 0.5 * xp.asarray(angle)
    return xp.concatenate([xp.expand_dims(xp.cos(half), -1),
                           xp.expand_dims(xp.sin(half), -1) * n], axis=-1)


def to_rotation_vector(q: Any, xp: Any = np) -> Any:
    """Axis × angle, angle in ``[0, π]``: ``2 log`` of the ``w ≥ 0`` representative.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Unit quaternions.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    v : array, shape (..., 3)
        Rotation vectors (the rotation by ``‖v‖`` about ``v/‖v‖``).

    Raises
    ------
    TypeError
        If ``q`` is not real numbers (concrete input).
    ValueError
        If ``q`` is not a unit quaternion of shape ``(..., 4)`` or is not finite.
    """
    q = unit_unchecked(check_unit("q", q), xp)
    return 2.0 * log_unchecked(shortest(q, xp), xp)


def from_rotation_vector(v: Any, xp: Any = np) -> Any:
    """Inverse of :func:`to_rotation_vector`: ``exp(v / 2)`` (eq. 6).

    Parameters
    ----------
    v : array-like, shape (..., 3)
        Rotation vectors (axis × angle, rad).
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    q : array, shape (..., 4)
        Unit quaternions.

    Raises
    ------
    TypeError
        If ``v`` is not real numbers (concrete input).
    ValueError
        If the last axis is not 3 or an entry is not finite.
    """
    v = check_vector("v", v, 3)
    return exp(0.5 * v, xp=xp)


def to_axis_angle(q: Any, xp: Any = np) -> tuple[Any, Any]:
    """Axis and angle of a rotation, the shorter way round (angle in ``[0, π]``).

    At the identity the axis is undefined; ``(1, 0, 0)`` is returned with angle 0.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Unit quaternions.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    axis : array, shape (..., 3)
        Unit rotation axes.
    angle : array, shape (...)
        Angles in ``[0, π]`` (rad).

    Raises
    ------
    TypeError
        If ``q`` is not real numbers (concrete input).
    ValueError
        If ``q`` is not a unit quaternion of shape ``(..., 4)`` or is not finite.
    """
    v = to_rotation_vector(q, xp=xp)
    n2 = xp.sum(v * v, axis=-1)
    small = n2 < SMALL_SQUARED
    angle = xp.where(small, 0.0, xp.sqrt(xp.where(small, 1.0, n2)))
    safe = xp.where(small, 1.0, angle)
    x_axis = xp.asarray([1.0, 0.0, 0.0])
    axis = xp.where(xp.expand_dims(small, -1), x_axis, v / xp.expand_dims(safe, -1))
    return axis, angle


def from_yaw(psi: Any, xp: Any = np) -> Any:
    """Rotation by ``psi`` about +z, counter-clockwise: ``(cos ψ/2, 0, 0, sin ψ/2)``.

    Parameters
    ----------
    psi : float or array-like, shape (...)
        Yaw angles ψ (rad).
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    q : array, shape (..., 4)
        Unit quaternions.

    Raises
    ------
    TypeError
        If ``psi`` is not real numbers (concrete input).
    ValueError
        If ``psi`` is not finite (concrete input).
    """
    psi = check_angle("psi", psi)
    half = 0.5 * xp.asarray(psi)
    zero = xp.zeros_like(half)
    return xp.stack([xp.cos(half), zero, zero, xp.sin(half)], axis=-1)


def to_yaw(q: Any, xp: Any = np) -> Any:
    """Heading: the direction of the rotated x axis in the xy plane (ZYX yaw).

    ``atan2(2(wz + xy), 1 − 2(y² + z²))``; for yaw-only ``q`` it inverts
    :func:`from_yaw`.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Unit quaternions.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    psi : array, shape (...)
        Yaw angles in ``(−π, π]`` (rad).

    Raises
    ------
    TypeError
        If ``q`` is not real numbers (concrete input).
    ValueError
        If ``q`` is not a unit quaternion of shape ``(..., 4)`` or is not finite.
    """
    q = unit_unchecked(check_unit("q", q), xp)
    w, x, y, z = components(q)
    return xp.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def to_matrix(q: Any, xp: Any = np) -> Any:
    """Rotation matrix of a unit quaternion: ``R v = rotate(q, v)``.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Unit quaternions.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    R : array, shape (..., 3, 3)
        Orthogonal matrices with determinant 1.

    Raises
    ------
    TypeError
        If ``q`` is not real numbers (concrete input).
    ValueError
        If ``q`` is not a unit quaternion of shape ``(..., 4)`` or is not finite.
    """
    q = unit_unchecked(check_unit("q", q), xp)
    w, x, y, z = components(q)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)


def rotate(q: Any, v: Any, xp: Any = np) -> Any:
    """Rotate vectors by ``q`` (active): ``q v q̄``, as ``v + 2w (u × v) + 2 u × (u × v)``.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Unit quaternions.
    v : array-like, shape (..., 3)
        Vectors; the batch shape broadcasts with ``q``'s.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    v_rotated : array, shape (..., 3)
        The rotated vectors.

    Raises
    ------
    TypeError
        If ``q`` or ``v`` is not real numbers (concrete input).
    ValueError
        If ``q`` is not a unit quaternion of shape ``(..., 4)``, ``v`` is not of
        shape ``(..., 3)``, a value is not finite, or the batch shapes do not
        broadcast.
    """
    q = unit_unchecked(check_unit("q", q), xp)
    v = check_vector("v", v, 3)
    check_broadcast(("q", q, 1), ("v", v, 1))
    w = xp.expand_dims(q[..., 0], -1)
    u = q[..., 1:]
    t = 2.0 * _cross(u, v, xp)
    return v + w * t + _cross(u, t, xp)


def _cross(a: Any, b: Any, xp: Any) -> Any:
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return xp.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


