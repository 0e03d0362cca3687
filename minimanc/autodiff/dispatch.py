"""Chapter 1 — traced values behave like arrays: operators, methods and NumPy's own functions.

``x + y``, ``x @ w``, ``x[i]``, ``x.T``, ``x.sum()`` on a
:class:`~minimanc.autodiff.boxes.Box` call the primitives of
:mod:`minimanc.autodiff.numpy`; so do ``np.sum(x)``, ``np.exp(x)`` and
``ndarray * x`` through ``__array_function__`` / ``__array_ufunc__``, as in HIPS
autograd. A NumPy function without a primitive (``np.prod``, ``np.linalg.svd`` …)
raises a ``TypeError`` naming the closest function of the namespace, and so does
``out=`` (an in-place write cannot be traced). Installed on ``Box`` when
:mod:`minimanc.autodiff` is imported.
"""

from __future__ import annotations

import builtins
import inspect
import types

import numpy as np

from minimanc.autodiff import numpy as anp
from minimanc.autodiff.arrays import nondiff
from minimanc.autodiff.boxes import Box, unbox
from minimanc.autodiff.numpy import (  # noqa: A004 - the namespace shadows builtins on purpose
    abs,
    add,
    all,
    any,
    arccos,
    arcsin,
    arctan,
    arctan2,
    argmax,
    argmin,
    astype,
    broadcast_to,
    ceil,
    clip,
    concatenate,
    cos,
    cosh,
    cross,
    cumsum,
    divide,
    dot,
    einsum,
    equal,
    exp,
    expand_dims,
    expm1,
    floor,
    floor_divide,
    getitem,
    greater,
    greater_equal,
    isfinite,
    isinf,
    isnan,
    less,
    less_equal,
    linalg,
    log,
    log1p,
    logaddexp,
    logical_and,
    logical_not,
    logical_or,
    matmul,
    max,
    maximum,
    mean,
    min,
    minimum,
    moveaxis,
    multiply,
    negative,
    not_equal,
    pad,
    power,
    ravel,
    remainder,
    reshape,
    sign,
    sin,
    sinh,
    sqrt,
    square,
    squeeze,
    stack,
    std,
    subtract,
    sum,
    swapaxes,
    tan,
    tanh,
    transpose,
    var,
    where,
)

__all__: list[str] = []  # installs methods on Box; nothing to import from here

# ---------------------------------------------------------------------------
# Operators and methods of traced values (so model code reads like NumPy)
# ---------------------------------------------------------------------------
def _method(fun):
    if isinstance(fun, types.FunctionType):  # binds as a method itself: one call less
        return fun
    return lambda self, *args, **kwargs: fun(self, *args, **kwargs)


def _reflected(fun):
    return lambda self, other: fun(other, self)


def _shape_arg(shape):
    return shape[0] if len(shape) == 1 and isinstance(shape[0], tuple | list) else shape


def _box_getitem(self, idx):
    if type(idx) is tuple:
        for i in idx:
            if isinstance(i, Box):
                idx = tuple(unbox(i) for i in idx)
                break
    elif isinstance(idx, tuple | Box):
        idx = tuple(unbox(i) for i in idx) if isinstance(idx, tuple) else idx._value
    return getitem(self, idx)


def _box_len(self):
    return len(self._value)


def _box_iter(self):
    return (self[i] for i in range(len(self._value)))


def _attr(name: str, fun):
    """The property ``name`` of the value: read off an array directly, else ``fun(value)``."""

    def get(self):
        value = self._value
        if type(value) is np.ndarray:
            return getattr(value, name)
        return fun(value)

    return get


def _comparison(fun):
    return lambda self, other: fun(self._value, unbox(other))


