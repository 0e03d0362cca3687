"""Chapter 5 — ``minimanc.vagn``: the visual automaton generative network (eqs. 8–9).

* :mod:`minimanc.vagn.automaton` — the soft automaton: its weights and states, the
  transition matrix of eq. 9, one :func:`step`, a :func:`rollout` and what a trained
  automaton shows (stationary distribution, most likely states and path); its names are
  gathered here (``vagn.step``, ``vagn.rollout``, ...);
* :mod:`minimanc.vagn.fused` — one vAGN update as one differentiable function with a
  hand-written VJP (:data:`~minimanc.vagn.fused.fused_step`), the NumPy engine's kernel.

The figures (``plot_automaton``, ``plot_q_heatmap``) are in :mod:`minimanc.viz.automaton`.
"""

from minimanc.vagn.automaton import (
    check_state,
    check_weights,
    combined_weights,
    init_vagn,
    min_transition_probability,
    most_likely_path,
    most_likely_states,
    random_state,
    rollout,
    stationary_distribution,
    step,
    transition_matrix,
    uniform_state,
)

__all__ = [
    "check_state",
    "check_weights",
    "combined_weights",
    "init_vagn",
    "min_transition_probability",
    "most_likely_path",
    "most_likely_states",
    "random_state",
    "rollout",
    "stationary_distribution",
    "step",
    "transition_matrix",
    "uniform_state",
]
