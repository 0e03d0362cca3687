"""Chapter 1 — pytrees: the nested dicts and lists that hold a model's parameters.

A pytree is an array (any leaf), or a dict / list / tuple (named tuples included) of
pytrees; ``None`` is an empty subtree, as in JAX. :func:`tree_flatten` lists the leaves
with readable paths and returns the function that rebuilds the tree, as
``jax.tree_util`` does (:func:`minimanc.autodiff.grad` differentiates with respect to
every leaf; :func:`tree_unflatten` is its inverse).
:func:`leaves` visits dict entries in sorted key order, so it sees the leaves in one
order whatever the insertion order was (the order :mod:`minimanc.optim` and the
checkpoints of :mod:`minimanc.train` rely on); :func:`map` and :func:`cast_floats`
rebuild dicts in their own key order. :func:`to_flat_dict` / :func:`from_flat_dict` give a
tree as flat ``"a/b/#0/w"`` keys, the layout of a checkpoint file.
"""

from __future__ import annotations

import builtins
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

__all__ = ["cast_floats", "from_flat_dict", "leaves", "map", "to_flat_dict", "tree_flatten",
           "tree_unflatten"]


def leaves(tree: Any) -> list:
    """The leaves of ``tree`` in a fixed order: dicts by sorted key, lists and tuples in order.

    Parameters
    ----------
    tree : pytree
        An array (a leaf), ``None`` (no leaf), or a dict / list / tuple of pytrees.

    Returns
    -------
    list
        The leaves, each the object itself (not copied).
    """
    if tree is None:
        return []
    if isinstance(tree, dict):
        return [x for k in sorted(tree) for x in leaves(tree[k])]
    if isinstance(tree, list | tuple):
        return [x for v in tree for x in leaves(v)]
    return [tree]


def _children(node: Any, keys: list, seq: bool, i: int, where: str) -> list:
    """The entries ``keys`` of ``node`` (tree ``i + 1`` of :func:`map`, at ``where``), checked
    to match the first tree's node there: a sequence when ``seq``, else a dict."""
    if seq:
        ok = isinstance(node, list | tuple) and len(node) == len(keys)
        want = f"a list or tuple of {len(keys)}"
    else:
        ok = isinstance(node, dict) and set(node) == set(keys)
        want = f"a dict with keys {sorted(builtins.map(str, keys))}"
    if not ok:
        got = (f"a dict with keys {sorted(builtins.map(str, node))}" if isinstance(node, dict)
               else f"a {type(node).__name__} of {len(node)}" if isinstance(node, list | tuple)
               else f"a {type(node).__name__} leaf")
        raise ValueError(f"map: trees differ in structure at {where or 'the root'}: tree "
                         f"{i + 1} is {got}, the first tree is {want}")
    return [node[k] for k in keys]


def map(f: Callable[..., Any], tree: Any, *rest: Any) -> Any:
    """``tree`` with every leaf ``x`` replaced by ``f(x, *matching leaves of rest)``.

    Parameters
    ----------
    f : callable
        Called once per leaf of ``tree``, never on ``None`` (an empty subtree, kept).
    tree : pytree
        Gives the structure of the result: dicts (rebuilt as plain dicts, in ``tree``'s key
        order), lists, tuples and named tuples (rebuilt as their own type).
    *rest : pytree
        Trees with ``tree``'s structure down to its leaves (a list may stand for a tuple);
        at a leaf of ``tree`` their whole subtree is passed to ``f``.

    Returns
    -------
    pytree
        ``tree``'s structure with ``f``'s results as leaves.

    Raises
    ------
    ValueError
        When a tree of ``rest`` differs from ``tree`` in structure, naming where.
    """
    return _map(f, tree, rest, "")


def _map(f: Callable[..., Any], tree: Any, rest: tuple, where: str) -> Any:
    if tree is None:
        return None
    if isinstance(tree, dict):
        keys = list(tree)
        subs = [_children(r, keys, False, i, where) for i, r in enumerate(rest)]
        return {k: _map(f, tree[k], tuple(s[j] for s in subs), f"{where}[{k!r}]")
                for j, k in enumerate(keys)}
    if isinstance(tree, list | tuple):
        idx = list(range(len(tree)))
        subs = [_children(r, idx, True, i, where) for i, r in enumerate(rest)]
        items = [_map(f, v, tuple(s[j] for s in subs), f"{where}[{j}]")
                 for j, v in enumerate(tree)]
        return type(tree)(*items) if hasattr(tree, "_fields") else type(tree)(items)
    return f(tree, *rest)


