"""Chapter 2 — functional layers: initialisers and pure forward functions.

Parameters are plain dicts of NumPy arrays (pytrees), created from a
``numpy.random.Generator``; every forward function is pure and takes the
array namespace (``xp``) and/or the neural-net primitives (``nn``) of an
engine, so one model code runs on ``engine("numpy")`` and ``engine("jax")``::

    eng = minimanc.engine("numpy")
    p = layers.init_conv(rng, 3, 3, 3, 16)
    h = eng.nn.relu(layers.conv2d(p, images, eng.nn, stride=2, padding=1))
    feat = layers.global_avg_pool(h, eng.nn)           # eq. 7: conv -> GAP -> linear
    pred = layers.dense(layers.init_dense(rng, 16, 8), feat, xp=eng.xp)

Initialisation: He (Kaiming) normal for convolutions (followed by ReLU/SiLU),
Glorot (Xavier) uniform for dense and LSTM weights, zero biases, LSTM forget
gate bias 1 (Jozefowicz et al. 2015) so the cell remembers by default.
"""

from __future__ import annotations

from numbers import Integral
from typing import Any

import numpy as np

__all__ = [
    "init_dense",
    "init_conv",
    "init_lstm",
    "init_lstm_carry",
    "dense",
    "conv2d",
    "global_avg_pool",
    "lstm_cell",
    "flatten",
]


# ---------------------------------------------------------------------------
# Checks and defaults
# ---------------------------------------------------------------------------
def _check_rng(rng: Any) -> None:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got rng={rng!r}")


def _check_size(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, Integral) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {name}={value!r}")
    return int(value)


def _check_float_dtype(dtype: Any) -> np.dtype:
    dt = np.dtype(dtype)
    if not np.issubdtype(dt, np.floating):
        raise ValueError(f"dtype must be a floating-point type, got dtype={dtype!r}")
    return dt


def _is_jax_namespace(xp: Any) -> bool:
    return getattr(xp, "__name__", "").startswith("jax")


def _default_nn(nn: Any, xp: Any = np) -> Any:
    """``nn`` if given, else the primitives of the engine that ``xp`` belongs to."""
    if nn is not None:
        return nn
    from minimanc.engine import get_engine

    return get_engine("jax" if _is_jax_namespace(xp) else "numpy").nn


def _glorot_uniform(rng: np.random.Generator, fan_in: int, fan_out: int, shape,
                    dtype: np.dtype) -> np.ndarray:
    limit = np.sqrt(6.0 / (fan_in + fan_out))
    return rng.uniform(-limit, limit, size=shape).astype(dtype)


# ---------------------------------------------------------------------------
# Initialisers
# ---------------------------------------------------------------------------
def init_dense(rng: np.random.Generator, n_in: int, n_out: int,
               dtype: Any = np.float64) -> dict:
    """Dense layer ``{"w": (n_in, n_out), "b": (n_out,)}``, Glorot-uniform weights.

    Glorot: ``w ~ U(-a, a)`` with ``a = sqrt(6 / (n_in + n_out))`` keeps the
    variance of activations and of gradients roughly constant across layers.
    """
    _check_rng(rng)
    n_in, n_out = _check_size("n_in", n_in), _check_size("n_out", n_out)
    dt = _check_float_dtype(dtype)
    return {
        "w": _glorot_uniform(rng, n_in, n_out, (n_in, n_out), dt),
        "b": np.zeros(n_out, dtype=dt),
    }


def init_conv(rng: np.random.Generator, kh: int, kw: int, c_in: int, c_out: int,
              dtype: Any = np.float64) -> dict:
    """Convolution ``{"w": (kh, kw, c_in, c_out) HWIO, "b": (c_out,)}``, He-normal weights.

    He: ``w ~ N(0, 2 / fan_in)`` with ``fan_in = kh kw c_in``, the variance that
    keeps ReLU activations from shrinking or growing with depth.
    """
    _check_rng(rng)
    kh, kw = _check_size("kh", kh), _check_size("kw", kw)
    c_in, c_out = _check_size("c_in", c_in), _check_size("c_out", c_out)
    dt = _check_float_dtype(dtype)
    std = np.sqrt(2.0 / (kh * kw * c_in))
    return {
        "w": (std * rng.standard_normal((kh, kw, c_in, c_out))).astype(dt),
        "b": np.zeros(c_out, dtype=dt),
    }


def init_lstm(rng: np.random.Generator, n_in: int, n_hidden: int,
              dtype: Any = np.float64) -> dict:
    """LSTM cell ``{"wx": (n_in, 4H), "wh": (H, 4H), "b": (4H,)}``; gate order i, f, g, o.

    Glorot-uniform input and recurrent weights (fans of one gate), zero biases
    except the forget gate's, which starts at 1.
    """
    _check_rng(rng)
    n_in, n_hidden = _check_size("n_in", n_in), _check_size("n_hidden", n_hidden)
    dt = _check_float_dtype(dtype)
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
    """Zero initial carry ``(h, c)``, each ``(batch, n_hidden)``."""
    batch, n_hidden = _check_size("batch", batch), _check_size("n_hidden", n_hidden)
    dt = _check_float_dtype(dtype)
    return xp.zeros((batch, n_hidden), dtype=dt), xp.zeros((batch, n_hidden), dtype=dt)


# ---------------------------------------------------------------------------
# Forward functions
# ---------------------------------------------------------------------------
def dense(params: dict, x: Any, xp: Any = np) -> Any:
    """Affine map ``x @ w + b`` over the last axis (the ``Linear`` of eq. 7)."""
    return xp.matmul(x, params["w"]) + params["b"]


def conv2d(params: dict, x: Any, nn: Any = None, stride: int = 1, padding: int = 0) -> Any:
    """Convolution layer (``ConvEncoder`` of eq. 7): ``nn.conv2d(x, w, b, stride, padding)``.

    ``x`` is NHWC; the output has ``(H + 2 padding - kh) // stride + 1`` rows
    (same for columns) and ``c_out`` channels. ``nn`` defaults to the NumPy
    engine's primitives.
    """
    nn = _default_nn(nn)
    return nn.conv2d(x, params["w"], params["b"], stride=stride, padding=padding)


def global_avg_pool(x: Any, nn: Any = None) -> Any:
    """Global average pooling ``(N, H, W, C) -> (N, C)`` (eq. 7)."""
    return _default_nn(nn).global_avg_pool(x)


def flatten(x: Any, xp: Any = np) -> Any:
    """``(N, ...) -> (N, prod(...))``: keep the batch axis, flatten the rest."""
    if len(x.shape) < 1:
        raise ValueError(f"x must have a batch axis, got x.shape={tuple(x.shape)}")
    return xp.reshape(x, (x.shape[0], -1))


def lstm_cell(params: dict, carry: tuple[Any, Any], x: Any, xp: Any = np,
              nn: Any = None) -> tuple[Any, Any]:
    """One LSTM step (Hochreiter & Schmidhuber 1997): returns the new carry ``(h, c)``.

    ``z = x wx + h wh + b`` split into gates ``i, f, g, o`` (each ``H`` wide)::

        c' = sigmoid(f) * c + sigmoid(i) * tanh(g)
        h' = sigmoid(o) * tanh(c')

    The vAGN state ``q`` of eq. 9 plays the role of this hidden state in MANC;
    the CNN-LSTM and RvS-G baselines use this cell.
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
