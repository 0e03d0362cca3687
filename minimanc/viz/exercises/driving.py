"""Chapter 0 — the figures of chapters 8 and 9, closed-loop driving: the student's DMP head
driving a map over the library's (:func:`plot_drive_attempts`, through
:func:`minimanc.rollout.drive_on_route`), and the displacement from the human split along
and across the human's heading by the student's split over
:func:`minimanc.metrics.along_cross_track` (:func:`plot_track_error_attempts`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from minimanc.metrics.trajectory import along_cross_track as library_along_cross_track
from minimanc.rollout.route import Head, drive_on_route
from minimanc.viz.exercises.attempts import attempt
from minimanc.viz.style import pyplot
from minimanc.viz.world import plot_map
from minimanc.world.geometry import DT
from minimanc.world.lanes import Map

__all__ = ["plot_drive_attempts", "plot_track_error_attempts"]


def plot_drive_attempts(
    m: Map,
    start: Any,
    motion: Any,
    head: Head,
    reference: Head,
    steps: int = 40,
    dt: float = DT,
) -> Any:
    """Chapter 8's figure: the student's DMP head and the library's driving one map.

    Both heads run :func:`drive_on_route` from the same pose and motion; the left panel draws
    the two paths on the map (the student's solid, the library's dashed), the right
    one the speed over time. The title gives the largest distance between the two
    paths, or names the error of a head that raised.

    Parameters
    ----------
    m : Map
        The map (its route gives the lane target).
    start : array-like, shape (3,)
        The first pose.
    motion : array-like, shape (2,)
        The first ``[speed, yaw rate]``.
    head : callable
        The student's head, ``(lane_target (1, K, 2), motion (1, 2)) -> (1, 2)``.
    reference : callable
        The library's head, same signature.
    steps : int, optional (default: 40)
        Control steps.
    dt : float, optional (default: 0.5)
        The step in seconds.

    Returns
    -------
    fig : matplotlib Figure
    """
    ref_poses, ref_u = drive_on_route(reference, m, start, motion, steps, dt)
    out, error = attempt(drive_on_route, head, m, start, motion, steps, dt)
    plt = pyplot()
    fig, (top, speed) = plt.subplots(1, 2, figsize=(10, 4.2))
    plot_map(m, top)
    top.plot(ref_poses[:, 0], ref_poses[:, 1], "--", color="tab:green", lw=2.5,
             label="library head")
    t = dt * np.arange(1, steps + 1)
    speed.plot(t, ref_u[:, 0], "--", color="tab:green", lw=2.5, label="library head")
    drawn = [ref_poses[:, :2]]
    if error:
        title = f"your head: {error}"
    else:
        poses, u = out
        drawn.append(poses[:, :2])
        top.plot(poses[:, 0], poses[:, 1], "-", color="tab:red", lw=1.2, label="your head")
        speed.plot(t, u[:, 0], "-", color="tab:red", lw=1.2, label="your head")
        gap = float(np.max(np.linalg.norm(poses[:, :2] - ref_poses[:, :2], axis=1)))
        title = f"your head (solid) over the library's (dashed): paths at most {gap:.2f} m apart"
    every = np.concatenate(drawn)
    lo, hi = every.min(axis=0) - 20.0, every.max(axis=0) + 20.0
    half = 0.5 * float(np.max(hi - lo))
    mid = 0.5 * (lo + hi)
    top.set_xlim(mid[0] - half, mid[0] + half)
    top.set_ylim(mid[1] - half, mid[1] + half)
    top.legend(fontsize=8, loc="lower right")
    speed.set_xlabel("time (s)")
    speed.set_ylabel("speed (m/s)")
    speed.legend(fontsize=8)
    fig.suptitle(title, fontsize=9)
    return fig


def plot_track_error_attempts(
    runs: Mapping[str, Callable[[], Any]],
    human: Any,
    along_cross_track: Callable[[Any, Any], Any],
    dt: float = DT,
) -> Any:
    """Chapter 9's figure: how far each closed-loop run is behind or ahead of the human
    (left) and beside the human's line (right), over time.

    The displacement from the human at each step is split in the frame of the human's
    heading (along, cross); each panel shows its mean magnitude over the scenes, from
    the student's ``along_cross_track`` (solid) over
    :func:`minimanc.metrics.along_cross_track` (dashed), one colour per run. A run or a
    split that raises is named in the title and only what could be computed is drawn.

    Parameters
    ----------
    runs : mapping of label to callable
        ``run()`` returns the poses ``(S, T, 3)`` of one closed-loop run.
    human : array-like, shape (S, T, 3)
        The human's poses.
    along_cross_track : callable
        The student's ``(ego, human) -> (along, cross)``, each ``(S, T)``.
    dt : float, optional (default: 0.5)
        The step in seconds (the time axis).

    Returns
    -------
    fig : matplotlib Figure

    Raises
    ------
    ValueError
        If ``human`` is not ``(S, T, 3)``.
    """
    ref_human = np.asarray(human, dtype=float)
    if ref_human.ndim != 3 or ref_human.shape[-1] != 3:
        raise ValueError(f"human must have shape (S, T, 3), got {ref_human.shape}")
    t = dt * np.arange(ref_human.shape[1])
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    errors = []
    for k, (label, run) in enumerate(runs.items()):
        colour = f"C{k}"
        ego, error = attempt(run)
        if error:
            errors.append(f"{label}: {error}")
            continue
        reference = library_along_cross_track(ego, ref_human)
        split, error = attempt(along_cross_track, ego, ref_human)
        if not error:
            shapes = [np.shape(x) for x in split] if isinstance(split, tuple) else None
            if shapes != [np.shape(reference[0])] * 2:
                error = f"expected (along, cross) of shape {np.shape(reference[0])}, got {shapes}"
        if error:
            errors.append(f"your along_cross_track on {label}: {error}")
        for j, ax in enumerate(axes):
            ax.plot(t, np.abs(reference[j]).mean(axis=0), "--", color=colour, lw=1,
                    label=f"{label}: library")
            if not error:
                ax.plot(t, np.abs(np.asarray(split[j], dtype=float)).mean(axis=0), "o-",
                        color=colour, ms=3, label=f"{label}: yours")
    for ax, name in zip(axes, ("along", "across")):
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"mean |{'along' if name == 'along' else 'cross'}| (m)")
        ax.set_yscale("symlog", linthresh=0.1)
        ax.set_title(f"{name} the human's heading", fontsize=9)
        if ax.get_lines():
            ax.legend(fontsize=7)
    fig.suptitle("\n".join(errors) or "your along_cross_track (solid) over the library's "
                 "(dashed)", fontsize=9)
    return fig
