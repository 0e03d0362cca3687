"""Chapter 10 — the figure of the highway-env sandbox: episodes driven by a controller.

:func:`plot_episode_attempts` is the last figure of the chapter-10 exercises: a highway-env
episode (:class:`minimanc.highway.Episode`) driven by the student's controller, its path and
its speed, over the library's episodes of the same seed (the expert's, the lane follower's).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from minimanc.viz.exercises import attempt
from minimanc.viz.style import pyplot

__all__ = ["plot_episode_attempts"]


def _episode_arrays(episode: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An episode's ``poses (T+1, 3)``, ``speeds (T+1,)`` and ``crashed (T+1,)``, checked."""
    poses = np.asarray(episode.poses, dtype=float)
    speeds = np.asarray(episode.speeds, dtype=float)
    crashed = np.asarray(episode.crashed, dtype=bool)
    if poses.ndim != 2 or poses.shape[1] != 3 or speeds.shape != poses.shape[:1] \
            or crashed.shape != poses.shape[:1]:
        raise ValueError(f"expected poses (T+1, 3), speeds and crashed (T+1,); got "
                         f"{poses.shape}, {speeds.shape}, {crashed.shape}")
    return poses, speeds, crashed


def plot_episode_attempts(
    yours: Mapping[str, Callable[[], Any]],
    reference: Mapping[str, Any],
    axes: Any = None,
) -> Any:
    """The chapter-10 exercises' figure: episodes driven by the student's controller.

    An episode is anything with ``poses`` ``(T+1, 3)`` world poses, ``speeds`` ``(T+1,)``
    and ``crashed`` ``(T+1,)`` (a :class:`minimanc.highway.Episode`). Left: the paths, the
    start as a dot and the first crashed step as a cross; right: the speed over the steps.
    Each entry of ``yours`` is run through :func:`minimanc.viz.exercises.attempt`, so a stub
    or a bug is named in the title and only the references are drawn.

    Parameters
    ----------
    yours : mapping of label to callable
        ``fn() -> episode`` driving with the student's functions (solid lines).
    reference : mapping of label to episode
        The library's episodes of the same seed, e.g. the expert's (dashed lines).
    axes : pair of matplotlib axes, optional (default: None)
        Where to draw the paths and the speeds; None makes a new figure.

    Returns
    -------
    axes : pair of matplotlib axes
        The path and speed axes.
    """
    if axes is None:
        _, axes = pyplot().subplots(1, 2, figsize=(11, 4))
    path_ax, speed_ax = axes
    errors = []

    def draw(label: str, episode: Any, style: str, colour: str) -> None:
        poses, speeds, crashed = _episode_arrays(episode)
        tag = " (crashed)" if crashed.any() else ""
        path_ax.plot(poses[:, 0], poses[:, 1], style, color=colour, label=f"{label}{tag}")
        path_ax.plot(poses[:1, 0], poses[:1, 1], "o", color=colour, ms=5)
        if crashed.any():
            k = int(np.argmax(crashed))
            path_ax.plot(poses[k, 0], poses[k, 1], "x", color=colour, ms=10, mew=2)
        speed_ax.plot(np.arange(len(speeds)), speeds, style, color=colour, label=label)

    for k, (label, episode) in enumerate(reference.items()):
        draw(f"{label} (library)", episode, "--", f"C{k}")
    for k, (label, fn) in enumerate(yours.items(), start=len(reference)):
        episode, error = attempt(fn)
        if not error:
            _, error = attempt(draw, label, episode, "-", f"C{k}")
        if error:
            errors.append(f"{label}: {error}")
    path_ax.set_aspect("equal", adjustable="datalim")
    path_ax.set_xlabel("x (m)")
    path_ax.set_ylabel("y (m)")
    path_ax.set_title("\n".join(errors) or "paths (dot: start, cross: first crash)",
                      fontsize=8 if errors else 10)
    speed_ax.set_xlabel("step (0.5 s)")
    speed_ax.set_ylabel("speed (m/s)")
    for ax in axes:
        if ax.get_lines():
            ax.legend(fontsize=7)
    return axes
