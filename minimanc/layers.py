"""Chapter 2 — functional layers: initialisers and pure forward functions.

Parameters are plain dicts of NumPy arrays (pytrees), created from a
``numpy.random.Generator``; every forward function is pure and takes the
array namespace (``xp``) and/or the neural-net primitives (``nn``) of an
engine, so one model code runs on ``engine("numpy")`` and ``engine("jax")``::

    eng = minimanc.engine("numpy")
    p = layers.init_conv(rng, 3, 3, 3, 16)
    h = eng.nn.relu(layers.conv(p, images, eng.nn, stride=2, padding=1))
    feat = eng.nn.global_avg_pool(h)                # eq. 7: conv -> GAP -> linear
    pred = layers.dense(layers.init_dense(rng, 16, 8), feat, xp=eng.xp)

Initialisation: He (Kaiming) normal for convolutions (followed by ReLU/SiLU),
Glorot (Xavier) uniform for dense and LSTM weights, zero biases, LSTM forget
gate bias 1 (Jozefowicz et al. 2015) so the cell remembers by default.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.checks import check_float_dtype, check_int, check_rng
from minimanc.engine import engine_of, get_engine

__all__ = [
    "init_dense",
    "init_conv",
    "init_lstm",
    "init_lstm_carry",
    "dense",
    "conv",
    "lstm_cell",
    "flatten",
]


# ---------------------------------------------------------------------------
# Defaults
# ---------------------------------------------------------------------------
def _default_nn(nn: Any, xp: Any = np) -> Any:
    """``nn`` if given, else the primitives of the engine that ``xp`` belongs to.

    A namespace of no engine (plain ``numpy`` included) gets the NumPy engine's.
    """
    if nn is not None:
        return nn
    return (engine_of(xp) or get_engine("numpy")).nn


def _glorot_uniform(rng: np.random.Generator, fan_in: int, fan_out: int, shape,
                    dtype: np.dtype) -> np.ndarray:
    limit = np.sqrt(6.0 / (fan_in + fan_out))
    return rng.uniform(-limit, limit, size=shape).astype(dtype)


# ---------------------------------------------------------------------------
# Initialisers
# ---------------------------------------------------------------------------
def init_dense(rng: np.random.Generator, n_in: int, n_out: int,
               dtype: Any = np.float64) -> dict:
    """Dense layer with Glorot-uniform weights and zero bias.

    Glorot: ``w ~ U(-a, a)`` with ``a = sqrt(6 / (n_in + n_out))`` keeps the
    variance of activations and of gradients roughly constant across layers.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    n_in : int
        Input features, ≥ 1.
    n_out : int
        Output features, ≥ 1.
    dtype : NumPy float dtype, optional (default: float64)
        Precision of the parameters.

    Returns
    -------
    params : dict
        ``{"w": (n_in, n_out), "b": (n_out,)}``.

    Raises
    ------
    ValueError
        If ``rng`` is not a ``numpy.random.Generator``, a size is not an integer
        ≥ 1, or ``dtype`` is not a float type.
    """
    check_rng("rng", rng)
    n_in, n_out = check_int("n_in", n_in, 1), check_int("n_out", n_out, 1)
    dt = check_float_dtype("dtype", dtype)
    return {
        "w": _glorot_uniform(rng, n_in, n_out, (n_in, n_out), dt),
        "b": np.zeros(n_out, dtype=dt),
    }


def init_conv(rng: np.random.Generator, kh: int, kw: int, c_in: int, c_out: int,
              dtype: Any = np.float64) -> dict:
    """Convolution layer (HWIO kernel) with He-normal weights and zero bias.

    He: ``w ~ N(0, 2 / fan_in)`` with ``fan_in = kh kw c_in``, the variance that
    keeps ReLU activations from shrinking or growing with depth.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    kh : int
        Kernel height, ≥ 1.
    kw : int
        Kernel width, ≥ 1.
    c_in : int
        Input channels, ≥ 1.
    c_out : int
        Output channels, ≥ 1.
    dtype : NumPy float dtype, optional (default: float64)
        Precision of the parameters.

    Returns
    -------
    params : dict
        ``{"w": (kh, kw, c_in, c_out), "b": (c_out,)}``.

    Raises
    ------
    ValueError
        If ``rng`` is not a ``numpy.random.Generator``, a size is not an integer
        ≥ 1, or ``dtype`` is not a float type.
    """
    check_rng("rng", rng)
    kh, kw = check_int("kh", kh, 1), check_int("kw", kw, 1)
    c_in, c_out = check_int("c_in", c_in, 1), check_int("c_out", c_out, 1)
    dt = check_float_dtype("dtype", dtype)
    std = np.sqrt(2.0 / (kh * kw * c_in))
    return {
        "w": (std * rng.standard_normal((kh, kw, c_in, c_out))).astype(dt),
        "b": np.zeros(c_out, dtype=dt),
    }


def init_lstm(rng: np.random.Generator, n_in: int, n_hidden: int,
              dtype: Any = np.float64) -> dict:
    """LSTM cell parameters; gate order i, f, g, o along the last axis.

    Glorot-uniform input and recurrent weights (fans of one gate), zero biases
    except the forget gate's, which starts at 1 (Jozefowicz et al. 2015).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    n_in : int
        Input features, ≥ 1.
    n_hidden : int
        Hidden size ``H``, ≥ 1.
    dtype : NumPy float dtype, optional (default: float64)
        Precision of the parameters.

    Returns
    -------
    params : dict
        ``{"wx": (n_in, 4H), "wh": (H, 4H), "b": (4H,)}``.

    Raises
    ------
    ValueError
        If ``rng`` is not a ``numpy.random.Generator``, a size is not an integer
        ≥ 1, or ``dtype`` is not a float type.
    """
    check_rng("rng", rng)
    n_in, n_hidden = check_int("n_in", n_in, 1), check_int("n_hidden", n_hidden, 1)
    dt = check_float_dtype("dtype", dtype)
    h = n_hidden
    b = np.zeros(4 * h, dtype=dt)
    b[h:2 * h] = 1
    return {
        "wx": _glorot_uniform(rng, n_in, h, (n_in, 4 * h), dt),
        "wh": _glorot_uniform(rng, h, h, (h, 4 * h), dt),
        "b": b,
    }


def init_lstm_carry(batch: int, n_hidden: int, dtype: Any = np.float64,
                    xp: Any = np) -> tuple[Any, Any]:
    """Zero initial carry ``(h, c)`` of :func:`lstm_cell`.

    Parameters
    ----------
    batch : int
        Batch size ``B``, ≥ 1.
    n_hidden : int
        Hidden size ``H``, ≥ 1.
    dtype : NumPy float dtype, optional (default: float64)
        Precision of the carry.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    h : array, shape (B, H)
        Zero hidden state.
    c : array, shape (B, H)
        Zero cell state.

    Raises
    ------
    ValueError
        If a size is not an integer ≥ 1 or ``dtype`` is not a float type.
    """
    batch, n_hidden = check_int("batch", batch, 1), check_int("n_hidden", n_hidden, 1)
    dt = check_float_dtype("dtype", dtype)
    return xp.zeros((batch, n_hidden), dtype=dt), xp.zeros((batch, n_hidden), dtype=dt)


# ---------------------------------------------------------------------------
# Forward functions
# ---------------------------------------------------------------------------
def dense(params: dict, x: Any, xp: Any = np) -> Any:
    """Affine map ``x @ w + b`` over the last axis (the ``Linear`` of eq. 7).

    Parameters
    ----------
    params : dict
        ``{"w": (n_in, n_out), "b": (n_out,)}`` from :func:`init_dense`.
    x : array-like, shape (..., n_in)
        Inputs.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    y : array, shape (..., n_out)
        Outputs.
    """
    return xp.matmul(x, params["w"]) + params["b"]


def conv(params: dict, x: Any, nn: Any = None, stride: int = 1, padding: int = 0) -> Any:
    """Convolution layer (``ConvEncoder`` of eq. 7): ``nn.conv2d(x, w, b, stride, padding)``.

    Parameters
    ----------
    params : dict
        ``{"w": (kh, kw, c_in, c_out), "b": (c_out,)}`` from :func:`init_conv`.
    x : array-like, shape (N, H, W, c_in)
        NHWC inputs.
    nn : namespace, optional (default: None)
        An engine's neural-net primitives (``eng.nn``); None is the NumPy
        engine's.
    stride : int, optional (default: 1)
        Step of the kernel in both directions.
    padding : int, optional (default: 0)
        Rows and columns of zeros added on each side.

    Returns
    -------
    y : array, shape (N, H', W', c_out)
        ``H' = (H + 2 padding − kh) // stride + 1``, likewise ``W'``.
    """
    nn = _default_nn(nn)
    return nn.conv2d(x, params["w"], params["b"], stride=stride, padding=padding)


def flatten(x: Any, xp: Any = np) -> Any:
    """Keep the batch axis, flatten the rest: ``(N, ...) → (N, prod(...))``.

    Parameters
    ----------
    x : array-like, shape (N, ...)
        Inputs with a batch axis.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    y : array, shape (N, prod(...))
        Flattened inputs.

    Raises
    ------
    ValueError
        If ``x`` is a scalar (no batch axis).
    """
    if len(x.shape) < 1:
        raise ValueError(f"x must have a batch axis, got x.shape={tuple(x.shape)}")
    return xp.reshape(x, (x.shape[0], -1))


def lstm_cell(params: dict, carry: tuple[Any, Any], x: Any, xp: Any = np,
              nn: Any = None) -> tuple[Any, Any]:
    """One LSTM step (Hochreiter & Schmidhuber 1997).

    ``z = x wx + h wh + b`` split into gates ``i, f, g, o`` (each ``H`` wide)::

        c' = sigmoid(f) * c + sigmoid(i) * tanh(g)
        h' = sigmoid(o) * tanh(c')

    The vAGN state ``q`` of eq. 9 plays the role of this hidden state in MANC;
    the CNN-LSTM and RvS-G baselines use this cell.

    Parameters
    ----------
    params : dict
        ``{"wx": (n_in, 4H), "wh": (H, 4H), "b": (4H,)}`` from :func:`init_lstm`.
    carry : tuple of two arrays, each of shape (B, H)
        Previous ``(h, c)``, e.g. from :func:`init_lstm_carry`.
    x : array-like, shape (B, n_in)
        Inputs of this step.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.
    nn : namespace, optional (default: None)
        An engine's neural-net primitives; None is the engine of ``xp``.

    Returns
    -------
    h : array, shape (B, H)
        New hidden state ``h'``.
    c : array, shape (B, H)
        New cell state ``c'``.

    Raises
    ------
    ValueError
        If ``carry`` is not a pair ``(h, c)``.
    """
    if not isinstance(carry, tuple | list) or len(carry) != 2:
        raise ValueError(f"carry must be a pair (h, c), got carry of type {type(carry).__name__}")
    h, c = carry
    nn = _default_nn(nn, xp)
    n = params["wh"].shape[0]
    z = xp.matmul(x, params["wx"]) + xp.matmul(h, params["wh"]) + params["b"]
    i = nn.sigmoid(z[..., 0:n])
    f = nn.sigmoid(z[..., n:2 * n])
    g = xp.tanh(z[..., 2 * n:3 * n])
    o = nn.sigmoid(z[..., 3 * n:4 * n])
    c_new = f * c + i * g
    h_new = o * xp.tanh(c_new)
    return h_new, c_new