_BOX_METHODS = {
    "__add__": _method(add), "__radd__": _reflected(add),
    "__sub__": _method(subtract), "__rsub__": _reflected(subtract),
    "__mul__": _method(multiply), "__rmul__": _reflected(multiply),
    "__truediv__": _method(divide), "__rtruediv__": _reflected(divide),
    "__pow__": _method(power), "__rpow__": _reflected(power),
    "__matmul__": _method(matmul), "__rmatmul__": _reflected(matmul),
    "__mod__": _method(remainder), "__rmod__": _reflected(remainder),
    "__floordiv__": _method(floor_divide), "__rfloordiv__": _reflected(floor_divide),
    "__neg__": _method(negative), "__pos__": lambda self: self, "__abs__": _method(abs),
    "__getitem__": _box_getitem, "__len__": _box_len, "__iter__": _box_iter,
    "__lt__": _comparison(np.less), "__le__": _comparison(np.less_equal),
    "__gt__": _comparison(np.greater), "__ge__": _comparison(np.greater_equal),
    "__eq__": _comparison(np.equal), "__ne__": _comparison(np.not_equal),
    "__hash__": None,
    "shape": property(_attr("shape", np.shape)),
    "ndim": property(_attr("ndim", np.ndim)),
    "size": property(_attr("size", np.size)),
    "dtype": property(_attr("dtype", np.result_type)),
    "T": property(lambda self: transpose(self)),
    "sum": _method(sum), "mean": _method(mean), "max": _method(max), "min": _method(min),
    "var": _method(var), "std": _method(std), "cumsum": _method(cumsum),
    "reshape": lambda self, *shape: reshape(self, _shape_arg(shape)),
    "transpose": lambda self, *axes: transpose(self, _shape_arg(axes) or None),
    "swapaxes": _method(swapaxes), "squeeze": _method(squeeze), "ravel": _method(ravel),
    "flatten": _method(ravel), "astype": _method(astype), "dot": _method(dot),
    "clip": _method(clip), "all": _method(all), "any": _method(any), "argmax": _method(argmax),
    "argmin": _method(argmin),
}
for _name, _attr in _BOX_METHODS.items():
    setattr(Box, _name, _attr)
del _name, _attr


# ---------------------------------------------------------------------------
# NumPy's own functions on traced values: np.sum(x), np.exp(x), ndarray * x
# ---------------------------------------------------------------------------
# ``Box.__array_ufunc__`` and ``Box.__array_function__`` send a NumPy function
# called on a traced value to the primitive of the same meaning here, as HIPS
# autograd does; ``ndarray <op> Box`` is a ufunc call too and lands here. A
# NumPy function without a primitive raises instead of losing the gradient.
_INPLACE = (
    "{what} writes into an existing array in place, which cannot be traced: build a new "
    "array instead (y = y + x rather than y += x or np.add(y, x, out=y))"
)

_CLOSEST = {
    "prod": "anp.exp(anp.sum(anp.log(x))) for positive x",
    "cumprod": "anp.exp(anp.cumsum(anp.log(x))) for positive x",
    "copy": "x itself (traced values are never modified in place)",
    "average": "anp.sum(x * w) / anp.sum(w)",
    "nansum": "anp.sum(anp.where(anp.isnan(x), 0.0, x))",
    "nanmean": "anp.mean of the finite entries, via anp.where",
    "outer": "x[:, None] * y[None, :]",
    "multiply.outer": "x[:, None] * y[None, :]",
    "multiply.reduce": "anp.exp(anp.sum(anp.log(x))) for positive x",
    "add.accumulate": "anp.cumsum",
    "ufunc.outer": "broadcasting, x[:, None] <op> y[None, :]",
    "inner": "anp.dot or anp.einsum",
    "vdot": "anp.sum(x * y)",
    "tensordot": "anp.einsum",
    "trace": "anp.einsum('ii->', x)",
    "diagonal": "anp.einsum('ii->i', x)",
    "take": "x[idx]",
    "flip": "x[::-1] (indexing)",
    "broadcast_arrays": "anp.broadcast_to",
    "hstack": "anp.concatenate",
    "vstack": "anp.concatenate or anp.stack",
    "atleast_1d": "anp.reshape or anp.expand_dims",
    "atleast_2d": "anp.reshape or anp.expand_dims",
    "hypot": "anp.sqrt(x * x + y * y)",
    "reciprocal": "1.0 / x",
    "exp2": "anp.power(2.0, x)",
    "log2": "anp.log(x) / anp.log(2.0)",
    "log10": "anp.log(x) / anp.log(10.0)",
    "cbrt": "anp.power(x, 1.0 / 3.0) for positive x",
    "float_power": "anp.power",
    "deg2rad": "x * (anp.pi / 180)",
    "radians": "x * (anp.pi / 180)",
    "rad2deg": "x * (180 / anp.pi)",
    "degrees": "x * (180 / anp.pi)",
}


def _np_name(func) -> str:
    """``np.sum``, ``np.linalg.svd``: how the user wrote the NumPy function."""
    module = getattr(func, "__module__", None) or "numpy"
    if isinstance(func, np.ufunc) or not module.startswith("numpy") or "._" in module:
        module = "numpy"
    return "np" + module[len("numpy"):] + "." + func.__name__


