"""Chapter 3 — learned gains of eq. (10): network logits ↔ gains, and the ζ penalty.

Learned gains (:func:`gains_from_logits`) pass network outputs through a
sigmoid into the boxes :data:`~minimanc.dmp.params.ALPHA_RANGE` ×
:data:`~minimanc.dmp.params.BETA_RANGE`; :func:`logits_from_gains` inverts it;
:func:`zeta_penalty` is the auxiliary loss the paper suggests against ζ ≈ 0
(eq. 13).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from minimanc.checks import check_finite, check_positive, first_bad
from minimanc.dmp.attractor import damping_ratio
from minimanc.dmp.params import ALPHA_RANGE, BETA_RANGE
from minimanc.engine import engine_of

__all__ = [
    "gains_from_logits",
    "logits_from_gains",
    "zeta_penalty",
]

# --------------------------------------------------------------------------- learned gains


def _squash(z: Any, lo: float, hi: float, xp: Any) -> Any:
    """``lo + (hi − lo) σ(z)`` with the overflow-free ``σ(z) = ½ (1 + tanh(z / 2))``."""
    return lo + (hi - lo) * (0.5 * (1.0 + xp.tanh(0.5 * z)))


def _squash_fwd(z, lo, hi, xp):
    t = xp.tanh(0.5 * z)
    return lo + (hi - lo) * (0.5 * (1.0 + t)), (t, z)


def _squash_bwd(lo, hi, xp, res, g):
    t, z = res
    ct = g * ((0.25 * (hi - lo)) * (1.0 - t * t))  # d/dz ½(1 + tanh(z/2)) = ¼ (1 − tanh²)
    dtype = getattr(z, "dtype", None)
    return (ct if dtype is None or ct.dtype == dtype else ct.astype(dtype),)


@functools.cache
def _squash_for(eng: Any) -> Any:
    f = eng.custom_vjp(_squash, nondiff_argnums=(1, 2, 3))
    f.defvjp(_squash_fwd, _squash_bwd)
    return f


def _scaled_sigmoid(z: Any, lo: float, hi: float, xp: Any) -> Any:
    """:func:`_squash` as one traced operation on the engine of ``xp`` (if it has one)."""
    eng = engine_of(xp)
    return _squash(z, lo, hi, xp) if eng is None else _squash_for(eng)(z, lo, hi, xp)


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

    Parameters
    ----------
    z_alpha, z_beta : array, shape (..., 1) typically
        Network outputs; ``z_beta`` is ignored (pass ``None``) when critically damped.
    xp : module
        Array namespace; on an engine's namespace each gain is one traced operation.
    alpha_range, beta_range : (float, float)
        Boxes ``0 < low < high``.
    critically_damped : bool
        Tie β to α/4.

    Returns
    -------
    alpha, beta : array, shaped like the logits
        The gains in 1/s, inside their boxes.

    Raises
    ------
    ValueError
        If a range is not a finite pair ``0 < low < high``, or ``z_beta`` is None without
        ``critically_damped=True``.
    """
    a_lo, a_hi = _check_range("alpha_range", alpha_range)
    b_lo, b_hi = _check_range("beta_range", beta_range)
    if not critically_damped and z_beta is None:
        raise ValueError("z_beta=None is only allowed with critically_damped=True")
    alpha = _scaled_sigmoid(z_alpha, a_lo, a_hi, xp)
    if critically_damped:
        return alpha, alpha / 4.0
    return alpha, _scaled_sigmoid(z_beta, b_lo, b_hi, xp)


def logits_from_gains(
    alpha: Any,
    beta: Any,
    alpha_range: tuple[float, float] = ALPHA_RANGE,
    beta_range: tuple[float, float] = BETA_RANGE,
) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`gains_from_logits` (plain NumPy), e.g. to initialise a bias.

    The gains must lie strictly inside their ranges.

    Parameters
    ----------
    alpha, beta : array or float
        Gains strictly inside ``alpha_range`` and ``beta_range``.
    alpha_range, beta_range : (float, float)
        The boxes of :func:`gains_from_logits`.

    Returns
    -------
    z_alpha, z_beta : ndarray, shaped like the gains
        The logits with ``gains_from_logits(z_alpha, z_beta) == (alpha, beta)``.

    Raises
    ------
    ValueError
        If a gain is not finite or not strictly inside its range, or a range is not a
        finite pair ``0 < low < high`` (naming the parameter and its value).
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

    Parameters
    ----------
    alpha, beta : array
        Gains in 1/s of any shape (``αβ > 0``, broadcast).
    xp : module
        Array namespace.
    zeta_min : float
        The ζ below which the penalty grows (> 0, dimensionless).

    Returns
    -------
    array, shape ()
        The mean squared shortfall of ζ (eq. 13), dimensionless.

    Raises
    ------
    ValueError
        If ``zeta_min`` is not > 0, or concrete gains have ``αβ ≤ 0``
        (:func:`~minimanc.dmp.attractor.damping_ratio`).
    """
    zm = float(check_positive("zeta_min", zeta_min))
    zeta = damping_ratio(alpha, beta, xp=xp)
    return xp.mean(xp.maximum(zm - zeta, 0.0) ** 2)