def _cast_float(x: Any, dtype: Any) -> np.ndarray:
    arr = np.asarray(x)
    return arr.astype(dtype) if np.issubdtype(arr.dtype, np.floating) else arr


def cast_floats(tree: Any, dtype: Any) -> Any:
    """``tree`` with NumPy leaves: the floating-point ones cast to ``dtype``, the others
    (integers, booleans) kept as they are (``numpy.asarray`` of the leaf).

    Parameters
    ----------
    tree : pytree
        Leaves are arrays or scalars; dicts are rebuilt in their own key order (:func:`map`).
    dtype : numpy dtype or type
        The floating-point type of the result's float leaves, e.g. ``numpy.float32``.

    Returns
    -------
    pytree
        ``tree``'s structure with ``numpy.ndarray`` leaves of the same shapes.
    """
    return map(lambda x: _cast_float(x, dtype), tree)


def to_flat_dict(tree: Any, prefix: str = "") -> dict[str, np.ndarray]:
    """``{"a/b/#0/w": array}``: a pytree as flat keys (dicts by sorted key, list and tuple
    entries as ``#i``), each leaf ``numpy.asarray``; ``None`` subtrees have no key.

    Parameters
    ----------
    tree : pytree
        Dict keys are strings without ``"/"`` (and not starting with ``"#"``), so that
        :func:`from_flat_dict` can rebuild the tree.
    prefix : str
        Put in front of every key (used by the recursion; ``""`` at the root).

    Returns
    -------
    dict of str to ndarray
        One entry per leaf, keys in :func:`leaves` order, each array of the leaf's shape.
    """
    out: dict[str, np.ndarray] = {}
    if isinstance(tree, dict):
        for k in sorted(tree):
            out.update(to_flat_dict(tree[k], f"{prefix}{k}/"))
    elif isinstance(tree, list | tuple):
        for i, v in enumerate(tree):
            out.update(to_flat_dict(v, f"{prefix}#{i}/"))
    elif tree is not None:
        out[prefix[:-1]] = np.asarray(tree)
    return out


def from_flat_dict(flat: dict[str, Any]) -> Any:
    """Inverse of :func:`to_flat_dict` (tuples come back as lists).

    Parameters
    ----------
    flat : dict of str to array
        Keys ``"a/b/#0/w"`` as :func:`to_flat_dict` writes them.

    Returns
    -------
    pytree
        Nested dicts, with lists where every key of a level is ``#i``; leaves as given.
    """
    root: dict = {}
    for key, value in flat.items():
        parts = key.split("/")
        node = root
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return _lists(root)


def _lists(node: Any) -> Any:
    if not isinstance(node, dict):
        return node
    if node and all(k.startswith("#") for k in node):
        return [_lists(node[f"#{i}"]) for i in range(len(node))]
    return {k: _lists(v) for k, v in node.items()}


def _dict_keys(d: dict) -> list:
    try:
        return sorted(d)
    except TypeError:
        return list(d)


def tree_flatten(tree) -> tuple[list, list[str], Callable[[Sequence], Any]]:
    """The leaves of ``tree``, their paths and the function that rebuilds the tree.

    Parameters
    ----------
    tree : pytree
        An array (a leaf), ``None`` (no leaf), or a dict / list / tuple (named tuples
        included) of pytrees. Dicts are visited in sorted key order when their keys sort.

    Returns
    -------
    leaves : list
        The leaves, each the object itself.
    paths : list of str
        Their readable locations, such as ``"['layers'][1]['w']"``.
    rebuild : callable
        ``rebuild(new_leaves)`` is the tree with ``new_leaves`` in place of ``leaves``.
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
    """Inverse of :func:`tree_flatten`: the tree ``rebuild`` makes of ``leaves``.

    Parameters
    ----------
    rebuild : callable
        The third value :func:`tree_flatten` returned.
    leaves : sequence
        One leaf per leaf of the flattened tree, in :func:`tree_flatten`'s order.

    Returns
    -------
    pytree
    """
    return rebuild(leaves)
