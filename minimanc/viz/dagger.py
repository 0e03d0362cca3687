"""Chapter 11 — the figures of DAgger: a metric over the rounds, against behaviour cloning.

:func:`plot_rounds` draws one line per DAgger run of :func:`minimanc.dagger.dagger` (the
metric of each round's closed loop, round 0 being behaviour cloning on the first
demonstrations) and behaviour cloning at the same label budget
(:func:`minimanc.dagger.behaviour_cloning`) as a dashed line; :func:`plot_study_rounds`
draws the same from the study's summary (:func:`minimanc.studies.dagger_study.run_dagger`),
one colour per model. :func:`plot_round_attempts` is the last figure of the chapter-11
exercises: the metric over the rounds of a DAgger loop run with the student's functions (the
β schedule, the budget split, the aggregation), drawn over the same loop run with the
library's (:func:`minimanc.dagger.beta_schedule`, :func:`minimanc.dagger.plan_budget`,
:func:`minimanc.dagger.concat`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.dagger.loop import DaggerResult, RoundResult
from minimanc.viz.exercises import attempt
from minimanc.viz.style import METRIC_LABELS, model_colour, model_label, pyplot

__all__ = ["plot_round_attempts", "plot_rounds", "plot_study_rounds"]


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


def plot_round_attempts(
    yours: Mapping[str, Callable[[], Sequence[float]]],
    reference: Mapping[str, Sequence[float]],
    bc: float | None = None,
    metric: str = "ade",
    ax: Any = None,
) -> Any:
    """The chapter-11 exercises' figure: a metric by DAgger round, the student's over the library's.

    Each entry of ``yours`` runs a DAgger loop with the student's functions and returns the
    metric after each round (round 0 = behaviour cloning on the first demonstrations); it
    is run through :func:`minimanc.viz.exercises.attempt`, so a stub or a bug is named in the
    title instead of stopping the figure, and only the reference is drawn for it.

    Parameters
    ----------
    yours : mapping of label to callable
        ``fn() -> [metric of round 0, round 1, ...]`` from the student's functions (markers,
        solid lines).
    reference : mapping of label to sequence of float
        The same loops run with the library's functions (dashed lines, same colour as the
        entry of ``yours`` with the same label).
    bc : float, optional (default: None)
        Behaviour cloning at the same label budget: a dotted horizontal line (none when
        None).
    metric : str, optional (default: "ade")
        The metric's name, for the axis label.
    ax : matplotlib axes, optional (default: None)
        Where to draw; None makes a new figure.

    Returns
    -------
    ax : matplotlib axes
        The axes drawn on.
    """
    if ax is None:
        _, ax = pyplot().subplots(figsize=(6, 3.6))
    labels = list(dict.fromkeys([*reference, *yours]))
    errors = []
    for k, label in enumerate(labels):
        colour = f"C{k}"
        ref = reference.get(label)
        if ref is not None:
            ax.plot(range(len(ref)), np.asarray(ref, dtype=float), "--", color=colour, lw=1.5,
                    alpha=0.7, label=f"{label} (library)")
        if label not in yours:
            continue
        values, error = attempt(yours[label])
        if not error:
            values, error = attempt(lambda v=values: np.asarray(v, dtype=float).reshape(-1))
        if not error and ref is not None and len(values) != len(ref):
            error = f"expected {len(ref)} rounds, got {len(values)}"
        if error:
            errors.append(f"{label}: {error}")
            continue
        ax.plot(range(len(values)), values, "o-", color=colour, ms=4, label=f"{label} (yours)")
    if bc is not None:
        ax.axhline(float(bc), ls=":", color="k", label="BC, same budget")
    ax.set_xlabel("round (0 = behaviour cloning on the first demonstrations)")
    ax.set_ylabel(METRIC_LABELS.get(metric, metric))
    ax.set_title("\n".join(errors) or "your DAgger rounds (solid) over the library's (dashed)",
                 fontsize=8 if errors else 10)
    if ax.get_lines():
        ax.legend(fontsize=7)
    return ax
