"""Chapter 7 — car-following laws: the Intelligent Driver Model, its ACC variant, curve braking.

:func:`idm_acceleration` is the IDM of Treiber, Hennecke & Helbing (2000),
:func:`acc_acceleration` the constant-acceleration-heuristic blend of it,
:func:`curve_braking` the comfortable deceleration ahead of a curve and
:func:`earliest_arrival` the time a vehicle needs to reach a point (gap
acceptance at junctions, :mod:`minimanc.world.traffic`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "acc_acceleration",
    "curve_braking",
    "earliest_arrival",
    "idm_acceleration",
]

def idm_acceleration(
    v: np.ndarray | float,
    v0: np.ndarray | float,
    gap: np.ndarray | float,
    dv: np.ndarray | float,
    a_max: np.ndarray | float = 1.5,
    b: np.ndarray | float = 2.0,
    s0: np.ndarray | float = 2.0,
    T: np.ndarray | float = 1.5,
    delta: float = 4.0,
) -> np.ndarray:
    """Intelligent Driver Model acceleration (vectorised).

    ``v`` own speed, ``v0`` desired speed, ``gap`` bumper-to-bumper distance
    to the leader (``inf`` for a free road), ``dv = v - v_lead`` the closing
    speed; ``a_max`` maximum acceleration, ``b`` comfortable deceleration,
    ``s0`` jam distance, ``T`` time headway, ``delta`` the free-road exponent.
    Returns ``a_max [1 - (v/v0)^delta - (s*/gap)^2]`` with
    ``s* = s0 + max(0, v T + v dv / (2 sqrt(a_max b)))`` (no clipping).
    """
    v = np.asarray(v, dtype=np.float64)
    v0 = np.maximum(np.asarray(v0, dtype=np.float64), 1e-3)
    gap = np.maximum(np.asarray(gap, dtype=np.float64), 1e-2)
    s_star = s0 + np.maximum(0.0, v * T + v * dv / (2.0 * np.sqrt(a_max * b)))
    return a_max * (1.0 - (v / v0) ** delta - (s_star / gap) ** 2)


def acc_acceleration(
    v: np.ndarray | float,
    v0: np.ndarray | float,
    gap: np.ndarray | float,
    v_lead: np.ndarray | float,
    a_max: np.ndarray | float = 1.5,
    b: np.ndarray | float = 2.0,
    s0: np.ndarray | float = 2.0,
    T: np.ndarray | float = 1.5,
    coolness: float = 0.99,
) -> np.ndarray:
    """IDM with the constant-acceleration heuristic (the "ACC model", Treiber & Kesting 2013).

    Plain IDM over-reacts when a vehicle cuts in a few metres ahead while
    driving *faster*: ``s* / gap`` is large although the gap is opening. The
    constant-acceleration heuristic (CAH, the leader assumed not to
    accelerate) gives the deceleration that is actually needed,
    ``a_cah = 0`` if the leader is faster, else ``-(v - v_lead)^2 / (2 gap)``;
    when IDM asks for more braking than that, the two are blended:
    ``(1 - c) a_idm + c [a_cah + b tanh((a_idm - a_cah) / b)]``.
    """
    v = np.asarray(v, dtype=np.float64)
    v_lead = np.asarray(v_lead, dtype=np.float64)
    gap_c = np.maximum(np.asarray(gap, dtype=np.float64), 1e-2)
    a_idm = idm_acceleration(v, v0, gap_c, v - v_lead, a_max, b, s0, T)
    closing = np.maximum(v - v_lead, 0.0)
    a_cah = np.minimum(-(closing**2) / (2.0 * gap_c), a_max)
    blend = (1 - coolness) * a_idm + coolness * (a_cah + b * np.tanh((a_idm - a_cah) / b))
    return np.where(a_idm >= a_cah, a_idm, blend)


def curve_braking(v: np.ndarray, vlim2: np.ndarray, dist: np.ndarray,
                  dt: float) -> np.ndarray:
    """Acceleration bound from speed limits ahead: ``min_k (vlim_k^2 - v^2) / (2 d_k)``.

    ``vlim2 (N, P)`` squared limits at distances ``dist (N, P)`` ahead (``inf``
    where none). Negative: the deceleration that exactly meets the limit at
    the curve; positive: the most a vehicle may accelerate without exceeding
    a limit (distances are at least one step of travel, ``v dt``).
    """
    d = np.maximum(dist, np.maximum(v[:, None] * dt, 1.0))
    return ((vlim2 - v[:, None] ** 2) / (2.0 * d)).min(axis=1)


def earliest_arrival(d: float, v: float, v0: float, a: float) -> float:
    """Earliest time to cover ``d`` metres from speed ``v``, accelerating at ``a`` up to ``v0``."""
    if d <= 0:
        return 0.0
    v0 = max(v0, v, 0.5)
    t_acc = (v0 - v) / a
    d_acc = v * t_acc + 0.5 * a * t_acc**2
    if d <= d_acc:
        return (-v + math.sqrt(v * v + 2 * a * d)) / a
    return t_acc + (d - d_acc) / v0
