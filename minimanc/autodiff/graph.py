"""Chapter 1 — the computation graph of a function at a point, with a cotangent on each edge.

:func:`computation_graph` runs ``f(*args)`` once with every argument traced (a
:class:`~minimanc.autodiff.Box`), then walks the tape the way
:func:`~minimanc.autodiff.backward` does, but records what ``backward``
throws away: the cotangent that travels along **each edge**. An edge
``parent → child`` carries ``∂L/∂parent`` *through that one use*, i.e. the VJP
of ``child``'s primitive applied to ``child``'s cotangent; a node's cotangent
is the sum over the edges that leave it (a value used twice receives two
contributions). At the inputs these sums are the gradient, which is what the
paper's training (Algorithm 1, the behaviour-cloning loss of eqs. 7–11) needs.

>>> import numpy as np
>>> import minimanc.autodiff.numpy as anp
>>> g = computation_graph(lambda x: anp.sin(x * x) + x, np.array(0.7))
>>> [n.name for n in g.nodes]
['arg0', 'multiply', 'sin', 'add']
>>> round(float(g.gradients()[0]), 6)   # cos(0.49) * 2 * 0.7 + 1
2.235266
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from minimanc.autodiff.boxes import Box
from minimanc.autodiff.reverse import backward, toposort
from minimanc.checks import check_int

__all__ = ["Node", "Edge", "Graph", "computation_graph"]


@dataclass(frozen=True)
class Node:
    """One value of the traced computation.

    ``name`` is ``"arg<k>"`` for the k-th input and the primitive's name
    (``"multiply"``, ``"sin"`` …) otherwise; ``value`` is the forward value.
    """

    index: int
    name: str
    shape: tuple[int, ...]
    value: np.ndarray


@dataclass(frozen=True)
class Edge:
    """``parent`` was positional argument ``argnum`` of ``child`` (indices into ``Graph.nodes``).

    ``cotangent`` is the contribution to ``∂L/∂parent`` that flows back along
    this edge: the VJP of the child's primitive, for argument ``argnum``,
    applied to the child's cotangent. It has the parent's shape.
    """

    parent: int
    child: int
    argnum: int
    cotangent: np.ndarray


@dataclass(frozen=True)
class Graph:
    """Nodes in forward order (inputs first, the output last) and cotangent-carrying edges.

    ``inputs`` are the node indices of the arguments of ``f`` (in argument
    order), ``output`` the index of the node holding ``f(*args)``.
    """

    nodes: tuple[Node, ...]
    edges: tuple[Edge, ...]
    inputs: tuple[int, ...]
    output: int

    def cotangent(self, index: int) -> np.ndarray:
        """``∂L/∂node``: 1 at the output, else the sum of the cotangents on the edges leaving it."""
        if isinstance(index, bool) or not isinstance(index, int | np.integer) or not (
            0 <= index < len(self.nodes)
        ):
            raise ValueError(
                f"index must be a node index in [0, {len(self.nodes)}), got index={index!r}"
            )
        node = self.nodes[index]
        if index == self.output:
            return np.ones(node.shape, dtype=np.result_type(node.value))
        total = np.zeros(node.shape, dtype=np.result_type(node.value))
        for edge in self.edges:
            if edge.parent == index:
                total = total + edge.cotangent
        return np.asarray(total)

    def gradients(self) -> tuple[np.ndarray, ...]:
        """The cotangent of each input: the gradient of ``f`` with respect to every argument."""
        return tuple(self.cotangent(i) for i in self.inputs)

    def lines(self, digits: int = 4) -> list[str]:
        """One line per edge, ``parent -> child (arg k)  cotangent``, rounded to ``digits``."""
        digits = check_int("digits", digits, 0)
        label = {n.index: f"{n.name}#{n.index}" for n in self.nodes}
        width = max(len(s) for s in label.values())
        out = []
        for e in self.edges:
            ct = np.round(np.asarray(e.cotangent, dtype=np.float64), digits) + 0.0  # no -0.0
            text = (f"{float(ct):.{digits}f}" if ct.ndim == 0
                    else np.array2string(ct, precision=digits, separator=", ",
                                         max_line_width=10**6))
            out.append(f"{label[e.parent]:>{width}} -> {label[e.child]:<{width}} "
                       f"(arg {e.argnum})  cotangent {text}")
        return out

    def __str__(self) -> str:
        return "\n".join(self.lines())

    def depths(self) -> tuple[dict[int, int], int]:
        """``({node index: depth}, largest depth)``: a node's depth is the length of the
        longest path from an input to it (inputs: 0)."""
        depth = {i: 0 for i in range(len(self.nodes))}
        for e in sorted(self.edges, key=lambda e: e.child):  # nodes are in forward order
            depth[e.child] = max(depth[e.child], depth[e.parent] + 1)
        return depth, max(depth.values(), default=0)


def _check_input(value: Any, k: int) -> np.ndarray:
    if isinstance(value, Box):
        raise TypeError(f"computation_graph: argument {k} is already traced; pass a plain array")
    if isinstance(value, bool):
        raise TypeError(f"computation_graph: argument {k} must be a real floating-point array, "
                        f"got bool {value!r}")
    arr = np.asarray(value)
    if not np.issubdtype(arr.dtype, np.floating):
        raise TypeError(f"computation_graph: argument {k} must be a real floating-point array, "
                        f"got dtype {arr.dtype}")
    return arr


def computation_graph(f: Callable, *args: Any) -> Graph:
    """The computation graph of the scalar function ``f`` at ``args``, cotangents on the edges.

    Every positional argument (a floating-point array or float) becomes an
    input node; ``f`` must return a scalar that depends on them through the
    primitives of :mod:`minimanc.autodiff.numpy`. The cotangents are those of
    the reverse pass started with ``∂L/∂output = 1``, so ``graph.gradients()``
    equals ``grad(f, argnums=tuple(range(len(args))))(*args)``.
    """
    if not callable(f):
        raise TypeError(f"computation_graph: f must be callable, got f={f!r}")
    if not args:
        raise ValueError("computation_graph: give at least one argument to trace, got args=()")
    leaves = [Box(_check_input(a, k)) for k, a in enumerate(args)]
    out = f(*leaves)
    if out is None or isinstance(out, tuple | list | dict | str):
        raise TypeError(f"computation_graph: f must return a scalar, got {type(out).__name__}")
    value = out.value if isinstance(out, Box) else np.asarray(out)
    if np.shape(value) != ():
        raise TypeError(f"computation_graph: f must return a scalar (shape ()), got shape "
                        f"{np.shape(value)}; reduce it first, e.g. with .sum()")
    if not np.issubdtype(np.result_type(value), np.floating):
        raise TypeError(f"computation_graph: f must return a real floating-point scalar, got "
                        f"dtype {np.result_type(value)}")

    index = {id(b): k for k, b in enumerate(leaves)}
    nodes = [Node(k, f"arg{k}", np.shape(b.value), b.value) for k, b in enumerate(leaves)]
    if not isinstance(out, Box):  # f does not depend on its arguments
        nodes.append(Node(len(nodes), "constant", (), value))
        return Graph(tuple(nodes), (), tuple(range(len(leaves))), len(nodes) - 1)
    for box in reversed(toposort(out)):  # forward order: each box after its parents
        if id(box) not in index:
            if not box.parents:
                raise TypeError("computation_graph: f traced a value that is not one of its "
                                "arguments (a Box created inside f?)")
            index[id(box)] = len(nodes)
            nodes.append(Node(len(nodes), box.primitive_name, np.shape(box.value), box.value))
    edges = []

    def record(box: Box, argnum: int, parent: Box, ct: np.ndarray) -> None:
        edges.append(Edge(index[id(parent)], index[id(box)], argnum, ct))

    backward(out, np.ones((), dtype=np.result_type(value)), on_edge=record)  # the one reverse pass
    return Graph(tuple(nodes), tuple(edges), tuple(range(len(leaves))), index[id(out)])