def _no_derivative(display: str, name: str) -> TypeError:
    hint = _CLOSEST.get(name)
    if hint is None and name in _FUNCTION_NAMES:
        hint = f"anp.{name}"
    where = (f"use minimanc.autodiff.numpy (anp): {hint}," if hint else
             "use the functions of minimanc.autodiff.numpy (the `xp` namespace)")
    return TypeError(
        f"{display} has no derivative in minimanc.autodiff: {where} or write the primitive "
        "(@primitive with defvjp, see minimanc.autodiff)"
    )


def _positive(x):
    return x


_UFUNCS = {
    np.add: add, np.subtract: subtract, np.multiply: multiply, np.divide: divide,
    np.negative: negative, np.positive: _positive, np.power: power, np.square: square,
    np.remainder: remainder, np.logaddexp: logaddexp, np.maximum: maximum, np.minimum: minimum,
    np.exp: exp, np.expm1: expm1, np.log: log, np.log1p: log1p, np.sqrt: sqrt,
    np.absolute: abs, np.tanh: tanh, np.sinh: sinh, np.cosh: cosh, np.sin: sin, np.cos: cos,
    np.tan: tan, np.arcsin: arcsin, np.arccos: arccos, np.arctan: arctan, np.arctan2: arctan2,
    np.matmul: matmul,
    # no useful derivative: plain values out
    np.floor_divide: floor_divide, np.sign: sign, np.floor: floor, np.ceil: ceil,
    np.isfinite: isfinite, np.isnan: isnan, np.isinf: isinf, np.equal: equal,
    np.not_equal: not_equal, np.less: less, np.less_equal: less_equal, np.greater: greater,
    np.greater_equal: greater_equal, np.logical_and: logical_and, np.logical_or: logical_or,
    np.logical_not: logical_not,
}
_UFUNC_REDUCE = {np.add: sum, np.maximum: max, np.minimum: min}
_UFUNC_DEFAULTS = {"where": True, "casting": "same_kind", "order": "K", "dtype": None,
                   "subok": True, "signature": None, "axis": 0, "keepdims": False}


def _box_array_ufunc(self, ufunc, method, *inputs, **kwargs):
    """``np.exp(x)``, ``ndarray * x``, ``np.add.reduce(x)`` → our primitive (or a clear error)."""
    if method == "__call__" and not kwargs:  # the common case: ndarray * x, np.exp(x)
        ours = _UFUNCS.get(ufunc)
        if ours is not None:
            return ours(*inputs)
    display = _np_name(ufunc) + ("" if method == "__call__" else f".{method}")
    out = kwargs.pop("out", None)
    if method == "at" or (out is not None and builtins.any(o is not None for o in out)):
        what = f"{display}(...)" if method == "at" else (
            f"{display}(..., out=...) (also `a += x` with a NumPy array a)")
        raise TypeError(_INPLACE.format(what=what))
    table = _UFUNCS if method == "__call__" else _UFUNC_REDUCE if method == "reduce" else {}
    ours = table.get(ufunc)
    if ours is None:
        key = ufunc.__name__ if method == "__call__" else f"{ufunc.__name__}.{method}"
        raise _no_derivative(display, key if key in _CLOSEST or method == "__call__"
                             else f"ufunc.{method}")
    keep = ("axis", "keepdims") if method == "reduce" else ()
    call_kw = {}
    for key, val in kwargs.items():
        if key in keep:
            call_kw[key] = val
        elif not (key in _UFUNC_DEFAULTS and _same(val, _UFUNC_DEFAULTS[key])):
            raise TypeError(
                f"{display}(..., {key}=...) is not supported on traced values: call "
                f"minimanc.autodiff.numpy.{ours.__name__} without {key}="
            )
    return ours(*inputs, **call_kw)


def _same(val, default) -> bool:
    if val is default:
        return True
    simple = (str, int, float, bool, type(None))
    return isinstance(val, simple) and isinstance(default, simple) and val == default


_POSITIONAL = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)


def _numpy_signature(np_func, our_sig: inspect.Signature) -> inspect.Signature:
    """NumPy's signature of ``np_func``; where NumPy publishes none (C functions such as
    ``np.where``, ``np.concatenate`` and ``np.dot`` before NumPy 2), ours with NumPy's
    ``out=None`` added, so that ``out=`` is still refused by name."""
    try:
        return inspect.signature(np_func)
    except (TypeError, ValueError):
        params = list(our_sig.parameters.values())
        if "out" not in our_sig.parameters:
            params.append(inspect.Parameter("out", inspect.Parameter.KEYWORD_ONLY, default=None))
        return our_sig.replace(parameters=params)


