"""Chapter 2 — neural-net primitives for the NumPy autodiff engine.

Each primitive is a plain-NumPy function made traceable with
:func:`minimanc.autodiff.primitive`, with its vector-Jacobian product
written right beside it:

- activations ``relu``, ``sigmoid``, ``silu`` (the paper's main model uses SiLU);
- ``softmax`` and ``log_softmax`` along an axis (the column softmax of eq. 9 is
  ``softmax(x, axis=0)``);
- ``conv2d`` (NHWC images, HWIO kernels) and ``global_avg_pool`` — the
  ``ConvEncoder`` and ``GlobalAveragePooling`` of the visual predicate
  extractor, eq. 7.

``engine("numpy").nn`` is this module; ``engine("jax").nn`` has the same names
and signatures, so model code runs unchanged on both engines.

How ``conv2d`` is made fast (channels-last, no transposes anywhere):

1. **im2col** is one ``np.copyto`` from an ``as_strided`` window view of the
   (persistently) zero-padded input into a column matrix ``col`` of shape
   ``(N*Ho*Wo, kh*kw*C [+1])``. With a bias, the last column holds ones and the
   bias is the last row of the weight matrix, so the bias add is part of the
   GEMM and its gradient falls out of the same GEMM in the backward pass.
2. The forward pass is one ``matmul(col, W, out=...)`` whose output *is* the
   next NHWC activation (a reshape, no copy).
3. ``col`` is kept as a residual (``defvjp_fwd``), so the backward pass costs
   two GEMMs (``dW = colᵀ g``, ``dcol = g Wᵀ``) plus a **col2im** that sums
   the kernel offsets back. Offsets are grouped in blocks of ``stride``
   consecutive offsets per axis: a full block tiles the input exactly, so the
   first block is a single assignment (no zero fill) and each other block one
   strided add. For 3×3 kernels and stride 2: 1 assignment (4 offsets) + 3 adds.
4. Buffers are reused: padded inputs and ``dcol`` are persistent per shape;
   ``col`` matrices come from a small pool, are handed to the residual and go
   back to the pool once the backward pass has used them.

float32 inputs stay float32 end to end. The VJPs are first-order (they are
plain NumPy), which is all that training needs.
"""

from __future__ import annotations

from collections import OrderedDict
from numbers import Integral

import numpy as np
from numpy.lib.stride_tricks import as_strided

from minimanc.autodiff.boxes import Box
from minimanc.autodiff.primitives import defvjp, defvjp_fwd, primitive
from minimanc.checks import check_int

__all__ = [
    "relu",
    "sigmoid",
    "silu",
    "softmax",
    "log_softmax",
    "conv2d",
    "conv2d_output_size",
    "global_avg_pool",
    "clear_buffers",
]


# ---------------------------------------------------------------------------
# Element-wise activations
# ---------------------------------------------------------------------------
def _sigmoid_np(x: np.ndarray) -> np.ndarray:
    """Logistic function ``1 / (1 + exp(-x))`` in one buffer (four passes, no temporaries).

    For ``x → −∞`` ``exp(-x)`` overflows to ``inf`` and the result is exactly 0
    (the overflow is expected and not reported); both tails keep full relative
    precision.
    """
    x = np.asarray(x)
    if x.dtype.kind != "f":
        x = x.astype(np.float64)
    t = np.negative(x, out=np.empty_like(x))
    with np.errstate(over="ignore"):
        np.exp(t, out=t)
    t += 1
    return np.reciprocal(t, out=t)


@primitive
def relu(x):
    """Rectified linear unit ``max(x, 0)`` (gradient 0 at 0, as in JAX)."""
    return np.maximum(x, 0)


defvjp(relu, lambda g, ans, x: g * (ans > 0))


@primitive
def sigmoid(x):
    """Logistic function ``1 / (1 + exp(-x))``, computed without overflow."""
    return _sigmoid_np(x)


defvjp(sigmoid, lambda g, ans, x: g * (ans * (1 - ans)))


