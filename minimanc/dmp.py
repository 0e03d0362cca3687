"""Chapter 3 — the DMP of eq. (1): point attractor, damping ratio, step stability, forcing term.

The paper (``../shared/paper/manc.tex``) starts from the linear DMP of eq. (1),
``τ ÿ = α(β(g − y) − ẏ) + f(x)`` with the canonical system ``τ ẋ = −α_x x``
(the paper prints ``τ ẋ = α_x x``, a sign slip: the phase must decay), drops the
forcing term ``f`` and lets a network choose the gains instead (eq. 10)::

    ÿ = α(s) (β(s) (g − y) − ẏ)

With the error ``e = y − g`` this is the second-order system of eq. (12),
``ë + α ė + αβ e = 0``, whose character is set by the damping ratio of eq. (13),
``ζ = α / (2 √(αβ))``.

The paper steps the system at the data rate, ``DT = 0.5`` s. The continuous
system is stable for every α, β > 0, but its *discrete* step need not be: the
textbook gains α = 25, β = α/4 with one explicit Euler step of 0.5 s multiply
the error by −5.25 each step. This module therefore analyses both:

* the continuous system — :func:`eigenvalues`, :func:`damping_ratio`,
  :func:`classify`;
* the discrete one-step map of each integrator — :func:`step_matrix`,
  :func:`spectral_radius`, :func:`step_stable`, :func:`max_stable_alpha`;

and integrates it — :func:`step`, :func:`rollout` — with the three integrators

* ``"euler"`` (explicit):         ``y ← y + h ẏ``,  ``ẏ ← ẏ + h a(y, ẏ)``;
* ``"semi_implicit"`` (symplectic Euler, the usual DMP update, the default):
  ``ẏ ← ẏ + h a(y, ẏ)``, then ``y ← y + h ẏ`` with the *new* velocity;
* ``"rk4"`` (classical Runge–Kutta),

each repeated ``substeps`` times with ``h = dt / substeps``.

The full DMP of eq. (1) is here too, for the chapter that builds it (MANC's
head outputs gains only): the phase of the canonical system
(:func:`canonical_system`, :func:`phase`), Gaussian basis functions spaced in
phase (:func:`basis_centres`, :func:`basis_functions`), the forcing term
``f(x) = Σ ψ_i(x) w_i / Σ ψ_i(x) · x · (g − y0)`` (:func:`forcing_term`,
:class:`Forcing`), its weights fitted to one demonstration by locally weighted
regression (:func:`fit_forcing_weights`), and :func:`rollout` with
``forcing=...``, which adds the term inside the same integrators.

Learned gains (:func:`gains_from_logits`) pass network outputs through a
sigmoid into the boxes :data:`ALPHA_RANGE` × :data:`BETA_RANGE`, chosen so that
the default integrator is stable at :data:`DT` everywhere in the box (proved in
``tests/test_dmp.py``); :func:`zeta_penalty` is the auxiliary loss the paper
suggests against ζ ≈ 0.

Differentiable functions take the array namespace as ``xp`` (plain NumPy by
default, ``engine(...).xp`` to differentiate); the analysis functions are plain
NumPy. Bad input raises ``ValueError`` naming the parameter and its value; on
traced values (inside ``grad``/``jit``) the value checks are skipped.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from typing import Any, NamedTuple

import numpy as np

from minimanc.checks import (
    check_finite,
    check_finite_if_concrete,
    check_int,
    check_leading_axis,
    check_positive,
    first_bad,
    float_tolerance,
    is_traced,
)

__all__ = [
    "ALPHA_RANGE",
    "BETA_RANGE",
    "DEFAULT_METHOD",
    "DEFAULT_SUBSTEPS",
    "DT",
    "Forcing",
    "METHODS",
    "PHASE_END",
    "Rollout",
    "acceleration",
    "basis_centres",
    "basis_functions",
    "canonical_system",
    "fit_forcing_weights",
    "forcing_term",
    "phase",
    "classify",
    "damping_ratio",
    "eigenvalues",
    "gains_from_logits",
    "logits_from_gains",
    "max_stable_alpha",
    "rollout",
    "spectral_radius",
    "step",
    "step_matrix",
    "step_stable",
    "check_dt",
    "check_gains",
    "check_step_stability",
    "zeta_penalty",
]

DT: float = 0.5
"""The package's control period in seconds (nuScenes keyframes at 2 Hz)."""

METHODS: tuple[str, ...] = ("euler", "semi_implicit", "rk4")
"""Integrator names accepted by every ``method=`` argument."""

DEFAULT_METHOD: str = "semi_implicit"
"""Integrator used by default (symplectic Euler: velocity first, then position)."""

DEFAULT_SUBSTEPS: int = 10
"""Sub-steps per step by default: at ``DT = 0.5`` the inner step is ``h = 0.05`` s."""

ALPHA_RANGE: tuple[float, float] = (0.5, 20.0)
"""Range (1/s) of the learned α. With ``DEFAULT_METHOD``, ``DEFAULT_SUBSTEPS``
and ``DT``, semi-implicit Euler is stable iff ``α < 4 / (h (2 + h β))`` (see
:func:`max_stable_alpha`); at the corner α = 20, β = 5 that bound is 35.6, so
the whole box is stable with a margin (spectral radius ≤ 0.98 per step)."""

BETA_RANGE: tuple[float, float] = (0.05, 5.0)
"""Range (1/s) of the learned β. Far from the goal ``ẏ → β (g − y)``: β is the
rate at which the position error is closed. ``ALPHA_RANGE[1] / 4`` equals
``BETA_RANGE[1]``, so the critically damped option β = α/4 stays inside it."""

CRITICAL_RTOL: float = 1e-9
"""Relative tolerance on ``|α − 4β| / α`` under which :func:`classify` calls a
system critically damped (the repeated root is not exact in floating point)."""