def _adapt(np_func, ours):
    """Call ``ours`` with the arguments of a call of ``np_func`` (NumPy's signature).

    Parameters are matched by name (NumPy's first arguments ``a``/``array`` become
    ours ``x``); the arrays and the leading parameters go positionally, as
    primitives differentiate positional arguments only. ``out=`` is refused (an
    in-place write), and so is any NumPy option ours lacks, unless it has its
    default value.
    """
    our_sig = inspect.signature(ours)
    np_sig = _numpy_signature(np_func, our_sig)
    np_params = np_sig.parameters
    our_params = list(our_sig.parameters.values())
    our_names = {p.name for p in our_params}
    our_positional = [p.name for p in our_params if p.kind in _POSITIONAL]
    rename = {}
    for i, (name, p) in enumerate(np_params.items()):
        if (name not in our_names and p.kind in _POSITIONAL and i < len(our_positional)
                and our_positional[i] not in np_params):
            rename[name] = our_positional[i]
    display = _np_name(np_func)

    def call(*args, **kwargs):
        try:
            bound = np_sig.bind(*args, **kwargs)
        except TypeError as err:
            raise TypeError(f"{display}: {err}") from None
        varargs, given = (), {}
        for name, val in bound.arguments.items():
            kind = np_params[name].kind
            if kind is inspect.Parameter.VAR_POSITIONAL:
                varargs = val
                continue
            items = val.items() if kind is inspect.Parameter.VAR_KEYWORD else ((name, val),)
            for key, v in items:
                if key == "out" and v is not None:
                    raise TypeError(_INPLACE.format(what=f"{display}(..., out=...)"))
                ours_key = rename.get(key, key)
                if ours_key in our_names:
                    given[ours_key] = v
                elif not (key in np_params and _same(v, np_params[key].default)):
                    raise TypeError(
                        f"{display}(..., {key}=...) is not supported on traced values: "
                        f"minimanc.autodiff.numpy.{ours.__name__} takes "
                        f"({', '.join(p.name for p in our_params)})"
                    )
        pos = list(varargs)
        if not varargs:
            for name in our_positional:
                if name not in given:
                    break
                pos.append(given.pop(name))
        return ours(*pos, **given)

    call.__name__ = np_func.__name__
    return call


_DIFFERENTIABLE = (
    (np.sum, sum), (np.mean, mean), (np.max, max), (np.amax, max), (np.min, min),
    (np.amin, min), (np.var, var), (np.std, std), (np.cumsum, cumsum),
    (np.linalg.norm, linalg.norm), (np.reshape, reshape), (np.ravel, ravel),
    (np.expand_dims, expand_dims), (np.squeeze, squeeze), (np.broadcast_to, broadcast_to),
    (np.transpose, transpose), (np.swapaxes, swapaxes), (np.moveaxis, moveaxis), (np.pad, pad),
    (np.concatenate, concatenate), (np.stack, stack), (np.where, where), (np.clip, clip),
    (np.dot, dot), (np.einsum, einsum), (np.cross, cross),
)
_PLAIN = (  # no useful derivative: run NumPy on the values
    np.zeros_like, np.ones_like, np.full_like, np.empty_like, np.shape, np.ndim, np.size,
    np.result_type, np.all, np.any, np.argmax, np.argmin, np.argsort, np.allclose, np.isclose,
    np.count_nonzero, np.round, np.around, np.iscomplexobj, np.isrealobj, np.array_equal,
    np.array_equiv, np.nonzero, np.flatnonzero, np.argwhere,
)
_FUNCTIONS = {f: _adapt(f, ours) for f, ours in _DIFFERENTIABLE}
_FUNCTION_NAMES = frozenset(  # the public functions of this namespace, for hints
    k for k, v in vars(anp).items()
    if not k.startswith("_") and callable(v) and not isinstance(v, type | types.ModuleType)
)
_FUNCTIONS.update({f: nondiff(f) for f in _PLAIN})


def _box_array_function(self, func, types, args, kwargs):
    """``np.sum(x)``, ``np.concatenate([x, y])`` … → our primitive (or a clear error)."""
    impl = _FUNCTIONS.get(func)
    if impl is None:
        raise _no_derivative(_np_name(func), func.__name__)
    return impl(*args, **kwargs)


Box.__array_ufunc__ = _box_array_ufunc
Box.__array_function__ = _box_array_function
