"""Chapter 9 — the closed-loop metrics table: one rollout's averages, and mean ± std over seeds.

Every per-scene metric (:mod:`minimanc.metrics.trajectory`,
:mod:`minimanc.metrics.safety`) returns an ``(S,)`` array; :func:`evaluate` averages
over the scenes and :func:`aggregate` turns one dict per training seed into
``mean ± std`` (population std over seeds, ``ddof = 0``; 0 for one seed).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.metrics.boxes import check_poses
from minimanc.metrics.safety import (
    CLOSE_GAP,
    at_fault_collisions,
    close_encounters,
    collisions,
    ttc_rate,
)
from minimanc.metrics.trajectory import (
    ade,
    goal_distance,
    max_acceleration,
    off_road,
    route_progress,
)

__all__ = [
    "TABLE_METRICS",
    "METRICS",
    "SAFETY_METRICS",
    "ALL_METRICS",
    "evaluate",
    "aggregate",
]

TABLE_METRICS: tuple[str, ...] = ("close_encounters", "max_acceleration", "ade", "goal_distance")
"""The paper's four Table I metrics, in its order."""

METRICS: tuple[str, ...] = TABLE_METRICS + ("collision_rate", "off_road_rate")
"""The paper's metrics and the two honesty checks (keys of :func:`evaluate`)."""

SAFETY_METRICS: tuple[str, ...] = ("at_fault_collision_rate", "ttc_rate", "route_progress")
"""At-fault collisions (%), time-to-collision below the bound (% of steps) and the progress
along the route relative to the human (a ratio), also returned by :func:`evaluate`."""

ALL_METRICS: tuple[str, ...] = METRICS + SAFETY_METRICS
"""Every key :func:`evaluate` returns."""


def evaluate(traj: Any, ds: Any, gap: float = CLOSE_GAP) -> dict[str, float]:
    """All metrics of one rollout, averaged over its scenes.

    The ados are the rollout's own when it holds them
    (``traj.ado``, ``traj.ado_valid``: the reactive protocol,
    ``agents="reactive"``), else the dataset's log.
    Keys: :data:`ALL_METRICS`; ``close_encounters``, ``collision_rate``,
    ``off_road_rate``, ``at_fault_collision_rate`` and ``ttc_rate`` in percent,
    ``route_progress`` a ratio, the rest in m or m/s².

    Parameters
    ----------
    traj : Rollout
        Has ``.ego``, poses ``(S, T, 3)`` ``[x, y, yaw]`` (a :class:`minimanc.rollout.Rollout`),
        and optionally ``.ado`` ``(S, T, A, 5)`` and ``.ado_valid`` ``(S, T, A)``.
    ds : Dataset
        The validation dataset it was rolled out on: ``ego`` ``(S, T, 3)``, ``ado``
        ``(S, T, A, 5)``, ``ado_valid`` ``(S, T, A)``, ``maps`` (one per scene).
    gap : float
        The close-encounter distance in m (:func:`~minimanc.metrics.safety.close_encounters`).

    Returns
    -------
    dict of str to float
        One value per key of :data:`ALL_METRICS`, the mean over the scenes.

    Raises
    ------
    ValueError
        If ``traj.ego`` and ``ds.ego`` are not finite poses of one shape ``(S, T, 3)``, or
        an input of a metric is invalid (each metric's own check).
    """
    ego = check_poses(traj.ego)
    human = check_poses(ds.ego, "ds.ego")
    if ego.shape != human.shape:
        raise ValueError(
            f"traj.ego must have the dataset's shape {human.shape}; got {ego.shape}"
        )
    ado, valid = ds.ado, ds.ado_valid
    if getattr(traj, "ado", None) is not None:
        ado, valid = traj.ado, traj.ado_valid
    return {
        "close_encounters": 100.0 * float(close_encounters(ego, ado, valid, gap).mean()),
        "max_acceleration": float(max_acceleration(ego).mean()),
        "ade": float(ade(ego, human).mean()),
        "goal_distance": float(goal_distance(ego, human[:, -1]).mean()),
        "collision_rate": 100.0 * float(collisions(ego, ado, valid).mean()),
        "off_road_rate": 100.0 * float(off_road(ego, ds.maps).mean()),
        "at_fault_collision_rate": 100.0 * float(
            at_fault_collisions(ego, ado, valid, ds.maps).mean()),
        "ttc_rate": 100.0 * float(ttc_rate(ego, ado, valid).mean()),
        "route_progress": float(route_progress(ego, human, ds.maps).mean()),
    }


def aggregate(per_seed: Sequence[Mapping[str, float]]) -> dict[str, dict[str, float]]:
    """``[{metric: value} per seed]`` → ``{metric: {"mean", "std", "n", "values"}}``.

    ``std`` is the population standard deviation over seeds (``ddof = 0``; NaN
    when a seed's value is infinite, e.g. a closed loop that blew up).
    Only the numeric keys present in every seed's dict are kept.

    Parameters
    ----------
    per_seed : sequence of mapping of str to float
        One dict of metrics per training seed (e.g. :func:`evaluate`'s), at least one.

    Returns
    -------
    dict of str to dict
        Per metric, ``"mean"`` and ``"std"`` (float, the metric's unit), ``"n"`` (int, the
        number of seeds) and ``"values"`` (list of float, one per seed).

    Raises
    ------
    ValueError
        If ``per_seed`` is empty.
    """
    if len(per_seed) == 0:
        raise ValueError("per_seed must hold at least one dict of metrics; got an empty sequence")
    def numeric(v: Any) -> bool:
        return isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool)

    keys = [k for k in per_seed[0] if all(k in d and numeric(d[k]) for d in per_seed)]
    out: dict[str, dict[str, Any]] = {}
    for k in keys:
        vals = np.array([float(d[k]) for d in per_seed])
        out[k] = {
            "mean": float(vals.mean()),
            "std": float(vals.std()) if np.all(np.isfinite(vals)) else float("nan"),
            "n": len(vals),
            "values": [float(x) for x in vals],
        }
    return out
