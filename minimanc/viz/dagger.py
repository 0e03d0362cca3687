"""Chapter 11 — the figure of DAgger: a metric over the rounds, against behaviour cloning.

:func:`plot_rounds` draws one line per DAgger run of :func:`minimanc.dagger.dagger` (the
metric of each round's closed loop, round 0 being behaviour cloning on the first
demonstrations) and behaviour cloning at the same label budget
(:func:`minimanc.dagger.behaviour_cloning`) as a dashed line.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from minimanc.viz.style import pyplot

if TYPE_CHECKING:  # for the annotations only: the figure needs no part of the loop
    from minimanc.dagger.loop import DaggerResult, RoundResult

__all__ = ["plot_rounds"]


def plot_rounds(results: Sequence[DaggerResult], metric: str = "ade",
                bc: Sequence[RoundResult] = (), ax: Any = None) -> Any:
    """A metric against the DAgger round, with behaviour cloning at the same budget.

    Parameters
    ----------
    results : sequence of DaggerResult
        DAgger runs; one line each, labelled with the run's ``name``.
    metric : str, optional (default: "ade")
        A key of the rounds' ``metrics``; rounds without it are left out.
    bc : sequence of RoundResult, optional (default: ())
        Behaviour-cloning runs at the same label budget: the mean of their ``metric`` is
        drawn as a dashed horizontal line (none when empty).
    ax : matplotlib axes, optional (default: None)
        Where to draw; None makes a new figure.

    Returns
    -------
    ax : matplotlib axes
        The axes drawn on.
    """
    if ax is None:
        _, ax = pyplot().subplots(figsize=(5, 3.2))
    for res in results:
        xs = [r.round for r in res.rounds if metric in r.metrics]
        ys = [r.metrics[metric] for r in res.rounds if metric in r.metrics]
        ax.plot(xs, ys, marker="o", label=f"DAgger {res.name}")
    vals = [r.metrics[metric] for r in bc if metric in r.metrics]
    if vals:
        ax.axhline(float(np.mean(vals)), ls="--", color="k", label="BC, same budget")
    ax.set_xlabel("round (0 = behaviour cloning)")
    ax.set_ylabel(metric)
    ax.legend(fontsize=8)
    return ax
