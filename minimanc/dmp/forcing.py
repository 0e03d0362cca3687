"""Chapter 3 — the full DMP of eq. (1): canonical system, basis functions, forcing term, its fit.

The phase of the canonical system ``τ ẋ = −α_x x`` (:func:`canonical_system`,
:func:`phase`), Gaussian basis functions spaced in phase (:func:`basis_centres`,
:func:`basis_functions`), the forcing term
``f(x) = Σ ψ_i(x) w_i / Σ ψ_i(x) · x · (g − y0)`` (:func:`forcing_term`,
:class:`Forcing`) and its weights fitted to one demonstration by locally
weighted regression (:func:`fit_forcing_weights`). :func:`minimanc.dmp.rollout`
with ``forcing=...`` adds the term inside its integrators.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from minimanc.checks import check_dt, check_finite, check_int, check_positive, first_bad

__all__ = [
    "Forcing",
    "PHASE_END",
    "basis_centres",
    "basis_functions",
    "canonical_system",
    "check_alpha_x",
    "check_tau",
    "fit_forcing_weights",
    "forcing_of_time",
    "forcing_term",
    "phase",
]

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


def check_alpha_x(alpha_x: Any) -> float:
    """The canonical system's rate ``α_x`` as a float: a finite scalar > 0 (ValueError)."""
    arr = check_positive("alpha_x", alpha_x)
    if arr.ndim:
        raise ValueError(f"alpha_x must be a scalar, got alpha_x with shape {arr.shape}")
    return float(arr)


def check_tau(tau: Any) -> float:
    """The time constant ``τ`` of eq. (1) as a float: a finite scalar > 0 (ValueError)."""
    arr = check_positive("tau", tau)
    if arr.ndim:
        raise ValueError(f"tau must be a scalar, got tau with shape {arr.shape}")
    return float(arr)


def phase(t: Any, alpha_x: float, tau: float = 1.0) -> np.ndarray:
    """Phase of the canonical system of eq. (1), ``x(t) = exp(−α_x t / τ)``.

    The solution of ``τ ẋ = −α_x x`` with ``x(0) = 1`` (the paper's eq. 1 prints
    ``τ ẋ = α_x x``, which would make x grow: the phase must decay so that the
    forcing term fades). Plain NumPy.

    Parameters
    ----------
    t : array or float, any shape
        Time since the start of the movement in seconds (finite, ≥ 0).
    alpha_x : float
        Rate of the canonical system in 1/s (a finite scalar > 0).
    tau : float
        Temporal scaling τ of eq. (1), dimensionless (a finite scalar > 0; 1 keeps the pace).

    Returns
    -------
    ndarray, shape of ``t``
        The phase ``x(t)`` in ``(0, 1]``, dimensionless.

    Raises
    ------
    ValueError
        If ``t`` is negative or not finite, or ``alpha_x`` or ``tau`` is not a finite
        scalar > 0 (naming the parameter and its value).
    TypeError
        If an argument is not a real number or array.
    """
    a = check_alpha_x(alpha_x)
    tau = check_tau(tau)
    tt = check_finite("t", t)
    if (tt < 0).any():
        raise ValueError(f"t must be >= 0, got t={first_bad(tt, tt < 0)!r}")
    return np.exp(-a * tt / tau)


