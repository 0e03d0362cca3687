"""Chapter 0 — a chapter's key figure, redrawn from the student's own functions.

Every exercises notebook ends with one cell that calls a function of this module with
the functions the student wrote (it saves nothing, the cell ends in ``plt.show()``).
The figure draws the student's result over the library's reference, so a wrong answer
shows as a curve, a path or a label that departs from it. A function that raises (a
stub still raising ``NotImplementedError``, or a bug) is named in its panel's title
with the error, and only the reference is drawn: the notebook runs to the end.

* chapter 1: :func:`plot_edge_cotangents` — the computation graph with the cotangent
  on each edge (the student's ``edge_cotangents`` next to
  :func:`minimanc.autodiff.graph.computation_graph`);
* chapter 2: :func:`plot_valley_paths` — optimiser paths on the valley
  ½(100 θ₀² + θ₁²) (the student's momentum and Adam steps next to
  :mod:`minimanc.optim`);
* chapter 3: :func:`plot_stability_boundary` — the largest stable α over β for one
  sub-step of each integrator (the student's bounds next to the library's);
* chapter 4 (and any chapter whose figure is curves over time):
  :func:`plot_curve_attempts` — each of the student's curves solid over its reference
  dashed (the yaw of the quaternion DMP of eq. 2 turning the short way, trailing and
  tracking a turning goal).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.autodiff import toposort
from minimanc.autodiff.graph import Edge, Graph, Node
from minimanc.viz.graph import plot_graph
from minimanc.viz.style import pyplot

__all__ = [
    "attempt",
    "graph_of_edges",
    "plot_curve_attempts",
    "plot_edge_cotangents",
    "plot_stability_boundary",
    "plot_valley_paths",
]


def attempt(fn: Callable[..., Any], *args: Any) -> tuple[Any, str]:
    """``(fn(*args), "")``, or ``(None, "ErrorName: message")`` when ``fn`` raises.

    Parameters
    ----------
    fn : callable
        A student's function (or anything that may raise).
    *args
        Its arguments.

    Returns
    -------
    value, error : tuple
        The value (None on an error) and the error as one line ("" when none).
    """
    try:
        return fn(*args), ""
    except Exception as exc:  # noqa: BLE001 - the figure names any error of the student's
        text = " ".join(str(exc).split())
        return None, f"{type(exc).__name__}: {text[:80]}" if text else type(exc).__name__


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


Step = Callable[[np.ndarray, np.ndarray, Any, int], tuple[np.ndarray, Any]]


def _path(step: Step, state: Any, scales: np.ndarray, start: np.ndarray, steps: int):
    theta, path = start.copy(), [start.copy()]
    for t in range(1, steps + 1):
        theta, state = step(theta, scales * theta, state, t)
        path.append(np.asarray(theta, float).copy())
    return np.array(path)


def plot_valley_paths(
    yours: Mapping[str, tuple[Step, Any]],
    reference: Mapping[str, tuple[Step, Any]],
    steps: int = 100,
    scales: Sequence[float] = (100.0, 1.0),
    start: Sequence[float] = (1.0, 1.0),
) -> Any:
    """Chapter 2's figure: optimiser paths on the valley f(θ) = ½ Σ scalesᵢ θᵢ².

    Each run is ``(step, state)`` with ``step(theta, grad, state, t) -> (theta, state)``
    (``t`` counts from 1); the gradient is ``scales * theta``.

    Parameters
    ----------
    yours : mapping of label to (step, initial state)
        Runs that call the student's functions (solid lines).
    reference : mapping of label to (step, initial state)
        The same runs with the library's optimisers (dashed lines).
    steps : int, optional (default: 100)
        Steps per run.
    scales : sequence of float, optional (default: (100, 1))
        The curvature of each coordinate.
    start : sequence of float, optional (default: (1, 1))
        The first θ.

    Returns
    -------
    fig : matplotlib Figure
    """
    plt = pyplot()
    scale, theta0 = np.asarray(scales, float), np.asarray(start, float)
    fig, ax = plt.subplots(figsize=(6.5, 4))
    errors, drawn = [], [np.array([[-1.2, -0.3], [1.2, 1.2]])]
    for label, (step, state) in reference.items():
        path = _path(step, state, scale, theta0, steps)
        drawn.append(path)
        ax.plot(path[:, 0], path[:, 1], "--", lw=2.5, alpha=0.6, label=f"{label} (library)")
    for label, (step, state) in yours.items():
        path, error = attempt(_path, step, state, scale, theta0, steps)
        if error:
            errors.append(f"{label}: {error}")
        else:
            drawn.append(path[np.all(np.isfinite(path), axis=1)])
            ax.plot(path[:, 0], path[:, 1], ".-", lw=1, ms=3, label=label)
    every = np.concatenate(drawn)
    lo, hi = np.clip(every.min(axis=0), -10, 0), np.clip(every.max(axis=0), 0, 10)
    t0, t1 = np.meshgrid(np.linspace(lo[0], hi[0], 120), np.linspace(lo[1], hi[1], 120))
    ax.contour(t0, t1, scale[0] * t0 ** 2 + scale[1] * t1 ** 2, levels=20, colors="0.85")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_xlabel("θ0 (steep)")
    ax.set_ylabel("θ1 (flat)")
    ax.set_title("\n".join(errors) or "your steps (solid) over the library's (dashed)",
                 fontsize=9)
    ax.legend(fontsize=8)
    return fig


def plot_stability_boundary(
    yours: Mapping[str, Callable[[float], float]],
    reference: Mapping[str, Callable[[float], float]],
    betas: Sequence[float],
    h: float,
) -> Any:
    """Chapter 3's figure: the largest stable α over β for one sub-step of length ``h``.

    Parameters
    ----------
    yours : mapping of label to callable
        ``beta -> alpha_max`` from the student's functions (markers).
    reference : mapping of label to callable
        The same bounds from the library (lines), in the same order.
    betas : sequence of float
        Where to evaluate them.
    h : float
        The sub-step length in seconds (for the title).

    Returns
    -------
    fig : matplotlib Figure
    """
    plt = pyplot()
    grid = np.asarray(betas, float)
    fig, ax = plt.subplots(figsize=(7, 4))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (label, fn) in enumerate(reference.items()):
        ax.plot(grid, [fn(float(b)) for b in grid], "-", color=colours[k % len(colours)],
                alpha=0.6, label=f"{label} (library)")
    errors = []
    for k, (label, fn) in enumerate(yours.items()):
        values, error = attempt(lambda f=fn: [float(f(float(b))) for b in grid])
        if error:
            errors.append(f"{label}: {error}")
        else:
            ax.plot(grid, values, "o", ms=3.5, color=colours[k % len(colours)], label=label)
    ax.set_xlabel("β (1/s)")
    ax.set_ylabel("largest stable α (1/s)")
    ax.set_title("\n".join(errors) or f"stable below each curve, one sub-step h = {h:g} s",
                 fontsize=9)
    ax.legend(fontsize=8)
    return fig


def plot_curve_attempts(
    x: Any,
    curves: Sequence[tuple[str, Callable[[], Any], Any]],
    ax: Any = None,
    title: str = "",
) -> Any:
    """Draw each of a student's curves (solid) over its reference (dashed).

    Parameters
    ----------
    x : array-like, shape (n,)
        Abscissa shared by every curve.
    curves : sequence of (label, fn, reference)
        ``fn()`` returns the student's ``n`` values; ``reference`` is the library's
        (or None: nothing to compare with). A ``fn`` that raises is named in the title
        and only its reference is drawn.
    ax : matplotlib Axes, optional (default: None)
        Axes to draw on; a new figure when None.
    title : str, optional (default: "")
        Title when no function raised.

    Returns
    -------
    ax : matplotlib Axes
        The axes with one line per curve that could be drawn, and a legend if any.
    """
    plt = pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(6.5, 3.5))
    x = np.asarray(x, dtype=float)
    errors = []
    for k, (label, fn, reference) in enumerate(curves):
        colour = f"C{k}"
        if reference is not None:
            ax.plot(x, np.asarray(reference, dtype=float), "--", color=colour, lw=1,
                    label=f"{label}: reference")
        values, error = attempt(fn)
        if error:
            errors.append(f"{label}: {error}")
            continue
        values = np.asarray(values, dtype=float)
        if values.shape != x.shape:
            errors.append(f"{label}: expected {x.shape[0]} values, got shape {values.shape}")
            continue
        ax.plot(x, values, "o-", color=colour, ms=3, label=f"{label}: yours")
    ax.set_title("\n".join(errors) or title, fontsize=7 if errors else None)
    if ax.get_lines():
        ax.legend(fontsize=8)
    return ax

