"""Chapter 9 — why a driver fails: the driving regime of every state, the open-loop error per
regime, and the collisions a closed loop caused, by kind, with the speed at contact.

**Regimes.** Each state of a drive is in one regime (:data:`REGIMES`), decided from what the
human perceives there (:mod:`minimanc.dagger.privileged` computes it) and the acceleration
it applied, in this order:

* ``yielding`` — a junction stop point where it must yield is closer than
  :data:`YIELD_DISTANCE`;
* ``braking`` — the applied acceleration is below :data:`BRAKING`;
* ``following`` — a leader is within :data:`FOLLOW_HEADWAY` seconds (plus
  :data:`FOLLOW_MARGIN` m) at the current speed;
* ``cruising`` — everything else (free road).

:func:`error_by_regime` splits the root-mean-square error of predicted controls by regime,
so that an error concentrated where the human brakes or yields shows as such.

**Perception.** :func:`linear_probe` asks whether a representation (a model's backbone
features of each state) holds a quantity (the gap to the leader, say): a ridge regression
``y ≈ [z, 1] w`` with ``z`` the features standardised on the training states and
``w = (ZᵀZ + λI)⁻¹ Zᵀ y`` (intercept not penalised), scored by its coefficient of
determination ``R² = 1 − Σ(y − ŷ)² / Σ(y − ȳ)²`` on held-out states. A quantity the
features hold linearly has ``R²`` near 1; one they do not, near 0 (or below).

**Collisions.** :func:`collision_taxonomy` counts the first contacts of
:func:`minimanc.metrics.safety.collision_events` by kind (``front``: the ego ran into the
vehicle ahead; ``stopped_ado``: into a standing one; ``lateral``: beside it, at fault when
outside its lane; ``rear``: hit from behind; ``stopped_ego``: hit while standing) and, for
the contacts the ego is at fault in, compares its speed at the step of contact with the
human's at the same step of the same scene (speeds: finite differences of positions).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc.metrics.boxes import check_poses
from minimanc.metrics.safety import COLLISION_TYPES, collision_events
from minimanc.world.geometry import DT

__all__ = ["BRAKING", "FOLLOW_HEADWAY", "FOLLOW_MARGIN", "REGIMES", "YIELD_DISTANCE",
           "collision_taxonomy", "error_by_regime", "linear_probe", "regimes"]

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


def _matrix(name: str, x: Any) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    a = a.reshape(len(a), -1) if a.ndim >= 1 else a
    if a.ndim != 2 or len(a) == 0 or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a finite array with a leading axis of states; got "
                         f"shape {np.shape(x)}")
    return a


def linear_probe(z_train: Any, y_train: Any, z_test: Any, y_test: Any, ridge: float = 1.0
                 ) -> dict[str, np.ndarray]:
    """The ridge read-out of the module docstring: fitted on ``z_train (N, …)`` (flattened
    per state) → ``y_train (N, K)``, scored on ``z_test``, ``y_test``. Returns ``r2 (K,)``
    and ``rmse (K,)`` on the test states and ``std (K,)`` of ``y_test``."""
    Z, Zt = _matrix("z_train", z_train), _matrix("z_test", z_test)
    Y, Yt = _matrix("y_train", y_train), _matrix("y_test", y_test)
    if Z.shape[1] != Zt.shape[1] or Y.shape[1] != Yt.shape[1] or len(Z) != len(Y) \
            or len(Zt) != len(Yt):
        raise ValueError(f"z_train {Z.shape}, y_train {Y.shape}, z_test {Zt.shape} and y_test "
                         f"{Yt.shape} must agree in states and columns")
    if not (np.isfinite(ridge) and ridge >= 0):
        raise ValueError(f"ridge must be >= 0, got {ridge!r}")
    mu, sd = Z.mean(0), Z.std(0) + 1e-8
    A = np.hstack([(Z - mu) / sd, np.ones((len(Z), 1))])
    pen = np.full(A.shape[1], float(ridge))
    pen[-1] = 0.0
    w = np.linalg.solve(A.T @ A + np.diag(pen), A.T @ Y)
    pred = np.hstack([(Zt - mu) / sd, np.ones((len(Zt), 1))]) @ w
    res = ((Yt - pred) ** 2).sum(0)
    tot = ((Yt - Yt.mean(0)) ** 2).sum(0)
    return {"r2": 1.0 - res / np.where(tot > 0, tot, 1.0),
            "rmse": np.sqrt(res / len(Yt)), "std": Yt.std(0)}


def _speeds(ego: np.ndarray, dt: float) -> np.ndarray:
    """``(S, T)`` speeds: the step that led to ``t`` (the first step's: that of ``t = 1``)."""
    d = np.linalg.norm(np.diff(ego[..., :2], axis=1), axis=-1) / dt
    return np.concatenate([d[:, :1], d], axis=1)


def collision_taxonomy(ego: Any, ado: Any, ado_valid: Any, human: Any,
                       maps: Sequence[Any] | None = None, dt: float = DT) -> dict[str, float]:
    """The collisions of a rollout ``ego (S, T, 3)`` among ``ado``/``ado_valid`` by kind:
    ``{kind: contacts}`` for every kind of :data:`minimanc.metrics.safety.COLLISION_TYPES`,
    ``"at_fault"`` (contacts the ego is at fault in), and for those ``"ego_speed"`` and
    ``"human_speed"`` (mean m/s at the step of contact; NaN without one) and ``"faster"``
    (the share in which the ego was faster than the human ``human (S, T, 3)``)."""
    e = check_poses(ego)
    h = check_poses(human, "human")
    if h.shape != e.shape:
        raise ValueError(f"human must have the rollout's shape {e.shape}; got {h.shape}")
    events = collision_events(e, ado, ado_valid, maps, dt)
    out: dict[str, float] = {k: float(sum(ev.kind == k for ev in events))
                             for k in COLLISION_TYPES}
    fault = [ev for ev in events if ev.at_fault]
    out["at_fault"] = float(len(fault))
    ve, vh = _speeds(e, dt), _speeds(h, dt)
    a = np.array([ve[ev.scene, ev.step] for ev in fault])
    b = np.array([vh[ev.scene, ev.step] for ev in fault])
    out["ego_speed"] = float(a.mean()) if len(a) else float("nan")
    out["human_speed"] = float(b.mean()) if len(b) else float("nan")
    out["faster"] = float((a > b).mean()) if len(a) else float("nan")
    return out
