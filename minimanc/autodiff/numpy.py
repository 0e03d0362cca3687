"""Chapter 1 — a NumPy-like namespace whose functions are traced primitives.

Import it as ``anp`` (it is the ``xp`` of ``engine("numpy")``)::

    import minimanc.autodiff.numpy as anp
    from minimanc.autodiff import grad
    grad(lambda w: anp.sum(anp.tanh(w @ w.T)))(w0)

Every differentiable function is a :func:`~minimanc.autodiff.core.primitive`
with its vector-Jacobian product (VJP) registered right below it. A VJP maps
the cotangent ``g = ∂L/∂ans`` to ``∂L/∂arg``; for broadcasting operations the
result is summed back to the argument's shape with ``unbroadcast``. Functions
without a useful derivative (``zeros``, ``sign``, ``isfinite`` …) take the
values out of their boxes and return plain arrays. Given plain NumPy inputs,
every function returns plain NumPy results.

Ties in ``max``/``min``/``maximum``/``minimum`` (and ``clip``, built from them)
share the gradient equally, as in JAX. First-order derivatives only.

NumPy's own functions also work on traced values, as in HIPS autograd:
``np.sum(x)``, ``np.exp(x)``, ``np.ones(3) * x``, ``A @ x`` dispatch (through
``__array_function__`` / ``__array_ufunc__``) to the primitive of the same name
here. A NumPy function without one (``np.prod``, ``np.linalg.svd`` …) raises a
``TypeError`` naming the closest function here, and so does ``out=`` (an
in-place write cannot be traced).
"""

from __future__ import annotations

import builtins
import inspect
import math
import string
import types
from collections import Counter

import numpy as np

from minimanc.autodiff.core import Box, defvjp, defvjp_fwd, primitive, unbroadcast

# Constants and dtypes, passed through from NumPy.
pi, e, inf, nan, newaxis = np.pi, np.e, np.inf, np.nan, np.newaxis
float32, float64, int32, int64, bool_ = np.float32, np.float64, np.int32, np.int64, np.bool_
dtype, finfo, iinfo, ndarray = np.dtype, np.finfo, np.iinfo, np.ndarray


def _unbox(x):
    return x._value if isinstance(x, Box) else x


def _unbox_all(x):
    if isinstance(x, Box):
        return x._value
    if isinstance(x, list | tuple):
        return type(x)(_unbox_all(v) for v in x)
    return x


def _contains_box(x) -> bool:
    if isinstance(x, Box):
        return True
    return isinstance(x, list | tuple) and builtins.any(_contains_box(v) for v in x)


# ---------------------------------------------------------------------------
# Element-wise arithmetic (with broadcasting)
# ---------------------------------------------------------------------------
add = primitive(np.add)
defvjp(add, lambda g, ans, x, y: unbroadcast(x, g), lambda g, ans, x, y: unbroadcast(y, g))

subtract = primitive(np.subtract)
defvjp(subtract, lambda g, ans, x, y: unbroadcast(x, g), lambda g, ans, x, y: unbroadcast(y, -g))

multiply = primitive(np.multiply)
defvjp(
    multiply,
    lambda g, ans, x, y: unbroadcast(x, g * y),
    lambda g, ans, x, y: unbroadcast(y, g * x),
)

divide = primitive(np.divide)
defvjp(
    divide,
    lambda g, ans, x, y: unbroadcast(x, g / y),
    lambda g, ans, x, y: unbroadcast(y, -g * ans / y),
)
true_divide = divide

negative = primitive(np.negative)
defvjp(negative, lambda g, ans, x: -g)


def _pow_vjp_x(g, ans, x, y):
    with np.errstate(divide="ignore", invalid="ignore"):
        d = y * np.power(x, y - 1)
    return unbroadcast(x, g * np.where(np.equal(y, 0), 0, d))  # d/dx x**0 = 0, as in JAX


def _pow_vjp_y(g, ans, x, y):
    with np.errstate(divide="ignore", invalid="ignore"):
        return unbroadcast(y, g * ans * np.log(np.where(np.equal(x, 0), 1, x)))


power = primitive(np.power)
defvjp(power, _pow_vjp_x, _pow_vjp_y)

square = primitive(np.square)
defvjp(square, lambda g, ans, x: g * 2 * x)


