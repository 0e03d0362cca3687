"""Chapter 11 — the figures of DAgger: a metric over the rounds, against behaviour cloning.

:func:`plot_rounds` draws one line per DAgger run of :func:`minimanc.dagger.dagger` (the
metric of each round's closed loop, round 0 being behaviour cloning on the first
demonstrations) and behaviour cloning at the same label budget
(:func:`minimanc.dagger.behaviour_cloning`) as a dashed line; :func:`plot_study_rounds`
draws the same from the study's summary (:func:`minimanc.studies.dagger_study.run_dagger`),
one colour per model.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from minimanc.viz.style import METRIC_LABELS, model_colour, model_label, pyplot

if TYPE_CHECKING:  # for the annotations only: the figure needs no part of the loop
    from minimanc.dagger.loop import DaggerResult, RoundResult

__all__ = ["plot_rounds", "plot_study_rounds"]


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


def plot_study_rounds(res: dict, metric: str) -> Any:
    """The study's DAgger against BC for one metric: DAgger's mean by round, BC's as a line.

    Parameters
    ----------
    res : dict
        :func:`minimanc.studies.dagger_study.run_dagger`'s result: ``res["models"][model]``
        holds ``"by_round"`` (one ``{metric: {"mean": ...}}`` per round) and ``"bc"``
        (``{metric: {"mean": ...}}``).
    metric : str
        A metric every model's ``"by_round"`` and ``"bc"`` entries hold.

    Returns
    -------
    fig : matplotlib Figure
        One axes: per model (in its colour), DAgger by round (solid) and BC (dashed).
    """
    fig, ax = pyplot().subplots(figsize=(5, 3.5))
    for model, m in res["models"].items():
        y = [r[metric]["mean"] for r in m["by_round"]]
        c = model_colour(model)
        ax.plot(range(len(y)), y, "o-", color=c, label=f"{model_label(model)} DAgger")
        ax.axhline(m["bc"][metric]["mean"], color=c, ls="--",
                   label=f"{model_label(model)} BC")
    ax.set_xlabel("round")
    ax.set_ylabel(METRIC_LABELS.get(metric, metric))
    ax.legend(fontsize=7)
    return fig
