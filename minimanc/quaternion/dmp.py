"""Chapter 4 — the quaternion DMP (eq. 2 with learned gains, eq. 10):
``η̇ = α (β · 2 log(g_q * q̄) − η)``, ``q̇ = ½ η * q``, one step and a rollout.
See :mod:`minimanc.quaternion`."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from minimanc import dmp
from minimanc.checks import (
    check_broadcast,
    check_dt,
    check_int,
    check_leading_axis,
    is_traced,
    shape_of,
)
from minimanc.quaternion.algebra import (
    check_unit,
    check_vector,
    error_unchecked,
    integrate_unchecked,
    unit_unchecked,
)

__all__ = [
    "QuaternionRollout",
    "quaternion_rollout",
    "quaternion_step",
]


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


# --------------------------------------------------------------------------- quaternion DMP

_Q_METHODS = ("euler", "semi_implicit")


def _q_substep(q, eta, g_q, alpha, beta, h, method, xp):
    err = error_unchecked(g_q, q, xp)
    deta = alpha * (beta * err - eta)
    if method == "euler":
        return integrate_unchecked(q, eta, h, xp), eta + h * deta
    eta_new = eta + h * deta
    return integrate_unchecked(q, eta_new, h, xp), eta_new


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
    check_dt(dt)
    q = unit_unchecked(check_unit("q", q), xp)
    g_q = unit_unchecked(check_unit("g_q", g_q), xp)
    eta = check_vector("eta", eta, 3)
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
    check_dt(dt)
    per_step = tuple(per_step)
    unknown = [p for p in per_step if p not in ("g_q", "alpha", "beta")]
    if unknown:
        raise ValueError(f"per_step entries must be 'g_q', 'alpha' or 'beta', got {unknown!r}")
    q = unit_unchecked(check_unit("q0", q0), xp)
    eta = check_vector("eta0", eta0, 3)
    g_q = unit_unchecked(check_unit("g_q", g_q), xp)
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