@primitive
def silu(x):
    """SiLU / swish ``x * sigmoid(x)``."""
    return x * _sigmoid_np(x)


def _silu_fwd(x):
    s = _sigmoid_np(x)
    return x * s, (x, s)


def _silu_bwd(g, res):
    x, s = res
    d = np.subtract(1, s, dtype=s.dtype)  # d/dx x σ(x) = σ (1 + x (1 − σ)), in place
    d *= x
    d += 1
    d *= s
    d *= g
    return (d,)


defvjp_fwd(silu, _silu_fwd, _silu_bwd)


# ---------------------------------------------------------------------------
# Softmax family
# ---------------------------------------------------------------------------
def _check_axis(x, axis) -> None:
    ndim = np.ndim(x)
    if not isinstance(axis, Integral) or not -ndim <= int(axis) < max(ndim, 1):
        raise ValueError(f"axis={axis!r} is out of range for an array with ndim={ndim}")


@primitive
def _softmax(x, axis=-1):
    e = np.exp(x - np.max(x, axis=axis, keepdims=True))
    return e / np.sum(e, axis=axis, keepdims=True)


defvjp(
    _softmax,
    lambda g, ans, x, axis=-1: ans * (g - np.sum(g * ans, axis=axis, keepdims=True)),
)


@primitive
def _log_softmax(x, axis=-1):
    shifted = x - np.max(x, axis=axis, keepdims=True)
    return shifted - np.log(np.sum(np.exp(shifted), axis=axis, keepdims=True))


defvjp(
    _log_softmax,
    lambda g, ans, x, axis=-1: g - np.exp(ans) * np.sum(g, axis=axis, keepdims=True),
)


def softmax(x, axis: int = -1):
    """Softmax ``exp(x) / Σ exp(x)`` along ``axis`` (max-shifted, no overflow).

    ``softmax(x, axis=0)`` is the column softmax of eq. 9.
    """
    _check_axis(x, axis)
    return _softmax(x, axis=int(axis))


def log_softmax(x, axis: int = -1):
    """``x - log Σ exp(x)`` along ``axis``, computed stably."""
    _check_axis(x, axis)
    return _log_softmax(x, axis=int(axis))


# ---------------------------------------------------------------------------
# Global average pooling (eq. 7)
# ---------------------------------------------------------------------------
@primitive
def _global_avg_pool(x):
    return np.mean(x, axis=(1, 2))


def _gap_vjp(g, ans, x):
    n, h, w, c = np.shape(x)
    dt = np.result_type(np.asarray(x).dtype, np.float32)
    scaled = np.asarray(g, dtype=dt) * (1.0 / (h * w))
    out = np.empty((n, h, w, c), dtype=dt)
    np.copyto(out, scaled[:, None, None, :])
    return out


defvjp(_global_avg_pool, _gap_vjp)


def global_avg_pool(x):
    """Global average pooling ``(N, H, W, C) -> (N, C)``: the mean over H and W (eq. 7)."""
    if np.ndim(x) != 4:
        raise ValueError(f"x must be NHWC (ndim 4), got shape={np.shape(x)}")
    return _global_avg_pool(x)


# ---------------------------------------------------------------------------
# conv2d: buffers
# ---------------------------------------------------------------------------
_MAX_KEYS = 12  # shapes remembered per buffer cache (LRU)
_MAX_POOLED = 4  # free col matrices kept per shape

_pad_cache: OrderedDict = OrderedDict()  # key -> zero-bordered padded input buffer
_dcol_cache: OrderedDict = OrderedDict()  # key -> scratch buffer for dcol
_col_pool: OrderedDict = OrderedDict()  # key -> list of free col matrices


def clear_buffers() -> None:
    """Free every buffer kept by :func:`conv2d` (they are re-created on demand)."""
    _pad_cache.clear()
    _dcol_cache.clear()
    _col_pool.clear()


def _lru_get(cache: OrderedDict, key, make):
    buf = cache.get(key)
    if buf is None:
        buf = make()
        cache[key] = buf
        if len(cache) > _MAX_KEYS:
            cache.popitem(last=False)
    else:
        cache.move_to_end(key)
    return buf


