"""Chapter 9 — every figure of the closed-loop study, under the module name the chapter uses.

The figures live in :mod:`minimanc.viz` and are re-exported here unchanged:

* **study plots** (:mod:`minimanc.viz.study`), drawn from the ``results`` dict that
  :mod:`minimanc.studies` writes to ``results.json`` — :func:`plot_table1`,
  :func:`plot_families`, :func:`plot_sample_efficiency` (Fig. 5a),
  :func:`plot_param_counts` (Fig. 5b), :func:`plot_q_states` (Fig. 7),
  :func:`plot_ablation` (Fig. 8), and ``FAMILY_METRICS``;
* **explainability** (:mod:`minimanc.viz.explain`), drawn from a
  :class:`minimanc.rollout.Rollout` — :func:`plot_explain_trace` (Fig. 4),
  :func:`saliency_maps` and :func:`plot_saliency_steps` (Fig. 3),
  :func:`plot_trajectories`, :func:`plot_speeds`, :func:`plot_q_modes`,
  :func:`gif_frames` and :func:`save_gif`;
* **names, colours, saving** (:mod:`minimanc.viz.style`) — :func:`model_label`,
  :func:`model_colour`, ``REFERENCE_LABELS``, ``REFERENCE_COLOURS``, ``METRIC_LABELS``,
  :func:`save`, and ``MODEL_LABELS`` / ``MODEL_COLOURS`` (read from the model registry
  when asked).

Every function returns the matplotlib ``Figure`` (or the GIF's path) and never calls
``plt.show()``; :func:`save` writes a figure to PNG and closes it.  Importing this module
imports no matplotlib: each figure imports it when drawn.
"""

from __future__ import annotations

from minimanc.viz.explain import (
    gif_frames,
    plot_explain_trace,
    plot_q_modes,
    plot_saliency_steps,
    plot_speeds,
    plot_trajectories,
    saliency_maps,
    save_gif,
)
from minimanc.viz.forward import forwarder
from minimanc.viz.study import (
    FAMILY_METRICS,
    plot_ablation,
    plot_families,
    plot_param_counts,
    plot_q_states,
    plot_sample_efficiency,
    plot_table1,
)
from minimanc.viz.style import (
    METRIC_LABELS,
    REFERENCE_COLOURS,
    REFERENCE_LABELS,
    model_colour,
    model_label,
    save,
)

__all__ = [
    "FAMILY_METRICS",
    "METRIC_LABELS",
    "REFERENCE_COLOURS",
    "REFERENCE_LABELS",
    "model_colour",
    "model_label",
    "save",
    "plot_table1",
    "plot_families",
    "plot_speeds",
    "plot_q_modes",
    "plot_sample_efficiency",
    "plot_param_counts",
    "plot_q_states",
    "plot_ablation",
    "plot_trajectories",
    "plot_explain_trace",
    "plot_saliency_steps",
    "saliency_maps",
    "gif_frames",
    "save_gif",
]

# read from the model registry on every access (a model registered later is listed)
__getattr__, __dir__ = forwarder(__name__, globals(), {
    "MODEL_LABELS": "minimanc.viz.style",
    "MODEL_COLOURS": "minimanc.viz.style",
})
