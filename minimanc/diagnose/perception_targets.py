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
centre less than ``metres_side`` to the side, in the ego frame (:func:`in_view`): the human
finds leaders up to ``25 + 3.5 v`` m ahead along its path, beyond what a raster shows, and a
leader the raster does not show cannot be read from it.

:func:`state_targets` gives the same numbers in any state the expert is asked in
(:class:`~minimanc.dagger.expert.Situation`): DAgger's teacher records them in the states the
learner visits (:class:`minimanc.dagger.WorldTeacher`'s ``perceive``), so that the auxiliary
loss also trains on-policy.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from minimanc.dagger.expert import HumanExpert, Situation
from minimanc.diagnose.privileged import FEATURES, features
from minimanc.train.perception import PerceptionTargets
from minimanc.world.geometry import to_ego_frame

__all__ = ["LOGITS", "TARGETS", "in_view", "leader_boxes", "perception_targets",
           "state_targets"]

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
    check_view(view)
    expert = HumanExpert(ds) if expert is None else expert
    pose = np.asarray(ds.ego, dtype=np.float64)
    S, T = pose.shape[:2]
    values = np.zeros((S, T, len(TARGETS)))
    mask = np.ones(values.shape, dtype=bool)
    for s in range(S):
        for t, step in enumerate(expert.steps(s)):
            values[s, t], mask[s, t] = state_targets(
                expert.situation(s, t, pose[s, t], step.speed), view)
    return PerceptionTargets(TARGETS, values, mask, tuple(n in LOGITS for n in TARGETS))


def check_view(view: Any) -> None:
    """``ValueError`` unless ``view`` is ``None`` or has ``metres_ahead`` and ``metres_side``
    (a :class:`~minimanc.world.RasterConfig`)."""
    if view is not None and not all(hasattr(view, a) for a in ("metres_ahead", "metres_side")):
        raise ValueError(f"view must be a minimanc.world.RasterConfig or None, got {view!r}")


def in_view(box: Any, view: Any) -> np.ndarray:
    """Whether leader boxes reach into the raster ``view``: the box's rear less than
    ``view.metres_ahead`` ahead and its centre less than ``view.metres_side`` to the side.

    Parameters
    ----------
    box : array_like, shape (..., 5)
        ``[x, y, yaw, length, width]`` in the ego frame (m, m, rad, m, m); NaN for none
        (:func:`leader_boxes`).
    view : minimanc.world.RasterConfig
        The raster the model reads.

    Returns
    -------
    numpy.ndarray of bool, shape (...)
        ``False`` where there is no box.
    """
    x, y, yaw, length, width = np.moveaxis(np.asarray(box, dtype=np.float64), -1, 0)
    rear = x - 0.5 * (np.abs(np.cos(yaw)) * length + np.abs(np.sin(yaw)) * width)
    with np.errstate(invalid="ignore"):
        return (rear < view.metres_ahead) & (np.abs(y) < view.metres_side)


def state_targets(sit: Situation, view: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """The targets :data:`TARGETS` in one asked state and where each counts.

    Parameters
    ----------
    sit : minimanc.dagger.expert.Situation
        What the expert perceives there (:meth:`HumanExpert.situation`).
    view : minimanc.world.RasterConfig, optional
        The raster the model reads: a leader outside it (:func:`in_view`) is no leader.

    Returns
    -------
    values : numpy.ndarray, shape (len(TARGETS),), float64
        :func:`minimanc.diagnose.privileged.features` but the last acceleration.
    mask : numpy.ndarray of bool, shape (len(TARGETS),)
        ``False`` for the targets of :data:`MASKED_BY` whose flag is 0.
    """
    check_view(view)
    values = features(sit)[[FEATURES.index(n) for n in TARGETS]]
    lead = TARGETS.index("has_leader")
    if view is not None and values[lead] > 0:
        veh, pose = sit.leader, sit.pose
        x, y = to_ego_frame(np.asarray(veh.xy, dtype=np.float64), pose)
        box = np.array([x, y, veh.yaw - pose[2], veh.length, veh.width])
        values[lead] = float(in_view(box, view))
    mask = np.ones(values.shape, dtype=bool)
    for name, flag in MASKED_BY.items():
        mask[TARGETS.index(name)] = values[TARGETS.index(flag)] > 0
    return values, mask
