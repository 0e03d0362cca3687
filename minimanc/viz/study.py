"""Chapter 9 — the study's figures: Table I, scenario families, Figs. 5a, 5b, 7 and 8.

Each is drawn from the ``results`` dict that :mod:`minimanc.studies` writes to
``results.json``: :func:`plot_table1` (Table I as bars, both information settings, one
protocol of the ados), :func:`plot_families` (one metric per scenario family),
:func:`plot_sample_efficiency` (Fig. 5a), :func:`plot_param_counts` (Fig. 5b),
:func:`plot_q_states` (Fig. 7) and :func:`plot_ablation` (Fig. 8).  An aggregate is
``{metric: {"mean", "std"}}`` (:func:`minimanc.metrics.aggregate`); error bars are the std
over seeds.  Every function returns the matplotlib ``Figure`` and never calls
``plt.show()``; :func:`minimanc.viz.style.save_figure` writes it to PNG.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.viz.style import METRIC_LABELS, check_metrics, model_colour, model_label, pyplot

__all__ = [
    "FAMILY_METRICS",
    "plot_table1",
    "plot_families",
    "plot_sample_efficiency",
    "plot_param_counts",
    "plot_q_states",
    "plot_ablation",
]

_TABLE = ("close_encounters", "max_acceleration", "ade", "goal_distance")


def _ms(agg: Mapping[str, Any], metric: str) -> tuple[float, float]:
    entry = agg.get(metric)
    if entry is None:
        return float("nan"), 0.0
    return float(entry["mean"]), float(entry["std"])


def _grouped_bars(
    aggs: Mapping[str, Mapping[str, Mapping[str, Any]]],
    metrics: Sequence[str],
    panel_width: float,
    bar_style: Callable[[int, str, list[str]], dict],
    label: Callable[[str], str],
    **tick_kw: Any,
) -> tuple[Any, np.ndarray]:
    """A figure with one panel per metric: a bar group per inner key of ``aggs`` (in order of
    appearance, ticks named ``label(group)``), in it one bar per outer key (``aggs[series]
    [group]`` an aggregate, error bar its std); ``bar_style(k, series, groups)`` gives the
    series' colour, hatch and label. Returns the figure and its axes."""
    series = list(aggs)
    groups = list(dict.fromkeys(g for name in series for g in aggs[name]))
    fig, axes = pyplot().subplots(1, len(metrics), figsize=(panel_width * len(metrics), 3.4))
    axes = np.atleast_1d(axes)
    width = 0.8 / len(series)
    x = np.arange(len(groups))
    for ax, metric in zip(axes, metrics):
        for k, name in enumerate(series):
            means, stds = zip(*[_ms(aggs[name].get(g, {}), metric) for g in groups])
            ax.bar(x + (k - (len(series) - 1) / 2) * width, means, width, yerr=stds,
                   edgecolor="black", linewidth=0.5, capsize=2, **bar_style(k, name, groups))
        ax.set_xticks(x)
        ax.set_xticklabels([label(g) for g in groups], **tick_kw)
        ax.set_title(METRIC_LABELS[metric], fontsize=10)
    return fig, axes


def plot_table1(
    table: Mapping[str, Mapping[str, Mapping[str, Any]]],
    metrics: Sequence[str] = _TABLE,
) -> Any:
    """Table I as bar charts: one panel per metric, one bar group per model, one bar per setting.

    ``table[setting][model]`` is an aggregate from :func:`minimanc.metrics.aggregate`
    (``{metric: {"mean", "std"}}``); error bars are the std over seeds.
    """
    check_metrics(metrics)
    if not table:
        raise ValueError("table must hold at least one setting; got an empty mapping")
    hatches = ["", "//", "..", "xx"]
    fig, axes = _grouped_bars(table, metrics, 3.6, lambda k, setting, models: {
        "color": [model_colour(m, "grey") for m in models],
        "hatch": hatches[k % len(hatches)], "label": setting},
        model_label, rotation=40, ha="right")
    if len(table) > 1:
        axes[0].legend(title="setting", fontsize=8)
    fig.suptitle("Closed-loop performance (Table I); lower is better")
    fig.tight_layout()
    return fig


FAMILY_METRICS: tuple[str, ...] = ("ade", "along_track", "cross_track",
                                    "at_fault_collision_rate")
"""The panels of :func:`plot_families`: the ADE, its split, and at-fault collisions."""


