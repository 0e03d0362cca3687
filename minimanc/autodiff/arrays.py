"""Chapter 1 — array functions of the ``xp`` namespace: shapes, indexing, joining, creation.

``reshape`` … ``pad``, ``getitem`` (fancy indexing scatter-adds in its VJP),
``concatenate`` / ``stack`` (one primitive each), ``asarray``; and the functions
without a useful derivative (``zeros``, ``sign``, comparisons, ``isfinite`` …),
which take the values out of their boxes (:func:`nondiff`). Re-exported by
:mod:`minimanc.autodiff.numpy`.
"""

from __future__ import annotations

import builtins

import numpy as np

from minimanc.autodiff.boxes import Box
from minimanc.autodiff.primitives import defvjp, defvjp_fwd, primitive, unbroadcast


def unbox_all(x):
    """``x`` with traced values (also inside lists and tuples) replaced by their values."""
    if isinstance(x, Box):
        return x._value
    if isinstance(x, (list, tuple)):
        return type(x)(unbox_all(v) for v in x)
    return x


def contains_box(x) -> bool:
    """True if ``x`` is traced or a list/tuple holding a traced value."""
    if isinstance(x, Box):
        return True
    return isinstance(x, (list, tuple)) and builtins.any(contains_box(v) for v in x)


# ---------------------------------------------------------------------------
# Shapes, indexing, joining
# ---------------------------------------------------------------------------
def _reshape_back(g, ans, x, *args, **kwargs):
    if type(g) is np.ndarray and type(x) is np.ndarray:
        return g.reshape(x.shape)
    return np.reshape(g, np.shape(x))


@primitive
def reshape(x, shape):
    """``x`` with a new shape (one entry may be -1)."""
    return np.reshape(x, shape)


defvjp(reshape, _reshape_back)


@primitive
def ravel(x):
    """``x`` flattened to 1-D."""
    return np.ravel(x)


defvjp(ravel, _reshape_back)


@primitive
def expand_dims(x, axis):
    """Insert axes of size one at ``axis``."""
    if isinstance(axis, int) and type(x) is np.ndarray:  # one axis: a reshape, no checks
        n = x.ndim + 1
        if -n <= axis < n:
            a = axis % n
            return x.reshape(x.shape[:a] + (1,) + x.shape[a:])
    return np.expand_dims(x, axis)


defvjp(expand_dims, _reshape_back)


@primitive
def squeeze(x, axis=None):
    """Remove axes of size one."""
    return np.squeeze(x, axis=axis)


defvjp(squeeze, _reshape_back)


@primitive
def broadcast_to(x, shape):
    """``x`` broadcast to ``shape``."""
    return np.broadcast_to(x, shape)


defvjp(broadcast_to, lambda g, ans, x, shape: unbroadcast(x, g))


@primitive
def transpose(x, axes=None):
    """Permute the axes (reverse them by default)."""
    return np.transpose(x, axes)


def _transpose_vjp(g, ans, x, axes=None):
    if axes is None:
        return np.transpose(g)
    return np.transpose(g, np.argsort([a % np.ndim(x) for a in axes]))


defvjp(transpose, _transpose_vjp)


@primitive
def swapaxes(x, axis1, axis2):
    """Exchange two axes."""
    return np.swapaxes(x, axis1, axis2)


defvjp(swapaxes, lambda g, ans, x, a1, a2: np.swapaxes(g, a1, a2))


@primitive
def moveaxis(x, source, destination):
    """Move axes to new positions."""
    return np.moveaxis(x, source, destination)


defvjp(moveaxis, lambda g, ans, x, src, dst: np.moveaxis(g, dst, src))


def _astype_fn(x, dtype):
    return np.asarray(x).astype(dtype)


_astype_fn.__name__ = "astype"
_astype = primitive(_astype_fn)
defvjp(_astype, lambda g, ans, x, dtype: np.asarray(g).astype(np.result_type(x)))


def astype(x, dtype):
    """``x`` converted to ``dtype`` (the cotangent is converted back); a traced value that
    already has that dtype is returned as it is (no new node on the tape)."""
    if isinstance(x, Box) and x._value.dtype == np.dtype(dtype):
        return x
    return _astype(x, dtype)


def _pad_fn(x, pad_width, mode="constant", constant_values=0):
    if mode != "constant":
        raise ValueError(f"pad: only mode='constant' is supported, got mode={mode!r}")
    return np.pad(x, pad_width, mode="constant", constant_values=constant_values)


def _pad_vjp(g, ans, x, pad_width, mode="constant", constant_values=0):
    widths = np.broadcast_to(np.asarray(pad_width, dtype=int), (np.ndim(x), 2))
    return g[tuple(slice(lo, n - hi) for (lo, hi), n in zip(widths, g.shape))]


_pad_fn.__name__ = "pad"
pad = primitive(_pad_fn)
defvjp(pad, _pad_vjp)


def _is_basic_index(idx) -> bool:
    """True for ints, slices, None and Ellipsis (no element can be selected twice)."""
    for i in idx if isinstance(idx, tuple) else (idx,):
        kind = type(i)
        if kind is slice or kind is int or i is None or i is Ellipsis:
            continue
        if not isinstance(i, slice | int | np.integer) or isinstance(i, bool):
            return False
    return True