def _take_col(rows: int, k: int, with_bias: bool, dtype) -> np.ndarray:
    key = (rows, k, with_bias, np.dtype(dtype).str)
    free = _col_pool.get(key)
    if free:
        _col_pool.move_to_end(key)
        return free.pop()
    if with_bias:
        col = np.empty((rows, k + 1), dtype=dtype)
        col[:, k] = 1  # the ones column that folds the bias into the GEMM
    else:
        col = np.empty((rows, k), dtype=dtype)
    return col


def _give_col(col: np.ndarray, k: int, with_bias: bool) -> None:
    key = (col.shape[0], k, with_bias, col.dtype.str)
    free = _lru_get(_col_pool, key, list)
    if len(free) < _MAX_POOLED:
        free.append(col)


def conv2d_output_size(size: int, kernel: int, stride: int = 1, padding: int = 0) -> int:
    """Output length ``(size + 2 padding - kernel) // stride + 1`` of a convolution."""
    return (size + 2 * padding - kernel) // stride + 1


class _ConvResiduals:
    """What the backward pass needs; ``col`` is released to the pool after use."""

    __slots__ = ("x", "w", "b_dtype", "stride", "padding", "col", "wmat", "dtype", "out_hw",
                 "need_dx")

    def __init__(self, x, w, b_dtype, stride, padding, col, wmat, dtype, out_hw, need_dx=True):
        self.x = x
        self.w = w
        self.b_dtype = b_dtype
        self.stride = stride
        self.padding = padding
        self.col = col
        self.wmat = wmat
        self.dtype = dtype
        self.out_hw = out_hw
        self.need_dx = need_dx


def _conv_dtype(x: np.ndarray, w: np.ndarray, b) -> np.dtype:
    dtypes = (x.dtype, w.dtype) if b is None else (x.dtype, w.dtype, b.dtype)
    dt = np.result_type(*dtypes)
    if not np.issubdtype(dt, np.floating):
        dt = np.dtype(np.float64)
    return np.dtype(dt)


def _im2col(x: np.ndarray, kh: int, kw: int, stride: int, padding: int, col: np.ndarray,
            dtype: np.dtype) -> tuple[int, int]:
    """Fill ``col[:, :kh*kw*C]`` with the (kh, kw, C)-ordered windows of ``x``."""
    n, h, w, c = x.shape
    ho = conv2d_output_size(h, kh, stride, padding)
    wo = conv2d_output_size(w, kw, stride, padding)
    if padding:
        hp, wp = h + 2 * padding, w + 2 * padding
        # keyed by the input shape *and* the padding: a buffer of the same padded shape
        # filled for another padding would keep that call's pixels in the zero border
        key = (n, h, w, c, padding, dtype.str)
        xp_buf = _lru_get(_pad_cache, key, lambda: np.zeros((n, hp, wp, c), dtype=dtype))
        np.copyto(xp_buf[:, padding:padding + h, padding:padding + w, :], x, casting="unsafe")
        src = xp_buf
    else:
        src = x
    s0, s1, s2, s3 = src.strides
    windows = as_strided(
        src,
        shape=(n, ho, wo, kh, kw, c),
        strides=(s0, stride * s1, stride * s2, s1, s2, s3),
        writeable=False,
    )
    r0, r1 = col.strides
    dest = as_strided(
        col,
        shape=(n, ho, wo, kh, kw, c),
        strides=(ho * wo * r0, wo * r0, r0, kw * c * r1, c * r1, r1),
    )
    np.copyto(dest, windows, casting="unsafe")
    return ho, wo


