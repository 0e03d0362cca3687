"""Chapter 12 — what a perception must read: the numbers the expert perceives in every logged
state, as targets of the auxiliary perception loss (:mod:`minimanc.train.perception`).

The privileged learner drives on :func:`minimanc.diagnose.privileged.features`; an image model
must find the same numbers in its raster. :func:`perception_targets` gives them for every
state of a generated dataset (:data:`TARGETS`: own speed, the gap and closing speed
``v_lead − v`` to the leader and whether there is one, the distance to the yield point and
whether there is one, the curves' braking bound, the lateral offset, the heading error and
the path's lateral position ahead) with the mask that says where each one means something:
the gap and the closing speed only where there is a leader, the yield distance only where
there is a yield point (elsewhere the features hold the placeholders ``FAR`` and 0, which a
network must not be taught to predict).

With ``view`` (the :class:`~minimanc.world.RasterConfig` the model sees) a leader counts only
when its box reaches into the raster — its rear less than ``metres_ahead`` ahead and its
centre less than ``metres_side`` to the side, in the ego frame: the human finds leaders up to
``25 + 3.5 v`` m ahead along its path, beyond what a raster shows, and a leader the raster
does not show cannot be read from it.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from minimanc.dagger.expert import HumanExpert
from minimanc.diagnose.privileged import FEATURES, features
from minimanc.train.perception import PerceptionTargets
from minimanc.world.geometry import DT, to_ego_frame

__all__ = ["LOGITS", "TARGETS", "leader_boxes", "perception_targets"]

TARGETS: tuple[str, ...] = tuple(f for f in FEATURES if f != "a_prev")
"""The targets, in order: the expert's features (:data:`minimanc.diagnose.privileged.FEATURES`)
but its last acceleration, which one raster does not show."""
LOGITS: tuple[str, ...] = ("has_leader", "has_stop")
"""The presence flags among :data:`TARGETS` (a logistic loss)."""
MASKED_BY: dict[str, str] = {"gap": "has_leader", "dv": "has_leader", "stop": "has_stop"}
"""A target → the flag without which it means nothing (its mask)."""


def leader_boxes(ds: Any, expert: HumanExpert | None = None) -> np.ndarray:
    """The box of the leader the human perceives in every logged state, in the ego frame.

    Parameters
    ----------
    ds : minimanc.world.Dataset
        A generated dataset (its human can be re-simulated).
    expert : minimanc.dagger.expert.HumanExpert, optional
        The expert of ``ds`` (built when not given).

    Returns
    -------
    numpy.ndarray, shape (S, T, 5), float64
        ``[x, y, yaw, length, width]`` of the leader (NaN where there is none): the vehicle
        :meth:`minimanc.world.traffic.Traffic.perceive` names for the ego at that step of
        the human's run.
    """
    expert = HumanExpert(ds) if expert is None else expert
    pose = np.asarray(ds.ego, dtype=np.float64)
    out = np.full(pose.shape[:2] + (5,), np.nan)
    for s in range(pose.shape[0]):
        for t, step in enumerate(expert.steps(s)):
            w = copy.copy(step.traffic)  # perceive writes stamps and accepted gaps: on copies
            w.vehicles = [copy.copy(v) for v in step.traffic.vehicles]
            w.going = set(step.traffic.going)
            w.update_stamps(t)
            who = int(w.perceive()["who"][0])
            if who >= 0:
                veh = w.vehicles[who]
                x, y = to_ego_frame(np.asarray(veh.xy, dtype=np.float64), pose[s, t])
                out[s, t] = [x, y, veh.yaw - pose[s, t, 2], veh.length, veh.width]
    return out


def perception_targets(ds: Any, view: Any = None, expert: HumanExpert | None = None
                       ) -> PerceptionTargets:
    """The targets of the auxiliary perception loss for every logged state of ``ds``.

    Parameters
    ----------
    ds : minimanc.world.Dataset
        A generated dataset (its human can be re-simulated).
    view : minimanc.world.RasterConfig, optional
        The raster the model reads: a leader counts only when its box reaches into it
        (see the module docstring). ``None``: every leader the human perceives.
    expert : minimanc.dagger.expert.HumanExpert, optional
        The expert of ``ds`` (built when not given).

    Returns
    -------
    minimanc.train.perception.PerceptionTargets
        :data:`TARGETS` with values ``(S, T, K)`` as
        :func:`minimanc.diagnose.privileged.features` gives them (with ``view``,
        ``has_leader`` is 0 for a leader outside it), the masks of :data:`MASKED_BY` and
        the presence flags :data:`LOGITS`.

    Raises
    ------
    ValueError
        If ``view`` has no ``metres_ahead`` and ``metres_side``, or ``ds`` does not
        regenerate (:class:`~minimanc.dagger.expert.HumanExpert`).
    """
    if view is not None and not all(hasattr(view, a) for a in ("metres_ahead", "metres_side")):
        raise ValueError(f"view must be a minimanc.world.RasterConfig or None, got {view!r}")
    expert = HumanExpert(ds) if expert is None else expert
    pose = np.asarray(ds.ego, dtype=np.float64)
    S, T = pose.shape[:2]
    X = np.zeros((S, T, len(FEATURES)))
    for s in range(S):
        steps = expert.steps(s)
        for t, step in enumerate(steps):
            a_prev = (step.speed - steps[t - 1].speed) / DT if t else 0.0
            X[s, t] = features(expert.situation(s, t, pose[s, t], step.speed), a_prev)
    values = X[..., [FEATURES.index(n) for n in TARGETS]]
    if view is not None:
        box = leader_boxes(ds, expert)
        x, y, yaw, length, width = np.moveaxis(box, -1, 0)
        rear = x - 0.5 * (np.abs(np.cos(yaw)) * length + np.abs(np.sin(yaw)) * width)
        with np.errstate(invalid="ignore"):
            seen = (rear < view.metres_ahead) & (np.abs(y) < view.metres_side)
        lead = TARGETS.index("has_leader")
        values[..., lead] = values[..., lead] * seen
    mask = np.ones(values.shape, dtype=bool)
    for name, flag in MASKED_BY.items():
        mask[..., TARGETS.index(name)] = values[..., TARGETS.index(flag)] > 0
    return PerceptionTargets(TARGETS, values, mask, tuple(n in LOGITS for n in TARGETS))
