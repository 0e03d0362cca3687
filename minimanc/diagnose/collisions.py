"""Chapter 12 — how a driver crashes: the collisions a closed loop caused, by kind, with the
speed at contact.

:func:`collision_taxonomy` counts the first contacts of
:func:`minimanc.metrics.safety.collision_events` (nuPlan's rules, as Table I's at-fault
collisions) by kind (``front``: the ego ran into the vehicle ahead; ``stopped_ado``: into a
standing one; ``lateral``: beside it, at fault when outside its lane; ``rear``: hit from
behind; ``stopped_ego``: hit while standing) and, for the contacts the ego is at fault in,
compares its speed at the step of contact with the human's at the same step of the same
scene (speeds: finite differences of positions). A driver that does not see its leader
rear-ends it (``front``, ``stopped_ado``), faster than the human was.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc.metrics.boxes import check_poses
from minimanc.metrics.safety import COLLISION_TYPES, collision_events
from minimanc.world.geometry import DT

__all__ = ["collision_taxonomy"]


def _speeds(ego: np.ndarray, dt: float) -> np.ndarray:
    """``(S, T)`` speeds: the step that led to ``t`` (the first step's: that of ``t = 1``)."""
    d = np.linalg.norm(np.diff(ego[..., :2], axis=1), axis=-1) / dt
    return np.concatenate([d[:, :1], d], axis=1)


def collision_taxonomy(ego: Any, ado: Any, ado_valid: Any, human: Any,
                       maps: Sequence[Any] | None = None, dt: float = DT) -> dict[str, float]:
    """The collisions of a rollout by kind, and the speeds at the at-fault contacts.

    Parameters
    ----------
    ego : array_like, shape (S, T, 3)
        The rollout's poses.
    ado : array_like, shape (S, T, A, 5)
        The ados' boxes the rollout drove among.
    ado_valid : array_like, shape (S, T, A)
        Which ados exist.
    human : array_like, shape (S, T, 3)
        The logged human's poses in the same scenes.
    maps : sequence of Map, optional
        The scenes' maps (a lateral contact is at fault outside a lane).
    dt : float, optional (default: DT)
        The step (s).

    Returns
    -------
    dict of str to float
        ``{kind: contacts}`` for every kind of
        :data:`minimanc.metrics.safety.COLLISION_TYPES`, ``"at_fault"`` (contacts the ego is
        at fault in), and for those ``"ego_speed"`` and ``"human_speed"`` (mean m/s at the
        step of contact; NaN without one) and ``"faster"`` (the share in which the ego was
        faster than the human).

    Raises
    ------
    ValueError
        If ``human`` does not have the rollout's shape (or the poses are not finite).
    """
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
