"""Chapter 3 — stability of the discrete DMP step: step matrices, spectral radius, Jury, bounds.

The continuous system of eq. (12) is stable for every α, β > 0, but its
*discrete* step need not be: the textbook gains α = 25, β = α/4 with one
explicit Euler step of 0.5 s multiply the error by −5.25 each step. This
module analyses the one-step map of each integrator (:func:`step_matrix`,
:func:`spectral_radius`, :func:`step_stable`, :func:`max_stable_alpha`) and
refuses an unstable step (:func:`check_step_stability`).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from minimanc.checks import check_int, check_positive, float_tolerance
from minimanc.dmp.attractor import eigenvalues
from minimanc.dmp.params import DEFAULT_METHOD, DEFAULT_SUBSTEPS, DT, check_method

__all__ = [
    "check_step_stability",
    "max_stable_alpha",
    "spectral_radius",
    "step_matrix",
    "step_stable",
]

def _maybe_scalar(arr: np.ndarray) -> Any:
    return arr.item() if arr.ndim == 0 else arr


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
    method = check_method(method)
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

    Parameters
    ----------
    alpha, beta : array or float
        Gains of eq. (10) in 1/s (α > 0, β > 0), broadcasting against each other.
    dt : float
        Step length in seconds (default :data:`~minimanc.dmp.params.DT`).
    method : str
        Integrator, one of :data:`~minimanc.dmp.params.METHODS`.
    substeps : int
        Sub-steps of ``h = dt / substeps`` per step (an integer >= 1).

    Returns
    -------
    ndarray, shape broadcast(alpha, beta).shape + (2, 2)
        The matrix acting on ``[y − g, ẏ]``.

    Raises
    ------
    ValueError
        If ``alpha``, ``beta`` or ``dt`` is not finite and > 0, ``dt`` is not a scalar,
        ``method`` is not one of :data:`~minimanc.dmp.params.METHODS`, or ``substeps`` is
        not an integer >= 1 (naming the parameter and its value).
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

    Parameters
    ----------
    alpha, beta : array or float
        Gains of eq. (10) in 1/s (α > 0, β > 0), broadcasting against each other.
    dt : float
        Step length in seconds (default :data:`~minimanc.dmp.params.DT`).
    method : str
        Integrator, one of :data:`~minimanc.dmp.params.METHODS`.
    substeps : int
        Sub-steps of ``h = dt / substeps`` per step (an integer >= 1).

    Returns
    -------
    float or ndarray, shape broadcast(alpha, beta).shape
        ρ of each step matrix (a float for scalar gains).

    Raises
    ------
    ValueError
        If ``alpha``, ``beta`` or ``dt`` is not finite and > 0, ``dt`` is not a scalar,
        ``method`` is not one of :data:`~minimanc.dmp.params.METHODS`, or ``substeps`` is
        not an integer >= 1 (naming the parameter and its value).
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

    Parameters
    ----------
    alpha, beta : array or float
        Gains of eq. (10) in 1/s (α > 0, β > 0), broadcasting against each other.
    dt : float
        Step length in seconds (default :data:`~minimanc.dmp.params.DT`).
    method : str
        Integrator, one of :data:`~minimanc.dmp.params.METHODS`.
    substeps : int
        Sub-steps of ``h = dt / substeps`` per step (an integer >= 1).

    Returns
    -------
    bool or ndarray of bool, shape broadcast(alpha, beta).shape
        True where ρ < 1.

    Raises
    ------
    ValueError
        If ``alpha``, ``beta`` or ``dt`` is not finite and > 0, ``dt`` is not a scalar,
        ``method`` is not one of :data:`~minimanc.dmp.params.METHODS`, or ``substeps`` is
        not an integer >= 1 (naming the parameter and its value).
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

    Parameters
    ----------
    beta : float
        The spring gain β > 0 in 1/s.
    dt : float
        Step length in seconds.
    method : str
        One of :data:`~minimanc.dmp.params.METHODS`.
    substeps : int
        Sub-steps per step (an integer >= 1).

    Returns
    -------
    float
        The supremum of the stable α in 1/s (0 when none is stable).

    Raises
    ------
    ValueError
        If ``beta`` or ``dt`` is not finite and > 0, ``method`` is not one of
        :data:`~minimanc.dmp.params.METHODS`, or ``substeps`` is not an integer >= 1.
    """
    b = float(check_positive("beta", beta))
    d = float(check_positive("dt", dt))
    method = check_method(method)
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

    Parameters
    ----------
    alpha, beta : array or float
        Gains of eq. (10) in 1/s (α > 0, β > 0), broadcasting against each other.
    dt : float
        Step length in seconds (default :data:`~minimanc.dmp.params.DT`).
    method : str
        Integrator, one of :data:`~minimanc.dmp.params.METHODS`.
    substeps : int
        Sub-steps of ``h = dt / substeps`` per step (an integer >= 1).
    allow_unstable : bool
        Run an unstable step with a ``RuntimeWarning`` instead of raising.
    stacklevel : int
        Of that warning (2: the caller's line).

    Raises
    ------
    ValueError
        When ρ > 1 and ``allow_unstable`` is False, stating ρ and the stable α.
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
