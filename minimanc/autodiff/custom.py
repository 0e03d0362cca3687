"""Chapter 1 — :class:`custom_vjp`: a function with a hand-written VJP (``jax.custom_vjp``'s API).

A long chain of small operations (the sub-steps of one DMP step, eq. 10) costs one
tape node per operation. Written as one function with its own VJP it is **one**
node: the forward runs on plain arrays and keeps what the backward needs, the
backward is written by hand. The contract is ``jax.custom_vjp``'s, so the same
three functions serve both engines (:attr:`minimanc.engine.Engine.custom_vjp`)::

    f = custom_vjp(fun, nondiff_argnums=(2,))
    f.defvjp(fwd, bwd)
    # fwd(*args) -> (out, residuals);  bwd(*nondiff_args, residuals, g) -> cotangents

``out`` is an array or a tuple of arrays; ``bwd`` receives the output cotangent
``g`` in the same structure (zeros for outputs that were not used) and returns a
tuple with one cotangent per differentiable argument (the positional arguments
not listed in ``nondiff_argnums``), each of that argument's shape.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from minimanc.autodiff.boxes import FRAMES, Box, unbox
from minimanc.autodiff.primitives import Outputs, primitive, select_output
from minimanc.tree import tree_flatten

__all__ = ["custom_vjp"]

_CONTAINERS = (list, tuple, dict)  # a pytree argument, flattened into its leaves
_SEQUENCES = (tuple, list)


class custom_vjp:  # noqa: N801 - named after jax.custom_vjp
    """``fun`` with the VJP registered by :meth:`defvjp`; one tape node per call.

    With no traced positional argument the call is simply ``fun(*args)`` (any
    array type passes through, JAX's included). Otherwise ``fwd`` runs on the
    plain values and the result is boxed once; the backward pass calls ``bwd``.
    Positional arguments only; those in ``nondiff_argnums`` are static (an
    integer, a string, a concrete float) and must not be traced.
    """

    def __init__(self, fun: Callable, nondiff_argnums: tuple[int, ...] = ()) -> None:
        self.fun = fun
        self.nondiff_argnums = tuple(nondiff_argnums)
        self.fwd: Callable | None = None
        self.bwd: Callable | None = None
        functools.update_wrapper(self, fun)
        self._node = primitive(fun)
        self._node.bwd = self._node_bwd

    def defvjp(self, fwd: Callable, bwd: Callable) -> None:
        """Register ``fwd(*args) -> (out, residuals)`` and ``bwd(*nondiff, residuals, g)``."""
        self.fwd, self.bwd = fwd, bwd

    def __call__(self, *args, **kwargs):
        if kwargs:
            raise TypeError(f"{self.__name__}: a custom_vjp function takes positional "
                            f"arguments only, got keywords {sorted(kwargs)}")
        parents, raw, nested = [], list(args), False
        for k, a in enumerate(args):
            if isinstance(a, Box):
                parents.append((k, a))
                raw[k] = a._value
            elif isinstance(a, _CONTAINERS):
                nested = True
                break
        if not nested:  # flat arguments
            if not parents:
                return self.fun(*args)
            flat, owner, counts = None, range(len(args)), [1] * len(args)
        else:
            flat = [tree_flatten(a) if isinstance(a, _CONTAINERS) else None for a in args]
            leaves, owner = [], []  # every leaf of every argument, and its argument's index
            for i, (a, f) in enumerate(zip(args, flat)):
                arg_leaves = [a] if f is None else f[0]
                leaves += arg_leaves
                owner += [i] * len(arg_leaves)
            counts = [owner.count(i) for i in range(len(args))]
            parents = [(k, b) for k, b in enumerate(leaves) if isinstance(b, Box)]
        if not parents:
            return self.fun(*args)
        if self.fwd is None:
            raise NotImplementedError(f"{self.__name__}: register its VJP with .defvjp(fwd, bwd)")
        nondiff = self.nondiff_argnums
        for k, _ in parents if nondiff else ():
            if owner[k] in nondiff:
                raise TypeError(f"{self.__name__}: argument {owner[k]} is traced but listed in "
                                f"nondiff_argnums={nondiff}")
        if flat is not None:
            raw = [unbox(a) if f is None else f[2]([unbox(v) for v in f[0]])
                   for a, f in zip(args, flat)]
        out, res = self.fwd(*raw)
        multi = isinstance(out, _SEQUENCES)
        value = Outputs(out) if multi else out
        shapes = None if not multi else [
            (o.shape, o.dtype) if type(o) is np.ndarray else (np.shape(o), np.result_type(o))
            for o in out]
        node = Box(value, tuple(parents), self._node, (), None,
                   (tuple(raw[i] for i in nondiff), res, shapes, counts))
        if FRAMES:
            FRAMES[-1][id(node)] = node
        if not multi:
            return node
        outs = []
        for k, o in enumerate(out):  # what select_output(node, k) makes, without its call overhead
            box = Box(o, ((0, node),), select_output, (), None, (k, len(out)))
            if FRAMES:
                FRAMES[-1][id(box)] = box
            outs.append(box)
        return type(out)(outs)

    def _node_bwd(self, g, node_res) -> tuple:
        """Cotangents of every leaf of the arguments (``None`` for the static ones)."""
        nondiff_vals, res, shapes, counts = node_res
        n_args = len(counts)
        if shapes is not None:  # a tuple of outputs: unused ones have a None cotangent
            g = tuple(np.zeros(s, dtype=d) if gk is None else gk
                      for gk, (s, d) in zip(g, shapes))
        cts = self.bwd(*nondiff_vals, res, g)
        if not isinstance(cts, _SEQUENCES):
            raise TypeError(f"{self.__name__}: bwd must return a tuple of cotangents, got "
                            f"{type(cts).__name__}")
        n_diff = n_args - len(self.nondiff_argnums)
        if len(cts) != n_diff:
            raise TypeError(f"{self.__name__}: bwd returned {len(cts)} cotangents for "
                            f"{n_diff} differentiable arguments")
        it = iter(cts)
        out: list = []
        nondiff = self.nondiff_argnums
        for i in range(n_args):
            if nondiff and i in nondiff:
                out += [None] * counts[i]  # a static argument, never traced
                continue
            ct = next(it)
            if isinstance(ct, _CONTAINERS):
                out += tree_flatten(ct)[0]
            else:
                out.append(ct)
        if len(out) != sum(counts):
            raise TypeError(f"{self.__name__}: bwd returned cotangents whose structure does not "
                            "match the arguments")
        return tuple(out)
