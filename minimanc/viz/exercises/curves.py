"""Chapter 0 — the figures of chapters 3 and 4, curves drawn from the student's functions over
the library's: the largest stable α over β of each integrator
(:func:`plot_stability_boundary`, chapter 3) and any curves over time
(:func:`plot_curve_attempts`: the yaw of the quaternion DMP of eq. 2, chapter 4)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.viz.exercises.attempts import attempt
from minimanc.viz.style import pyplot

__all__ = ["plot_curve_attempts", "plot_stability_boundary"]


def plot_stability_boundary(
    yours: Mapping[str, Callable[[float], float]],
    reference: Mapping[str, Callable[[float], float]],
    betas: Sequence[float],
    h: float,
) -> Any:
    """Chapter 3's figure: the largest stable α over β for one sub-step of length ``h``.

    Parameters
    ----------
    yours : mapping of label to callable
        ``beta -> alpha_max`` from the student's functions (markers).
    reference : mapping of label to callable
        The same bounds from the library (lines), in the same order.
    betas : sequence of float
        Where to evaluate them.
    h : float
        The sub-step length in seconds (for the title).

    Returns
    -------
    fig : matplotlib Figure
    """
    plt = pyplot()
    grid = np.asarray(betas, float)
    fig, ax = plt.subplots(figsize=(7, 4))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (label, fn) in enumerate(reference.items()):
        ax.plot(grid, [fn(float(b)) for b in grid], "-", color=colours[k % len(colours)],
                alpha=0.6, label=f"{label} (library)")
    errors = []
    for k, (label, fn) in enumerate(yours.items()):
        values, error = attempt(lambda f=fn: [float(f(float(b))) for b in grid])
        if error:
            errors.append(f"{label}: {error}")
        else:
            ax.plot(grid, values, "o", ms=3.5, color=colours[k % len(colours)], label=label)
    ax.set_xlabel("β (1/s)")
    ax.set_ylabel("largest stable α (1/s)")
    ax.set_title("\n".join(errors) or f"stable below each curve, one sub-step h = {h:g} s",
                 fontsize=9)
    ax.legend(fontsize=8)
    return fig


def plot_curve_attempts(
    x: Any,
    curves: Sequence[tuple[str, Callable[[], Any], Any]],
    ax: Any = None,
    title: str = "",
) -> Any:
    """Draw each of a student's curves (solid) over its reference (dashed).

    Parameters
    ----------
    x : array-like, shape (n,)
        Abscissa shared by every curve.
    curves : sequence of (label, fn, reference)
        ``fn()`` returns the student's ``n`` values; ``reference`` is the library's
        (or None: nothing to compare with). A ``fn`` that raises is named in the title
        and only its reference is drawn.
    ax : matplotlib Axes, optional (default: None)
        Axes to draw on; a new figure when None.
    title : str, optional (default: "")
        Title when no function raised.

    Returns
    -------
    ax : matplotlib Axes
        The axes with one line per curve that could be drawn, and a legend if any.
    """
    plt = pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(6.5, 3.5))
    x = np.asarray(x, dtype=float)
    errors = []
    for k, (label, fn, reference) in enumerate(curves):
        colour = f"C{k}"
        if reference is not None:
            ax.plot(x, np.asarray(reference, dtype=float), "--", color=colour, lw=1,
                    label=f"{label}: reference")
        values, error = attempt(fn)
        if error:
            errors.append(f"{label}: {error}")
            continue
        values = np.asarray(values, dtype=float)
        if values.shape != x.shape:
            errors.append(f"{label}: expected {x.shape[0]} values, got shape {values.shape}")
            continue
        ax.plot(x, values, "o-", color=colour, ms=3, label=f"{label}: yours")
    ax.set_title("\n".join(errors) or title, fontsize=7 if errors else None)
    if ax.get_lines():
        ax.legend(fontsize=8)
    return ax
