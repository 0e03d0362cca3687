"""Chapter 0 — chapter 2's figure: optimiser paths on the valley ½(100 θ₀² + θ₁²), the
student's momentum and Adam steps over :mod:`minimanc.optim`'s (:func:`plot_valley_paths`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.viz.exercises.attempts import attempt
from minimanc.viz.style import pyplot

__all__ = ["plot_valley_paths"]

Step = Callable[[np.ndarray, np.ndarray, Any, int], tuple[np.ndarray, Any]]


def _path(step: Step, state: Any, scales: np.ndarray, start: np.ndarray, steps: int):
    theta, path = start.copy(), [start.copy()]
    for t in range(1, steps + 1):
        theta, state = step(theta, scales * theta, state, t)
        path.append(np.asarray(theta, float).copy())
    return np.array(path)


def plot_valley_paths(
    yours: Mapping[str, tuple[Step, Any]],
    reference: Mapping[str, tuple[Step, Any]],
    steps: int = 100,
    scales: Sequence[float] = (100.0, 1.0),
    start: Sequence[float] = (1.0, 1.0),
) -> Any:
    """Chapter 2's figure: optimiser paths on the valley f(θ) = ½ Σ scalesᵢ θᵢ².

    Each run is ``(step, state)`` with ``step(theta, grad, state, t) -> (theta, state)``
    (``t`` counts from 1); the gradient is ``scales * theta``.

    Parameters
    ----------
    yours : mapping of label to (step, initial state)
        Runs that call the student's functions (solid lines).
    reference : mapping of label to (step, initial state)
        The same runs with the library's optimisers (dashed lines).
    steps : int, optional (default: 100)
        Steps per run.
    scales : sequence of float, optional (default: (100, 1))
        The curvature of each coordinate.
    start : sequence of float, optional (default: (1, 1))
        The first θ.

    Returns
    -------
    fig : matplotlib Figure
    """
    plt = pyplot()
    scale, theta0 = np.asarray(scales, float), np.asarray(start, float)
    fig, ax = plt.subplots(figsize=(6.5, 4))
    errors, drawn = [], [np.array([[-1.2, -0.3], [1.2, 1.2]])]
    for label, (step, state) in reference.items():
        path = _path(step, state, scale, theta0, steps)
        drawn.append(path)
        ax.plot(path[:, 0], path[:, 1], "--", lw=2.5, alpha=0.6, label=f"{label} (library)")
    for label, (step, state) in yours.items():
        path, error = attempt(_path, step, state, scale, theta0, steps)
        if error:
            errors.append(f"{label}: {error}")
        else:
            drawn.append(path[np.all(np.isfinite(path), axis=1)])
            ax.plot(path[:, 0], path[:, 1], ".-", lw=1, ms=3, label=label)
    every = np.concatenate(drawn)
    lo, hi = np.clip(every.min(axis=0), -10, 0), np.clip(every.max(axis=0), 0, 10)
    t0, t1 = np.meshgrid(np.linspace(lo[0], hi[0], 120), np.linspace(lo[1], hi[1], 120))
    ax.contour(t0, t1, scale[0] * t0 ** 2 + scale[1] * t1 ** 2, levels=20, colors="0.85")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_xlabel("θ0 (steep)")
    ax.set_ylabel("θ1 (flat)")
    ax.set_title("\n".join(errors) or "your steps (solid) over the library's (dashed)",
                 fontsize=9)
    ax.legend(fontsize=8)
    return fig