def _conv_fwd(x, w, b=None, stride=1, padding=0, need_dx=True):
    x = np.asarray(x)
    w = np.asarray(w)
    if x.ndim != 4:
        raise ValueError(f"x must be NHWC (ndim 4), got shape={x.shape}")
    if w.ndim != 4:
        raise ValueError(f"w must be HWIO (ndim 4), got shape={w.shape}")
    n, h, wd, c = x.shape
    kh, kw, ci, co = w.shape
    if ci != c:
        raise ValueError(f"w.shape={w.shape} expects {ci} input channels but x has {c}")
    if b is not None:
        b = np.asarray(b)
        if b.shape != (co,):
            raise ValueError(f"b must have shape ({co},), got shape={b.shape}")
    ho = conv2d_output_size(h, kh, stride, padding)
    wo = conv2d_output_size(wd, kw, stride, padding)
    if ho < 1 or wo < 1:
        raise ValueError(
            f"kernel {kh}x{kw} does not fit the padded input {h + 2 * padding}x"
            f"{wd + 2 * padding} (x.shape={x.shape}, padding={padding})"
        )
    dt = _conv_dtype(x, w, b)
    k = kh * kw * c
    rows = n * ho * wo
    col = _take_col(rows, k, b is not None, dt)
    _im2col(x, kh, kw, stride, padding, col, dt)
    if b is None:
        wmat = np.ascontiguousarray(w.reshape(k, co), dtype=dt)
    else:
        wmat = np.empty((k + 1, co), dtype=dt)
        wmat[:k] = w.reshape(k, co)
        wmat[k] = b
    out = np.empty((rows, co), dtype=dt)
    np.matmul(col, wmat, out=out)
    res = _ConvResiduals(x, w, None if b is None else b.dtype, stride, padding, col, wmat, dt,
                         (ho, wo), need_dx)
    return out.reshape(n, ho, wo, co), res


