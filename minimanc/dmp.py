"""Chapter 3 — the DMP point attractor, its damping ratio and the stability of its discrete step.

The paper (``../shared/paper/manc.tex``) starts from the linear DMP of eq. (1),
``τ ÿ = α(β(g − y) − ẏ) + f``, drops the forcing term ``f`` and lets a network
choose the gains instead (eq. 10)::

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

import numbers
from collections.abc import Iterable
from typing import Any, NamedTuple

import numpy as np

__all__ = [
    "ALPHA_RANGE",
    "BETA_RANGE",
    "DEFAULT_METHOD",
    "DEFAULT_SUBSTEPS",
    "DT",
    "METHODS",
    "Rollout",
    "acceleration",
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


def _is_concrete(x: Any) -> bool:
    """True for plain Python/NumPy values (checked), False for traced ones (skipped)."""
    if isinstance(x, (numbers.Number, np.ndarray, np.generic)):
        return True
    if isinstance(x, (list, tuple)):
        return all(_is_concrete(v) for v in x)
    return False


def _first_bad(values: np.ndarray, bad: np.ndarray) -> Any:
    """The first offending entry, for error messages."""
    return float(values[bad].flat[0] if values.ndim else values.item())


def _check_real(name: str, value: Any) -> np.ndarray:
    """Concrete, finite, real array (any shape) or ValueError naming ``name``."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a real number or array, got {value!r}") from exc
    bad = ~np.isfinite(arr)
    if bad.any():
        raise ValueError(f"{name} must be finite, got {name}={_first_bad(arr, bad)!r}")
    return arr


def _check_positive(name: str, value: Any) -> np.ndarray:
    arr = _check_real(name, value)
    bad = arr <= 0
    if bad.any():
        raise ValueError(f"{name} must be > 0, got {name}={_first_bad(arr, bad)!r}")
    return arr


def _check_method(method: Any) -> str:
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got method={method!r}")
    return method


