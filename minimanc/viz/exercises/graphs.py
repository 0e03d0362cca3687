"""Chapter 0 — chapter 1's figure: the computation graph with the cotangent on each edge,
the student's ``edge_cotangents`` (:func:`plot_edge_cotangents`, through
:func:`graph_of_edges`) next to :func:`minimanc.autodiff.graph.computation_graph`."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.autodiff import toposort
from minimanc.autodiff.graph import Edge, Graph, Node
from minimanc.viz.exercises.attempts import attempt
from minimanc.viz.graph import plot_graph
from minimanc.viz.style import pyplot

__all__ = ["graph_of_edges", "plot_edge_cotangents"]


def graph_of_edges(edges: Sequence[tuple[Any, Any, Any]], names: Mapping[int, str]) -> Graph:
    """A :class:`~minimanc.autodiff.graph.Graph` of ``(parent, child, cotangent)`` triples.

    The nodes are any objects with ``.parents`` and ``.value`` (chapter 1's ``Var``);
    the output is the one child that is nobody's parent.

    Parameters
    ----------
    edges : sequence of (parent, child, cotangent)
        One triple per edge, as chapter 1's ``edge_cotangents`` returns them.
    names : mapping of id(node) to str
        Labels of the inputs; other nodes are named ``v<k>`` in forward order.

    Returns
    -------
    Graph
        Nodes in forward order (inputs first), one edge per triple.

    Raises
    ------
    ValueError
        If ``edges`` is empty or has no single output.
    """
    if not edges:
        raise ValueError("edges must hold at least one (parent, child, cotangent) triple")
    parents = {id(p) for p, _, _ in edges}
    ends = {id(c): c for _, c, _ in edges if id(c) not in parents}
    if len(ends) != 1:
        raise ValueError(f"edges must have one output (a child that is nobody's parent), "
                         f"got {len(ends)}")
    forward = toposort(next(iter(ends.values())), parents_of=lambda v: v.parents)[::-1]
    index = {id(n): k for k, n in enumerate(forward)}
    nodes = tuple(
        Node(k, names.get(id(n), f"v{k}"), (), np.asarray(getattr(n, "value", np.nan)))
        for k, n in enumerate(forward)
    )
    argnum: dict[int, int] = {}
    out = []
    for p, c, cot in edges:
        argnum[id(c)] = argnum.get(id(c), -1) + 1
        out.append(Edge(index[id(p)], index[id(c)], argnum[id(c)], np.asarray(cot, float)))
    inputs = tuple(index[id(n)] for n in forward if not n.parents)
    return Graph(nodes, tuple(out), inputs, index[id(forward[-1])])


def plot_edge_cotangents(
    edge_cotangents: Callable[[Any], Sequence[tuple[Any, Any, Any]]],
    end: Any,
    names: Mapping[int, str],
    reference: Graph,
) -> Any:
    """Chapter 1's figure: the library's computation graph (left) and the student's (right).

    Parameters
    ----------
    edge_cotangents : callable
        The student's function: output node → list of ``(parent, child, cotangent)``.
    end : node
        The output of a computation built from nodes with ``.parents`` and ``.value``.
    names : mapping of id(node) to str
        Labels of the inputs.
    reference : Graph
        The same computation from :func:`~minimanc.autodiff.graph.computation_graph`.

    Returns
    -------
    fig : matplotlib Figure
    """
    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 3.6))
    plot_graph(reference, ax=left)
    left.set_title("library: computation_graph")
    edges, error = attempt(edge_cotangents, end)
    if not error:
        graph, error = attempt(graph_of_edges, list(edges), names)
    if error:
        right.set_axis_off()
        right.set_title(f"your edge_cotangents: {error}", fontsize=9)
    else:
        plot_graph(graph, ax=right)
        right.set_title("yours: edge_cotangents (the labels must agree)")
    return fig
