"""Chapter 1 — a NumPy-like namespace whose functions are traced primitives.

Import it as ``anp`` (it is the ``xp`` of ``engine("numpy")``)::

    import minimanc.autodiff.numpy as anp
    from minimanc.autodiff import grad
    grad(lambda w: anp.sum(anp.tanh(w @ w.T)))(w0)

Every differentiable function is a :func:`~minimanc.autodiff.primitive`
with its vector-Jacobian product (VJP) registered right below it: the
element-wise ones in :mod:`~minimanc.autodiff.elementwise`, the reductions in
:mod:`~minimanc.autodiff.reductions`, shapes, indexing and joining in
:mod:`~minimanc.autodiff.arrays`, and linear algebra (``matmul``, ``einsum``,
``dot``, ``cross``) here. A VJP maps
the cotangent ``g = ∂L/∂ans`` to ``∂L/∂arg``; for broadcasting operations the
result is summed back to the argument's shape with ``unbroadcast``. Functions
without a useful derivative (``zeros``, ``sign``, ``isfinite`` …) take the
values out of their boxes and return plain arrays. Given plain NumPy inputs,
every function returns plain NumPy results.

Ties in ``max``/``min``/``maximum``/``minimum`` (and ``clip``, built from them)
share the gradient equally, as in JAX. First-order derivatives only.

NumPy's own functions also work on traced values, as in HIPS autograd
(:mod:`~minimanc.autodiff.dispatch`):
``np.sum(x)``, ``np.exp(x)``, ``np.ones(3) * x``, ``A @ x`` dispatch (through
``__array_function__`` / ``__array_ufunc__``) to the primitive of the same name
here. A NumPy function without one (``np.prod``, ``np.linalg.svd`` …) raises a
``TypeError`` naming the closest function here, and so does ``out=`` (an
in-place write cannot be traced).
"""

from __future__ import annotations

import builtins
import string
from collections import Counter

import numpy as np

from minimanc.autodiff.arrays import (
    all,
    allclose,
    any,
    arange,
    argmax,
    argmin,
    argsort,
    array,
    asarray,
    astype,
    broadcast_to,
    ceil,
    concatenate,
    count_nonzero,
    equal,
    expand_dims,
    eye,
    floor,
    floor_divide,
    full,
    full_like,
    getitem,
    greater,
    greater_equal,
    identity,
    isclose,
    isfinite,
    isinf,
    isnan,
    less,
    less_equal,
    linspace,
    logical_and,
    logical_not,
    logical_or,
    moveaxis,
    ndim,
    not_equal,
    ones,
    ones_like,
    pad,
    ravel,
    reshape,
    result_type,
    round,
    shape,
    sign,
    size,
    squeeze,
    stack,
    swapaxes,
    transpose,
    zeros,
    zeros_like,
)
from minimanc.autodiff.boxes import unbox
from minimanc.autodiff.elementwise import (
    abs,
    absolute,
    add,
    arccos,
    arcsin,
    arctan,
    arctan2,
    clip,
    cos,
    cosh,
    divide,
    exp,
    expm1,
    log,
    log1p,
    logaddexp,
    maximum,
    minimum,
    mod,
    multiply,
    negative,
    power,
    remainder,
    sin,
    sinh,
    sqrt,
    square,
    subtract,
    tan,
    tanh,
    true_divide,
    where,
)
from minimanc.autodiff.primitives import defvjp, primitive, unbroadcast
from minimanc.autodiff.reductions import (
    amax,
    amin,
    cumsum,
    linalg,
    max,
    mean,
    min,
    std,
    sum,
    var,
)

__all__ = [
    "abs", "absolute", "add", "all", "allclose", "amax", "amin", "any", "arange", "arccos",
    "arcsin", "arctan", "arctan2", "argmax", "argmin", "argsort", "array", "asarray", "astype",
    "bool_", "broadcast_to", "ceil", "clip", "concatenate", "cos", "cosh", "count_nonzero",
    "cross", "cumsum", "divide", "dot", "dtype", "e", "einsum", "equal", "exp", "expand_dims",
    "expm1", "eye", "finfo", "float32", "float64", "floor", "floor_divide", "full", "full_like",
    "getitem", "greater", "greater_equal", "identity", "iinfo", "inf", "int32", "int64",
    "isclose", "isfinite", "isinf", "isnan", "less", "less_equal", "linalg", "linspace", "log",
    "log1p", "logaddexp", "logical_and", "logical_not", "logical_or", "matmul", "max", "maximum",
    "mean", "min", "minimum", "mod", "moveaxis", "multiply", "nan", "ndarray", "ndim", "negative",
    "newaxis", "not_equal", "ones", "ones_like", "pad", "pi", "power", "ravel", "remainder",
    "reshape", "result_type", "round", "shape", "sign", "sin", "sinh", "size", "sqrt", "square",
    "squeeze", "stack", "std", "subtract", "sum", "swapaxes", "tan", "tanh", "transpose",
    "true_divide", "var", "where", "zeros", "zeros_like",
]

# Constants and dtypes, passed through from NumPy.
pi, e, inf, nan, newaxis = np.pi, np.e, np.inf, np.nan, np.newaxis
float32, float64, int32, int64, bool_ = np.float32, np.float64, np.int32, np.int64, np.bool_
dtype, finfo, iinfo, ndarray = np.dtype, np.finfo, np.iinfo, np.ndarray



# ---------------------------------------------------------------------------
# Linear algebra
# ---------------------------------------------------------------------------
def _check_aligned(name, x, y):
    sx = x.shape if type(x) is np.ndarray else np.shape(x)
    sy = y.shape if type(y) is np.ndarray else np.shape(y)
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


def _matrices(g, x, y) -> bool:
    """Both operands (and the cotangent) arrays of at least two dimensions: no promotion."""
    return (type(x) is np.ndarray and type(y) is np.ndarray and type(g) is np.ndarray
            and x.ndim >= 2 and y.ndim >= 2)


def _matmul_vjp_x(g, ans, x, y):
    if _matrices(g, x, y):
        return unbroadcast(x, g @ y.swapaxes(-1, -2))
    g2, x2, y2 = _matmul_promoted(g, x, y)
    return unbroadcast(x2.shape, g2 @ np.swapaxes(y2, -1, -2)).reshape(np.shape(x))


def _matmul_vjp_y(g, ans, x, y):
    if _matrices(g, x, y):
        return unbroadcast(y, x.swapaxes(-1, -2) @ g)
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
    nda, ndb = np.ndim(unbox(a)), np.ndim(unbox(b))
    if nda == 0 or ndb == 0:
        return multiply(a, b)
    _check_aligned("dot", unbox(a), unbox(b))
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