def _blocks(k: int, s: int) -> list[tuple[int, int]]:
    """Group kernel offsets ``0..k-1`` into blocks ``(first, count)`` of ``s`` offsets.

    Offsets ``q*s + r`` (``r < s``) of one block land on disjoint rows ``q*s + r + s*t``,
    so a block is written with one strided operation; a full block tiles a range.
    """
    return [(q * s, min(s, k - q * s)) for q in range((k + s - 1) // s)]


def _col2im(dcol: np.ndarray, x_shape, kh: int, kw: int, stride: int, padding: int,
            ho: int, wo: int, dtype: np.dtype) -> np.ndarray:
    """Sum the window gradients ``dcol`` back onto the input: the adjoint of im2col."""
    n, h, w, c = x_shape
    s = stride
    bh, bw = _blocks(kh, s), _blocks(kw, s)
    hb = max(h + 2 * padding, bh[-1][0] + s * ho)
    wb = max(w + 2 * padding, bw[-1][0] + s * wo)
    buf = np.empty((n, hb, wb, c), dtype=dtype)
    t0, t1, t2, t3 = buf.strides
    d0, d1 = dcol.strides
    d6 = as_strided(  # (N, Ho, Wo, kh, kw, C) view of dcol
        dcol,
        shape=(n, ho, wo, kh, kw, c),
        strides=(ho * wo * d0, wo * d0, d0, kw * c * d1, c * d1, d1),
        writeable=False,
    )
    first_full = bh[0][1] == s and bw[0][1] == s
    if first_full:
        # the first block covers [0, s*Ho) x [0, s*Wo) exactly; zero only the rest
        buf[:, s * ho:, :, :] = 0
        buf[:, : s * ho, s * wo:, :] = 0
    else:
        buf.fill(0)
    for ia, (a0, ra) in enumerate(bh):
        for ib, (b0, rb) in enumerate(bw):
            target = as_strided(  # (N, Ho, ra, Wo, rb, C) rows a0 + r + s*t
                buf[:, a0:, b0:, :],
                shape=(n, ho, ra, wo, rb, c),
                strides=(t0, s * t1, t1, s * t2, t2, t3),
            )
            src = d6[:, :, :, a0:a0 + ra, b0:b0 + rb, :].transpose(0, 1, 3, 2, 4, 5)
            if ia == 0 and ib == 0 and first_full:
                np.copyto(target, src)
            else:
                np.add(target, src, out=target)
    return buf[:, padding:padding + h, padding:padding + w, :]


def _conv_bwd(g, res: _ConvResiduals):
    x, w = res.x, res.w
    n, h, wd, c = x.shape
    kh, kw, _, co = w.shape
    ho, wo = res.out_hw
    dt = res.dtype
    k = kh * kw * c
    rows = n * ho * wo
    with_bias = res.b_dtype is not None
    col = res.col
    if col is None:  # backward called twice on the same residuals: rebuild the columns
        col = _take_col(rows, k, with_bias, dt)
        _im2col(x, kh, kw, res.stride, res.padding, col, dt)
    res.col = None
    gm = np.ascontiguousarray(np.reshape(g, (rows, co)), dtype=dt)
    dwmat = col.T @ gm  # (k [+1], co): the bias gradient is the last row
    _give_col(col, k, with_bias)
    dx = None  # not wanted when x is data (not traced): skips a GEMM and the col2im
    if res.need_dx:
        dcol = _lru_get(_dcol_cache, (rows, k, dt.str), lambda: np.empty((rows, k), dtype=dt))
        np.matmul(gm, res.wmat[:k].T, out=dcol)
        dx = _col2im(dcol, x.shape, kh, kw, res.stride, res.padding, ho, wo, dt)
        if dx.dtype != x.dtype and np.issubdtype(x.dtype, np.floating):
            dx = dx.astype(x.dtype)
    dw = dwmat[:k].reshape(kh, kw, c, co)
    if dw.dtype != w.dtype and np.issubdtype(w.dtype, np.floating):
        dw = dw.astype(w.dtype)
    if not with_bias:
        return dx, dw
    db = dwmat[k]
    if db.dtype != res.b_dtype and np.issubdtype(res.b_dtype, np.floating):
        db = db.astype(res.b_dtype)
    return dx, dw, db


def _conv_plain(x, w, b=None, stride=1, padding=0, need_dx=True):
    out, res = _conv_fwd(x, w, b, stride, padding)
    _give_col(res.col, res.wmat.shape[0] - (b is not None), b is not None)
    return out


@primitive
def _conv2d_b(x, w, b, stride=1, padding=0, need_dx=True):
    return _conv_plain(x, w, b, stride, padding)


@primitive
def _conv2d_nob(x, w, stride=1, padding=0, need_dx=True):
    return _conv_plain(x, w, None, stride, padding)


defvjp_fwd(
    _conv2d_b,
    lambda x, w, b, stride=1, padding=0, need_dx=True: _conv_fwd(x, w, b, stride, padding,
                                                                 need_dx),
    _conv_bwd,
)
defvjp_fwd(
    _conv2d_nob,
    lambda x, w, stride=1, padding=0, need_dx=True: _conv_fwd(x, w, None, stride, padding,
                                                              need_dx),
    _conv_bwd,
)


def conv2d(x, w, b=None, stride: int = 1, padding: int = 0):
    """2-D convolution (cross-correlation, as in deep learning), the ``ConvEncoder`` of eq. 7.

    Args:
        x: images ``(N, H, W, C)`` (NHWC).
        w: kernels ``(kh, kw, C, O)`` (HWIO).
        b: optional bias ``(O,)``.
        stride: step between windows, same along H and W (int ≥ 1).
        padding: zero pixels added on each side of H and W (int ≥ 0).

    Returns:
        ``(N, Ho, Wo, O)`` with ``Ho = (H + 2 padding - kh) // stride + 1`` (same for W):
        ``out[n, i, j, o] = b[o] + Σ_{p,q,c} xpad[n, s i + p, s j + q, c] w[p, q, c, o]``.
    """
    stride = check_int("stride", stride, 1)
    padding = check_int("padding", padding, 0)
    # an untraced x (the input images) needs no cotangent: the backward pass then
    # skips the dcol GEMM and the col2im, the most expensive part for 3-channel inputs
    kw = {"stride": int(stride), "padding": int(padding), "need_dx": isinstance(x, Box)}
    if b is None:
        return _conv2d_nob(x, w, **kw)
    return _conv2d_b(x, w, b, **kw)
