"""Chapter 9 — the smallest closed loop: :func:`drive_on_route` drives a bare head function
``(lane_target, motion) -> controls`` alone along a map's route (no traffic, no dataset, no
observation but the lane target and the motion), so that the DMP head a student writes in
chapter 8 can drive before any model exists (the chapter's figure,
:func:`minimanc.viz.exercises.plot_drive_attempts`). The course's closed loop is
:func:`minimanc.rollout.drive`."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from minimanc.world.geometry import DT, unicycle_step
from minimanc.world.lanes import Map
from minimanc.world.maps import lane_targets

__all__ = ["Head", "drive_on_route"]

Head = Callable[[np.ndarray, np.ndarray], Any]


def drive_on_route(head: Head, m: Map, start: Any, motion: Any, steps: int,
                   dt: float = DT) -> tuple[np.ndarray, np.ndarray]:
    """Drive ``head`` along the route of the map ``m`` in closed loop, alone on the road.

    A figure's minimal loop (no traffic, no scene, no observation but the lane target and
    the motion), so that a student's bare head function can drive; the course's closed
    loop is :func:`minimanc.rollout.drive`.

    Every step the lane target is read from the current pose
    (:func:`minimanc.world.lane_targets`), the head maps ``(lane_target (1, K, 2),
    motion (1, 2))`` to the controls ``[speed, yaw rate]``, the unicycle moves the pose
    by them (:func:`minimanc.world.unicycle_step`) and they become the next motion.

    Parameters
    ----------
    head : callable
        ``(lane_target, motion) -> controls`` of shape ``(1, 2)``.
    m : Map
        The map whose route gives the lane target.
    start : array-like, shape (3,)
        The first pose ``[x, y, yaw]``.
    motion : array-like, shape (2,)
        The first ``[speed, yaw rate]``.
    steps : int
        Control steps.
    dt : float, optional (default: 0.5)
        The step in seconds.

    Returns
    -------
    poses : ndarray, shape (steps + 1, 3)
    controls : ndarray, shape (steps, 2)

    Raises
    ------
    ValueError
        If the head returns another shape than ``(1, 2)`` or a value that is not finite.
    """
    pose, mot = np.asarray(start, dtype=float), np.asarray(motion, dtype=float)
    poses, controls = [pose], []
    for _ in range(steps):
        u = np.asarray(head(lane_targets(m, pose)[None], mot[None]), dtype=float)
        if u.shape != (1, 2) or not np.all(np.isfinite(u)):
            raise ValueError(f"the head must return finite controls of shape (1, 2), got "
                             f"{u.shape} {np.round(u, 3).tolist()}")
        mot = u[0]
        pose = unicycle_step(pose, mot, dt)
        poses.append(pose)
        controls.append(mot)
    return np.array(poses), np.array(controls)