remainder = primitive(np.remainder)  # x % y: d/dx = 1, d/dy = -floor(x / y), as in JAX
defvjp(
    remainder,
    lambda g, ans, x, y: unbroadcast(x, g),
    lambda g, ans, x, y: unbroadcast(y, -g * np.floor_divide(x, y)),
)
mod = remainder

logaddexp = primitive(np.logaddexp)  # log(e^x + e^y), without overflow
defvjp(
    logaddexp,
    lambda g, ans, x, y: unbroadcast(x, g * np.exp(x - ans)),
    lambda g, ans, x, y: unbroadcast(y, g * np.exp(y - ans)),
)


def _balanced(first, second, g):
    """Weight 1 where ``first`` wins, 1/2 on ties, 0 elsewhere (JAX's convention)."""
    w = np.where(first > second, 1.0, np.where(first == second, 0.5, 0.0))
    return g * w.astype(g.dtype, copy=False)


maximum = primitive(np.maximum)
defvjp(
    maximum,
    lambda g, ans, x, y: unbroadcast(x, _balanced(x, y, g)),
    lambda g, ans, x, y: unbroadcast(y, _balanced(y, x, g)),
)

minimum = primitive(np.minimum)
defvjp(
    minimum,
    lambda g, ans, x, y: unbroadcast(x, _balanced(y, x, g)),
    lambda g, ans, x, y: unbroadcast(y, _balanced(x, y, g)),
)


def clip(x, a_min=None, a_max=None, *, min=None, max=None):  # noqa: A002
    """``minimum(maximum(x, a_min), a_max)``, like ``jnp.clip`` (gradient included)."""
    lo = a_min if a_min is not None else min
    hi = a_max if a_max is not None else max
    if lo is not None:
        x = maximum(x, lo)
    if hi is not None:
        x = minimum(x, hi)
    return x


# ---------------------------------------------------------------------------
# Element-wise functions
# ---------------------------------------------------------------------------
exp = primitive(np.exp)
defvjp(exp, lambda g, ans, x: g * ans)

expm1 = primitive(np.expm1)
defvjp(expm1, lambda g, ans, x: g * (ans + 1))

log = primitive(np.log)
defvjp(log, lambda g, ans, x: g / x)

log1p = primitive(np.log1p)
defvjp(log1p, lambda g, ans, x: g / (1 + x))


def _sqrt_vjp(g, ans, x):
    with np.errstate(divide="ignore"):
        return g * 0.5 / ans


sqrt = primitive(np.sqrt)
defvjp(sqrt, _sqrt_vjp)

abs = primitive(np.abs)  # noqa: A001
defvjp(abs, lambda g, ans, x: g * np.sign(x))
absolute = abs

tanh = primitive(np.tanh)
defvjp(tanh, lambda g, ans, x: g * (1 - ans * ans))

sinh = primitive(np.sinh)
defvjp(sinh, lambda g, ans, x: g * np.cosh(x))

cosh = primitive(np.cosh)
defvjp(cosh, lambda g, ans, x: g * np.sinh(x))

sin = primitive(np.sin)
defvjp(sin, lambda g, ans, x: g * np.cos(x))

cos = primitive(np.cos)
defvjp(cos, lambda g, ans, x: -g * np.sin(x))

tan = primitive(np.tan)
defvjp(tan, lambda g, ans, x: g * (1 + ans * ans))

arcsin = primitive(np.arcsin)
defvjp(arcsin, lambda g, ans, x: g / np.sqrt(1 - x * x))

arccos = primitive(np.arccos)
defvjp(arccos, lambda g, ans, x: -g / np.sqrt(1 - x * x))

arctan = primitive(np.arctan)
defvjp(arctan, lambda g, ans, x: g / (1 + x * x))

arctan2 = primitive(np.arctan2)  # arctan2(y, x): the angle of the point (x, y)
defvjp(
    arctan2,
    lambda g, ans, y, x: unbroadcast(y, g * x / (x * x + y * y)),
    lambda g, ans, y, x: unbroadcast(x, -g * y / (x * x + y * y)),
)


def _where_fn(condition, x, y):
    return np.where(condition, x, y)


_where_fn.__name__ = "where"
_where = primitive(_where_fn)
defvjp(
    _where,
    None,
    lambda g, ans, c, x, y: unbroadcast(x, np.where(c, g, np.zeros_like(g))),
    lambda g, ans, c, x, y: unbroadcast(y, np.where(c, np.zeros_like(g), g)),
)


