"""What every figure shares (chapters 5, 6 and 9): display names and colours, axes, saving.

* the names and colours of the models (read from :mod:`minimanc.models`' registry) and of the
  reference rows, and the axis labels of the metrics of :mod:`minimanc.metrics`;
* :func:`pyplot` (``matplotlib.pyplot``, imported on first use), :func:`save_figure`;
* :func:`state_labels` (the ``q_0 … q_{N-1}`` of every q-state figure) and
  :func:`clear_ticks`.

:func:`model_labels` and :func:`model_colours` read the registry on every call, so a model
registered later appears in them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from minimanc.models import registry

__all__ = [
    "METRIC_LABELS",
    "REFERENCE_COLOURS",
    "REFERENCE_LABELS",
    "check_metrics",
    "clear_ticks",
    "model_colour",
    "model_colours",
    "model_label",
    "model_labels",
    "pyplot",
    "save_figure",
    "state_labels",
]

REFERENCE_LABELS: dict[str, str] = {"human": "Human", "dmp_prior": "DMP at fixed gains",
                                    "expert": "Expert (the world's driver)",
                                    "style_floor": "Style floor (median-style driver)",
                                    "privileged": "Privileged learner (the expert's numbers)"}
"""Display names of the rows that are not learned models: the logged human (Table I) and the
no-learning reference (:func:`minimanc.rollout.fixed_gains`). A model's own display name is
the ``label`` of its :class:`~minimanc.models.ModelSpec`."""

REFERENCE_COLOURS: dict[str, str] = {"human": "#444444", "dmp_prior": "#a0a0a0",
                                     "expert": "#222222", "style_floor": "#777777",
                                     "privileged": "#555555"}
"""Colours of the rows that are not learned models (a model's is its spec's ``colour``)."""


def model_label(name: str) -> str:
    """Display name of a model or reference row.

    Parameters
    ----------
    name : str
        A registered model's name, or a key of :data:`REFERENCE_LABELS`.

    Returns
    -------
    label : str
        The model spec's ``label``, the :data:`REFERENCE_LABELS` entry, or ``name`` itself.
    """
    if name in registry.names():
        return registry.get(name).label
    return REFERENCE_LABELS.get(name, name)


def model_colour(name: str, default: str | None = None) -> str | None:
    """Colour of a model or reference row in figures.

    Parameters
    ----------
    name : str
        A registered model's name, or a key of :data:`REFERENCE_COLOURS`.
    default : str, optional (default: None)
        Returned for any other name.

    Returns
    -------
    colour : str or None
        The model spec's ``colour``, the :data:`REFERENCE_COLOURS` entry, or ``default``.
    """
    if name in registry.names():
        return registry.get(name).colour
    return REFERENCE_COLOURS.get(name, default)


def model_labels() -> dict[str, str]:
    """Display names of the logged human, every registered model and the fixed-gain DMP.

    Returns
    -------
    labels : dict of str to str
        ``{name: label}``: ``"human"`` first, then the models in registration order, then
        ``"dmp_prior"``; read from the registry on every call.
    """
    return {"human": REFERENCE_LABELS["human"],
            **{s.name: s.label for s in registry.specs()},
            "dmp_prior": REFERENCE_LABELS["dmp_prior"]}


def model_colours() -> dict[str, str]:
    """Colours of the reference rows and of every registered model.

    Returns
    -------
    colours : dict of str to str
        ``{name: colour}``: :data:`REFERENCE_COLOURS`, then the models in registration order;
        read from the registry on every call.
    """
    return {**REFERENCE_COLOURS, **{s.name: s.colour for s in registry.specs()}}


METRIC_LABELS: dict[str, str] = {
    "close_encounters": "% close encounters",
    "max_acceleration": "max |acceleration| (m/s²)",
    "ade": "ADE to human (m)",
    "goal_distance": "goal distance (m)",
    "collision_rate": "% scenes with a collision",
    "off_road_rate": "% scenes off road",
    "at_fault_collision_rate": "% scenes with an at-fault collision",
    "ttc_rate": "% steps with TTC < 1 s",
    "route_progress": "route progress (human = 1)",
    "along_track": "along-track error (m)",
    "cross_track": "cross-track error (m)",
    "along_bias": "along-track bias (m, < 0: behind)",
}
"""Axis labels of the metrics of :mod:`minimanc.metrics`."""


def check_metrics(metrics: Sequence[str]) -> None:
    """Refuse a metric name that has no :data:`METRIC_LABELS` entry.

    Parameters
    ----------
    metrics : sequence of str
        Metric names of :mod:`minimanc.metrics`.

    Raises
    ------
    ValueError
        Naming the first unknown metric.
    """
    for m in metrics:
        if m not in METRIC_LABELS:
            raise ValueError(f"metrics must be names from {sorted(METRIC_LABELS)}; got {m!r}")


def pyplot() -> Any:
    """``matplotlib.pyplot``, imported when the first figure is drawn.

    Returns
    -------
    plt : module
        ``matplotlib.pyplot``.
    """
    import matplotlib.pyplot as plt  # matplotlib only when a figure is drawn

    return plt


def save_figure(fig: Any, path: str | Path, dpi: int = 110) -> Path:
    """Write ``fig`` to ``path`` as PNG (parent folders created) and close it.

    Parameters
    ----------
    fig : matplotlib Figure
        The figure; closed afterwards.
    path : str or Path
        Where to write it.
    dpi : int, optional (default: 110)
        Resolution.

    Returns
    -------
    path : Path
        ``path``.
    """
    plt = pyplot()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return path


def state_labels(labels: Sequence[str] | None, n_states: int) -> Sequence[str]:
    """The ``N`` names of the q-states: ``labels``, or ``$q_0$ … $q_{N-1}$`` when None.

    Parameters
    ----------
    labels : sequence of str or None
        Names given by the caller.
    n_states : int
        Number of q-states ``N``.

    Returns
    -------
    labels : sequence of str
        ``N`` names.

    Raises
    ------
    ValueError
        If ``labels`` does not have ``N`` entries.
    """
    if labels is None:
        return [f"$q_{{{i}}}$" for i in range(n_states)]
    if len(labels) != n_states:
        raise ValueError(f"labels must have N = {n_states} entries; got {len(labels)}")
    return labels


def clear_ticks(ax: Any) -> Any:
    """Remove the x and y ticks of ``ax`` (for images).

    Parameters
    ----------
    ax : matplotlib Axes
        The axes.

    Returns
    -------
    ax : matplotlib Axes
        ``ax``, without ticks.
    """
    ax.set_xticks([])
    ax.set_yticks([])
    return ax
