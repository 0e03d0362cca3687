"""Chapter 4 — unit quaternions: product, log and exp maps, integration, and the quaternion DMP.

Quaternions are arrays ``(..., 4)`` in the order ``(w, x, y, z)`` — the paper's
``q = [v, u]`` with scalar part ``v = w`` and vector part ``u = (x, y, z)``
(scipy's ``Rotation`` is scalar-*last*; convert with ``q[..., [1, 2, 3, 0]]``).
Every function broadcasts over leading axes and is differentiable through the
``xp`` keyword on both engines (only indexing, arithmetic and the namespace
listed in CONTRIBUTING.md are used; no in-place assignment).

Paper equations (``../shared/paper/manc.tex``):

* eq. (3) :func:`multiply` — ``(v1 + u1)(v2 + u2) = (v1 v2 − u1·u2) + (v1 u2 + v2 u1 + u1 × u2)``;
* eq. (4) :func:`log` — ``arccos(v) u/‖u‖``, computed as ``atan2(‖u‖, v) u/‖u‖``;
* eq. (5) :func:`integrate` — ``q(t + δt) = Exp(δt/2 · η/τ) * q(t)``;
* eq. (6) :func:`exp` — ``cos‖ω‖ + sin‖ω‖ ω/‖ω‖``;
* eq. (2) with learned gains, eq. (10) — :func:`quaternion_step`,
  :func:`quaternion_rollout`: ``η̇ = α (β · 2 log(g_q * q̄) − η)``, ``q̇ = ½ η * q``.

Conventions and edge cases (decided here, tested in ``tests/test_quaternion.py``):

* **Half angles.** ``log`` returns the *half*-angle vector: a rotation by θ
  about ``n`` is ``q = (cos θ/2, sin θ/2 n)`` and ``log q = θ/2 n``. The
  rotation vector (axis × angle) is ``2 log q`` (:func:`to_rotation_vector`).
* **Active rotations, world-frame composition.** ``rotate(q, v) = q v q̄``;
  ``multiply(p, q)`` applies q first, then p; ``integrate`` left-multiplies, so
  η is the angular velocity in the world frame.
* **Unit norm.** Functions that need a unit quaternion (``log``, ``rotate``,
  ``to_matrix``, ``to_axis_angle``, ``to_yaw``, ``integrate``,
  ``orientation_error``, the DMP) normalise their input. On concrete NumPy
  input they first check it: the zero quaternion raises ``ValueError``, and so
  does a norm further than :func:`unit_tolerance` of its dtype from 1 (a sign
  of a bug, not of rounding: a few float64 or float32 roundings are accepted).
  On traced values (inside ``grad``/``jit``) no check is possible; they are
  normalised silently. ``multiply``, ``conjugate`` and ``exp`` are
  plain algebra and accept any input.
* **Sign.** ``q`` and ``−q`` are the same rotation. ``log`` is eq. (4) as
  written — angle ``atan2(‖u‖, w) ∈ [0, π]`` — so ``exp(log q) = q`` exactly
  (not merely up to sign). The choice of the shorter way round is made where it
  matters: :func:`orientation_error`, :func:`to_axis_angle` and
  :func:`to_rotation_vector` use the representative with ``w ≥ 0``.
* **log at q = −1** (a 2π rotation in the double cover) is undefined: every
  ``π n`` is a valid answer. Concrete input raises ``ValueError``; on traced
  values the result is the meaningless ``≈ 0``. :func:`orientation_error` never
  hits it (it flips to ``w ≥ 0`` first).
* **exp of ‖ω‖ ≥ π** is computed as written and is a valid unit quaternion, but
  the map is no longer one-to-one: ``log(exp ω) = ω − 2π ω/‖ω‖`` for
  π < ‖ω‖ < 2π, and ``‖ω‖ = π`` gives −1. Only ‖ω‖ < π round-trips.
* **Gradients at the identity.** ``log`` at ``u = 0`` and ``exp`` at ``ω = 0``
  use a series branch selected with the double-``where`` trick (the unused
  branch is fed a safe value), so gradients are finite and exact there: the
  Jacobian of ``log`` at the identity is ``I`` and that of ``exp`` is ``[0; I]``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from minimanc import dmp
from minimanc.checks import (
    check_broadcast,
    check_finite,
    check_int,
    check_leading_axis,
    check_positive,
    check_real,
    float_tolerance,
    is_traced,
    shape_of,
    value_dtype,
)

__all__ = [
    "QuaternionRollout",
    "conjugate",
    "exp",
    "from_axis_angle",
    "from_rotation_vector",
    "from_yaw",
    "identity",
    "integrate",
    "log",
    "multiply",
    "normalize",
    "orientation_error",
    "quaternion_rollout",
    "quaternion_step",
    "rotate",
    "to_axis_angle",
    "to_matrix",
    "to_rotation_vector",
    "to_yaw",
    "unit_tolerance",
]

_SMALL2: float = 1e-24
"""``‖u‖²`` (or ``‖ω‖²``) below which the series branch is used (‖u‖ < 1e-12).
The dropped series terms are of relative size ``‖u‖²/3 < 1e-24``."""


class QuaternionRollout(NamedTuple):
    """Result of :func:`quaternion_rollout`; time is the leading axis.

    Attributes
    ----------
    q : array, shape (steps + 1, ..., 4)
        Orientations, the initial one included.
    eta : array, shape (steps + 1, ..., 3)
        Angular velocities η (world frame, rad/s), the initial one included.
    deta : array, shape (steps, ..., 3)
        Mean angular acceleration ``(η_{k+1} − η_k) / dt`` of each step.
    """

    q: Any
    eta: Any
    deta: Any


# --------------------------------------------------------------------------- validation


def unit_tolerance(dtype: Any = np.float64) -> float:
    """Largest ``|‖q‖ − 1|`` accepted where a unit quaternion is expected.

    It is ``float_tolerance(dtype, 4)`` (:func:`minimanc.checks.float_tolerance`):
    a few roundings of the four squares, ≈ 7e-15 in float64 and ≈ 3.8e-6 in
    float32.  A norm further from 1 is a bug, not rounding; a norm within it is
    normalised away.

    Parameters
    ----------
    dtype : NumPy dtype, optional (default: float64)
        Precision of the quaternion's values.

    Returns
    -------
    tol : float
        The accepted deviation of the norm from 1.
    """
    return float_tolerance(dtype, 4)


def _check_last(name: str, x: Any, size: int) -> Any:
    if not is_traced(x):
        x = check_real(name, x)
    shape = shape_of(x)
    if len(shape) == 0 or shape[-1] != size:
        raise ValueError(f"{name} must have shape (..., {size}), got {name} with shape {shape}")
    if not is_traced(x) and not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite, got {name}={x!r}")
    return x


def _check_angle(name: str, x: Any) -> Any:
    """A concrete angle (any shape) must be real and finite; traced passes."""
    if not is_traced(x):
        x = check_finite(name, x)
    return x


def _check_unit(name: str, q: Any) -> Any:
    """Validate a (concrete) unit quaternion; return it as an array."""
    tol = unit_tolerance(value_dtype(q)) if not is_traced(q) else 0.0
    q = _check_last(name, q, 4)
    if not is_traced(q):
        n = np.linalg.norm(q, axis=-1)
        if np.any(n == 0):
            raise ValueError(f"{name} contains the zero quaternion, which is not a rotation")
        off = np.abs(n - 1.0)
        if np.any(off > tol):
            worst = float(n.flat[np.argmax(off)]) if n.ndim else float(n)
            raise ValueError(
                f"{name} must be a unit quaternion (|norm - 1| <= unit_tolerance = {tol:.3g} "
                f"for its dtype), got norm {worst!r}; call quaternion.normalize first if "
                "that is intended"
            )
    return q


def _norm(v: Any, xp: Any) -> Any:
    return xp.sqrt(xp.sum(v * v, axis=-1))


def _unit(q: Any, xp: Any) -> Any:
    """q / ‖q‖ without checks (the caller validated concrete input)."""
    return q / xp.expand_dims(_norm(q, xp), -1)


def _parts(q: Any) -> tuple[Any, Any, Any, Any]:
    return q[..., 0], q[..., 1], q[..., 2], q[..., 3]


# --------------------------------------------------------------------------- algebra


def identity(shape: tuple[int, ...] = (), xp: Any = np) -> Any:
    """The identity rotation ``(1, 0, 0, 0)``, broadcast to ``shape + (4,)``.

    Parameters
    ----------
    shape : tuple of int, optional (default: ())
        Batch shape.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    q : array, shape (*shape, 4)
        Identity quaternions.
    """
    return xp.zeros(tuple(shape) + (4,)) + xp.asarray([1.0, 0.0, 0.0, 0.0])


def multiply(p: Any, q: Any, xp: Any = np) -> Any:
    """Quaternion (Hamilton) product ``p * q`` of eq. (3); not commutative.

    ``(v1 + u1)(v2 + u2) = (v1 v2 − u1·u2) + (v1 u2 + v2 u1 + u1 × u2)``.  As
    rotations, ``p * q`` applies ``q`` first, then ``p``.  Plain algebra: the
    inputs need not be unit quaternions.

    Parameters
    ----------
    p : array-like, shape (..., 4)
        Left factor ``(w, x, y, z)``.
    q : array-like, shape (..., 4)
        Right factor; its batch shape broadcasts with ``p``'s.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    pq : array, shape (..., 4)
        The product, over the broadcast batch shape.

    Raises
    ------
    TypeError
        If ``p`` or ``q`` is not real numbers (concrete input).
    ValueError
        If the last axis is not 4, an entry is not finite, or the batch shapes
        do not broadcast.
    """
    p, q = _check_last("p", p, 4), _check_last("q", q, 4)
    check_broadcast(("p", p, 1), ("q", q, 1))
    return _multiply(p, q, xp)


def _multiply(p: Any, q: Any, xp: Any) -> Any:
    w1, x1, y1, z1 = _parts(p)
    w2, x2, y2, z2 = _parts(q)
    return xp.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,  # v1 v2 − u1·u2
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,  # v1 u2 + v2 u1 + u1 × u2
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def conjugate(q: Any, xp: Any = np) -> Any:
    """Conjugate ``q̄ = v − u``: the inverse of a unit quaternion (eq. 2).

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Quaternions ``(w, x, y, z)``, not necessarily unit.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    q_bar : array, shape (..., 4)
        ``(w, −x, −y, −z)``.

    Raises
    ------
    TypeError
        If ``q`` is not real numbers (concrete input).
    ValueError
        If the last axis is not 4 or an entry is not finite.
    """
    return _conjugate(_check_last("q", q, 4), xp)


def _conjugate(q: Any, xp: Any) -> Any:
    w, x, y, z = _parts(q)
    return xp.stack([w, -x, -y, -z], axis=-1)


def normalize(q: Any, xp: Any = np) -> Any:
    """``q / ‖q‖`` for any non-zero ``q``.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Non-zero quaternions.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    q_unit : array, shape (..., 4)
        Unit quaternions.

    Raises
    ------
    TypeError
        If ``q`` is not real numbers (concrete input).
    ValueError
        If the last axis is not 4, an entry is not finite, or (concrete input)
        ``q`` contains the zero quaternion.
    """
    q = _check_last("q", q, 4)
    if not is_traced(q) and np.any(np.linalg.norm(q, axis=-1) == 0):
        raise ValueError("q contains the zero quaternion, which cannot be normalised")
    return _unit(q, xp)


# --------------------------------------------------------------------------- log and exp


def _log(q: Any, xp: Any) -> Any:
    """Eq. (4) without checks. Scale-invariant: log(c q) = log(q) for c > 0."""
    w = q[..., 0]
    u = q[..., 1:]
    n2 = xp.sum(u * u, axis=-1)
    small = n2 < _SMALL2
    s = xp.sqrt(xp.where(small, 1.0, n2))  # safe ‖u‖: never 0, so sqrt' is finite
    w_safe = xp.where(small, w, 1.0)  # the series branch divides by w; the other never does
    # angle / ‖u‖, with its series 1/w (1 − ‖u‖²/(3w²) + …) at the identity
    factor = xp.where(small, 1.0 / w_safe, xp.arctan2(s, w) / s)
    return xp.expand_dims(factor, -1) * u


def log(q: Any, xp: Any = np) -> Any:
    """Logarithmic map of eq. (4), ``S³ → R³``: the half-angle vector ``θ/2 · n``.

    Computed as ``atan2(‖u‖, w) u/‖u‖`` (accurate near the identity and near
    ±π, unlike ``arccos(w)``), with ``0`` at ``u = 0, w > 0``.  No sign flip is
    made (see the module notes); the Jacobian at the identity is ``I``.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Unit quaternions (normalised after the check of :func:`unit_tolerance`).
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    omega : array, shape (..., 3)
        ``log q``, of norm in ``[0, π]``.

    Raises
    ------
    TypeError
        If ``q`` is not real numbers (concrete input).
    ValueError
        If the last axis is not 4, an entry is not finite, ``q`` is zero or not
        of unit norm, or (concrete input) ``q = −1``, where the map is undefined.
    """
    q = _check_unit("q", q)
    if not is_traced(q):
        at_minus_one = (np.sum(q[..., 1:] ** 2, axis=-1) < _SMALL2) & (q[..., 0] < 0)
        if np.any(at_minus_one):
            raise ValueError(
                "log is undefined at q = -1 (u = 0, w < 0): every pi*n is a logarithm. "
                "Use orientation_error / to_rotation_vector, which take the w >= 0 "
                "representative (the same rotation)."
            )
    return _log(q, xp)


def exp(omega: Any, xp: Any = np) -> Any:
    """Exponential map of eq. (6), ``R³ → S³``: ``cos‖ω‖ + sin‖ω‖ ω/‖ω‖`` (1 at ω = 0).

    Defined for every ω; the inverse of :func:`log` only for ‖ω‖ < π (see the
    module notes).  The series ``1 − ‖ω‖²/2`` and ``1 − ‖ω‖²/6`` are used at
    ω = 0, so the gradient there is finite: ``∂q/∂ω = [0; I]``.

    Parameters
    ----------
    omega : array-like, shape (..., 3)
        Half-angle vectors.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    q : array, shape (..., 4)
        Unit quaternions ``Exp(ω)``.

    Raises
    ------
    TypeError
        If ``omega`` is not real numbers (concrete input).
    ValueError
        If the last axis is not 3 or an entry is not finite.
    """
    return _exp(_check_last("omega", omega, 3), xp)


def _exp(omega: Any, xp: Any) -> Any:
    n2 = xp.sum(omega * omega, axis=-1)
    small = n2 < _SMALL2
    theta = xp.sqrt(xp.where(small, 1.0, n2))
    w = xp.where(small, 1.0 - 0.5 * n2, xp.cos(theta))
    sinc = xp.where(small, 1.0 - n2 / 6.0, xp.sin(theta) / theta)
    return xp.concatenate([xp.expand_dims(w, -1), xp.expand_dims(sinc, -1) * omega], axis=-1)


# --------------------------------------------------------------------------- integration, error


def integrate(q: Any, eta: Any, dt: Any, tau: Any = 1.0, xp: Any = np) -> Any:
    """One step of eq. (5): ``q(t + dt) = Exp(dt/2 · η/τ) * q(t)``, renormalised.

    For constant η the result is exact: ``exp(t η / 2) * q`` after time ``t``.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Unit quaternions at time ``t``.
    eta : array-like, shape (..., 3)
        Angular velocity η in the world frame (rad/s); broadcasts with ``q``.
    dt : float or array-like
        Time step δt > 0 (s).
    tau : float or array-like, optional (default: 1.0)
        Time constant τ > 0.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    q_next : array, shape (..., 4)
        Unit quaternions at time ``t + dt``.

    Raises
    ------
    TypeError
        If an argument is not real numbers (concrete input).
    ValueError
        If ``q`` is not a unit quaternion, a shape is wrong, the batch shapes do
        not broadcast, a value is not finite, or ``dt`` or ``tau`` is not > 0.
    """
    q = _check_unit("q", q)
    eta = _check_last("eta", eta, 3)
    check_broadcast(("q", q, 1), ("eta", eta, 1))
    for name, value in (("dt", dt), ("tau", tau)):
        if not is_traced(value):
            check_positive(name, value)
    return _integrate(_unit(q, xp), eta, dt / tau, xp)


def _integrate(q: Any, eta: Any, h: Any, xp: Any) -> Any:
    return _unit(_multiply(_exp((0.5 * h) * eta, xp), q, xp), xp)


def _shortest(r: Any, xp: Any) -> Any:
    """The representative of ±r with w ≥ 0 (w = 0 is left as is)."""
    sign = xp.where(r[..., 0] < 0, -1.0, 1.0)
    return r * xp.expand_dims(sign, -1)


def orientation_error(g: Any, q: Any, xp: Any = np) -> Any:
    """Rotation vector from ``q`` to ``g``: ``2 log(g * q̄)`` (eq. 2), the shorter way round.

    ``g * q̄`` is flipped to its ``w ≥ 0`` representative first, so the angle
    ``‖error‖`` lies in ``[0, π]`` and the errors for ``g`` and ``−g`` agree.  For
    rotations about z it equals the yaw difference wrapped into ``(−π, π]``
    (exactly at ±π both directions are equally short; the rounding of
    ``w ≈ 0`` picks one).

    Parameters
    ----------
    g : array-like, shape (..., 4)
        Goal orientations (unit quaternions).
    q : array-like, shape (..., 4)
        Current orientations (unit quaternions); broadcasts with ``g``.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    error : array, shape (..., 3)
        Axis × angle in the world frame, angle in ``[0, π]``.

    Raises
    ------
    TypeError
        If ``g`` or ``q`` is not real numbers (concrete input).
    ValueError
        If either is not a unit quaternion of shape ``(..., 4)``, is not finite,
        or the batch shapes do not broadcast.
    """
    g = _unit(_check_unit("g", g), xp)
    q = _unit(_check_unit("q", q), xp)
    check_broadcast(("g", g, 1), ("q", q, 1))
    return _error(g, q, xp)


def _error(g: Any, q: Any, xp: Any) -> Any:
    return 2.0 * _log(_shortest(_multiply(g, _conjugate(q, xp), xp), xp), xp)


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
    axis = _check_last("axis", axis, 3)
    angle = _check_angle("angle", angle)
    check_broadcast(("axis", axis, 1), ("angle", angle, 0))
    if not is_traced(axis) and np.any(np.linalg.norm(axis, axis=-1) == 0):
        raise ValueError("axis contains a zero vector, which has no direction")
    n = axis / xp.expand_dims(_norm(axis, xp), -1)
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
    q = _unit(_check_unit("q", q), xp)
    return 2.0 * _log(_shortest(q, xp), xp)


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
    v = _check_last("v", v, 3)
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
    small = n2 < _SMALL2
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
    psi = _check_angle("psi", psi)
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
    q = _unit(_check_unit("q", q), xp)
    w, x, y, z = _parts(q)
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
    q = _unit(_check_unit("q", q), xp)
    w, x, y, z = _parts(q)
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
    q = _unit(_check_unit("q", q), xp)
    v = _check_last("v", v, 3)
    check_broadcast(("q", q, 1), ("v", v, 1))
    w = xp.expand_dims(q[..., 0], -1)
    u = q[..., 1:]
    t = 2.0 * _cross(u, v, xp)
    return v + w * t + _cross(u, t, xp)


def _cross(a: Any, b: Any, xp: Any) -> Any:
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return xp.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


# --------------------------------------------------------------------------- quaternion DMP

_Q_METHODS = ("euler", "semi_implicit")


def _q_substep(q, eta, g_q, alpha, beta, h, method, xp):
    err = _error(g_q, q, xp)
    deta = alpha * (beta * err - eta)
    if method == "euler":
        return _integrate(q, eta, h, xp), eta + h * deta
    eta_new = eta + h * deta
    return _integrate(q, eta_new, h, xp), eta_new


def _check_q_method(method: Any) -> str:
    if not isinstance(method, str) or method not in _Q_METHODS:
        raise ValueError(f"method must be one of {_Q_METHODS} for the quaternion DMP, "
                         f"got method={method!r}")
    return method


def quaternion_step(
    q: Any,
    eta: Any,
    g_q: Any,
    alpha: Any,
    beta: Any,
    dt: Any = dmp.DT,
    method: str = dmp.DEFAULT_METHOD,
    substeps: int = dmp.DEFAULT_SUBSTEPS,
    xp: Any = np,
    allow_unstable: bool = False,
) -> tuple[Any, Any, Any]:
    """Advance the quaternion DMP (eq. 2 without forcing, gains as in eq. 10) by ``dt``.

    ``η̇ = α (β · orientation_error(g_q, q) − η)`` and ``q̇ = ½ η * q``, with
    ``h = dt / substeps`` and per sub-step

    * ``"semi_implicit"``: ``η ← η + h η̇``, then ``q ← Exp(h/2 η) * q`` (eq. 5);
    * ``"euler"``: ``q ← Exp(h/2 η) * q`` with the old η, then ``η ← η + h η̇``.

    The error is taken the shorter way round (``w ≥ 0``), so the attractor turns
    through less than π.  For yaw-only motion this is exactly the 1-D DMP of
    :func:`minimanc.dmp.step` on the wrapped yaw error.  Near the goal the error
    is the rotation vector and the map linearises to the 1-D DMP's step, per
    axis, so :func:`minimanc.dmp.check_step_stability` applies unchanged.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Current orientations (unit quaternions).
    eta : array-like, shape (..., 3)
        Current angular velocities η (world frame, rad/s).
    g_q : array-like, shape (..., 4)
        Goal orientations (unit quaternions); ``q``, ``eta`` and ``g_q`` broadcast.
    alpha : float or array-like, shape (..., 1)
        Gain α > 0; the linear DMP's gains may be passed as they are.
    beta : float or array-like, shape (..., 1)
        Gain β ≥ 0.
    dt : float, optional (default: ``dmp.DT``)
        Step length (s).
    method : {"semi_implicit", "euler"}, optional (default: ``dmp.DEFAULT_METHOD``)
        Integration scheme of each sub-step.
    substeps : int, optional (default: ``dmp.DEFAULT_SUBSTEPS``)
        Sub-steps per step, ≥ 1.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.
    allow_unstable : bool, optional (default: False)
        Accept a step whose linearisation has spectral radius > 1 (with a
        ``RuntimeWarning``) instead of raising.

    Returns
    -------
    q_next : array, shape (..., 4)
        Orientations after ``dt``.
    eta_next : array, shape (..., 3)
        Angular velocities after ``dt``.
    deta : array, shape (..., 3)
        Mean angular acceleration ``(eta_next − eta) / dt``.

    Raises
    ------
    TypeError
        If a gain or quaternion is not real numbers, or ``allow_unstable`` is
        not a bool.
    ValueError
        If ``method`` is unknown, ``substeps`` is not an integer ≥ 1, ``dt`` is
        invalid, a quaternion is not of unit norm, a shape is wrong, the batch
        shapes do not broadcast, the gains are out of range (concrete values:
        α > 0, β ≥ 0, finite), or the step is unstable and ``allow_unstable``
        is False.
    """
    method = _check_q_method(method)
    substeps = check_int("substeps", substeps, 1)
    dmp.check_dt(dt)
    q = _unit(_check_unit("q", q), xp)
    g_q = _unit(_check_unit("g_q", g_q), xp)
    eta = _check_last("eta", eta, 3)
    check_broadcast(("q", q, 1), ("eta", eta, 1), ("g_q", g_q, 1))
    _check_q_gains(alpha, beta, dt, method, substeps, allow_unstable)
    return _q_step(q, eta, g_q, alpha, beta, dt, method, substeps, xp)


def _check_q_gains(alpha, beta, dt, method, substeps, allow_unstable, stacklevel=3):
    if not isinstance(allow_unstable, bool):
        raise TypeError(f"allow_unstable must be True or False, got "
                        f"allow_unstable={allow_unstable!r}")
    if dmp.check_gains(alpha, beta) and not is_traced(dt):
        dmp.check_step_stability(alpha, beta, dt, method, substeps, allow_unstable,
                                 stacklevel=stacklevel)


def _q_step(q, eta, g_q, alpha, beta, dt, method, substeps, xp):
    h = dt / substeps
    q_next, eta_next = q, eta
    for _ in range(substeps):
        q_next, eta_next = _q_substep(q_next, eta_next, g_q, alpha, beta, h, method, xp)
    return q_next, eta_next, (eta_next - eta) / dt


def quaternion_rollout(
    q0: Any,
    eta0: Any,
    g_q: Any,
    alpha: Any,
    beta: Any,
    dt: Any = dmp.DT,
    steps: int = 40,
    method: str = dmp.DEFAULT_METHOD,
    substeps: int = dmp.DEFAULT_SUBSTEPS,
    per_step: tuple[str, ...] = (),
    xp: Any = np,
    allow_unstable: bool = False,
) -> QuaternionRollout:
    """Roll the quaternion DMP (eqs. 2, 5, 10) out for ``steps`` steps of :func:`quaternion_step`.

    Gains and the stability of the step are checked once, as in
    :func:`quaternion_step`.

    Parameters
    ----------
    q0 : array-like, shape (..., 4)
        Initial orientations (unit quaternions).
    eta0 : array-like, shape (..., 3)
        Initial angular velocities (world frame, rad/s).
    g_q : array-like, shape (..., 4), or (steps, ..., 4) if listed in ``per_step``
        Goal orientations (unit quaternions).
    alpha : float or array-like, shape (..., 1), or (steps, ..., 1) if in ``per_step``
        Gain α > 0.
    beta : float or array-like, shape (..., 1), or (steps, ..., 1) if in ``per_step``
        Gain β ≥ 0.
    dt : float, optional (default: ``dmp.DT``)
        Step length (s).
    steps : int, optional (default: 40)
        Number of steps, ≥ 0.
    method : {"semi_implicit", "euler"}, optional (default: ``dmp.DEFAULT_METHOD``)
        Integration scheme of each sub-step.
    substeps : int, optional (default: ``dmp.DEFAULT_SUBSTEPS``)
        Sub-steps per step, ≥ 1.
    per_step : tuple of str, optional (default: ())
        Names among ``("g_q", "alpha", "beta")`` that carry a leading time axis
        of length ``steps``.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.
    allow_unstable : bool, optional (default: False)
        Accept an unstable step (with a ``RuntimeWarning``) instead of raising.

    Returns
    -------
    rollout : QuaternionRollout
        ``q`` (steps + 1, ..., 4), ``eta`` (steps + 1, ..., 3) and ``deta``
        (steps, ..., 3).

    Raises
    ------
    TypeError
        If a gain or quaternion is not real numbers, or ``allow_unstable`` is
        not a bool.
    ValueError
        If ``per_step`` names anything else, an argument listed in it has no
        leading axis of length ``steps``, ``steps`` or ``substeps`` is not an
        integer in range, or for any reason :func:`quaternion_step` raises.
    """
    method = _check_q_method(method)
    substeps = check_int("substeps", substeps, 1)
    steps = check_int("steps", steps, 0)
    dmp.check_dt(dt)
    per_step = tuple(per_step)
    unknown = [p for p in per_step if p not in ("g_q", "alpha", "beta")]
    if unknown:
        raise ValueError(f"per_step entries must be 'g_q', 'alpha' or 'beta', got {unknown!r}")
    q = _unit(_check_unit("q0", q0), xp)
    eta = _check_last("eta0", eta0, 3)
    g_q = _unit(_check_unit("g_q", g_q), xp)
    why = "is listed in per_step"
    if "g_q" in per_step:
        g_q = check_leading_axis("g_q", g_q, steps, why)
    alpha = check_leading_axis("alpha", alpha, steps, why) if "alpha" in per_step else alpha
    beta = check_leading_axis("beta", beta, steps, why) if "beta" in per_step else beta
    check_broadcast(("q0", q, 1), ("eta0", eta, 1),
                    ("g_q", g_q[0] if "g_q" in per_step and steps else g_q, 1))
    _check_q_gains(alpha, beta, dt, method, substeps, allow_unstable)
    qs, etas, detas = [q], [eta], []
    for k in range(steps):
        g_k = g_q[k] if "g_q" in per_step else g_q
        a_k = alpha[k] if "alpha" in per_step else alpha
        b_k = beta[k] if "beta" in per_step else beta
        q, eta, deta = _q_step(q, eta, g_k, a_k, b_k, dt, method, substeps, xp)
        qs.append(q)
        etas.append(eta)
        detas.append(deta)
    if steps == 0:
        return QuaternionRollout(xp.stack(qs), xp.stack(etas), xp.zeros((0,) + shape_of(eta)))
    qs[0] = qs[0] + xp.zeros(shape_of(qs[-1]))
    etas[0] = etas[0] + xp.zeros(shape_of(etas[-1]))
    return QuaternionRollout(xp.stack(qs), xp.stack(etas), xp.stack(detas))