def where(condition, x=None, y=None):
    """``x`` where ``condition`` holds, else ``y`` (the condition is not differentiated)."""
    condition = _unbox(condition)
    if x is None and y is None:
        return np.where(condition)
    return _where(condition, x, y)


# ---------------------------------------------------------------------------
# Linear algebra
# ---------------------------------------------------------------------------
def _check_aligned(name, x, y):
    sx, sy = np.shape(x), np.shape(y)
    if len(sx) >= 1 and len(sy) >= 1:
        kx, ky = sx[-1], sy[-2] if len(sy) >= 2 else sy[0]
        if kx != ky:
            raise ValueError(
                f"{name}: shapes {sx} and {sy} are not aligned "
                f"({kx} (dim {len(sx) - 1}) != {ky} (dim {builtins.max(len(sy) - 2, 0)}))"
            )


def _matmul_fn(x, y):
    _check_aligned("matmul", x, y)
    return np.matmul(x, y)


_matmul_fn.__name__ = "matmul"
matmul = primitive(_matmul_fn)


def _matmul_promoted(g, x, y):
    """Treat 1-D operands as matrices (a row for ``x``, a column for ``y``)."""
    x, y, g = np.asarray(x), np.asarray(y), np.asarray(g)
    if x.ndim == 1 and y.ndim == 1:
        return g.reshape(1, 1), x[None, :], y[:, None]
    if x.ndim == 1:
        x, g = x[None, :], np.expand_dims(g, -2)
    if y.ndim == 1:
        y, g = y[:, None], np.expand_dims(g, -1)
    return g, x, y


def _matmul_vjp_x(g, ans, x, y):
    g2, x2, y2 = _matmul_promoted(g, x, y)
    return unbroadcast(x2.shape, g2 @ np.swapaxes(y2, -1, -2)).reshape(np.shape(x))


def _matmul_vjp_y(g, ans, x, y):
    g2, x2, y2 = _matmul_promoted(g, x, y)
    return unbroadcast(y2.shape, np.swapaxes(x2, -1, -2) @ g2).reshape(np.shape(y))


defvjp(matmul, _matmul_vjp_x, _matmul_vjp_y)


_LETTERS = string.ascii_letters


def _einsum_np(subscripts, *operands):
    big = builtins.max(np.size(o) for o in operands) > 4096
    return np.einsum(subscripts, *operands, optimize=len(operands) > 2 or big)


def _einsum_parse(subscripts: str, shapes) -> tuple[list[str], str]:
    """Explicit per-operand subscripts and output, with ``...`` replaced by letters."""
    subs = subscripts.replace(" ", "")
    lhs, out = subs.split("->") if "->" in subs else (subs, None)
    terms = lhs.split(",")
    if len(terms) != len(shapes):
        raise ValueError(f"einsum: {len(terms)} operand subscripts but {len(shapes)} operands")
    free = [c for c in _LETTERS if c not in subs]
    ell_nd = builtins.max(
        [len(s) - (len(t) - 3) for t, s in zip(terms, shapes) if "..." in t], default=0
    )
    ell = "".join(free[:ell_nd])
    terms = [
        t.replace("...", ell[ell_nd - (len(s) - (len(t) - 3)):]) if "..." in t else t
        for t, s in zip(terms, shapes)
    ]
    if out is None:  # implicit mode: broadcast dims, then letters seen once, sorted
        counts = Counter("".join(terms))
        out = ell + "".join(sorted(c for c, n in counts.items() if n == 1 and c not in ell))
    else:
        out = out.replace("...", ell)
    return terms, out


def _einsum_fn(subscripts, *operands, optimize=None):
    if not isinstance(subscripts, str):
        raise ValueError("einsum: only the subscripts-string form einsum('ij,jk->ik', a, b)")
    return _einsum_np(subscripts, *operands)


_einsum_fn.__name__ = "einsum"
einsum = primitive(_einsum_fn)


