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

    ``q`` (steps + 1, ..., 4) and ``eta`` (steps + 1, ..., 3) include the initial
    state; ``deta`` (steps, ..., 3) is the mean angular acceleration of each step.
    """

    q: Any
    eta: Any
    deta: Any


# --------------------------------------------------------------------------- validation


def unit_tolerance(dtype: Any = np.float64) -> float:
    """Largest ``|‖q‖ − 1|`` accepted (and normalised away) where a unit quaternion is
    expected: ``float_tolerance(dtype, 4)`` (:func:`minimanc.checks.float_tolerance`),
    about 7e-15 in float64 and 3.8e-6 in float32 — a few roundings of the four
    squares, while a norm further from 1 is a bug, not rounding."""
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
    """The identity rotation ``(1, 0, 0, 0)``, broadcast to ``shape + (4,)``."""
    return xp.zeros(tuple(shape) + (4,)) + xp.asarray([1.0, 0.0, 0.0, 0.0])


def multiply(p: Any, q: Any, xp: Any = np) -> Any:
    """Quaternion (Hamilton) product ``p * q`` of eq. (3); broadcasts; not commutative.

    As rotations, ``p * q`` applies ``q`` first, then ``p``.
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
    """``q̄ = v − u`` (the inverse of a unit quaternion)."""
    return _conjugate(_check_last("q", q, 4), xp)


def _conjugate(q: Any, xp: Any) -> Any:
    w, x, y, z = _parts(q)
    return xp.stack([w, -x, -y, -z], axis=-1)


def normalize(q: Any, xp: Any = np) -> Any:
    """``q / ‖q‖`` for any non-zero ``q``; the zero quaternion raises ValueError (concrete)."""
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
    """Logarithmic map of eq. (4): ``S³ → R³``, the half-angle vector ``θ/2 · n``.

    Computed as ``atan2(‖u‖, w) u/‖u‖`` (accurate near the identity and near
    ±π, unlike ``arccos(w)``), with ``0`` at ``u = 0, w > 0``. The result has
    norm in ``[0, π]``; no sign flip is made (see the module notes). At
    ``q = −1`` the map is undefined: ValueError on concrete input.
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
    """Exponential map of eq. (6): ``R³ → S³``, ``cos‖ω‖ + sin‖ω‖ ω/‖ω‖`` (1 at ω = 0).

    Defined for every ω; inverse of :func:`log` only for ‖ω‖ < π (see the
    module notes). Uses the series ``1 − ‖ω‖²/2`` and ``1 − ‖ω‖²/6`` at ω = 0
    so the gradient there is finite (``∂q/∂ω = [0; I]``).
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
    """One step of eq. (5): ``Exp(dt/2 · η/τ) * q``, renormalised.

    ``η`` (..., 3) is the angular velocity in the world frame (rad/s); for
    constant η the result is exact: ``exp(t η / 2) * q`` after time ``t``.
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
    ``‖error‖`` lies in ``[0, π]`` and the error for ``g`` and ``−g`` agree. For
    rotations about z it equals the yaw difference wrapped into ``(−π, π]``
    (exactly at ±π both directions are equally short; the rounding of
    ``w ≈ 0`` picks one). Expressed in the world frame.
    """
    g = _unit(_check_unit("g", g), xp)
    q = _unit(_check_unit("q", q), xp)
    check_broadcast(("g", g, 1), ("q", q, 1))
    return _error(g, q, xp)


def _error(g: Any, q: Any, xp: Any) -> Any:
    return 2.0 * _log(_shortest(_multiply(g, _conjugate(q, xp), xp), xp), xp)


# --------------------------------------------------------------------------- conversions


