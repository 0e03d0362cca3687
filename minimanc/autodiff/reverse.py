"""Chapter 1 — the reverse pass: topological order, one chain-rule step, :func:`backward`.

:func:`backward` sorts the graph topologically (iteratively, so a chain of 10,000
operations does not hit Python's recursion limit) and runs the VJPs from the output
back to the inputs, summing the cotangents of values used more than once.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from minimanc.autodiff.boxes import Box, prim_name
from minimanc.autodiff.primitives import Outputs

__all__ = ["add_cotangents", "backward", "parent_cotangents", "toposort"]


def _box_parents(box: Box) -> list[Box]:
    return [parent for _, parent in box._parents]


def toposort(end, parents_of: Callable[[Any], Sequence] | None = None) -> list:
    """Nodes reachable from ``end``, each before its parents (iterative DFS).

    ``parents_of(node)`` lists a node's parents (default: a :class:`Box`'s). An
    explicit stack replaces recursion, so a chain of 10,000 operations is fine;
    the order depends only on the graph, never on memory addresses.
    """
    parents_of = parents_of or _box_parents
    order: list = []
    seen: dict[int, bool] = {}
    stack: list[tuple[Any, bool]] = [(end, False)]
    while stack:
        box, parents_done = stack.pop()
        if parents_done:  # all its parents are in `order`: post-order
            order.append(box)
            continue
        if id(box) in seen:
            continue
        seen[id(box)] = True
        stack.append((box, True))
        for parent in reversed(parents_of(box)):
            if id(parent) not in seen:
                stack.append((parent, False))
    order.reverse()  # post-order reversed: every box comes before its parents
    return order


def _checked(box: Box, parent: Box, ct) -> Any:
    """``ct`` as an array of the parent's shape and (floating) dtype, or ValueError."""
    pval = parent._value
    if type(ct) is np.ndarray and type(pval) is np.ndarray:  # the common case
        if ct.shape == pval.shape and (ct.dtype == pval.dtype or pval.dtype.kind != "f"):
            return ct
        pshape, pdtype = pval.shape, pval.dtype
    elif isinstance(pval, Outputs):  # a node's outputs: one cotangent (or None) each
        return ct
    else:
        ct = np.asarray(ct)
        pshape, pdtype = np.shape(pval), np.result_type(pval)
    if ct.shape != pshape:
        raise ValueError(
            f"VJP of '{prim_name(box._prim)}' returned a cotangent of shape {ct.shape} "
            f"for an argument of shape {pshape}"
        )
    if ct.dtype != pdtype and pdtype.kind == "f":
        ct = ct.astype(pdtype)
    return ct


def parent_cotangents(box: Box, g: np.ndarray) -> list:
    """``(argnum, parent, cotangent)`` for each traced parent of ``box``, given the
    cotangent ``g`` of ``box``: one application of the chain rule (a VJP), its shape
    checked and its dtype that of the parent (float32 stays float32)."""
    prim = box._prim
    out = []
    if prim.bwd is not None:
        cts = prim.bwd(g, box._res)
        if not isinstance(cts, (tuple, list)):
            cts = (cts,)
        n = len(cts)
        for argnum, parent in box._parents:
            ct = cts[argnum] if argnum < n else None
            if ct is None:
                raise NotImplementedError(
                    f"{prim_name(prim)}: argument {argnum} is not differentiable")
            pval = parent._value
            if not (type(ct) is np.ndarray and type(pval) is np.ndarray
                    and ct.shape == pval.shape and ct.dtype == pval.dtype):
                ct = _checked(box, parent, ct)
            out.append((argnum, parent, ct))
        return out
    vjps, ans, args, kwargs = prim.vjps, box._value, box._args, box._kwargs
    n = len(vjps)
    for argnum, parent in box._parents:
        vjp = vjps[argnum] if argnum < n else None
        if vjp is None:
            raise NotImplementedError(
                f"VJP of primitive '{prim_name(prim)}' with respect to argument {argnum} is not "
                "defined"
            )
        ct = vjp(g, ans, *args, **kwargs) if kwargs else vjp(g, ans, *args)
        pval = parent._value
        if not (type(ct) is np.ndarray and type(pval) is np.ndarray and ct.shape == pval.shape
                and ct.dtype == pval.dtype):
            ct = _checked(box, parent, ct)
        out.append((argnum, parent, ct))
    return out


def backward(end: Box, g: np.ndarray,
             on_edge: Callable[[Box, int, Box, np.ndarray], None] | None = None
             ) -> dict[int, np.ndarray]:
    """Run every VJP from ``end`` (with cotangent ``g``) back to the leaves.

    Returns ``{id(leaf): cotangent}`` for the leaves (boxes without parents).
    A value used several times receives the *sum* of its cotangents.
    ``on_edge(box, argnum, parent, cotangent)``, if given, sees every edge's
    cotangent as it is computed (:func:`minimanc.autodiff.graph.computation_graph`).
    """
    cotangents: dict[int, Any] = {id(end): g}
    leaves: dict[int, np.ndarray] = {}
    for box in toposort(end):
        g = cotangents.pop(id(box))
        if not box._parents:
            leaves[id(box)] = g
            continue
        for argnum, parent, ct in parent_cotangents(box, g):
            if on_edge is not None:
                on_edge(box, argnum, parent, ct)
            key = id(parent)
            prev = cotangents.get(key)
            if prev is None:
                cotangents[key] = ct
            else:
                cotangents[key] = (prev + ct if type(prev) is np.ndarray
                                   else add_cotangents(prev, ct))
    return leaves


def add_cotangents(a, b):
    """Sum two cotangents; those of a scan's outputs are tuples with ``None`` for zero."""
    if isinstance(a, tuple):
        return tuple(y if x is None else x if y is None else x + y for x, y in zip(a, b))
    return a + b

