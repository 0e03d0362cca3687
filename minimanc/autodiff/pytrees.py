"""Chapter 1 — pytrees: nested dicts, lists and tuples of arrays (``None`` is an empty subtree).

:func:`tree_flatten` lists the leaves with readable paths and returns the function that
rebuilds the tree, as ``jax.tree_util`` does; :func:`~minimanc.autodiff.api.grad`
differentiates with respect to every leaf.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["tree_flatten", "tree_unflatten"]


def _dict_keys(d: dict) -> list:
    try:
        return sorted(d)
    except TypeError:
        return list(d)


def tree_flatten(tree) -> tuple[list, list[str], Callable[[Sequence], Any]]:
    """Return ``(leaves, paths, rebuild)`` where ``rebuild(new_leaves)`` rebuilds the tree.

    ``paths`` are readable locations such as ``"['layers'][1]['w']"``.
    """
    leaves: list = []
    paths: list[str] = []

    def build(node, path):
        if node is None:
            return lambda it: None
        if isinstance(node, dict):
            keys = _dict_keys(node)
            subs = [build(node[k], f"{path}[{k!r}]") for k in keys]
            return lambda it: type(node)(zip(keys, [s(it) for s in subs]))
        if isinstance(node, (list, tuple)):
            subs = [build(c, f"{path}[{i}]") for i, c in enumerate(node)]
            if hasattr(node, "_fields"):  # namedtuple
                return lambda it: type(node)(*[s(it) for s in subs])
            return lambda it: type(node)([s(it) for s in subs])
        leaves.append(node)
        paths.append(path)
        return lambda it: next(it)

    rebuilder = build(tree, "")
    return leaves, paths, lambda new: rebuilder(iter(new))


def tree_unflatten(rebuild: Callable[[Sequence], Any], leaves: Sequence):
    """Inverse of :func:`tree_flatten`: ``tree_unflatten(rebuild, leaves)``."""
    return rebuild(leaves)