def _check_int(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {name}={value!r}")
    return int(value)


def _check_dt(dt: Any) -> None:
    if _is_concrete(dt):
        arr = _check_positive("dt", dt)
        if arr.ndim:
            raise ValueError(f"dt must be a scalar, got dt with shape {arr.shape}")


def _maybe_check_finite(name: str, value: Any) -> None:
    if _is_concrete(value):
        _check_real(name, value)


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
    a = _check_real("alpha", alpha)
    b = _check_real("beta", beta)
    a, b = np.broadcast_arrays(a, b)
    root = np.sqrt((a * a - 4.0 * a * b).astype(complex))
    return np.stack([(-a + root) / 2.0, (-a - root) / 2.0], axis=-1)


def damping_ratio(alpha: Any, beta: Any, xp: Any = np) -> Any:
    """Damping ratio of eq. (13), ``ζ = α / (2 √(αβ))`` (equal to ``½ √(α/β)`` for α, β > 0).

    Defined when ``αβ > 0``: both gains positive gives ζ > 0 (stable); both
    negative gives the paper's ζ < 0 (unstable). ``αβ ≤ 0`` raises ValueError
    (no natural frequency). Differentiable through ``xp``.
    """
    if _is_concrete(alpha) and _is_concrete(beta):
        a = _check_real("alpha", alpha)
        b = _check_real("beta", beta)
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
      overshoot), ``"critically damped"`` (ζ = 1, i.e. β = α/4, within
      :data:`CRITICAL_RTOL`), ``"overdamped"`` (ζ > 1, two real roots).

    Scalars give a ``str``; arrays give an array of strings.
    """
    a = _check_real("alpha", alpha)
    b = _check_real("beta", beta)
    a, b = np.broadcast_arrays(a, b)
    stable = (a > 0) & (b > 0)
    gap = (a - 4.0 * b) / np.where(stable, a, 1.0)  # ζ² − 1 = (α − 4β) / (4β): same sign
    out = np.where(
        ~stable,
        "unstable",
        np.where(
            np.abs(gap) <= CRITICAL_RTOL,
            "critically damped",
            np.where(gap < 0, "underdamped", "overdamped"),
        ),
    )
    return str(out) if out.ndim == 0 else out


# ------------------------------------------------------------------- dynamics and integrators


def acceleration(y: Any, dy: Any, goal: Any, alpha: Any, beta: Any) -> Any:
    """Right-hand side of eq. (10): ``ÿ = α (β (g − y) − ẏ)`` (broadcasts)."""
    return alpha * (beta * (goal - y) - dy)


def _substep(y: Any, dy: Any, goal: Any, alpha: Any, beta: Any, h: Any, method: str):
    if method == "euler":
        a = acceleration(y, dy, goal, alpha, beta)
        return y + h * dy, dy + h * a
    if method == "semi_implicit":
        dy_new = dy + h * acceleration(y, dy, goal, alpha, beta)
        return y + h * dy_new, dy_new
    # classical RK4 on (y, ẏ)
    k1y, k1v = dy, acceleration(y, dy, goal, alpha, beta)
    y2, v2 = y + 0.5 * h * k1y, dy + 0.5 * h * k1v
    k2y, k2v = v2, acceleration(y2, v2, goal, alpha, beta)
    y3, v3 = y + 0.5 * h * k2y, dy + 0.5 * h * k2v
    k3y, k3v = v3, acceleration(y3, v3, goal, alpha, beta)
    y4, v4 = y + h * k3y, dy + h * k3v
    k4y, k4v = v4, acceleration(y4, v4, goal, alpha, beta)
    return (
        y + (h / 6.0) * (k1y + 2.0 * k2y + 2.0 * k3y + k4y),
        dy + (h / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
    )


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
) -> tuple[Any, Any, Any]:
    """Advance eq. (10) by ``dt`` seconds; goal and gains are held over the step.

    All array arguments broadcast (position of any dimension in the last axis,
    any batch in front; scalar gains or gains of shape ``(..., 1)`` per sample).
    Returns ``(y_next, dy_next, ddy)`` with ``ddy = (dy_next − dy) / dt`` the
    mean acceleration over the step (for ``"euler"`` with one sub-step this is
    eq. (10) evaluated at the start). ``xp`` is accepted for uniformity: only
    arithmetic is used, so any engine's arrays pass through.
    """
    del xp  # arithmetic only
    method = _check_method(method)
    substeps = _check_int("substeps", substeps, 1)
    _check_dt(dt)
    h = dt / substeps
    y_next, dy_next = y, dy
    for _ in range(substeps):
        y_next, dy_next = _substep(y_next, dy_next, goal, alpha, beta, h, method)
    return y_next, dy_next, (dy_next - dy) / dt


def _per_step(name: str, value: Any, steps: int, varying: bool) -> Any:
    if not varying:
        return value
    shape = getattr(value, "shape", None)
    if shape is None:
        value = np.asarray(value, dtype=float)
        shape = value.shape
    if len(shape) == 0 or shape[0] != steps:
        raise ValueError(
            f"{name} is listed in per_step, so its leading axis must have length steps={steps}; "
            f"got {name} with shape {tuple(shape)}"
        )
    return value


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
) -> Rollout:
    """Integrate eq. (10) for ``steps`` steps of ``dt`` seconds.

    ``y0``, ``dy0``: shape ``(..., D)`` for any dimension ``D`` and batch ``...``.
    ``goal``, ``alpha``, ``beta`` broadcast against them (gains are usually a
    scalar or ``(..., 1)``). Names listed in ``per_step`` (a subset of
    ``("goal", "alpha", "beta")``) carry a leading time axis of length
    ``steps`` instead: a moving goal, or gains that a network changes every
    step. Returns a :class:`Rollout` with ``y``, ``dy`` of shape
    ``(steps + 1, ...)`` and ``ddy`` of shape ``(steps, ...)``.
    Differentiable: ``xp`` provides ``stack``.
    """
    method = _check_method(method)
    substeps = _check_int("substeps", substeps, 1)
    steps = _check_int("steps", steps, 0)
    _check_dt(dt)
    per_step = tuple(per_step)
    unknown = [p for p in per_step if p not in ("goal", "alpha", "beta")]
    if unknown:
        raise ValueError(f"per_step entries must be 'goal', 'alpha' or 'beta', got {unknown!r}")
    for name, value in (("y0", y0), ("dy0", dy0), ("goal", goal), ("alpha", alpha),
                        ("beta", beta)):
        _maybe_check_finite(name, value)
    goal = _per_step("goal", goal, steps, "goal" in per_step)
    alpha = _per_step("alpha", alpha, steps, "alpha" in per_step)
    beta = _per_step("beta", beta, steps, "beta" in per_step)

    y, dy = xp.asarray(y0), xp.asarray(dy0)
    ys, dys, ddys = [y], [dy], []
    for k in range(steps):
        g_k = goal[k] if "goal" in per_step else goal
        a_k = alpha[k] if "alpha" in per_step else alpha
        b_k = beta[k] if "beta" in per_step else beta
        y, dy, ddy = step(y, dy, g_k, a_k, b_k, dt, method, substeps)
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
    a = _check_positive("alpha", alpha)
    b = _check_positive("beta", beta)
    d = _check_positive("dt", dt)
    if d.ndim:
        raise ValueError(f"dt must be a scalar, got dt with shape {d.shape}")
    method = _check_method(method)
    substeps = _check_int("substeps", substeps, 1)
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


def step_stable(
    alpha: Any,
    beta: Any,
    dt: float = DT,
    method: str = DEFAULT_METHOD,
    substeps: int = DEFAULT_SUBSTEPS,
) -> Any:
    """True where the discrete step is asymptotically stable (:func:`spectral_radius` < 1)."""
    rho = np.asarray(spectral_radius(alpha, beta, dt, method, substeps))
    return _maybe_scalar(rho < 1.0)


def max_stable_alpha(
    beta: float,
    dt: float = DT,
    method: str = DEFAULT_METHOD,
    substeps: int = DEFAULT_SUBSTEPS,
) -> float:
    """Supremum of the stable α: the step is stable for ``0 < α < max_stable_alpha``.

    With ``h = dt / substeps`` (Jury's conditions on the 2×2 sub-step matrix):

    * ``"euler"``: ``4 / (h (2 − h β))`` if ``h β < 1``, else 0 (no α is stable:
      the complex roots ``1 + hλ`` have modulus² ``1 − hα + h²αβ``);
    * ``"semi_implicit"``: ``4 / (h (2 + h β))`` (det ``= 1 − hα``, and
      ``1 + det + tr = 4 − 2hα − h²αβ > 0``);
    * ``"rk4"``: found numerically (scan, then bisection on
      :func:`spectral_radius`), the end of the stable interval that starts at 0.
    """
    b = float(_check_positive("beta", beta))
    d = float(_check_positive("dt", dt))
    method = _check_method(method)
    substeps = _check_int("substeps", substeps, 1)
    h = d / substeps
    if method == "euler":
        return 4.0 / (h * (2.0 - h * b)) if h * b < 1.0 else 0.0
    if method == "semi_implicit":
        return 4.0 / (h * (2.0 + h * b))
    # RK4: its real stability interval ends at hλ ≈ −2.785, so scan up to 8/h.
    grid = np.linspace(0.0, 8.0 / h, 4001)[1:]
    rho = np.abs(_substep_eigs(grid, np.full_like(grid, b), h, "rk4")).max(axis=-1)
    unstable = np.nonzero(rho >= 1.0)[0]
    if unstable.size == 0:
        return float(grid[-1])
    if unstable[0] == 0:
        lo, hi = 0.0, float(grid[0])
    else:
        lo, hi = float(grid[unstable[0] - 1]), float(grid[unstable[0]])
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if np.abs(_substep_eigs(np.asarray(mid), np.asarray(b), h, "rk4")).max() < 1.0:
            lo = mid
        else:
            hi = mid
    return lo


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
        v = _check_real(name, value)
        bad = (v <= lo) | (v >= hi)
        if bad.any():
            raise ValueError(
                f"{name} must lie strictly inside {name}_range={rng!r}, "
                f"got {name}={_first_bad(v, bad)!r}"
            )
        p = (v - lo) / (hi - lo)
        out.append(np.log(p) - np.log1p(-p))
    return out[0], out[1]


def zeta_penalty(alpha: Any, beta: Any, xp: Any = np, zeta_min: float = 0.5) -> Any:
    """Auxiliary loss against ζ ≈ 0 (paper, after eq. 13): ``mean(max(ζ_min − ζ, 0)²)``.

    Zero while every ζ = ½ √(α/β) ≥ ``zeta_min``; grows quadratically below
    (continuous gradient). Add ``λ · zeta_penalty(α, β, xp)`` to the BC loss.
    """
    zm = float(_check_positive("zeta_min", zeta_min))
    zeta = damping_ratio(alpha, beta, xp=xp)
    return xp.mean(xp.maximum(zm - zeta, 0.0) ** 2)