def _einsum_vjp(k: int, g, subscripts: str, *operands, optimize=None):
    """Cotangent of operand ``k``: contract ``g`` with all the other operands."""
    terms, out = _einsum_parse(subscripts, [np.shape(o) for o in operands])
    target = terms[k]
    if len(set(target)) != len(target):
        raise NotImplementedError(
            f"einsum: VJP with a repeated index within one operand ({target!r}) is not supported"
        )
    others = [t for j, t in enumerate(terms) if j != k] + [out]
    ops = [o for j, o in enumerate(operands) if j != k] + [g]
    present = "".join(others)
    kept = "".join(c for c in target if c in present)
    r = _einsum_np(",".join(others) + "->" + kept, *ops)
    # letters only in operand k were summed in the forward pass: broadcast back
    r = r.reshape(tuple(r.shape[kept.index(c)] if c in present else 1 for c in target))
    return unbroadcast(operands[k], r)


defvjp(
    einsum,
    None,
    *[lambda g, ans, s, *ops, k=k, **kw: _einsum_vjp(k, g, s, *ops) for k in range(len(_LETTERS))],
)


def dot(a, b):
    """``np.dot``: a product for scalars, ``matmul`` up to 2-D, ``einsum`` beyond."""
    nda, ndb = np.ndim(_unbox(a)), np.ndim(_unbox(b))
    if nda == 0 or ndb == 0:
        return multiply(a, b)
    _check_aligned("dot", _unbox(a), _unbox(b))
    if nda <= 2 and ndb <= 2:
        return matmul(a, b)
    la = _LETTERS[: nda - 1] + "z"
    lb = _LETTERS[nda - 1 : nda - 1 + ndb - 1]
    lb = lb[:-1] + "z" + lb[-1:] if ndb >= 2 else "z"
    out = la[:-1] + (lb[:-2] + lb[-1:] if ndb >= 2 else "")
    return einsum(f"{la},{lb}->{out}", a, b)


def _cross_fn(a, b, axis=-1):
    return np.cross(a, b, axis=axis)


_cross_fn.__name__ = "cross"
cross = primitive(_cross_fn)
defvjp(
    cross,
    lambda g, ans, a, b, axis=-1: unbroadcast(a, np.cross(b, g, axis=axis)),
    lambda g, ans, a, b, axis=-1: unbroadcast(b, np.cross(g, a, axis=axis)),
)


# ---------------------------------------------------------------------------
# Reductions
# ---------------------------------------------------------------------------
def _axis(axis):
    return tuple(axis) if isinstance(axis, list) else axis


def _expand(g, axis, keepdims):
    """Give the reduced cotangent back its reduced axes (as size 1)."""
    return g if keepdims or axis is None else np.expand_dims(g, axis)


@primitive
def sum(x, axis=None, keepdims=False, dtype=None):  # noqa: A001
    """Sum over ``axis`` (all axes by default)."""
    return np.sum(x, axis=_axis(axis), keepdims=keepdims, dtype=dtype)


defvjp(
    sum,
    lambda g, ans, x, axis=None, keepdims=False, dtype=None: np.broadcast_to(
        _expand(g, _axis(axis), keepdims), np.shape(x)
    ),
)


@primitive
def mean(x, axis=None, keepdims=False, dtype=None):
    """Mean over ``axis`` (all axes by default)."""
    return np.mean(x, axis=_axis(axis), keepdims=keepdims, dtype=dtype)


def _mean_vjp(g, ans, x, axis=None, keepdims=False, dtype=None):
    count = np.size(x) // builtins.max(np.size(ans), 1)
    return np.broadcast_to(_expand(g, _axis(axis), keepdims) / count, np.shape(x))


defvjp(mean, _mean_vjp)


def _chooser_vjp(g, ans, x, axis=None, keepdims=False):
    """The gradient goes to the arg-max (arg-min) elements, shared equally on ties."""
    axis = _axis(axis)
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
    shp, axis_t = np.shape(_unbox(x)), _axis(axis)
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


# ---------------------------------------------------------------------------
# Shapes, indexing, joining
# ---------------------------------------------------------------------------
def _reshape_back(g, ans, x, *args, **kwargs):
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


@primitive
def astype(x, dtype):
    """``x`` converted to ``dtype`` (the cotangent is converted back)."""
    return np.asarray(x).astype(dtype)


defvjp(astype, lambda g, ans, x, dtype: np.asarray(g).astype(np.result_type(x)))


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
    items = idx if isinstance(idx, tuple) else (idx,)
    return builtins.all(
        i is None or i is Ellipsis or isinstance(i, slice | int | np.integer) and not isinstance(
            i, bool
        )
        for i in items
    )


