"""Chapter 4 — unit quaternions: validation, product (eq. 3), log and exp (eqs. 4, 6),
integration (eq. 5) and the orientation error; the ``*_unchecked`` forms skip the checks
of concrete input (callers that validated it use them). See :mod:`minimanc.quaternion`."""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.checks import (
    check_broadcast,
    check_finite,
    check_positive,
    check_real,
    float_tolerance,
    is_traced,
    shape_of,
    value_dtype,
)

__all__ = [
    "SMALL_SQUARED",
    "check_angle",
    "check_unit",
    "check_vector",
    "components",
    "conjugate",
    "conjugate_unchecked",
    "error_unchecked",
    "exp",
    "exp_unchecked",
    "identity",
    "integrate",
    "integrate_unchecked",
    "log",
    "log_unchecked",
    "multiply",
    "multiply_unchecked",
    "normalize",
    "orientation_error",
    "shortest",
    "unit_tolerance",
    "unit_unchecked",
    "vector_norm",
]

SMALL_SQUARED: float = 1e-24
"""``‖u‖²`` (or ``‖ω‖²``) below which the series branch is used (‖u‖ < 1e-12).
The dropped series terms are of relative size ``‖u‖²/3 < 1e-24``."""


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


def check_vector(name: str, x: Any, size: int) -> Any:
    if not is_traced(x):
        x = check_real(name, x)
    shape = shape_of(x)
    if len(shape) == 0 or shape[-1] != size:
        raise ValueError(f"{name} must have shape (..., {size}), got {name} with shape {shape}")
    if not is_traced(x) and not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite, got {name}={x!r}")
    return x


def check_angle(name: str, x: Any) -> Any:
    """A concrete angle (any shape) must be real and finite; traced passes."""
    if not is_traced(x):
        x = check_finite(name, x)
    return x


def check_unit(name: str, q: Any) -> Any:
    """Validate a (concrete) unit quaternion; return it as an array."""
    tol = unit_tolerance(value_dtype(q)) if not is_traced(q) else 0.0
    q = check_vector(name, q, 4)
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


def vector_norm(v: Any, xp: Any) -> Any:
    return xp.sqrt(xp.sum(v * v, axis=-1))


def unit_unchecked(q: Any, xp: Any) -> Any:
    """q / ‖q‖ without checks (the caller validated concrete input)."""
    return q / xp.expand_dims(vector_norm(q, xp), -1)


def components(q: Any) -> tuple[Any, Any, Any, Any]:
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
    p, q = check_vector("p", p, 4), check_vector("q", q, 4)
    check_broadcast(("p", p, 1), ("q", q, 1))
    return multiply_unchecked(p, q, xp)


def multiply_unchecked(p: Any, q: Any, xp: Any) -> Any:
    w1, x1, y1, z1 = components(p)
    w2, x2, y2, z2 = components(q)
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
    return conjugate_unchecked(check_vector("q", q, 4), xp)


def conjugate_unchecked(q: Any, xp: Any) -> Any:
    w, x, y, z = components(q)
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
    q = check_vector("q", q, 4)
    if not is_traced(q) and np.any(np.linalg.norm(q, axis=-1) == 0):
        raise ValueError("q contains the zero quaternion, which cannot be normalised")
    return unit_unchecked(q, xp)


# --------------------------------------------------------------------------- log and exp


def log_unchecked(q: Any, xp: Any) -> Any:
    """Eq. (4) without checks. Scale-invariant: log(c q) = log(q) for c > 0."""
    w = q[..., 0]
    u = q[..., 1:]
    n2 = xp.sum(u * u, axis=-1)
    small = n2 < SMALL_SQUARED
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
    q = check_unit("q", q)
    if not is_traced(q):
        at_minus_one = (np.sum(q[..., 1:] ** 2, axis=-1) < SMALL_SQUARED) & (q[..., 0] < 0)
        if np.any(at_minus_one):
            raise ValueError(
                "log is undefined at q = -1 (u = 0, w < 0): every pi*n is a logarithm. "
                "Use orientation_error / to_rotation_vector, which take the w >= 0 "
                "representative (the same rotation)."
            )
    return log_unchecked(q, xp)


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
    return exp_unchecked(check_vector("omega", omega, 3), xp)


def exp_unchecked(omega: Any, xp: Any) -> Any:
    n2 = xp.sum(omega * omega, axis=-1)
    small = n2 < SMALL_SQUARED
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
    q = check_unit("q", q)
    eta = check_vector("eta", eta, 3)
    check_broadcast(("q", q, 1), ("eta", eta, 1))
    for name, value in (("dt", dt), ("tau", tau)):
        if not is_traced(value):
            check_positive(name, value)
    return integrate_unchecked(unit_unchecked(q, xp), eta, dt / tau, xp)


def integrate_unchecked(q: Any, eta: Any, h: Any, xp: Any) -> Any:
    return unit_unchecked(multiply_unchecked(exp_unchecked((0.5 * h) * eta, xp), q, xp), xp)


def shortest(r: Any, xp: Any) -> Any:
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
    g = unit_unchecked(check_unit("g", g), xp)
    q = unit_unchecked(check_unit("q", q), xp)
    check_broadcast(("g", g, 1), ("q", q, 1))
    return error_unchecked(g, q, xp)


def error_unchecked(g: Any, q: Any, xp: Any) -> Any:
    r = multiply_unchecked(g, conjugate_unchecked(q, xp), xp)
    return 2.0 * log_unchecked(shortest(r, xp), xp)


