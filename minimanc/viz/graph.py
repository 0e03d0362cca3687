"""Chapter 1 — the computation graph of a function at a point, drawn with its cotangents.

:func:`plot_graph` draws a :class:`minimanc.autodiff.graph.Graph` (from
:func:`minimanc.autodiff.graph.computation_graph`): nodes in columns by depth, each edge an
arrow labelled with the cotangent that flows back along it (the VJP of its child's
primitive, as in reverse-mode training of the paper's Algorithm 1).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.autodiff.graph import Graph
from minimanc.viz.style import pyplot

__all__ = ["plot_graph"]


def plot_graph(graph: Graph, ax: Any = None, digits: int = 3) -> Any:
    """Draw ``graph`` on a matplotlib axes.

    Nodes sit in columns by depth (:meth:`~minimanc.autodiff.graph.Graph.depths`, the
    longest path from an input), each labelled with its name and shape; every edge is an
    arrow labelled with its cotangent (its value for a scalar, its norm ``|·|`` otherwise).

    Parameters
    ----------
    graph : Graph
        A computation graph.
    ax : matplotlib axes, optional (default: None)
        Where to draw; None makes a new figure.
    digits : int, optional (default: 3)
        Significant digits of the edge labels.

    Returns
    -------
    ax : matplotlib axes
        The axes drawn on.
    """
    if ax is None:
        _, ax = pyplot().subplots(figsize=(2.2 * (graph.depths()[1] + 1), 3.0))
    depth, max_depth = graph.depths()
    columns: dict[int, list[int]] = {}
    for node in graph.nodes:
        columns.setdefault(depth[node.index], []).append(node.index)
    pos = {}
    for d, members in columns.items():
        for k, i in enumerate(members):
            pos[i] = (float(d), (len(members) - 1) / 2.0 - k)
    seen: dict[tuple[int, int], int] = {}
    for e in graph.edges:
        k = seen.get((e.parent, e.child), 0)  # x * x: two edges between the same nodes
        seen[(e.parent, e.child)] = k + 1
        (x0, y0), (x1, y1) = pos[e.parent], pos[e.child]
        # a second edge between the same nodes, or one that would run through the
        # nodes of its row, is drawn as an arc below the straight line
        skips = y0 == y1 and abs(x1 - x0) > 1
        rad = 0.3 * k + (0.25 if skips else 0.0)
        ax.annotate("", xy=(x1, y1), xytext=(x0, y0),
                    arrowprops={"arrowstyle": "-|>", "color": "0.4", "shrinkA": 22,
                                "shrinkB": 22, "connectionstyle": f"arc3,rad={rad}"})
        ct = np.asarray(e.cotangent, dtype=np.float64)
        text = f"{float(ct):.{digits}g}" if ct.ndim == 0 else \
            f"|{float(np.linalg.norm(ct)):.{digits}g}|"
        if rad:  # the middle of the arc (data coordinates, as arc3 in a square box)
            lx, ly = (x0 + x1) / 2 + rad * (y1 - y0) / 2, (y0 + y1) / 2 - rad * (x1 - x0) / 2
        else:  # the middle of the arrow, just above it
            lx, ly = (x0 + x1) / 2, (y0 + y1) / 2 + 0.06
        ax.text(lx, ly, text, ha="center", va="bottom" if not rad else "center",
                fontsize=8, color="tab:red",
                bbox={"fc": "white", "ec": "none", "pad": 0.5, "alpha": 0.8})
    for node in graph.nodes:
        x, y = pos[node.index]
        shape = "()" if node.shape == () else str(node.shape)
        ax.text(x, y, f"{node.name}\n{shape}", ha="center", va="center", fontsize=9,
                bbox={"boxstyle": "round", "fc": "tab:blue" if node.index in graph.inputs
                      else "white", "ec": "0.3", "alpha": 0.3 if node.index in graph.inputs
                      else 1.0})
    height = max(len(m) for m in columns.values())
    ax.set_xlim(-0.5, max_depth + 0.5)
    ax.set_ylim(-height / 2 - 0.6, height / 2 + 0.5)
    ax.axis("off")
    return ax
