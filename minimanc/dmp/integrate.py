"""Chapter 3 — integrating the DMP: one step and a rollout of eq. (10), or eq. (1) with forcing.

Three integrators (:data:`~minimanc.dmp.params.METHODS`), each repeated
``substeps`` times with ``h = dt / substeps``:

* ``"euler"`` (explicit):         ``y ← y + h ẏ``,  ``ẏ ← ẏ + h a(y, ẏ)``;
* ``"semi_implicit"`` (symplectic Euler, the usual DMP update, the default):
  ``ẏ ← ẏ + h a(y, ẏ)``, then ``y ← y + h ẏ`` with the *new* velocity;
* ``"rk4"`` (classical Runge–Kutta).

:func:`step` and :func:`rollout` check the gains and the stability of the step
(:func:`~minimanc.dmp.stability.check_step_stability`) once per call.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from typing import Any, NamedTuple

import numpy as np

from minimanc.checks import (
    check_dt,
    check_finite_if_concrete,
    check_int,
    check_leading_axis,
    is_traced,
)
from minimanc.dmp.flow import flow, flow_for, force_times
from minimanc.dmp.forcing import Forcing, canonical_system, check_tau, forcing_of_time
from minimanc.dmp.params import (
    DEFAULT_METHOD,
    DEFAULT_SUBSTEPS,
    DT,
    check_gains,
    check_method,
)
from minimanc.dmp.stability import check_step_stability
from minimanc.engine import engine_of

__all__ = [
    "DMPRollout",
    "rollout",
    "step",
]


class DMPRollout(NamedTuple):
    """Result of :func:`rollout`: time is the leading axis.

    ``y`` and ``dy`` hold ``steps + 1`` states (the initial one first); ``ddy``
    holds ``steps`` mean accelerations, ``ddy[k] = (dy[k + 1] − dy[k]) / dt``.
    """

    y: Any
    dy: Any
    ddy: Any



def _warn_negative_gains(alpha: Any, beta: Any, stacklevel: int) -> bool:
    """One RuntimeWarning if some concrete α ≤ 0 or β < 0 (allowed by ``allow_unstable``)."""
    a, b = np.broadcast_arrays(np.asarray(alpha, dtype=float), np.asarray(beta, dtype=float))
    bad = (a <= 0) | (b < 0)
    if not bad.any():
        return False
    i = int(np.argmax(bad)) if bad.ndim else 0
    a_i, b_i = float(a.flat[i]), float(b.flat[i])
    zeta = f", zeta={a_i / (2.0 * np.sqrt(a_i * b_i)):.6g}" if a_i * b_i > 0 else ""
    warnings.warn(
        f"alpha={a_i!r}, beta={b_i!r}{zeta}: the continuous system of eq. (12) is unstable "
        "(alpha <= 0 or beta < 0), the DMP runs away from the goal. Running it anyway "
        "(allow_unstable=True).", RuntimeWarning, stacklevel=stacklevel + 1)
    return True



def _step(y, dy, goal, alpha, beta, dt, method, substeps, force=None, xp=np):
    """One step without checks (the callers validated their arguments once).

    ``force(t)``, if given, is the forcing acceleration at time ``t`` ∈ [0, dt]
    after the start of the step. With a concrete ``dt`` the sub-steps are one
    function with a hand-written VJP (:func:`~minimanc.dmp.flow.flow_for`) of the
    engine of ``xp``; a traced ``dt`` or another namespace takes them one by one.
    """
    forces = None
    if force is not None:
        forces = [force(t) for t in force_times(dt / substeps, method, substeps)]
    eng = None if is_traced(dt) else engine_of(xp)
    if eng is None:
        return flow(y, dy, goal, alpha, beta, forces, dt, method, substeps)
    if isinstance(dt, np.ndarray):  # a static argument must be hashable
        dt = dt[()]
    return flow_for(eng)(y, dy, goal, alpha, beta, forces, dt, method, substeps)


def _check_call(method, substeps, dt, alpha, beta, allow_unstable, stacklevel):
    """Shared argument checks of :func:`step` and :func:`rollout` (once per call)."""
    method = check_method(method)
    substeps = check_int("substeps", substeps, 1)
    check_dt(dt)
    if not isinstance(allow_unstable, bool):
        raise TypeError(f"allow_unstable must be True or False, got "
                        f"allow_unstable={allow_unstable!r}")
    if check_gains(alpha, beta, allow_negative=allow_unstable) and not is_traced(dt):
        if not (allow_unstable and _warn_negative_gains(alpha, beta, stacklevel + 1)):
            check_step_stability(alpha, beta, dt, method, substeps, allow_unstable,
                                 stacklevel=stacklevel + 1)
    return method, substeps


def step(
    y: Any,
    dy: Any,
    goal: Any,
    alpha: Any,
    beta: Any,
    dt: Any = DT,
    method: str = DEFAULT_METHOD,
    substeps: int = DEFAULT_SUBSTEPS,
    xp: Any = np,
    allow_unstable: bool = False,
) -> tuple[Any, Any, Any]:
    """Advance eq. (10) by ``dt`` seconds; goal and gains are held over the step.

    All array arguments broadcast (position of any dimension in the last axis,
    any batch in front; scalar gains or gains of shape ``(..., 1)`` per sample).
    Returns ``(y_next, dy_next, ddy)`` with ``ddy = (dy_next − dy) / dt`` the
    mean acceleration over the step (for ``"euler"`` with one sub-step this is
    eq. (10) evaluated at the start). Only arithmetic is used, so any engine's
    arrays pass through.

    Concrete gains are checked (:func:`check_gains`: α > 0, β ≥ 0, finite,
    real) and so is the step itself (:func:`check_step_stability`): a step
    whose spectral radius exceeds 1 — the error would grow every step, e.g.
    α = 25, β = α/4, ``dt = 0.5`` with one explicit Euler sub-step (ρ = 5.25)
    — raises ValueError stating ρ and the stable range of α, unless
    ``allow_unstable=True``, which runs it with a ``RuntimeWarning``; the same
    opt-in lets α ≤ 0 or β < 0 run (the paper's ζ < 0, eq. 13), with a
    ``RuntimeWarning`` that the continuous system is unstable.  Traced
    gains (inside ``grad``/``jit``) are not checked.

    On an engine's namespace ``xp`` the sub-steps are one differentiable
    function with a hand-written VJP (:func:`~minimanc.dmp.flow.flow_for`).

    Parameters
    ----------
    y, dy : array, shape (..., D)
        Position and velocity (per s) at the start of the step.
    goal : array, shape (..., D) or broadcastable
        The goal ``g`` of eq. (10).
    alpha, beta : array or float
        Gains in 1/s, scalars or shape ``(..., 1)`` per sample.
    dt : float
        Step length in seconds (concrete, or traced inside ``grad``).
    method : str
        Integrator, one of :data:`~minimanc.dmp.params.METHODS`.
    substeps : int
        Sub-steps per step (an integer >= 1).
    xp : module
        Array namespace (``numpy``, ``eng.xp``).
    allow_unstable : bool
        Run an unstable step (or negative gains) with a ``RuntimeWarning``.

    Returns
    -------
    y_next, dy_next, ddy : array, shape broadcast of the inputs
        Position, velocity (per s) after the step and the mean acceleration (per s²).

    Raises
    ------
    ValueError
        If concrete gains, ``y``, ``dy`` or ``goal`` are not finite, α ≤ 0 or β < 0 (without
        ``allow_unstable``), ``dt`` is not a finite scalar > 0, ``method`` is unknown,
        ``substeps`` is not an integer >= 1, or the step is unstable (ρ > 1) without
        ``allow_unstable`` (naming the parameter and its value).
    TypeError
        If ``allow_unstable`` is not a bool or a gain is not a real number or array.
    """
    method, substeps = _check_call(method, substeps, dt, alpha, beta, allow_unstable, 2)
    for name, value in (("y", y), ("dy", dy), ("goal", goal)):
        check_finite_if_concrete(name, value)
    return _step(y, dy, goal, alpha, beta, dt, method, substeps, xp=xp)


def rollout(
    y0: Any,
    dy0: Any,
    goal: Any,
    alpha: Any,
    beta: Any,
    dt: Any = DT,
    steps: int = 40,
    method: str = DEFAULT_METHOD,
    substeps: int = DEFAULT_SUBSTEPS,
    per_step: Iterable[str] = (),
    xp: Any = np,
    allow_unstable: bool = False,
    forcing: Forcing | None = None,
    tau: float = 1.0,
    gate: bool = True,
) -> DMPRollout:
    """Integrate eq. (10) — or, with ``forcing``, eq. (1) — for ``steps`` steps of ``dt`` seconds.

    ``y0``, ``dy0``: shape ``(..., D)`` for any dimension ``D`` and batch ``...``.
    ``goal``, ``alpha``, ``beta`` broadcast against them (gains are usually a
    scalar or ``(..., 1)``). Names listed in ``per_step`` (a subset of
    ``("goal", "alpha", "beta")``) carry a leading time axis of length
    ``steps`` instead: a moving goal, or gains that a network changes every
    step. Returns a :class:`DMPRollout` with ``y``, ``dy`` of shape
    ``(steps + 1, ...)`` and ``ddy`` of shape ``(steps, ...)``.
    Differentiable: ``xp`` provides ``stack``.

    The gains and the stability of the step are checked once for the whole
    rollout, as in :func:`step` (with per-step gains, every step's own matrix
    must have spectral radius ≤ 1); ``allow_unstable=True`` runs an unstable
    rollout with one ``RuntimeWarning`` (negative gains too: the paper's ζ < 0).

    **The full DMP of eq. (1).** With a :class:`Forcing` ``forcing``, the
    acceleration becomes that of ``τ ÿ = α (β (g − y) − ẏ) + f(x)`` with the
    forcing term of :func:`forcing_term` (scaled by ``g − y0``, ``y0`` the
    start of the rollout) and the phase ``x(t) = exp(−α_x t / τ)`` of the
    canonical system ``τ ẋ = −α_x x`` (the paper's eq. 1 prints ``+α_x x``),
    advanced exactly in the same time loop (:func:`canonical_system`); inside a
    step each sub-step evaluates ``f`` at its own phase (RK4 also at the
    midpoint and the end). The step is eq. (10)'s with the gain ``α / τ`` plus
    the input ``f / τ``: its stability check is that of gains ``(α / τ, β)``,
    and ``tau = 1`` with zero weights gives the point attractor exactly.
    ``tau`` is a concrete positive scalar (the gains may be traced).
    ``gate=False`` drops the factor ``x`` from ``f`` (a forcing term that never
    fades: the rollout settles away from the goal). Without ``forcing``, ``tau``
    still scales eq. (1)'s left-hand side.

    Parameters
    ----------
    y0, dy0 : array, shape (..., D)
        Initial position and velocity.
    goal, alpha, beta : array or float
        As in :func:`step`; with a leading axis of length ``steps`` when named
        in ``per_step``.
    dt : float
        Step length in seconds.
    steps : int
        Number of steps (an integer >= 0).
    method, substeps, xp, allow_unstable
        As in :func:`step`.
    per_step : iterable of str
        Subset of ``("goal", "alpha", "beta")`` that change every step.
    forcing : Forcing or None
        The forcing term of eq. (1) (:func:`fit_forcing_weights`).
    tau : float
        Temporal scaling τ of eq. (1) (concrete, > 0).
    gate : bool
        Multiply the forcing term by the phase ``x``.

    Returns
    -------
    DMPRollout
        ``y``, ``dy`` (per s) of shape ``(steps + 1, ...)``, ``ddy`` (per s²) of shape
        ``(steps, ...)``.

    Raises
    ------
    ValueError
        As :func:`step`; also if ``steps`` is not an integer >= 0, ``per_step`` names
        something else than ``"goal"``, ``"alpha"``, ``"beta"``, a per-step argument's
        leading axis is not of length ``steps``, ``tau`` is not a finite scalar > 0, or
        ``forcing`` is given with a traced ``dt``.
    TypeError
        If ``gate`` or ``allow_unstable`` is not a bool, or ``forcing`` is neither a
        :class:`Forcing` nor None.
    """
    method = check_method(method)
    substeps = check_int("substeps", substeps, 1)
    steps = check_int("steps", steps, 0)
    check_dt(dt)
    per_step = tuple(per_step)
    unknown = [p for p in per_step if p not in ("goal", "alpha", "beta")]
    if unknown:
        raise ValueError(f"per_step entries must be 'goal', 'alpha' or 'beta', got {unknown!r}")
    for name, value in (("y0", y0), ("dy0", dy0), ("goal", goal)):
        check_finite_if_concrete(name, value)
    why = "is listed in per_step"
    goal = check_leading_axis("goal", goal, steps, why) if "goal" in per_step else goal
    alpha = check_leading_axis("alpha", alpha, steps, why) if "alpha" in per_step else alpha
    beta = check_leading_axis("beta", beta, steps, why) if "beta" in per_step else beta
    tau = check_tau(tau)
    if not isinstance(gate, bool):
        raise TypeError(f"gate must be True or False, got gate={gate!r}")
    if forcing is not None and not isinstance(forcing, Forcing):
        raise TypeError(f"forcing must be a dmp.Forcing or None, got forcing={forcing!r}")
    if forcing is not None and is_traced(dt):
        raise ValueError("forcing needs a concrete dt (the phase is computed before the loop)")
    alpha_eff = alpha if tau == 1.0 else alpha / tau
    _check_call(method, substeps, dt, alpha_eff, beta, allow_unstable, 2)

    y, dy = xp.asarray(y0), xp.asarray(dy0)
    if forcing is not None:
        x_steps = canonical_system(steps, dt, forcing.alpha_x, tau)
    ys, dys, ddys = [y], [dy], []
    for k in range(steps):
        g_k = goal[k] if "goal" in per_step else goal
        a_k = alpha_eff[k] if "alpha" in per_step else alpha_eff
        b_k = beta[k] if "beta" in per_step else beta
        force = None
        if forcing is not None:
            force = forcing_of_time(forcing, float(x_steps[k]), tau, g_k, y0, gate, xp)
        y, dy, ddy = _step(y, dy, g_k, a_k, b_k, dt, method, substeps, force, xp)
        ys.append(y)
        dys.append(dy)
        ddys.append(ddy)
    if steps == 0:
        shape = np.broadcast_shapes(tuple(ys[0].shape), tuple(dys[0].shape))
        return DMPRollout(xp.stack([ys[0] + xp.zeros(shape)]),
                          xp.stack([dys[0] + xp.zeros(shape)]),
                          xp.zeros((0,) + tuple(shape)))
    # the initial state may broadcast to a larger batch (e.g. one start, many goals)
    full = tuple(ys[-1].shape)
    ys[0] = ys[0] + xp.zeros(full)
    dys[0] = dys[0] + xp.zeros(full)
    ddy_all = xp.stack(ddys)
    return DMPRollout(xp.stack(ys), xp.stack(dys), ddy_all)