def canonical_system(steps: int, dt: float, alpha_x: float, tau: float = 1.0) -> np.ndarray:
    """Phase at the step times ``k dt``, ``k = 0 … steps``, stepped exactly (eq. 1).

    The canonical system ``τ ẋ = −α_x x`` is linear, so its exact discrete
    solution is ``x_{k+1} = exp(−α_x dt / τ) x_k`` with ``x_0 = 1``: no
    integration error, whatever ``dt`` (explicit Euler, ``x_{k+1} = (1 − α_x dt / τ) x_k``,
    would even change sign once ``α_x dt > τ``). Equal to :func:`phase` at
    ``k dt`` up to rounding.

    Parameters
    ----------
    steps : int
        Number of steps (an integer >= 0).
    dt : float
        Step length in seconds (a finite scalar > 0).
    alpha_x : float
        Rate of the canonical system in 1/s (a finite scalar > 0).
    tau : float
        Temporal scaling τ of eq. (1), dimensionless (a finite scalar > 0).

    Returns
    -------
    ndarray, shape (steps + 1,)
        The phase ``x_k`` at ``t = k dt``, starting from ``x_0 = 1``.

    Raises
    ------
    ValueError
        If ``steps`` is not an integer >= 0, or ``dt``, ``alpha_x`` or ``tau`` is not a
        finite scalar > 0 (naming the parameter and its value).
    """
    steps = check_int("steps", steps, 0)
    check_dt(dt)
    decay = float(np.exp(-check_alpha_x(alpha_x) * float(dt) / check_tau(tau)))
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
    the one before).

    Parameters
    ----------
    n_basis : int
        Number of basis functions (an integer >= 2).
    alpha_x : float
        Rate of the canonical system in 1/s (a finite scalar > 0).
    duration : float
        Length of the movement in seconds (a finite scalar > 0).
    tau : float
        Temporal scaling τ of eq. (1), dimensionless (a finite scalar > 0).
    overlap : float
        Value of ``ψ_i`` at the next centre, a scalar in (0, 1).

    Returns
    -------
    centres : ndarray, shape (n_basis,)
        The phases ``c_i``, decreasing from 1.
    widths : ndarray, shape (n_basis,)
        The widths ``h_i`` > 0 (inverse squared phase).

    Raises
    ------
    ValueError
        If ``n_basis`` is not an integer >= 2, ``alpha_x``, ``duration`` or ``tau`` is not a
        finite scalar > 0, or ``overlap`` is not a scalar in (0, 1) (naming the parameter
        and its value).
    """
    n = check_int("n_basis", n_basis, 2)
    a = check_alpha_x(alpha_x)
    tau = check_tau(tau)
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

    Not normalised (:func:`forcing_term` divides by ``Σ_i ψ_i(x)``).

    Parameters
    ----------
    x : array or float, any shape
        Phase values (finite, dimensionless).
    centres : array, shape (n_basis,)
        The centres ``c_i`` in phase (:func:`basis_centres`).
    widths : array, shape (n_basis,)
        The widths ``h_i`` > 0.

    Returns
    -------
    ndarray, shape x.shape + (n_basis,)
        ``ψ_i(x)`` in ``(0, 1]``.

    Raises
    ------
    ValueError
        If ``centres`` and ``widths`` are not 1-D of one length, ``x`` or ``centres`` is not
        finite, or a width is not > 0 (naming the parameter and its value).
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

    The gate ``x`` makes ``f`` vanish as the phase decays, so the point attractor
    alone decides where the motion ends; ``gate=False`` drops it (then ``f``
    tends to the weighted mean of the last weights, a force that never fades).
    The factor ``g − y0`` rescales the learned shape to a new goal. The weights
    may be traced (``xp`` provides ``matmul``): the basis is plain NumPy.

    Parameters
    ----------
    x : array or float, shape () or (T,)
        Phase of the canonical system (finite, dimensionless).
    forcing : Forcing
        Weights ``(n_basis, D)``, centres and widths of the basis.
    goal, y0 : array, shape (..., D)
        The goal ``g`` and the start ``y0`` of the movement (units of ``y``).
    gate : bool
        Multiply by the phase ``x``.
    xp : module
        Array namespace (``numpy``, ``eng.xp``).

    Returns
    -------
    array, shape x.shape + (D,), broadcast with the batch of ``goal − y0``
        The forcing ``f(x)`` of eq. (1), in units of ``y`` per s².

    Raises
    ------
    TypeError
        If ``forcing`` is not a :class:`Forcing`.
    ValueError
        If ``x`` is not finite (naming it and its value).
    """
    if not isinstance(forcing, Forcing):
        raise TypeError(f"forcing must be a dmp.Forcing, got forcing={forcing!r}")
    xx = check_finite("x", x)
    basis = _normalised_basis(xx, forcing)  # (..., n)
    shape = xp.matmul(basis, forcing.weights)  # (..., D)
    if gate:
        shape = shape * xx[..., None] if xx.ndim else shape * float(xx)
    return shape * (goal - y0)


def forcing_of_time(
    forcing: Forcing, x_k: float, tau: float, goal: Any, y0: Any, gate: bool, xp: Any
) -> Callable[[float], Any]:
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

    Parameters
    ----------
    demo : array, shape (T + 1, D) or (T + 1,)
        Demonstrated positions, ``T + 1 >= 3`` samples, finite.
    dt : float
        Sampling period of ``demo`` in seconds (a finite scalar > 0).
    alpha, beta : float
        Gains of eq. (1)'s point attractor in 1/s (finite scalars > 0).
    n_basis : int
        Number of basis functions (an integer >= 2).
    alpha_x : float or None
        Rate of the canonical system in 1/s (> 0); None: ``−ln(PHASE_END) τ / (T dt)``.
    tau : float
        Temporal scaling τ of eq. (1), dimensionless (a finite scalar > 0).
    overlap : float
        Value of each ``ψ_i`` at the next centre, in (0, 1) (:func:`basis_centres`).
    regularization : float
        Added to each denominator (a scalar >= 0).

    Returns
    -------
    Forcing
        ``weights`` of shape ``(n_basis, D)``, ``centres`` and ``widths`` of shape
        ``(n_basis,)`` and the ``alpha_x`` used.

    Raises
    ------
    ValueError
        If ``demo`` has not shape ``(T + 1, D)`` with ``T + 1 >= 3`` or is not finite, if
        ``dt``, ``alpha``, ``beta``, ``tau`` or ``alpha_x`` is not a finite scalar > 0, if
        ``regularization`` is not a scalar >= 0, or if ``n_basis`` or ``overlap`` is out of
        range (naming the parameter and its value).
    """
    y = check_finite("demo", demo)
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2 or y.shape[0] < 3:
        raise ValueError(f"demo must have shape (T + 1, D) with T + 1 >= 3 samples, got demo "
                         f"with shape {np.shape(demo)}")
    check_dt(dt)
    dt = float(dt)
    tau = check_tau(tau)
    for name, value in (("alpha", alpha), ("beta", beta)):
        v = check_positive(name, value)
        if v.ndim:
            raise ValueError(f"{name} must be a scalar, got {name} with shape {v.shape}")
    reg = check_finite("regularization", regularization)
    if reg.ndim or float(reg) < 0:
        raise ValueError(f"regularization must be a scalar >= 0, got "
                         f"regularization={regularization!r}")
    duration = (y.shape[0] - 1) * dt
    a_x = -np.log(PHASE_END) * tau / duration if alpha_x is None else check_alpha_x(alpha_x)
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