def _getitem_fn(x, idx):
    return np.asarray(x)[idx]


def _getitem_vjp(g, ans, x, idx):
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
    return ans, (np.cumsum([np.shape(a)[axis] for a in arrays])[:-1], axis)


def _concatenate_bwd(g, res):
    splits, axis = res
    return tuple(np.split(g, splits, axis=axis))


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
    if isinstance(x, list | tuple) and _contains_box(x):
        out = stack([asarray(v) for v in x])
        return out if dtype is None else astype(out, dtype)
    return np.asarray(x, dtype=dtype)


def array(x, dtype=None):
    """Like :func:`asarray`, but plain inputs are copied (as ``np.array``)."""
    if isinstance(x, Box) or _contains_box(x):
        return asarray(x, dtype)
    return np.array(x, dtype=dtype)


# ---------------------------------------------------------------------------
# Non-differentiable functions: plain values in, plain values out
# ---------------------------------------------------------------------------
def _nondiff(fun):
    def wrapped(*args, **kwargs):
        return fun(*_unbox_all(args), **{k: _unbox_all(v) for k, v in kwargs.items()})

    wrapped.__name__ = fun.__name__
    wrapped.__doc__ = f"``numpy.{fun.__name__}`` on unboxed values (not differentiated)."
    return wrapped


zeros, ones, full, eye, identity = (_nondiff(f) for f in (np.zeros, np.ones, np.full, np.eye,
                                                           np.identity))
zeros_like, ones_like, full_like = (_nondiff(f) for f in (np.zeros_like, np.ones_like,
                                                          np.full_like))
arange, linspace = _nondiff(np.arange), _nondiff(np.linspace)
floor_divide = _nondiff(np.floor_divide)
sign, floor, ceil, round = (_nondiff(f) for f in (np.sign, np.floor, np.ceil, np.round))  # noqa: A001
isfinite, isnan, isinf = _nondiff(np.isfinite), _nondiff(np.isnan), _nondiff(np.isinf)
all, any = _nondiff(np.all), _nondiff(np.any)  # noqa: A001
argmax, argmin, argsort = _nondiff(np.argmax), _nondiff(np.argmin), _nondiff(np.argsort)
equal, not_equal = _nondiff(np.equal), _nondiff(np.not_equal)
less, less_equal = _nondiff(np.less), _nondiff(np.less_equal)
greater, greater_equal = _nondiff(np.greater), _nondiff(np.greater_equal)
logical_and, logical_or, logical_not = (_nondiff(f) for f in (np.logical_and, np.logical_or,
                                                              np.logical_not))
allclose, isclose, count_nonzero = _nondiff(np.allclose), _nondiff(np.isclose), _nondiff(
    np.count_nonzero
)
shape, ndim, size = _nondiff(np.shape), _nondiff(np.ndim), _nondiff(np.size)
result_type = _nondiff(np.result_type)


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
    if isinstance(idx, tuple):
        idx = tuple(_unbox(i) for i in idx)
    return getitem(self, _unbox(idx))


def _box_len(self):
    return len(self._value)


def _box_iter(self):
    return (self[i] for i in range(len(self._value)))


def _comparison(fun):
    return lambda self, other: fun(self._value, _unbox(other))


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
    "shape": property(lambda self: np.shape(self._value)),
    "ndim": property(lambda self: np.ndim(self._value)),
    "size": property(lambda self: np.size(self._value)),
    "dtype": property(lambda self: np.result_type(self._value)),
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
        "(@primitive with defvjp, see minimanc.autodiff.core)"
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
    k for k, v in globals().items()
    if not k.startswith("_") and callable(v) and not isinstance(v, type | types.ModuleType)
)
_FUNCTIONS.update({f: _nondiff(f) for f in _PLAIN})


def _box_array_function(self, func, types, args, kwargs):
    """``np.sum(x)``, ``np.concatenate([x, y])`` … → our primitive (or a clear error)."""
    impl = _FUNCTIONS.get(func)
    if impl is None:
        raise _no_derivative(_np_name(func), func.__name__)
    return impl(*args, **kwargs)


Box.__array_ufunc__ = _box_array_ufunc
Box.__array_function__ = _box_array_function
