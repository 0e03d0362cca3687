"""Chapter 1 — primitives: traced versions of plain-NumPy functions and their VJPs.

* :func:`primitive` — turns a plain-NumPy function into a traced one: when any
  positional argument is a :class:`~minimanc.autodiff.boxes.Box` the result is a
  ``Box`` linked to its parents.
* :func:`defvjp` / :func:`defvjp_fwd` — register the vector-Jacobian product
  (VJP) of a primitive. Given the cotangent ``g = ∂L/∂ans`` a VJP returns
  ``∂L/∂arg = gᵀ ∂ans/∂arg`` for one argument.
* :func:`unbroadcast` — the VJP of NumPy's broadcasting (a sum).
* :class:`Outputs` / :func:`select_output` — a node with several outputs (a scan, a
  :func:`~minimanc.autodiff.custom.custom_vjp` function returning a tuple): its value
  is the tuple of outputs and :func:`select_output` picks one, traced.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from minimanc.autodiff.boxes import FRAMES, Box, prim_name

__all__ = [
    "Outputs",
    "defvjp",
    "defvjp_fwd",
    "primitive",
    "select_output",
    "through_max",
    "unbroadcast",
]


def primitive(fun: Callable) -> Callable:
    """Return a traced version of the plain-NumPy function ``fun``.

    With no :class:`Box` among the positional arguments the result is simply
    ``fun(*args, **kwargs)``. Otherwise ``fun`` runs on the unboxed values and
    the result is boxed, remembering the primitive, its raw arguments and the
    boxed parents. Keyword arguments are never differentiated.
    A ``ValueError`` raised by ``fun`` is re-raised prefixed with its name, so
    shape errors say which operation failed.
    """
    name = fun.__name__

    @functools.wraps(fun)
    def traced(*args, **kwargs):
        parents = None
        for i, a in enumerate(args):
            if isinstance(a, Box):
                if parents is None:
                    parents, raw = [], list(args)
                parents.append((i, a))
                raw[i] = a._value
        try:
            if parents is None:
                return fun(*args, **kwargs)
            if kwargs:
                for key, val in kwargs.items():
                    if isinstance(val, Box):
                        raise TypeError(
                            f"{name}: keyword argument {key!r} is traced; pass differentiable "
                            "values positionally"
                        )
                if traced.fwd is not None:  # custom (fwd, bwd) pair, see defvjp_fwd
                    ans, res = traced.fwd(*raw, **kwargs)
                    box = Box(ans, tuple(parents), traced, (), None, res)
                elif traced.vjps is None:
                    raise _no_vjp(name)
                else:
                    box = Box(fun(*raw, **kwargs), tuple(parents), traced, raw, kwargs)
            elif traced.fwd is not None:
                ans, res = traced.fwd(*raw)
                box = Box(ans, tuple(parents), traced, (), None, res)
            elif traced.vjps is None:
                raise _no_vjp(name)
            else:
                box = Box(fun(*raw), tuple(parents), traced, raw, None)
            if FRAMES:  # inside a scan step: the box belongs to that step's tape
                FRAMES[-1][id(box)] = box
            return box
        except ValueError as err:
            msg = str(err)
            if msg.startswith(f"{name}:"):
                raise
            raise ValueError(f"{name}: {msg}") from err

    traced.fun = fun
    traced.vjps = None
    traced.fwd = None
    traced.bwd = None
    return traced


def _no_vjp(name: str) -> NotImplementedError:
    return NotImplementedError(
        f"VJP of primitive '{name}' is not defined: register one with "
        f"defvjp({name}, ...) or defvjp_fwd({name}, fwd, bwd)"
    )


def defvjp(prim: Callable, *vjps: Callable | None) -> None:
    """Register one VJP per positional argument of ``prim``.

    Each ``vjp(g, ans, *args, **kwargs)`` receives the output cotangent ``g``,
    the forward result ``ans`` and the raw (unboxed) arguments, and returns the
    cotangent of *its* argument (same shape as that argument). ``None`` marks
    a non-differentiable argument (an index, an axis …).

    Example (HIPS-autograd style)::

        defvjp(multiply, lambda g, ans, x, y: unbroadcast(x, g * y),
                         lambda g, ans, x, y: unbroadcast(y, g * x))
    """
    if not hasattr(prim, "fun"):
        raise TypeError(f"defvjp: {prim_name(prim)} is not a primitive (wrap it with @primitive)")
    prim.vjps = tuple(vjps)


def defvjp_fwd(prim: Callable, fwd: Callable, bwd: Callable) -> None:
    """Register a JAX ``custom_vjp``-style pair for an expensive primitive.

    When traced, ``fwd(*args, **kwargs) -> (ans, residuals)`` replaces the
    forward pass and ``bwd(g, residuals)`` returns a tuple with one cotangent
    per positional argument (``None`` = not differentiable). When nothing is
    traced, the plain function runs and no residuals are kept.
    """
    if not hasattr(prim, "fun"):
        raise TypeError(
            f"defvjp_fwd: {prim_name(prim)} is not a primitive (wrap it with @primitive)")
    prim.fwd = fwd
    prim.bwd = bwd


def unbroadcast(target, g: np.ndarray) -> np.ndarray:
    """Sum the cotangent ``g`` back to the shape of ``target`` (an array or a shape).

    Broadcasting copies a value along new leading axes and along axes of size
    one; the VJP of a copy is a sum, so we sum over exactly those axes. When
    ``target`` is a floating-point array the result keeps its dtype.
    """
    if type(target) is np.ndarray and type(g) is np.ndarray:
        if g.shape == target.shape and (g.dtype == target.dtype or target.dtype.kind != "f"):
            return g  # the common case: nothing was broadcast
        shape, dtype = target.shape, target.dtype
    elif isinstance(target, tuple):
        shape, dtype = target, None
    else:
        shape, dtype = np.shape(target), np.result_type(target)
    g = np.asarray(g)
    if g.shape != shape:
        extra = g.ndim - len(shape)
        if extra > 0:
            g = g.sum(axis=tuple(range(extra)))
        axes = tuple(i for i, n in enumerate(shape) if n == 1 and g.shape[i] != 1)
        if axes:
            g = g.sum(axis=axes, keepdims=True)
        if g.shape != shape:  # target was larger than g: broadcast the cotangent
            g = np.broadcast_to(g, shape)
    if dtype is not None and dtype.kind == "f" and g.dtype != dtype:
        g = g.astype(dtype)
    return g


def through_max(g: np.ndarray, a, b) -> np.ndarray:
    """``g · ∂ max(a, b) / ∂a``: all of ``g`` where ``a > b``, half of it where ``a == b``,
    none elsewhere — the tie rule of :func:`maximum` and :func:`minimum` (JAX's), for every
    hand-written VJP that passes a cotangent through a maximum, a minimum or a clip.

    ``a`` and ``b`` broadcast against ``g``; the result keeps ``g``'s dtype.
    """
    tie = np.equal(a, b)
    if not np.count_nonzero(tie):  # no ties (the common case): the comparison is the weight
        return g * np.greater(a, b)
    w = np.where(np.greater(a, b), 1.0, np.where(tie, 0.5, 0.0))
    return g * w.astype(g.dtype, copy=False)



class Outputs(tuple):
    """The value of a node with several outputs (its output arrays, in order)."""


@primitive
def select_output(outs, k):
    """Output ``k`` of a node with several outputs."""
    return outs[k]


def _select_fwd(outs, k):
    return outs[k], (k, len(outs))


def _select_bwd(g, res):
    k, n = res
    return tuple(g if j == k else None for j in range(n)), None


defvjp_fwd(select_output, _select_fwd, _select_bwd)
