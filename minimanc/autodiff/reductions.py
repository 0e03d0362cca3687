"""Chapter 1 — reductions of the ``xp`` namespace (sum, mean, max, min, var, std, cumsum,
``linalg.norm``), each primitive with its VJP beside it.

A reduction's VJP gives the reduced cotangent its reduced axes back (size one)
and broadcasts it; ``max``/``min`` send it to the arg-max (arg-min) elements,
shared equally on ties. Re-exported by :mod:`minimanc.autodiff.numpy`.
"""

from __future__ import annotations

import builtins
import math
import types

import numpy as np

from minimanc.autodiff.boxes import unbox
from minimanc.autodiff.elementwise import multiply, sqrt, subtract
from minimanc.autodiff.primitives import defvjp, primitive


# ---------------------------------------------------------------------------
# Reductions
# ---------------------------------------------------------------------------
def _axis(axis):
    return tuple(axis) if isinstance(axis, list) else axis


def _expand(g, axis, keepdims):
    """Give the reduced cotangent back its reduced axes (as size 1)."""
    return g if keepdims or axis is None else np.expand_dims(g, axis)


def _keep_shape(shape: tuple, axis) -> tuple | None:
    """``shape`` with the axes ``axis`` (an int or a tuple) set to 1; ``None`` if an axis is
    out of range (then :func:`numpy.expand_dims` reports it)."""
    nd = len(shape)
    axes = (axis,) if isinstance(axis, int) else axis
    out = list(shape)
    for a in axes:
        if not (isinstance(a, int) and -nd <= a < nd):
            return None
        out[a] = 1
    return tuple(out)


def _spread(g, x, axis, keepdims):
    """The cotangent ``g`` of a reduction of ``x`` over ``axis``, copied back to ``x``'s shape."""
    shape = x.shape if type(x) is np.ndarray else np.shape(x)
    if type(g) is np.ndarray:
        if not keepdims and axis is not None:
            kept = _keep_shape(shape, axis)
            g = np.expand_dims(g, axis) if kept is None else g.reshape(kept)
        out = np.empty(shape, dtype=g.dtype)
        out[...] = g
        return out
    return np.broadcast_to(_expand(g, axis, keepdims), shape)


@primitive
def sum(x, axis=None, keepdims=False, dtype=None):  # noqa: A001
    """Sum over ``axis`` (all axes by default)."""
    if type(x) is np.ndarray:  # the method skips np.sum's dispatch, same computation
        return x.sum(axis=_axis(axis), keepdims=keepdims, dtype=dtype)
    return np.sum(x, axis=_axis(axis), keepdims=keepdims, dtype=dtype)


defvjp(
    sum,
    lambda g, ans, x, axis=None, keepdims=False, dtype=None: _spread(g, x, _axis(axis), keepdims),
)


@primitive
def mean(x, axis=None, keepdims=False, dtype=None):
    """Mean over ``axis`` (all axes by default)."""
    if type(x) is np.ndarray:
        return x.mean(axis=_axis(axis), keepdims=keepdims, dtype=dtype)
    return np.mean(x, axis=_axis(axis), keepdims=keepdims, dtype=dtype)


def _mean_vjp(g, ans, x, axis=None, keepdims=False, dtype=None):
    count = np.size(x) // builtins.max(np.size(ans), 1)
    return _spread(g / count, x, _axis(axis), keepdims)


defvjp(mean, _mean_vjp)


def _chooser_vjp(g, ans, x, axis=None, keepdims=False):
    """The gradient goes to the arg-max (arg-min) elements, shared equally on ties."""
    axis = _axis(axis)
    if type(x) is np.ndarray and type(g) is np.ndarray and type(ans) is np.ndarray:
        if axis is None or keepdims:
            hit = x == ans
            return g * hit / hit.sum(axis=axis, keepdims=True).astype(g.dtype)
        kept = _keep_shape(x.shape, axis)
        if kept is not None:
            hit = x == ans.reshape(kept)
            return g.reshape(kept) * hit / hit.sum(axis=axis, keepdims=True).astype(g.dtype)
    hit = x == _expand(ans, axis, keepdims)
    share = np.sum(hit, axis=axis, keepdims=True).astype(g.dtype)
    return _expand(g, axis, keepdims) * hit / share


@primitive
def max(x, axis=None, keepdims=False):  # noqa: A001
    """Maximum over ``axis`` (all axes by default)."""
    return np.max(x, axis=_axis(axis), keepdims=keepdims)


defvjp(max, _chooser_vjp)
amax = max


@primitive
def min(x, axis=None, keepdims=False):  # noqa: A001
    """Minimum over ``axis`` (all axes by default)."""
    return np.min(x, axis=_axis(axis), keepdims=keepdims)


defvjp(min, _chooser_vjp)
amin = min


def var(x, axis=None, keepdims=False, ddof=0):
    """Variance, built from differentiable primitives."""
    d = subtract(x, mean(x, axis=axis, keepdims=True))
    shp, axis_t = np.shape(unbox(x)), _axis(axis)
    axes = range(len(shp)) if axis_t is None else np.atleast_1d(axis_t)
    n = math.prod(shp[a] for a in axes)
    return multiply(sum(d * d, axis=axis, keepdims=keepdims), 1.0 / (n - ddof))


def std(x, axis=None, keepdims=False, ddof=0):
    """Standard deviation, ``sqrt(var(x))``."""
    return sqrt(var(x, axis=axis, keepdims=keepdims, ddof=ddof))


@primitive
def cumsum(x, axis=None):
    """Cumulative sum along ``axis`` (flattened when ``axis`` is None)."""
    return np.cumsum(x, axis=axis)


def _cumsum_vjp(g, ans, x, axis=None):
    if axis is None:
        return np.flip(np.cumsum(np.flip(g))).reshape(np.shape(x))
    return np.flip(np.cumsum(np.flip(g, axis), axis), axis)


defvjp(cumsum, _cumsum_vjp)


def _norm_fn(x, ord=None, axis=None, keepdims=False):  # noqa: A002
    return np.linalg.norm(x, ord=ord, axis=_axis(axis), keepdims=keepdims)


def _norm_vjp(g, ans, x, ord=None, axis=None, keepdims=False):  # noqa: A002
    axis = _axis(axis)
    matrix = isinstance(axis, tuple) or (axis is None and np.ndim(x) == 2)
    if not (ord is None or ord == "fro" or (ord == 2 and not matrix)):
        raise NotImplementedError(
            f"linalg.norm: VJP only for ord=None, 'fro' or 2 (vectors), got ord={ord!r}"
        )
    n = _expand(ans, axis, keepdims)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(n == 0, 0, _expand(g, axis, keepdims) * x / n).astype(g.dtype)


_norm_fn.__name__ = "norm"
_norm = primitive(_norm_fn)
defvjp(_norm, _norm_vjp)
linalg = types.SimpleNamespace(norm=_norm)


