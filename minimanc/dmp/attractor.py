"""Chapter 3 — the point attractor of eqs. (10), (12), (13): its roots, damping ratio and character.

Eq. (10), ``ÿ = α (β (g − y) − ẏ)`` (:func:`acceleration`), is with the error
``e = y − g`` the second-order system of eq. (12), ``ë + α ė + αβ e = 0``
(:func:`eigenvalues`), whose character is set by the damping ratio of eq. (13),
``ζ = α / (2 √(αβ))`` (:func:`damping_ratio`, :func:`classify`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.checks import check_finite, is_traced

__all__ = [
    "CRITICAL_RTOL",
    "acceleration",
    "classify",
    "damping_ratio",
    "eigenvalues",
]

CRITICAL_RTOL: float = 1e-9
"""Relative tolerance on ``|α − 4β| / α`` under which :func:`classify` calls a
system critically damped (the repeated root is not exact in floating point)."""

# --------------------------------------------------------------------------- continuous system


def eigenvalues(alpha: Any, beta: Any) -> np.ndarray:
    """Roots of the characteristic polynomial of eq. (12), ``λ² + αλ + αβ = 0``.

    Accepts any finite real α, β (arrays broadcast) so that unstable
    coefficients can be studied too.

    Parameters
    ----------
    alpha, beta : array or float
        Finite real gains in 1/s (broadcast).

    Returns
    -------
    ndarray of complex, shape broadcast(alpha, beta).shape + (2,)
        The roots λ in 1/s: ``(−α + √(α² − 4αβ))/2`` then ``(−α − √(α² − 4αβ))/2``
        (for complex pairs, the one with positive imaginary part first).

    Raises
    ------
    ValueError
        If ``alpha`` or ``beta`` is not finite (naming it and the first bad value).
    TypeError
        If ``alpha`` or ``beta`` is not a real number or array.
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

    Parameters
    ----------
    alpha, beta : array or float
        Gains in 1/s with ``αβ > 0`` (broadcast); traced values are not checked.
    xp : module
        Array namespace (``numpy``, ``eng.xp``).

    Returns
    -------
    array, shape broadcast(alpha, beta).shape
        ζ of eq. (13), dimensionless.

    Raises
    ------
    ValueError
        If concrete gains have ``αβ ≤ 0`` (naming the first such pair) or are not finite.
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

    Parameters
    ----------
    alpha, beta : array or float
        Finite real gains in 1/s (broadcast).

    Returns
    -------
    str or ndarray of str, shape broadcast(alpha, beta).shape
        One of ``"unstable"``, ``"underdamped"``, ``"critically damped"``, ``"overdamped"``.

    Raises
    ------
    ValueError
        If ``alpha`` or ``beta`` is not finite (naming it and the first bad value).
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

    Parameters
    ----------
    y, dy : array, shape (..., D)
        Position and velocity (units of ``y``, and per s).
    goal : array, shape (..., D) or broadcastable
        The attractor ``g``.
    alpha, beta : array or float
        Gains in 1/s, e.g. shape ``(..., 1)`` per sample.
    force : array or None
        Extra acceleration (eq. 1's ``f / τ``), per s².

    Returns
    -------
    array, shape broadcast of the inputs
        ``ÿ``, units of ``y`` per s².
    """
    acc = alpha * (beta * (goal - y) - dy)
    return acc if force is None else acc + force