class Rollout(NamedTuple):
    """Result of :func:`rollout`: time is the leading axis.

    ``y`` and ``dy`` hold ``steps + 1`` states (the initial one first); ``ddy``
    holds ``steps`` mean accelerations, ``ddy[k] = (dy[k + 1] − dy[k]) / dt``.
    """

    y: Any
    dy: Any
    ddy: Any


# --------------------------------------------------------------------------- validation


def _check_method(method: Any) -> str:
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got method={method!r}")
    return method


def check_dt(dt: Any) -> None:
    """A concrete ``dt`` must be a finite scalar > 0 (ValueError naming it); traced passes."""
    if not is_traced(dt):
        arr = check_positive("dt", dt)
        if arr.ndim:
            raise ValueError(f"dt must be a scalar, got dt with shape {arr.shape}")


def check_gains(alpha: Any, beta: Any, allow_negative: bool = False) -> bool:
    """Check the gains of a step or rollout; True when both are concrete.

    Concrete gains must be real (``TypeError`` naming the argument for a
    string, ``None``, ...), finite, with ``α > 0`` and ``β ≥ 0`` (``ValueError``
    naming the argument and the first offending value): ``α ≤ 0`` removes or
    reverses the damping and ``β < 0`` makes the spring repel, and either runs
    away from the goal exponentially.  ``β = 0`` is allowed (pure damping: the
    velocity decays, the position stops where it is).  With
    ``allow_negative=True`` only reality and finiteness are checked (the
    opt-in of :func:`step` / :func:`rollout` with ``allow_unstable=True``, to
    study the paper's ζ < 0).  Traced gains are not inspected.
    """
    concrete = True
    for name, value, low in (("alpha", alpha, "> 0"), ("beta", beta, ">= 0")):
        if is_traced(value):
            concrete = False
            continue
        arr = check_finite(name, value)
        if allow_negative:
            continue
        bad = arr <= 0 if low == "> 0" else arr < 0
        if bad.any():
            raise ValueError(
                f"{name} must be {low} (otherwise the DMP runs away from the goal), "
                f"got {name}={first_bad(arr, bad)!r}; pass allow_unstable=True to run it anyway"
            )
    return concrete


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


def _maybe_scalar(arr: np.ndarray) -> Any:
    return arr.item() if arr.ndim == 0 else arr


# --------------------------------------------------------------------------- continuous system


def eigenvalues(alpha: Any, beta: Any) -> np.ndarray:
    """Roots of the characteristic polynomial of eq. (12), ``λ² + αλ + αβ = 0``.

    Accepts any finite real α, β (arrays broadcast) so that unstable
    coefficients can be studied too. Returns a complex array of shape
    ``broadcast(α, β).shape + (2,)``: ``(−α + √(α² − 4αβ))/2`` then
    ``(−α − √(α² − 4αβ))/2`` (for complex pairs, the one with positive
    imaginary part first).
    """
    a = check_finite("alpha", alpha)
    b = check_finite("beta", beta)
    a, b = np.broadcast_arrays(a, b)
    root = np.sqrt((a * a - 4.0 * a * b).astype(complex))
    return np.stack([(-a + root) / 2.0, (-a - root) / 2.0], axis=-1)


def damping_ratio(alpha: Any, beta: Any, xp: Any = np) -> Any:
    """Damping ratio of eq. (13), ``ζ = α / (2 √(αβ))`` (equal to ``½ √(α/β)`` for α, β > 0).

    Defined when ``αβ > 0``: both gains positive gives ζ > 0 (stable); both
    negative gives the paper's ζ < 0 (unstable). ``αβ ≤ 0`` raises ValueError
    (no natural frequency). Differentiable through ``xp``.
    """
    if not is_traced(alpha) and not is_traced(beta):
        a = check_finite("alpha", alpha)
        b = check_finite("beta", beta)
        ab, bb = np.broadcast_arrays(a, b)
        bad = ab * bb <= 0
        if bad.any():
            i = np.argmax(bad) if bad.ndim else 0
            raise ValueError(
                "damping_ratio needs alpha*beta > 0 (zeta is undefined otherwise), got "
                f"alpha={float(ab.flat[i])!r}, beta={float(bb.flat[i])!r}"
            )
    return alpha / (2.0 * xp.sqrt(alpha * beta))


def classify(alpha: Any, beta: Any) -> Any:
    """Character of the continuous system eq. (12) for finite real α, β.

    * ``"unstable"`` — not asymptotically stable, it does not converge to the
      goal: α ≤ 0 (no or negative damping, the paper's ζ ≤ 0) or β ≤ 0 (no or
      repelling spring);
    * otherwise by ζ of eq. (13): ``"underdamped"`` (ζ < 1, complex roots,
      overshoot), ``"critically damped"`` (ζ = 1, i.e. β = α/4),
      ``"overdamped"`` (ζ > 1, two real roots).

    **What counts as critical.** A repeated root is not exact in floating
    point, so the test is relative: critically damped iff
    ``|α − 4β| ≤ CRITICAL_RTOL · α`` (:data:`CRITICAL_RTOL` = 1e-9).  Since
    ``(α − 4β) / α = 1 − 1/ζ²``, that is ``|1 − 1/ζ²| ≤ 1e-9``, i.e. ζ within
    about ``5e-10`` of 1: ζ = 1 ± 1e-12 is critically damped, ζ = 1 ± 1e-9 is
    not.  Near β = α/4, ``α − 4β`` is computed exactly (``4β`` is exact and the
    difference of two floats within a factor 2 is exact), so the only rounding
    is that of the product ``CRITICAL_RTOL · α``, one ulp of the threshold.
    Outside the band, the sign of ``α − 4β`` decides.

    Scalars give a ``str``; arrays give an array of strings.
    """
    a = check_finite("alpha", alpha)
    b = check_finite("beta", beta)
    a, b = np.broadcast_arrays(a, b)
    stable = (a > 0) & (b > 0)
    gap = a - 4.0 * b  # ζ² − 1 = (α − 4β) / (4β): same sign
    out = np.where(
        ~stable,
        "unstable",
        np.where(
            np.abs(gap) <= CRITICAL_RTOL * np.abs(a),
            "critically damped",
            np.where(gap < 0, "underdamped", "overdamped"),
        ),
    )
    return str(out) if out.ndim == 0 else out