def from_axis_angle(axis: Any, angle: Any, xp: Any = np) -> Any:
    """Rotation by ``angle`` (rad, shape ``(...)``) about ``axis`` (..., 3; normalised).

    A zero axis, or a non-finite axis or angle, raises ValueError naming it;
    the batch shapes of ``axis[..., 0]`` and ``angle`` must broadcast.
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
    """Axis × angle (..., 3) with angle in ``[0, π]``: ``2 log`` of the ``w ≥ 0`` representative."""
    q = _unit(_check_unit("q", q), xp)
    return 2.0 * _log(_shortest(q, xp), xp)


def from_rotation_vector(v: Any, xp: Any = np) -> Any:
    """Inverse of :func:`to_rotation_vector`: ``exp(v / 2)``."""
    v = _check_last("v", v, 3)
    return exp(0.5 * v, xp=xp)


def to_axis_angle(q: Any, xp: Any = np) -> tuple[Any, Any]:
    """``(axis (..., 3), angle (...))`` with angle in ``[0, π]`` (the shorter way round).

    At the identity the axis is undefined; ``(1, 0, 0)`` is returned (angle 0).
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
    """Rotation by ``psi`` (rad) about +z, counter-clockwise: ``(cos ψ/2, 0, 0, sin ψ/2)``.

    A non-finite (or non-numeric) concrete ``psi`` raises ValueError (TypeError).
    """
    psi = _check_angle("psi", psi)
    half = 0.5 * xp.asarray(psi)
    zero = xp.zeros_like(half)
    return xp.stack([xp.cos(half), zero, zero, xp.sin(half)], axis=-1)


def to_yaw(q: Any, xp: Any = np) -> Any:
    """Heading in ``(−π, π]``: the direction of the rotated x axis in the xy plane (ZYX yaw).

    ``atan2(2(wz + xy), 1 − 2(y² + z²))``; for yaw-only ``q`` it inverts :func:`from_yaw`.
    """
    q = _unit(_check_unit("q", q), xp)
    w, x, y, z = _parts(q)
    return xp.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def to_matrix(q: Any, xp: Any = np) -> Any:
    """Rotation matrix (..., 3, 3) of a unit quaternion (``R v = rotate(q, v)``)."""
    q = _unit(_check_unit("q", q), xp)
    w, x, y, z = _parts(q)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)


def rotate(q: Any, v: Any, xp: Any = np) -> Any:
    """Rotate vectors ``v`` (..., 3) by ``q``: ``q v q̄`` as ``v + 2w (u × v) + 2 u × (u × v)``."""
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

    * ``"semi_implicit"`` (default): ``η ← η + h η̇``, then ``q ← Exp(h/2 η) * q``;
    * ``"euler"``: ``q ← Exp(h/2 η) * q`` with the old η, then ``η ← η + h η̇``.

    The error is taken the shorter way round (``w ≥ 0``), so the attractor
    turns through less than π. Gains broadcast against ``(..., 1)``; they may
    be the linear DMP's. Returns ``(q_next, eta_next, deta)`` with
    ``deta = (eta_next − eta) / dt``. For yaw-only motion this is exactly the
    1-D DMP of :func:`minimanc.dmp.step` on the wrapped yaw error.

    Gains are checked as in :func:`minimanc.dmp.step` (concrete values only:
    α > 0, β ≥ 0, finite, real).  Near the goal the error is the rotation
    vector and the map linearises to the 1-D DMP's step, per axis, so
    :func:`minimanc.dmp.check_step_stability` applies unchanged: a step with
    spectral radius > 1 raises ValueError unless ``allow_unstable=True``
    (then a ``RuntimeWarning``).  ``q``, ``eta`` and ``g_q`` must broadcast.
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
    """Roll the quaternion DMP out for ``steps`` steps (see :func:`quaternion_step`).

    ``q0`` (..., 4), ``eta0`` (..., 3), goal ``g_q`` (..., 4). Names in
    ``per_step`` (from ``("g_q", "alpha", "beta")``) carry a leading time axis
    of length ``steps``. Returns a :class:`QuaternionRollout`.  Gains and the
    stability of the step are checked once, as in :func:`quaternion_step`.
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
