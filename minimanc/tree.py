"""Pytrees: the nested dicts and lists that hold a model's parameters (chapter 2).

A pytree is an array, or a dict / list / tuple of pytrees. Dict entries are
visited in sorted key order, so every function here sees the leaves in one
order whatever the insertion order was (the order :mod:`minimanc.optim` and
the checkpoints of :mod:`minimanc.train` rely on).
"""

from __future__ import annotations

from typing import Any

__all__ = ["leaves"]


def leaves(tree: Any) -> list:
    """The arrays of ``tree`` in a fixed order: dicts by sorted key, lists and tuples in order."""
    if isinstance(tree, dict):
        return [x for k in sorted(tree) for x in leaves(tree[k])]
    if isinstance(tree, list | tuple):
        return [x for v in tree for x in leaves(v)]
    return [tree]