# ------------------------------------------------------------------- dynamics and integrators


def acceleration(y: Any, dy: Any, goal: Any, alpha: Any, beta: Any, force: Any = None) -> Any:
    """Right-hand side of eq. (10), ``ÿ = α (β (g − y) − ẏ)``, plus ``force`` if given.

    With ``force = f / τ`` and the gain ``α / τ`` this is eq. (1),
    ``τ ÿ = α (β (g − y) − ẏ) + f`` (what :func:`rollout` passes). Broadcasts.
    """
    acc = alpha * (beta * (goal - y) - dy)
    return acc if force is None else acc + force


def _substep(y: Any, dy: Any, goal: Any, alpha: Any, beta: Any, h: Any, method: str,
             force: Any = None, t0: float = 0.0):
    """One sub-step; ``force(t)`` (or None) is the forcing acceleration at local time ``t``."""
    def f(t):
        return None if force is None else force(t)

    if method == "euler":
        a = acceleration(y, dy, goal, alpha, beta, f(t0))
        return y + h * dy, dy + h * a
    if method == "semi_implicit":
        dy_new = dy + h * acceleration(y, dy, goal, alpha, beta, f(t0))
        return y + h * dy_new, dy_new
    # classical RK4 on (y, ẏ); the forcing is evaluated at t0, t0 + h/2 and t0 + h
    f_mid = f(t0 + 0.5 * h)
    k1y, k1v = dy, acceleration(y, dy, goal, alpha, beta, f(t0))
    y2, v2 = y + 0.5 * h * k1y, dy + 0.5 * h * k1v
    k2y, k2v = v2, acceleration(y2, v2, goal, alpha, beta, f_mid)
    y3, v3 = y + 0.5 * h * k2y, dy + 0.5 * h * k2v
    k3y, k3v = v3, acceleration(y3, v3, goal, alpha, beta, f_mid)
    y4, v4 = y + h * k3y, dy + h * k3v
    k4y, k4v = v4, acceleration(y4, v4, goal, alpha, beta, f(t0 + h))
    return (
        y + (h / 6.0) * (k1y + 2.0 * k2y + 2.0 * k3y + k4y),
        dy + (h / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
    )


def _step(y, dy, goal, alpha, beta, dt, method, substeps, force=None):
    """One step without checks (the callers validated their arguments once).

    ``force(t)``, if given, is the forcing acceleration at time ``t`` ∈ [0, dt]
    after the start of the step.
    """
    h = dt / substeps
    y_next, dy_next = y, dy
    for j in range(substeps):
        y_next, dy_next = _substep(y_next, dy_next, goal, alpha, beta, h, method, force, j * h)
    return y_next, dy_next, (dy_next - dy) / dt


def _check_call(method, substeps, dt, alpha, beta, allow_unstable, stacklevel):
    """Shared argument checks of :func:`step` and :func:`rollout` (once per call)."""
    method = _check_method(method)
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
    eq. (10) evaluated at the start). ``xp`` is accepted for uniformity: only
    arithmetic is used, so any engine's arrays pass through.

    Concrete gains are checked (:func:`check_gains`: α > 0, β ≥ 0, finite,
    real) and so is the step itself (:func:`check_step_stability`): a step
    whose spectral radius exceeds 1 — the error would grow every step, e.g.
    α = 25, β = α/4, ``dt = 0.5`` with one explicit Euler sub-step (ρ = 5.25)
    — raises ValueError stating ρ and the stable range of α, unless
    ``allow_unstable=True``, which runs it with a ``RuntimeWarning``; the same
    opt-in lets α ≤ 0 or β < 0 run (the paper's ζ < 0, eq. 13), with a
    ``RuntimeWarning`` that the continuous system is unstable.  Traced
    gains (inside ``grad``/``jit``) are not checked.
    """
    del xp  # arithmetic only
    method, substeps = _check_call(method, substeps, dt, alpha, beta, allow_unstable, 2)
    for name, value in (("y", y), ("dy", dy), ("goal", goal)):
        check_finite_if_concrete(name, value)
    return _step(y, dy, goal, alpha, beta, dt, method, substeps)


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
) -> Rollout:
    """Integrate eq. (10) — or, with ``forcing``, eq. (1) — for ``steps`` steps of ``dt`` seconds.

    ``y0``, ``dy0``: shape ``(..., D)`` for any dimension ``D`` and batch ``...``.
    ``goal``, ``alpha``, ``beta`` broadcast against them (gains are usually a
    scalar or ``(..., 1)``). Names listed in ``per_step`` (a subset of
    ``("goal", "alpha", "beta")``) carry a leading time axis of length
    ``steps`` instead: a moving goal, or gains that a network changes every
    step. Returns a :class:`Rollout` with ``y``, ``dy`` of shape
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
    """
    method = _check_method(method)
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
    tau = _check_tau(tau)
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
            force = _forcing_of_time(forcing, float(x_steps[k]), tau, g_k, y0, gate, xp)
        y, dy, ddy = _step(y, dy, g_k, a_k, b_k, dt, method, substeps, force)
        ys.append(y)
        dys.append(dy)
        ddys.append(ddy)
    if steps == 0:
        shape = np.broadcast_shapes(tuple(ys[0].shape), tuple(dys[0].shape))
        return Rollout(xp.stack([ys[0] + xp.zeros(shape)]), xp.stack([dys[0] + xp.zeros(shape)]),
                       xp.zeros((0,) + tuple(shape)))
    # the initial state may broadcast to a larger batch (e.g. one start, many goals)
    full = tuple(ys[-1].shape)
    ys[0] = ys[0] + xp.zeros(full)
    dys[0] = dys[0] + xp.zeros(full)
    ddy_all = xp.stack(ddys)
    return Rollout(xp.stack(ys), xp.stack(dys), ddy_all)


# --------------------------------------------------------------------------- forcing term (eq. 1)


PHASE_END: float = 0.01
"""Phase reached at the end of a demonstration by default: :func:`fit_forcing_weights`
picks ``α_x = −ln(PHASE_END) τ / T`` so that ``x(T) = 0.01`` (as movement_primitives)."""


class Forcing(NamedTuple):
    """The learned part of eq. (1): ``f(x) = Σ_i ψ_i(x) w_i / Σ_i ψ_i(x) · x · (g − y0)``.

    ``weights`` (n_basis, D): one weight per basis function and dimension;
    ``centres``, ``widths`` (n_basis,): the Gaussians ``ψ_i(x) = exp(−h_i (x − c_i)²)``
    in phase (:func:`basis_centres`); ``alpha_x``: the rate of the canonical
    system ``τ ẋ = −α_x x``.
    """

    weights: Any
    centres: np.ndarray
    widths: np.ndarray
    alpha_x: float


def _check_alpha_x(alpha_x: Any) -> float:
    arr = check_positive("alpha_x", alpha_x)
    if arr.ndim:
        raise ValueError(f"alpha_x must be a scalar, got alpha_x with shape {arr.shape}")
    return float(arr)


def _check_tau(tau: Any) -> float:
    arr = check_positive("tau", tau)
    if arr.ndim:
        raise ValueError(f"tau must be a scalar, got tau with shape {arr.shape}")
    return float(arr)


def phase(t: Any, alpha_x: float, tau: float = 1.0) -> np.ndarray:
    """Phase of the canonical system of eq. (1), ``x(t) = exp(−α_x t / τ)``.

    The solution of ``τ ẋ = −α_x x`` with ``x(0) = 1`` (the paper's eq. 1 prints
    ``τ ẋ = α_x x``, which would make x grow: the phase must decay so that the
    forcing term fades). ``t`` (s, ≥ 0) may be an array; plain NumPy.
    """
    a = _check_alpha_x(alpha_x)
    tau = _check_tau(tau)
    tt = check_finite("t", t)
    if (tt < 0).any():
        raise ValueError(f"t must be >= 0, got t={first_bad(tt, tt < 0)!r}")
    return np.exp(-a * tt / tau)


def canonical_system(steps: int, dt: float, alpha_x: float, tau: float = 1.0) -> np.ndarray:
    """Phase at the step times ``k dt``, ``k = 0 … steps``, stepped exactly (eq. 1).

    The canonical system ``τ ẋ = −α_x x`` is linear, so its exact discrete
    solution is ``x_{k+1} = exp(−α_x dt / τ) x_k`` with ``x_0 = 1``: no
    integration error, whatever ``dt`` (explicit Euler, ``x_{k+1} = (1 − α_x dt / τ) x_k``,
    would even change sign once ``α_x dt > τ``). Returns shape ``(steps + 1,)``,
    equal to :func:`phase` at ``k dt`` up to rounding (tested).
    """
    steps = check_int("steps", steps, 0)
    check_dt(dt)
    decay = float(np.exp(-_check_alpha_x(alpha_x) * float(dt) / _check_tau(tau)))
    x = np.empty(steps + 1)
    x[0] = 1.0
    for k in range(steps):
        x[k + 1] = x[k] * decay
    return x


def basis_centres(
    n_basis: int,
    alpha_x: float,
    duration: float,
    tau: float = 1.0,
    overlap: float = 0.5,
) -> tuple[np.ndarray, np.ndarray]:
    """Centres and widths of the Gaussian basis functions of the forcing term (eq. 1).

    The movement_primitives / Ijspeert convention: the centres are the phase at
    ``n_basis`` instants equally spaced in time over ``[0, duration]``,
    ``c_i = exp(−α_x t_i / τ)`` (so they crowd together near x = 0, where time
    runs slowly in phase), and each width ``h_i = −ln(overlap) / (c_{i+1} − c_i)²``
    makes ``ψ_i`` fall to ``overlap`` at the next centre (the last width repeats
    the one before). Returns ``(centres, widths)``, each of shape ``(n_basis,)``.
    """
    n = check_int("n_basis", n_basis, 2)
    a = _check_alpha_x(alpha_x)
    tau = _check_tau(tau)
    d = check_positive("duration", duration)
    if d.ndim:
        raise ValueError(f"duration must be a scalar, got duration with shape {d.shape}")
    ov = check_finite("overlap", overlap)
    if ov.ndim or not 0.0 < float(ov) < 1.0:
        raise ValueError(f"overlap must be a scalar in (0, 1), got overlap={overlap!r}")
    centres = np.exp(-a * np.linspace(0.0, float(d), n) / tau)
    widths = -np.log(float(ov)) / np.diff(centres) ** 2
    return centres, np.concatenate([widths, widths[-1:]])


def basis_functions(x: Any, centres: Any, widths: Any) -> np.ndarray:
    """Gaussian basis functions of eq. (1) in phase, ``ψ_i(x) = exp(−h_i (x − c_i)²)``.

    ``x`` of any shape; returns ``x.shape + (n_basis,)`` (not normalised).
    """
    xx = check_finite("x", x)
    c = check_finite("centres", centres)
    h = check_positive("widths", widths)
    if c.ndim != 1 or h.shape != c.shape:
        raise ValueError(f"centres and widths must be 1-D of one length, got shapes "
                         f"centres {c.shape}, widths {h.shape}")
    return np.exp(-h * (xx[..., None] - c) ** 2)


def _normalised_basis(x: Any, forcing: Forcing) -> np.ndarray:
    psi = basis_functions(x, forcing.centres, forcing.widths)
    return psi / psi.sum(axis=-1, keepdims=True)


def forcing_term(
    x: Any,
    forcing: Forcing,
    goal: Any,
    y0: Any,
    gate: bool = True,
    xp: Any = np,
) -> Any:
    """The forcing term of eq. (1), ``f(x) = Σ_i ψ_i(x) w_i / Σ_i ψ_i(x) · x · (g − y0)``.

    ``x``: phase, a scalar or shape ``(T,)``; ``goal``, ``y0``: shape ``(..., D)``.
    Returns ``x.shape + (D,)`` broadcast with the batch of ``goal − y0``. The
    gate ``x`` makes ``f`` vanish as the phase decays, so the point attractor
    alone decides where the motion ends; ``gate=False`` drops it (then ``f``
    tends to the weighted mean of the last weights, a force that never fades).
    The factor ``g − y0`` rescales the learned shape to a new goal. The weights
    may be traced (``xp`` provides ``matmul``): the basis is plain NumPy.
    """
    if not isinstance(forcing, Forcing):
        raise TypeError(f"forcing must be a dmp.Forcing, got forcing={forcing!r}")
    xx = check_finite("x", x)
    basis = _normalised_basis(xx, forcing)  # (..., n)
    shape = xp.matmul(basis, forcing.weights)  # (..., D)
    if gate:
        shape = shape * xx[..., None] if xx.ndim else shape * float(xx)
    return shape * (goal - y0)


def _forcing_of_time(forcing, x_k, tau, goal, y0, gate, xp):
    """``s ↦ f(x_k exp(−α_x s / τ)) / τ``, the forcing acceleration within one step."""
    def force(s):
        x = x_k * float(np.exp(-forcing.alpha_x * s / tau)) if s else x_k
        f = forcing_term(x, forcing, goal, y0, gate, xp)
        return f if tau == 1.0 else f / tau
    return force


def fit_forcing_weights(
    demo: Any,
    dt: float,
    alpha: float = 4.0,
    beta: float = 1.0,
    n_basis: int = 20,
    alpha_x: float | None = None,
    tau: float = 1.0,
    overlap: float = 0.5,
    regularization: float = 1e-10,
) -> Forcing:
    """Fit the forcing term of eq. (1) to one demonstration by locally weighted regression.

    ``demo``: positions, shape ``(T + 1, D)`` (or ``(T + 1,)`` for one
    dimension), sampled every ``dt`` seconds; ``y0 = demo[0]`` and
    ``g = demo[-1]``. Velocities and accelerations come from finite differences
    (second-order central, one-sided at the ends: ``numpy.gradient``). The
    target is what eq. (1) must add to the point attractor,
    ``f_target = τ ÿ − α (β (g − y) − ẏ)``; with ``s = x (g − y0)``, each weight
    is the weighted least-squares fit of ``f_target ≈ w_i s`` under the weights
    ``ψ_i(x)`` (Schaal and Atkeson's LWR, as in Ijspeert et al. 2013)::

        w_id = Σ_t ψ_i(x_t) s_td f_td / (Σ_t ψ_i(x_t) s_td² + regularization)

    A dimension with ``g = y0`` gets zero weights (the scaled forcing term
    cannot move it). ``alpha_x`` defaults to ``−ln(PHASE_END) τ / T``, so the
    phase reaches :data:`PHASE_END` at the end of the demonstration; the basis
    is :func:`basis_centres` over the demonstration's duration. Returns a
    :class:`Forcing` for :func:`rollout` (with the same ``alpha``, ``beta``,
    ``tau``, ``dt``, start at rest at ``demo[0]``).
    """
    y = check_finite("demo", demo)
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2 or y.shape[0] < 3:
        raise ValueError(f"demo must have shape (T + 1, D) with T + 1 >= 3 samples, got demo "
                         f"with shape {np.shape(demo)}")
    check_dt(dt)
    dt = float(dt)
    tau = _check_tau(tau)
    for name, value in (("alpha", alpha), ("beta", beta)):
        v = check_positive(name, value)
        if v.ndim:
            raise ValueError(f"{name} must be a scalar, got {name} with shape {v.shape}")
    reg = check_finite("regularization", regularization)
    if reg.ndim or float(reg) < 0:
        raise ValueError(f"regularization must be a scalar >= 0, got "
                         f"regularization={regularization!r}")
    duration = (y.shape[0] - 1) * dt
    a_x = -np.log(PHASE_END) * tau / duration if alpha_x is None else _check_alpha_x(alpha_x)
    centres, widths = basis_centres(n_basis, a_x, duration, tau, overlap)
    dy = np.gradient(y, dt, axis=0, edge_order=2)
    ddy = np.gradient(dy, dt, axis=0, edge_order=2)
    g, y0 = y[-1], y[0]
    f_target = tau * ddy - float(alpha) * (float(beta) * (g - y) - dy)  # (T + 1, D)
    x = np.exp(-a_x * np.arange(y.shape[0]) * dt / tau)
    psi = basis_functions(x, centres, widths)  # (T + 1, n)
    s = x[:, None] * (g - y0)  # (T + 1, D)
    num = psi.T @ (s * f_target)  # (n, D)
    den = psi.T @ (s * s) + float(reg)
    weights = np.divide(num, den, out=np.zeros_like(num), where=den > 0)
    return Forcing(weights, centres, widths, float(a_x))


# --------------------------------------------------------------------------- discrete step analysis


def _substep_matrix(a: np.ndarray, b: np.ndarray, h: float, method: str) -> np.ndarray:
    """Matrix ``M`` (…, 2, 2) with ``[e, ė]_{next} = M [e, ė]`` for one sub-step (e = y − g)."""
    A = np.zeros(a.shape + (2, 2))
    A[..., 0, 1] = 1.0
    A[..., 1, 0] = -a * b
    A[..., 1, 1] = -a
    eye = np.broadcast_to(np.eye(2), A.shape)
    hA = h * A
    if method == "euler":
        return eye + hA
    if method == "semi_implicit":
        M = np.empty(A.shape)
        M[..., 0, 0] = 1.0 - h * h * a * b
        M[..., 0, 1] = h * (1.0 - h * a)
        M[..., 1, 0] = -h * a * b
        M[..., 1, 1] = 1.0 - h * a
        return M
    hA2 = hA @ hA
    hA3 = hA2 @ hA
    return eye + hA + hA2 / 2.0 + hA3 / 6.0 + (hA3 @ hA) / 24.0


def _substep_eigs(a: np.ndarray, b: np.ndarray, h: float, method: str) -> np.ndarray:
    """Eigenvalues (…, 2) of the sub-step matrix, in closed form.

    Euler and RK4 map an eigenvalue λ of eq. (12) to their stability function
    ``R(hλ)`` (``1 + z`` and ``1 + z + z²/2 + z³/6 + z⁴/24``); this is exact even
    at the double root β = α/4, where a numerical eigensolver loses half the
    digits. Semi-implicit Euler is not of that form: its roots follow from
    ``tr = 2 − hα − h²αβ`` and ``det = 1 − hα``.
    """
    if method == "semi_implicit":
        tr = 2.0 - h * a - h * h * a * b
        det = 1.0 - h * a
        root = np.sqrt((tr * tr / 4.0 - det).astype(complex))
        return np.stack([tr / 2.0 + root, tr / 2.0 - root], axis=-1)
    z = h * eigenvalues(a, b)
    if method == "euler":
        return 1.0 + z
    return 1.0 + z + z**2 / 2.0 + z**3 / 6.0 + z**4 / 24.0


def _check_step_args(alpha, beta, dt, method, substeps):
    a = check_positive("alpha", alpha)
    b = check_positive("beta", beta)
    d = check_positive("dt", dt)
    if d.ndim:
        raise ValueError(f"dt must be a scalar, got dt with shape {d.shape}")
    method = _check_method(method)
    substeps = check_int("substeps", substeps, 1)
    a, b = np.broadcast_arrays(a, b)
    return a, b, float(d), method, substeps


def step_matrix(
    alpha: Any,
    beta: Any,
    dt: float = DT,
    method: str = DEFAULT_METHOD,
    substeps: int = DEFAULT_SUBSTEPS,
) -> np.ndarray:
    """Linear map of one full step (``substeps`` sub-steps) on ``[y − g, ẏ]``.

    For gains α, β > 0 (arrays broadcast), shape ``(..., 2, 2)``. The DMP is
    linear, so ``[y_{k+1} − g, ẏ_{k+1}] = step_matrix(...) @ [y_k − g, ẏ_k]``
    exactly (tested against :func:`step`).
    """
    a, b, dt, method, substeps = _check_step_args(alpha, beta, dt, method, substeps)
    return np.linalg.matrix_power(_substep_matrix(a, b, dt / substeps, method), substeps)


def spectral_radius(
    alpha: Any,
    beta: Any,
    dt: float = DT,
    method: str = DEFAULT_METHOD,
    substeps: int = DEFAULT_SUBSTEPS,
) -> Any:
    """Spectral radius ρ of :func:`step_matrix`: the error shrinks ~ρ per step iff ρ < 1.

    Computed as ``ρ(M_h) ** substeps`` from the sub-step matrix ``M_h`` (closed-form
    eigenvalues, see ``_substep_eigs``). Example: α = 25,
    β = α/4, ``dt = 0.5``, ``"euler"``, one sub-step gives ρ = 5.25 (diverges)
    although ζ = 1.
    """
    a, b, dt, method, substeps = _check_step_args(alpha, beta, dt, method, substeps)
    eig = _substep_eigs(a, b, dt / substeps, method)
    return _maybe_scalar(np.abs(eig).max(axis=-1) ** substeps)


def _jury(a: np.ndarray, b: np.ndarray, h: float, method: str):
    """``(det, 1 + tr + det, 1 − tr + det)`` of the Euler / semi-implicit sub-step matrix.

    Written in factored form so that the boundaries are exact in floating
    point: explicit Euler ``det = 1 − hα (1 − hβ)``, ``1 + tr + det = 4 − hα (2 − hβ)``;
    semi-implicit ``det = 1 − hα``, ``1 + tr + det = 4 − hα (2 + hβ)``; both
    ``1 − tr + det = h² αβ``.
    """
    if method == "euler":
        det = 1.0 - h * a * (1.0 - h * b)
        plus = 4.0 - h * a * (2.0 - h * b)
    else:
        det = 1.0 - h * a
        plus = 4.0 - h * a * (2.0 + h * b)
    return det, plus, (h * h) * a * b


#: Slack on ``ρ(M_h) ≤ 1`` for RK4, whose modulus is evaluated from a quartic.
_RK4_RHO_TOL: float = float_tolerance(np.float64, 16)


def _sub_radius(a: np.ndarray, b: np.ndarray, h: float, method: str) -> np.ndarray:
    return np.abs(_substep_eigs(a, b, h, method)).max(axis=-1)


def _stable(a: np.ndarray, b: np.ndarray, h: float, method: str) -> np.ndarray:
    """Asymptotic stability of the sub-step (ρ < 1), exact for the two Euler methods."""
    if method == "rk4":
        return _sub_radius(a, b, h, method) < 1.0
    det, plus, minus = _jury(a, b, h, method)
    return (np.abs(det) < 1.0) & (plus > 0.0) & (minus > 0.0)


def _bounded(a: np.ndarray, b: np.ndarray, h: float, method: str) -> np.ndarray:
    """``ρ ≤ 1`` (no eigenvalue outside the unit circle), exact for the two Euler methods.

    Jury's conditions with ``≤``: the roots of ``z² − tr z + det`` lie in the
    closed unit disc iff ``|det| ≤ 1`` and ``|tr| ≤ 1 + det``.
    """
    if method == "rk4":
        return _sub_radius(a, b, h, method) <= 1.0 + _RK4_RHO_TOL
    det, plus, minus = _jury(a, b, h, method)
    return (np.abs(det) <= 1.0) & (plus >= 0.0) & (minus >= 0.0)


def step_stable(
    alpha: Any,
    beta: Any,
    dt: float = DT,
    method: str = DEFAULT_METHOD,
    substeps: int = DEFAULT_SUBSTEPS,
) -> Any:
    """True where the discrete step is asymptotically stable (spectral radius ρ < 1).

    ``ρ(M_h^n) = ρ(M_h)^n``, so the step is stable iff one sub-step of
    ``h = dt / substeps`` is.  For ``"euler"`` and ``"semi_implicit"`` this is
    decided exactly by Jury's conditions on the sub-step matrix (``|det| < 1``,
    ``1 ± tr + det > 0``; see ``_jury``), not by comparing a rounded ρ with 1:

    * ``"euler"``: stable iff ``hβ < 1`` and ``hα (2 − hβ) < 4``.  At exactly
      ``hβ = 1`` no α is stable: ``det = 1 − hα (1 − hβ) = 1``, the complex
      roots ``1 + hλ`` have modulus² ``1 − hα (1 − hβ) = 1`` and the error
      oscillates forever without decaying (ρ = 1, "marginal");
    * ``"semi_implicit"``: stable iff ``hα (2 + hβ) < 4``;
    * ``"rk4"``: ``ρ < 1`` evaluated from its stability polynomial.
    """
    a, b, dt, method, substeps = _check_step_args(alpha, beta, dt, method, substeps)
    return _maybe_scalar(_stable(a, b, dt / substeps, method))


def _alpha_bound(b: float, h: float, method: str) -> float:
    """Supremum of the stable α at β = ``b`` ≥ 0 for one sub-step of ``h`` (no checks)."""
    if method == "euler":
        return 4.0 / (h * (2.0 - h * b)) if h * b < 1.0 else 0.0
    if method == "semi_implicit":
        return 4.0 / (h * (2.0 + h * b))
    # RK4: its real stability interval ends at hλ ≈ −2.785, so scan up to 8/h.
    grid = np.linspace(0.0, 8.0 / h, 4001)[1:]
    rho = _sub_radius(grid, np.full_like(grid, b), h, "rk4")
    unstable = np.nonzero(rho >= 1.0)[0]
    if unstable.size == 0:
        return float(grid[-1])
    if unstable[0] == 0:
        lo, hi = 0.0, float(grid[0])
    else:
        lo, hi = float(grid[unstable[0] - 1]), float(grid[unstable[0]])
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _sub_radius(np.asarray(mid), np.asarray(b), h, "rk4") < 1.0:
            lo = mid
        else:
            hi = mid
    return lo


def max_stable_alpha(
    beta: float,
    dt: float = DT,
    method: str = DEFAULT_METHOD,
    substeps: int = DEFAULT_SUBSTEPS,
) -> float:
    """Supremum of the stable α: the step is stable for ``0 < α < max_stable_alpha``.

    With ``h = dt / substeps`` (Jury's conditions on the 2×2 sub-step matrix):

    * ``"euler"``: ``4 / (h (2 − h β))`` if ``h β < 1``, else 0 (no α is stable:
      the complex roots ``1 + hλ`` have modulus² ``1 − hα + h²αβ``, which is
      ``≥ 1`` once ``hβ ≥ 1``; at exactly ``hβ = 1`` it is 1, marginal, not
      stable);
    * ``"semi_implicit"``: ``4 / (h (2 + h β))`` (det ``= 1 − hα``, and
      ``1 + det + tr = 4 − 2hα − h²αβ > 0``);
    * ``"rk4"``: found numerically (scan, then bisection on
      :func:`spectral_radius`), the end of the stable interval that starts at 0.

    The bound itself is not stable (ρ = 1 there): :func:`step_stable` is
    ``False`` at ``α = max_stable_alpha``.
    """
    b = float(check_positive("beta", beta))
    d = float(check_positive("dt", dt))
    method = _check_method(method)
    substeps = check_int("substeps", substeps, 1)
    return _alpha_bound(b, d / substeps, method)


_METHOD_NAMES = {"euler": "explicit Euler", "semi_implicit": "semi-implicit Euler",
                 "rk4": "RK4"}


def check_step_stability(
    alpha: Any,
    beta: Any,
    dt: float = DT,
    method: str = DEFAULT_METHOD,
    substeps: int = DEFAULT_SUBSTEPS,
    allow_unstable: bool = False,
    stacklevel: int = 2,
) -> None:
    """Refuse a step whose spectral radius exceeds 1 (the error would grow every step).

    For concrete gains α > 0, β ≥ 0 (arrays broadcast; :func:`step` and
    :func:`rollout` call it once per call).  A sub-step matrix with an
    eigenvalue outside the unit circle (decided as in :func:`step_stable`,
    with ``≤``: a marginal ρ = 1 passes) raises ValueError stating the
    spectral radius of the worst entry and the stable range of α for its β
    (:func:`max_stable_alpha`); with ``allow_unstable=True`` it emits one
    ``RuntimeWarning`` instead.  The cost is a few vectorised operations on
    the gains; the stable bound is computed only when reporting.
    """
    a = np.asarray(alpha, dtype=float)
    b = np.asarray(beta, dtype=float)
    a, b = np.broadcast_arrays(a, b)
    dt = float(dt)
    h = dt / substeps
    ok = _bounded(a, b, h, method)
    if np.all(ok):
        return
    rho = np.where(ok, -np.inf, _sub_radius(a, b, h, method) ** substeps)
    i = int(np.argmax(rho)) if rho.ndim else 0
    a_i, b_i, rho_i = float(a.flat[i]), float(b.flat[i]), float(rho.flat[i])
    n_bad = int(np.size(ok) - np.count_nonzero(ok))
    where = f" (the worst of {n_bad} unstable gain pairs)" if n_bad > 1 else ""
    bound = _alpha_bound(b_i, h, method)
    if method == "euler" and h * b_i >= 1.0:
        stable_range = (f"no alpha is stable (h*beta = {h * b_i:.6g} >= 1, "
                        f"with h = dt/substeps = {h:.6g})")
    elif b_i == 0.0:  # pure damping: at best marginal (an eigenvalue 1)
        stable_range = f"the step stays bounded only for 0 < alpha < {bound:.6g}"
    else:
        stable_range = f"the step is stable only for 0 < alpha < {bound:.6g}"
    head = (f"{_METHOD_NAMES[method]} (method={method!r}) with dt={dt!r} and substeps={substeps} "
            f"is unstable for alpha={a_i!r}, beta={b_i!r}{where}: the spectral radius of one "
            f"step is {rho_i:.6g} > 1, so the error grows {rho_i:.3g}x per step. At "
            f"beta={b_i!r} {stable_range}.")
    if allow_unstable:
        warnings.warn(head + " Running it anyway (allow_unstable=True).", RuntimeWarning,
                      stacklevel=stacklevel + 1)
        return
    other = "" if method == "semi_implicit" else ", method='semi_implicit'"
    raise ValueError(f"{head} Use more substeps, a smaller dt{other} or smaller gains, or pass "
                     "allow_unstable=True to run it anyway.")


# --------------------------------------------------------------------------- learned gains


def _sigmoid(z: Any, xp: Any) -> Any:
    """Overflow-free logistic function, ``½ (1 + tanh(z / 2))``."""
    return 0.5 * (1.0 + xp.tanh(0.5 * z))


def _check_range(name: str, rng: Any) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in rng)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a pair (low, high), got {name}={rng!r}") from exc
    if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 < lo < hi):
        raise ValueError(f"{name} must satisfy 0 < low < high (finite), got {name}={rng!r}")
    return lo, hi


def gains_from_logits(
    z_alpha: Any,
    z_beta: Any = None,
    xp: Any = np,
    alpha_range: tuple[float, float] = ALPHA_RANGE,
    beta_range: tuple[float, float] = BETA_RANGE,
    critically_damped: bool = False,
) -> tuple[Any, Any]:
    """Map unconstrained network outputs to DMP gains (eq. 10) through a sigmoid.

    ``α = α_lo + (α_hi − α_lo) σ(z_α)`` and likewise β, with the ranges
    :data:`ALPHA_RANGE`, :data:`BETA_RANGE` by default: both gains are > 0, so
    ζ > 0 (the paper's argument), and ζ ≥ ½ √(α_lo/β_hi) ≈ 0.16; the default
    integrator at :data:`DT` is stable on the whole box. With
    ``critically_damped=True``, ``β = α/4`` (ζ = 1) and ``z_beta`` is ignored
    (pass ``None``). Returns ``(alpha, beta)`` shaped like the logits.
    Custom ranges are not checked for discrete stability: use
    :func:`max_stable_alpha`.
    """
    a_lo, a_hi = _check_range("alpha_range", alpha_range)
    b_lo, b_hi = _check_range("beta_range", beta_range)
    alpha = a_lo + (a_hi - a_lo) * _sigmoid(z_alpha, xp)
    if critically_damped:
        return alpha, alpha / 4.0
    if z_beta is None:
        raise ValueError("z_beta=None is only allowed with critically_damped=True")
    return alpha, b_lo + (b_hi - b_lo) * _sigmoid(z_beta, xp)


def logits_from_gains(
    alpha: Any,
    beta: Any,
    alpha_range: tuple[float, float] = ALPHA_RANGE,
    beta_range: tuple[float, float] = BETA_RANGE,
) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`gains_from_logits` (plain NumPy), e.g. to initialise a bias.

    The gains must lie strictly inside their ranges.
    """
    out = []
    for name, value, rng in (("alpha", alpha, alpha_range), ("beta", beta, beta_range)):
        lo, hi = _check_range(f"{name}_range", rng)
        v = check_finite(name, value)
        bad = (v <= lo) | (v >= hi)
        if bad.any():
            raise ValueError(
                f"{name} must lie strictly inside {name}_range={rng!r}, "
                f"got {name}={first_bad(v, bad)!r}"
            )
        p = (v - lo) / (hi - lo)
        out.append(np.log(p) - np.log1p(-p))
    return out[0], out[1]


def zeta_penalty(alpha: Any, beta: Any, xp: Any = np, zeta_min: float = 0.5) -> Any:
    """Auxiliary loss against ζ ≈ 0 (paper, after eq. 13): ``mean(max(ζ_min − ζ, 0)²)``.

    Zero while every ζ = ½ √(α/β) ≥ ``zeta_min``; grows quadratically below
    (continuous gradient). Add ``λ · zeta_penalty(α, β, xp)`` to the BC loss.
    """
    zm = float(check_positive("zeta_min", zeta_min))
    zeta = damping_ratio(alpha, beta, xp=xp)
    return xp.mean(xp.maximum(zm - zeta, 0.0) ** 2)
