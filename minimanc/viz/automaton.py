"""Chapter 5 — the figures of vAGN: the automaton graph of ``T`` and q over time.

:func:`plot_automaton` draws the automaton of one transition matrix (eq. 9's
``T = colsoftmax(ReLU(W^p))``), :func:`plot_q_heatmap` a q-distribution over time as in
the paper's execution traces.  vAGN never produces an exact zero (see
:mod:`minimanc.vagn`), so a sparse graph comes only from ``plot_automaton``'s ``min_prob``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.checks import check_stochastic_columns
from minimanc.vagn import check_state
from minimanc.viz.style import pyplot, state_labels

__all__ = ["plot_automaton", "plot_q_heatmap"]


def plot_automaton(
    T: Any,
    ax: Any = None,
    labels: list[str] | None = None,
    q: Any = None,
    min_prob: float = 0.0,
    show_probs: bool = True,
    max_width: float = 8.0,
) -> Any:
    """Draw the automaton of a transition matrix ``T``.

    Nodes are the q-states on a circle (shaded by ``q`` if given: darker = more
    probable, as in the paper's q-distribution plots); the arrow ``j → i`` has
    width ``max_width · T[i, j]``; self-loops are drawn as small rings.

    Parameters
    ----------
    T : array-like, shape (N, N)
        Column-stochastic transition matrix.
    ax : matplotlib Axes, optional (default: None)
        Axes to draw on; a new 4 × 4 inch figure when None.
    labels : list of str, optional (default: None)
        ``N`` node labels; ``q_0 … q_{N-1}`` when None.
    q : array-like, shape (N,), optional (default: None)
        Distribution shading the nodes.
    min_prob : float, optional (default: 0.0)
        Edges with ``T[i, j] < min_prob`` are hidden — the only way to get a
        sparse picture, since vAGN never produces exact zeros.
    show_probs : bool, optional (default: True)
        Label each edge with its probability.
    max_width : float, optional (default: 8.0)
        Line width of an edge of probability 1.

    Returns
    -------
    ax : matplotlib Axes
        ``ax`` (or the new axes) holding the graph, its axis switched off.

    Raises
    ------
    TypeError
        If ``T`` or ``q`` is not real numbers.
    ValueError
        If ``T`` is not a column-stochastic ``(N, N)`` matrix, ``labels`` does not
        have ``N`` entries, or ``q`` is not a distribution over ``N`` states.
    """
    from matplotlib.patches import Circle, FancyArrowPatch  # matplotlib only when a figure is drawn

    plt = pyplot()
    T = check_stochastic_columns("T", T)
    if T.ndim != 2:
        raise ValueError(f"T must have shape (N, N); got T with shape {T.shape}")
    N = T.shape[0]
    labels = state_labels(labels, N)
    if q is not None:
        check_state(q, N)
        q = np.asarray(q, dtype=float)
    if ax is None:
        _, ax = plt.subplots(figsize=(4, 4))
    angles = np.pi / 2 - 2 * np.pi * np.arange(N) / N
    pos = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    r_node = 0.27 if N <= 6 else 0.16
    rad = 0.2  # curvature of the arcs, so that i → j and j → i do not overlap
    cmap = plt.get_cmap("Blues")
    text_box = {"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85}
    for j in range(N):
        for i in range(N):
            w = T[i, j]
            if w < min_prob:
                continue
            if i == j:
                out = pos[i] / np.linalg.norm(pos[i]) if N > 1 else np.array([0.0, 1.0])
                centre = pos[i] + out * (r_node + 0.12)
                ax.add_patch(
                    Circle(centre, 0.12, fill=False, lw=max(max_width * w, 0.3), color="0.3")
                )
                if show_probs:
                    ax.text(*(centre + out * 0.24), f"{w:.2f}", ha="center", va="center",
                            fontsize=7, bbox=text_box)
                continue
            d = pos[i] - pos[j]
            dist = np.linalg.norm(d)
            u = d / dist
            start, end = pos[j] + u * r_node, pos[i] - u * r_node
            ax.add_patch(
                FancyArrowPatch(start, end, arrowstyle="-|>", mutation_scale=12,
                                connectionstyle=f"arc3,rad={rad}",
                                lw=max(max_width * w, 0.3), color="0.3")
            )
            if show_probs:
                # arc3 bends towards (u_y, -u_x); the curve's midpoint sits rad·|d|/2
                # away; the label goes just beyond it, clear of a thick arrow
                normal = np.array([u[1], -u[0]])
                off = rad * np.linalg.norm(end - start) / 2 + 0.06 + 0.012 * max_width * w
                mid = (start + end) / 2 + normal * off
                ax.text(*mid, f"{w:.2f}", ha="center", va="center", fontsize=7, bbox=text_box)
    for i in range(N):
        face = cmap(0.15 + 0.8 * q[i]) if q is not None else "white"
        ax.add_patch(Circle(pos[i], r_node, facecolor=face, edgecolor="black", zorder=3))
        dark = q is not None and q[i] > 0.55
        ax.text(*pos[i], labels[i], ha="center", va="center", zorder=4, fontsize=9,
                color="white" if dark else "black")
    lo, hi = pos.min(axis=0) - 0.75, pos.max(axis=0) + 0.75
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.axis("off")
    return ax


def plot_q_heatmap(
    qs: Any,
    ax: Any = None,
    labels: list[str] | None = None,
    cmap: str = "Blues",
    colorbar: bool = True,
) -> Any:
    """Heat map of the q-distribution over time, as in the paper's execution traces.

    Rows are q-states, columns time steps, colour the probability in [0, 1]
    (darker = more probable).

    Parameters
    ----------
    qs : array-like, shape (T, N)
        Distributions over time.
    ax : matplotlib Axes, optional (default: None)
        Axes to draw on; a new figure when None.
    labels : list of str, optional (default: None)
        ``N`` row labels; ``q_0 … q_{N-1}`` when None.
    cmap : str, optional (default: "Blues")
        Matplotlib colormap name.
    colorbar : bool, optional (default: True)
        Add a colour bar.

    Returns
    -------
    ax : matplotlib Axes
        ``ax`` (or the new axes) holding the heat map, time along x.

    Raises
    ------
    TypeError
        If ``qs`` is not real numbers.
    ValueError
        If ``qs`` is not of shape ``(T, N)`` or not distributions, or ``labels``
        does not have ``N`` entries.
    """
    plt = pyplot()
    shape = np.shape(qs)
    if len(shape) != 2:
        raise ValueError(f"qs must have shape (T, N); got qs with shape {shape}")
    check_state(qs, shape[1], name="qs")
    qs = np.asarray(qs, dtype=float)
    N = qs.shape[1]
    labels = state_labels(labels, N)
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 0.4 * N + 1))
    im = ax.imshow(qs.T, aspect="auto", cmap=cmap, vmin=0.0, vmax=1.0,
                   interpolation="nearest")
    ax.set_yticks(range(N))
    ax.set_yticklabels(labels)
    ax.set_xlabel("time step")
    if colorbar:
        ax.figure.colorbar(im, ax=ax, label="P(q-state)")
    return ax
