"""The driving regime of every state and the open-loop error per regime: whether an error
concentrates where the human brakes or yields (read by ``dagger_budget.py``).

Each state of a drive is in one regime (:data:`REGIMES`), decided from what the human
perceives there (:func:`minimanc.diagnose.demonstrations` computes it) and the acceleration
it applied, in this order:

* ``yielding`` — a junction stop point where it must yield is closer than
  :data:`YIELD_DISTANCE`;
* ``braking`` — the applied acceleration is below :data:`BRAKING`;
* ``following`` — a leader is within :data:`FOLLOW_HEADWAY` seconds (plus
  :data:`FOLLOW_MARGIN` m) at the current speed;
* ``cruising`` — everything else (free road).

:func:`error_by_regime` splits the root-mean-square error of predicted controls by regime.
"""

from __future__ import annotations

from typing import Any

import numpy as np

REGIMES: tuple[str, ...] = ("cruising", "following", "braking", "yielding")
"""The driving regimes, by label index."""
YIELD_DISTANCE: float = 30.0
"""A stop point closer than this (m) makes the state ``yielding``."""
BRAKING: float = -0.5
"""An applied acceleration below this (m/s²) makes the state ``braking``."""
FOLLOW_HEADWAY: float = 3.0
"""A leader within this time gap (s) at the current speed makes the state ``following``."""
FOLLOW_MARGIN: float = 5.0
"""... plus this distance (m), so that a slow ego behind a close leader is following too."""


def _vec(name: str, x: Any, n: int | None = None) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 1 or (n is not None and len(a) != n):
        raise ValueError(f"{name} must be a 1-D array" + (f" of {n} states" if n else "")
                         + f"; got shape {a.shape}")
    if np.any(np.isnan(a)):
        raise ValueError(f"{name} holds NaN")
    return a


def regimes(speed: Any, gap: Any, stop: Any, acceleration: Any) -> np.ndarray:
    """The regime index (into :data:`REGIMES`) of ``N`` states: ``speed`` (m/s), ``gap`` to
    the leader and ``stop`` distance (m; ``inf`` or a far value when there is none) and the
    applied ``acceleration`` (m/s²), each ``(N,)``."""
    v = _vec("speed", speed)
    n = len(v)
    g, s, a = _vec("gap", gap, n), _vec("stop", stop, n), _vec("acceleration", acceleration, n)
    out = np.zeros(n, dtype=np.int64)
    out[g < FOLLOW_HEADWAY * v + FOLLOW_MARGIN] = REGIMES.index("following")
    out[a < BRAKING] = REGIMES.index("braking")
    out[s < YIELD_DISTANCE] = REGIMES.index("yielding")
    return out


def error_by_regime(pred: Any, target: Any, labels: Any) -> dict[str, dict[str, float]]:
    """``{regime: {"states", "share", "rmse_0", "rmse_1", …}}``: the number and share of the
    states in each regime and the RMSE of each column of ``pred (N, C)`` against
    ``target (N, C)`` over them (regimes with no state are left out)."""
    p = np.asarray(pred, dtype=np.float64)
    y = np.asarray(target, dtype=np.float64)
    lab = np.asarray(labels)
    if p.ndim != 2 or p.shape != y.shape or lab.shape != (len(p),):
        raise ValueError(f"pred and target must be (N, C) of one shape and labels (N,); got "
                         f"{p.shape}, {y.shape}, {lab.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(y))):
        raise ValueError("pred and target must be finite")
    out = {}
    for i, name in enumerate(REGIMES):
        m = lab == i
        if m.any():
            rmse = np.sqrt(((p[m] - y[m]) ** 2).mean(axis=0))
            out[name] = {"states": float(m.sum()), "share": float(m.mean()),
                         **{f"rmse_{c}": float(r) for c, r in enumerate(rmse)}}
    return out