def plot_families(
    families: Mapping[str, Mapping[str, Mapping[str, Any]]],
    metrics: Sequence[str] = FAMILY_METRICS,
    title: str = "",
) -> Any:
    """Table I's rows per scenario family: one panel per metric, one bar group per family,
    one bar per model.

    ``families[model][family]`` is an aggregate (:func:`minimanc.metrics.aggregate`), as
    in ``results["families"][agents][setting]``; error bars are the std over seeds.
    """
    check_metrics(metrics)
    if not families:
        raise ValueError("families must hold at least one model; got an empty mapping")
    colours = pyplot().rcParams["axes.prop_cycle"].by_key()["color"]
    fig, axes = _grouped_bars(families, metrics, 3.8, lambda k, m, fams: {
        "color": model_colour(m, colours[k % len(colours)]), "label": model_label(m)},
        lambda f: f.replace("_", "-"))
    axes[0].legend(fontsize=7)
    fig.suptitle(title or "Per scenario family; lower is better")
    fig.tight_layout()
    return fig


def plot_sample_efficiency(study: Mapping[str, Any], metric: str = "ade") -> Any:
    """ADE (or ``metric``) against the share of training data, one line per model (Fig. 5a).

    ``study = {"fractions": [...], "models": {name: [aggregate per fraction]}}``.
    """
    check_metrics([metric])
    plt = pyplot()
    fr = np.asarray(study["fractions"], dtype=float)
    fig, ax = plt.subplots(figsize=(4.6, 3.4))
    for name, aggs in study["models"].items():
        m, s = np.array([_ms(a, metric) for a in aggs]).T
        ax.errorbar(100 * fr, m, yerr=s, marker="o", capsize=3, label=model_label(name),
                    color=model_colour(name))
    ax.set_xlabel("training data used (%)")
    ax.set_ylabel(METRIC_LABELS[metric])
    ax.set_xticks(100 * fr)
    ax.set_title("Sample efficiency")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_param_counts(counts: Mapping[str, int]) -> Any:
    """Number of trainable parameters per model (Fig. 5b)."""
    if not counts:
        raise ValueError("counts must hold at least one model; got an empty mapping")
    plt = pyplot()
    names = list(counts)
    fig, ax = plt.subplots(figsize=(4.6, 3.0))
    vals = [int(counts[n]) for n in names]
    bars = ax.bar(range(len(names)), vals, color=[model_colour(n, "grey") for n in names])
    for b, v in zip(bars, vals):
        ax.text(b.get_x() + b.get_width() / 2, v, f"{v:,}", ha="center", va="bottom", fontsize=8)
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels([model_label(n) for n in names], rotation=30, ha="right")
    ax.set_ylabel("parameters")
    ax.set_title("Model size")
    fig.tight_layout()
    return fig


def plot_q_states(study: Mapping[str, Any], metrics: Sequence[str] = _TABLE) -> Any:
    """Every metric against the number of q-states (Fig. 7).

    ``study = {"n_states": [3, 6, ...], "results": [aggregate per n]}``.
    """
    check_metrics(metrics)
    plt = pyplot()
    n = np.asarray(study["n_states"])
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.3 * len(metrics), 3.0))
    axes = np.atleast_1d(axes)
    for ax, metric in zip(axes, metrics):
        m, s = np.array([_ms(a, metric) for a in study["results"]]).T
        ax.errorbar(n, m, yerr=s, marker="o", capsize=3, color=model_colour("manc"))
        ax.set_xticks(n)
        ax.set_xlabel("number of q-states")
        ax.set_title(METRIC_LABELS[metric], fontsize=10)
    fig.suptitle("MANC: varying the number of q-states")
    fig.tight_layout()
    return fig


def plot_ablation(study: Mapping[str, Any], metrics: Sequence[str] = _TABLE) -> Any:
    """MANC against its ablations, one panel per metric (Fig. 8).

    ``study = {"models": {name: aggregate}}``.
    """
    check_metrics(metrics)
    plt = pyplot()
    names = list(study["models"])
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.0 * len(metrics), 3.0))
    axes = np.atleast_1d(axes)
    for ax, metric in zip(axes, metrics):
        m, s = np.array([_ms(study["models"][k], metric) for k in names]).T
        ax.bar(range(len(names)), m, yerr=s, capsize=3,
               color=[model_colour(k, "grey") for k in names])
        ax.set_xticks(range(len(names)))
        ax.set_xticklabels([model_label(k) for k in names], rotation=30, ha="right")
        ax.set_title(METRIC_LABELS[metric], fontsize=10)
    fig.suptitle("Self-ablation")
    fig.tight_layout()
    return fig
