"""Chapter 3 — the DMP's shared parameters: control period, integrators, gain boxes, checks.

The constants every part of :mod:`minimanc.dmp` uses (the control period
:data:`DT`, the integrator names :data:`METHODS` and the defaults, the boxes
:data:`ALPHA_RANGE` × :data:`BETA_RANGE` of the learned gains of eq. 10) and
the argument checks shared by the integrators and the analysis
(:func:`check_method`, :func:`check_gains`; the time step's is
:func:`minimanc.checks.check_dt`).
"""

from __future__ import annotations

from typing import Any

from minimanc.checks import check_finite, first_bad, is_traced

__all__ = [
    "ALPHA_RANGE",
    "BETA_RANGE",
    "DEFAULT_METHOD",
    "DEFAULT_SUBSTEPS",
    "DT",
    "METHODS",
    "check_gains",
    "check_method",
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


# --------------------------------------------------------------------------- validation


def check_method(method: Any) -> str:
    """``method`` if it names an integrator of :data:`METHODS`, else ValueError naming it.

    Parameters
    ----------
    method : str
        An integrator name, one of :data:`METHODS`.

    Returns
    -------
    str
        ``method`` unchanged.

    Raises
    ------
    ValueError
        If ``method`` is not one of :data:`METHODS` (naming its value).
    """
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got method={method!r}")
    return method


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

    Parameters
    ----------
    alpha, beta : array or float
        The gains of eq. (10) in 1/s (any shapes; traced values pass).
    allow_negative : bool
        Check only reality and finiteness.

    Returns
    -------
    bool
        True when both gains are concrete (and were checked).

    Raises
    ------
    ValueError
        If a concrete gain is not finite, or (unless ``allow_negative``) α ≤ 0 or β < 0,
        naming the gain and its first offending value.
    TypeError
        If a gain is not a real number or array.
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