def _getitem_fn(x, idx):
    return np.asarray(x)[idx]


def _getitem_vjp(g, ans, x, idx):
    if type(x) is np.ndarray and type(g) is np.ndarray:
        out = np.zeros(x.shape, dtype=g.dtype)
    else:
        out = np.zeros(np.shape(x), dtype=np.result_type(g))
    if _is_basic_index(idx):
        out[idx] = g
    else:  # fancy indexing may pick an element several times: scatter-add
        np.add.at(out, idx, g)
    return out


_getitem_fn.__name__ = "getitem"
getitem = primitive(_getitem_fn)
defvjp(getitem, _getitem_vjp)


def _concatenate_fn(*arrays, axis=0):
    return np.concatenate(arrays, axis=axis)


def _concatenate_fwd(*arrays, axis=0):
    ans = np.concatenate(arrays, axis=axis)
    return ans, ([np.shape(a)[axis] for a in arrays], axis % ans.ndim)


def _concatenate_bwd(g, res):
    sizes, axis = res
    lead = (slice(None),) * axis
    parts, start = [], 0
    for n in sizes:  # the pieces np.split would give, as views of g
        parts.append(g[lead + (slice(start, start + n),)])
        start += n
    return tuple(parts)


_concatenate_fn.__name__ = "concatenate"
_concatenate = primitive(_concatenate_fn)
defvjp_fwd(_concatenate, _concatenate_fwd, _concatenate_bwd)


def concatenate(arrays, axis=0):
    """Join a sequence of arrays along an existing axis."""
    arrays = list(arrays)
    if axis is None:
        return _concatenate(*[ravel(a) for a in arrays], axis=0)
    return _concatenate(*arrays, axis=axis)


def _stack_fn(*arrays, axis=0):
    return np.stack(arrays, axis=axis)


def _stack_fwd(*arrays, axis=0):
    ans = np.stack(arrays, axis=axis)
    return ans, axis % ans.ndim


def _stack_bwd(g, axis):
    return tuple(np.moveaxis(g, axis, 0))


_stack_fn.__name__ = "stack"
_stack = primitive(_stack_fn)
defvjp_fwd(_stack, _stack_fwd, _stack_bwd)


def stack(arrays, axis=0):
    """Join a sequence of same-shape arrays along a new axis (one traced operation)."""
    arrays = list(arrays)
    if not builtins.any(isinstance(a, Box) for a in arrays):
        return np.stack(arrays, axis=axis)
    return _stack(*[a if isinstance(a, Box) else asarray(a) for a in arrays], axis=axis)


def asarray(x, dtype=None):
    """``x`` as an array; traced values stay traced (lists of them are stacked)."""
    if isinstance(x, Box):
        return x if dtype is None or np.dtype(dtype) == x._value.dtype else astype(x, dtype)
    if isinstance(x, (list, tuple)) and contains_box(x):
        out = stack([asarray(v) for v in x])
        return out if dtype is None else astype(out, dtype)
    return np.asarray(x, dtype=dtype)


def array(x, dtype=None):
    """Like :func:`asarray`, but plain inputs are copied (as ``np.array``)."""
    if isinstance(x, Box) or contains_box(x):
        return asarray(x, dtype)
    return np.array(x, dtype=dtype)


# ---------------------------------------------------------------------------
# Non-differentiable functions: plain values in, plain values out
# ---------------------------------------------------------------------------
def nondiff(fun):
    """``fun`` run on the plain values of its arguments (its result is not traced)."""

    def wrapped(*args, **kwargs):
        return fun(*unbox_all(args), **{k: unbox_all(v) for k, v in kwargs.items()})

    wrapped.__name__ = fun.__name__
    wrapped.__doc__ = f"``numpy.{fun.__name__}`` on unboxed values (not differentiated)."
    return wrapped


zeros, ones, full, eye, identity = (nondiff(f) for f in (np.zeros, np.ones, np.full, np.eye,
                                                           np.identity))
zeros_like, ones_like, full_like = (nondiff(f) for f in (np.zeros_like, np.ones_like,
                                                          np.full_like))
arange, linspace = nondiff(np.arange), nondiff(np.linspace)
floor_divide = nondiff(np.floor_divide)
sign, floor, ceil, round = (nondiff(f) for f in (np.sign, np.floor, np.ceil, np.round))  # noqa: A001
isfinite, isnan, isinf = nondiff(np.isfinite), nondiff(np.isnan), nondiff(np.isinf)
all, any = nondiff(np.all), nondiff(np.any)  # noqa: A001
argmax, argmin, argsort = nondiff(np.argmax), nondiff(np.argmin), nondiff(np.argsort)
equal, not_equal = nondiff(np.equal), nondiff(np.not_equal)
less, less_equal = nondiff(np.less), nondiff(np.less_equal)
greater, greater_equal = nondiff(np.greater), nondiff(np.greater_equal)
logical_and, logical_or, logical_not = (nondiff(f) for f in (np.logical_and, np.logical_or,
                                                              np.logical_not))
allclose, isclose, count_nonzero = nondiff(np.allclose), nondiff(np.isclose), nondiff(
    np.count_nonzero
)
shape, ndim, size = nondiff(np.shape), nondiff(np.ndim), nondiff(np.size)
result_type = nondiff(np.result_type)

