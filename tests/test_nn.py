"""Tests for minimanc.autodiff.nn: every primitive against central differences and JAX."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc.autodiff import check_grads, grad, nn
from minimanc.autodiff import numpy as anp
from minimanc.engine import get_engine

get_engine("jax")  # enables float64 in JAX

SETTINGS = settings(max_examples=25, deadline=None)
ACTIVATIONS = {"relu": jax.nn.relu, "sigmoid": jax.nn.sigmoid, "silu": jax.nn.silu}


def _arr(seed: int, shape, scale: float = 1.0) -> np.ndarray:
    return scale * np.random.default_rng(seed).standard_normal(shape)


def _weights(seed: int, shape) -> np.ndarray:
    """Fixed random weights so that a scalar loss mixes every output element."""
    return np.random.default_rng(seed + 1000).standard_normal(shape)


shapes = st.lists(st.integers(1, 4), min_size=1, max_size=3).map(tuple)
# the JAX oracles are jitted and compiled once per shape: draw those from a few shapes
jax_shapes = st.sampled_from([(5,), (3, 4), (2, 3, 4)])


def _jax_value_and_grad(ref, **kw):
    """jit(x, wts -> (ref(x), d/dx Σ ref(x) wts)), compiled once per shape."""
    def value_and_grad(v, wts):
        return ref(v, **kw), jax.grad(lambda u: jnp.sum(ref(u, **kw) * wts))(v)

    return jax.jit(value_and_grad)


_JAX_ACT = {name: _jax_value_and_grad(f) for name, f in ACTIVATIONS.items()}
_JAX_SOFT = {(name, axis): _jax_value_and_grad(getattr(jax.nn, name), axis=axis)
             for name in ("softmax", "log_softmax") for axis in range(-3, 3)}


# ---------------------------------------------------------------------------- activations
@pytest.mark.parametrize("name", sorted(ACTIVATIONS))
@SETTINGS
@given(shape=jax_shapes, seed=st.integers(0, 10_000), scale=st.sampled_from([0.5, 3.0, 30.0]))
def test_activation_value_and_grad_match_jax(name, shape, seed, scale):
    x = _arr(seed, shape, scale)
    wts = _weights(seed, shape)
    ours = getattr(nn, name)
    yj, gj = _JAX_ACT[name](x, wts)
    np.testing.assert_allclose(ours(x), np.asarray(yj), rtol=1e-12, atol=1e-14)
    g = grad(lambda v: anp.sum(ours(v) * wts))(x)
    np.testing.assert_allclose(g, np.asarray(gj), rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("name", sorted(ACTIVATIONS))
@settings(max_examples=10, deadline=None)
@given(shape=shapes, seed=st.integers(0, 10_000))
def test_activation_grad_matches_central_differences(name, shape, seed):
    x = _arr(seed, shape, 2.0)
    wts = _weights(seed, shape)
    f = getattr(nn, name)
    check_grads(lambda v: anp.sum(f(v) * wts), x, verbose=False)


def test_sigmoid_is_stable_and_relu_gradient_at_zero():
    x = np.array([-1000.0, -40.0, 0.0, 40.0, 1000.0])
    s = nn.sigmoid(x)
    assert np.all(np.isfinite(s)) and s[0] == 0.0 and s[-1] == 1.0 and s[2] == 0.5
    assert np.all(np.isfinite(nn.silu(x)))
    assert grad(lambda v: anp.sum(nn.relu(v)))(np.zeros(3)).tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("name", ["relu", "sigmoid", "silu"])
def test_activations_keep_float32(name):
    x = _arr(0, (3, 4)).astype(np.float32)
    f = getattr(nn, name)
    assert f(x).dtype == np.float32
    assert grad(lambda v: anp.sum(f(v)))(x).dtype == np.float32


# ---------------------------------------------------------------------------- softmax family
@pytest.mark.parametrize("name", ["softmax", "log_softmax"])
@SETTINGS
@given(shape=jax_shapes, seed=st.integers(0, 10_000), data=st.data())
def test_softmax_family_matches_jax(name, shape, seed, data):
    axis = data.draw(st.integers(-len(shape), len(shape) - 1), label="axis")
    x = _arr(seed, shape, 5.0)
    wts = _weights(seed, shape)
    ours = getattr(nn, name)
    yj, gj = _JAX_SOFT[(name, axis)](x, wts)
    np.testing.assert_allclose(ours(x, axis=axis), np.asarray(yj), rtol=1e-12, atol=1e-13)
    g = grad(lambda v: anp.sum(ours(v, axis=axis) * wts))(x)
    np.testing.assert_allclose(g, np.asarray(gj), rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("name", ["softmax", "log_softmax"])
@settings(max_examples=15, deadline=None)
@given(shape=shapes, seed=st.integers(0, 10_000), data=st.data())
def test_softmax_family_grad_matches_central_differences(name, shape, seed, data):
    axis = data.draw(st.integers(-len(shape), len(shape) - 1), label="axis")
    x = _arr(seed, shape, 5.0)
    wts = _weights(seed, shape)
    ours = getattr(nn, name)
    check_grads(lambda v: anp.sum(ours(v, axis=axis) * wts), x, verbose=False)


def test_softmax_does_not_overflow_and_sums_to_one():
    x = np.array([[1000.0, 0.0, -1000.0], [3.0, 3.0, 3.0]])
    s = nn.softmax(x, axis=-1)
    np.testing.assert_allclose(s.sum(axis=-1), 1.0)
    np.testing.assert_allclose(s[1], 1 / 3)
    assert np.all(np.isfinite(nn.log_softmax(x, axis=-1)))
    np.testing.assert_allclose(nn.softmax(x, axis=0).sum(axis=0), 1.0)  # eq. 9 column softmax


@pytest.mark.parametrize("axis", [2, -3, 1.0, "0"])
def test_softmax_bad_axis(axis):
    with pytest.raises(ValueError, match="axis"):
        nn.softmax(np.ones((2, 2)), axis=axis)
    with pytest.raises(ValueError, match="axis"):
        nn.log_softmax(np.ones((2, 2)), axis=axis)


# ---------------------------------------------------------------------------- global average pool
@SETTINGS
@given(n=st.integers(1, 3), h=st.integers(1, 5), w=st.integers(1, 5), c=st.integers(1, 4),
       seed=st.integers(0, 10_000))
def test_global_avg_pool_matches_mean_and_central_differences(n, h, w, c, seed):
    x = _arr(seed, (n, h, w, c))
    wts = _weights(seed, (n, c))
    np.testing.assert_allclose(nn.global_avg_pool(x), x.mean(axis=(1, 2)), rtol=1e-13)
    g = grad(lambda v: anp.sum(nn.global_avg_pool(v) * wts))(x)
    np.testing.assert_allclose(g, np.broadcast_to(wts[:, None, None, :] / (h * w), x.shape),
                               rtol=1e-13)
    check_grads(lambda v: anp.sum(nn.global_avg_pool(v) * wts), x, verbose=False)


@pytest.mark.parametrize("shape", [(2, 4, 3, 5), (1, 1, 1, 1), (3, 7, 2, 2)])
def test_global_avg_pool_grad_matches_jax(shape):
    x = _arr(7, shape)
    wts = _weights(7, (shape[0], shape[3]))
    g = grad(lambda v: anp.sum(nn.global_avg_pool(v) * wts))(x)
    gj = jax.grad(lambda v: jnp.sum(jnp.mean(v, axis=(1, 2)) * wts))(x)
    np.testing.assert_allclose(g, np.asarray(gj), rtol=1e-12)


def test_global_avg_pool_float32_and_bad_input():
    x = _arr(1, (2, 3, 3, 2)).astype(np.float32)
    assert nn.global_avg_pool(x).dtype == np.float32
    assert grad(lambda v: anp.sum(nn.global_avg_pool(v)))(x).dtype == np.float32
    with pytest.raises(ValueError, match="shape"):
        nn.global_avg_pool(np.ones((2, 3, 3)))


# ---------------------------------------------------------------------------- conv2d
def _lax_conv(x, w, b, stride, padding):
    y = jax.lax.conv_general_dilated(
        x, w, (stride, stride), [(padding, padding), (padding, padding)],
        dimension_numbers=("NHWC", "HWIO", "NHWC"),
    )
    return y if b is None else y + b


def _slice_conv(x, w, b, stride, padding):
    """Convolution as a sum over kernel offsets of shifted strided slices (a JAX oracle
    whose gradient does not go through XLA's convolution)."""
    xp_ = jnp.pad(x, ((0, 0), (padding, padding), (padding, padding), (0, 0)))
    kh, kw = w.shape[:2]
    ho = (xp_.shape[1] - kh) // stride + 1
    wo = (xp_.shape[2] - kw) // stride + 1
    y = 0.0
    for i in range(kh):
        for j in range(kw):
            win = xp_[:, i:i + stride * (ho - 1) + 1:stride, j:j + stride * (wo - 1) + 1:stride]
            y = y + win @ w[i, j]
    return y if b is None else y + b


@st.composite
def conv_cases(draw, max_hw: int = 8):
    kh, kw = draw(st.integers(1, 4)), draw(st.integers(1, 4))
    stride, padding = draw(st.integers(1, 3)), draw(st.integers(0, 2))
    h = draw(st.integers(max(1, kh - 2 * padding), max_hw))
    w = draw(st.integers(max(1, kw - 2 * padding), max_hw))
    n, c, o = draw(st.integers(1, 3)), draw(st.integers(1, 3)), draw(st.integers(1, 3))
    bias = draw(st.booleans())
    seed = draw(st.integers(0, 10_000))
    return n, h, w, c, o, kh, kw, stride, padding, bias, seed


def _conv_arrays(case, dtype=np.float64):
    n, h, w, c, o, kh, kw, stride, padding, bias, seed = case
    x = _arr(seed, (n, h, w, c)).astype(dtype)
    k = _arr(seed + 1, (kh, kw, c, o)).astype(dtype)
    b = _arr(seed + 2, (o,)).astype(dtype) if bias else None
    return x, k, b, stride, padding


@SETTINGS
@given(case=conv_cases())
def test_conv2d_forward_matches_lax_conv(case):
    x, k, b, s, p = _conv_arrays(case)
    y = nn.conv2d(x, k, b, stride=s, padding=p)
    n, h, w = x.shape[:3]
    assert y.shape == (n, (h + 2 * p - k.shape[0]) // s + 1, (w + 2 * p - k.shape[1]) // s + 1,
                       k.shape[3])
    np.testing.assert_allclose(y, np.asarray(_lax_conv(x, k, b, s, p)), rtol=1e-12, atol=1e-12)


def _loop_conv_vjp(x, k, b, s, p, gy):
    """Adjoint of the convolution by explicit loops over kernel offsets (NumPy oracle)."""
    xpad = np.pad(x, ((0, 0), (p, p), (p, p), (0, 0)))
    dxp, dk = np.zeros_like(xpad), np.zeros_like(k)
    ho, wo = gy.shape[1:3]
    for i in range(k.shape[0]):
        for j in range(k.shape[1]):
            rows = slice(i, i + s * (ho - 1) + 1, s)
            cols = slice(j, j + s * (wo - 1) + 1, s)
            dk[i, j] = np.einsum("nhwc,nhwo->co", xpad[:, rows, cols, :], gy)
            dxp[:, rows, cols, :] += gy @ k[i, j].T
    dx = dxp[:, p:p + x.shape[1], p:p + x.shape[2], :]
    return (dx, dk) if b is None else (dx, dk, gy.sum(axis=(0, 1, 2)))


def _ours_conv_grads(x, k, b, s, p, wts):
    if b is None:
        return grad(lambda x, k: anp.sum(nn.conv2d(x, k, stride=s, padding=p) * wts),
                    argnums=(0, 1))(x, k)
    return grad(lambda x, k, b: anp.sum(nn.conv2d(x, k, b, s, p) * wts),
                argnums=(0, 1, 2))(x, k, b)


@settings(max_examples=50, deadline=None)
@given(case=conv_cases())
def test_conv2d_grads_match_loop_adjoint(case):
    x, k, b, s, p = _conv_arrays(case)
    wts = _weights(case[-1], nn.conv2d(x, k, b, stride=s, padding=p).shape)
    for a, r in zip(_ours_conv_grads(x, k, b, s, p, wts), _loop_conv_vjp(x, k, b, s, p, wts)):
        np.testing.assert_allclose(a, r, rtol=1e-10, atol=1e-12)


@settings(max_examples=8, deadline=None)
@given(case=conv_cases(max_hw=7))
def test_conv2d_grads_match_jax(case):
    x, k, b, s, p = _conv_arrays(case)
    wts = _weights(case[-1], nn.conv2d(x, k, b, stride=s, padding=p).shape)
    bias = b if b is not None else np.zeros(k.shape[3])
    ref = jax.jit(jax.grad(lambda x, k, b: jnp.sum(_slice_conv(x, k, b, s, p) * wts),
                           argnums=(0, 1, 2)))(x, k, bias)
    for a, r in zip(_ours_conv_grads(x, k, b, s, p, wts), ref):
        np.testing.assert_allclose(a, np.asarray(r), rtol=1e-6, atol=1e-9)


def test_conv2d_same_padded_shape_other_padding_regression():
    """The hypothesis case (3, 3, 4, 1, 1, 1, 1, 1, 2, False, 0) failed once: an earlier
    conv whose padded input had the same shape (here 3x5x6 with padding 1, also 7x8)
    left its pixels in the padding ring of the shared buffer, so the first call of the
    case gave a kernel gradient of -0.2265 instead of JAX's -4.1137."""
    case = (3, 3, 4, 1, 1, 1, 1, 1, 2, False, 0)
    x, k, b, s, p = _conv_arrays(case)
    wts = _weights(case[-1], nn.conv2d(x, k, b, stride=s, padding=p).shape)
    expected = _loop_conv_vjp(x, k, b, s, p, wts)
    np.testing.assert_allclose(expected[1].ravel(), [-4.11369689], rtol=1e-8)
    rng = np.random.default_rng(1)
    for trial in range(3):
        # same padded shape (3, 7, 8, 1), other padding: must not leak into this call
        nn.conv2d(rng.standard_normal((3, 5, 6, 1)), k, stride=1, padding=1)
        for a, r in zip(_ours_conv_grads(x, k, b, s, p, wts), expected):
            np.testing.assert_allclose(a, r, rtol=1e-10, atol=1e-12, err_msg=f"call {trial}")


@pytest.mark.parametrize("kh,kw,stride,padding", [(3, 3, 1, 1), (3, 3, 2, 1), (5, 5, 2, 2),
                                                  (1, 1, 1, 0)])
def test_conv2d_grads_match_jax_lax_conv(kh, kw, stride, padding):
    rng = np.random.default_rng(kh * 100 + stride * 10 + padding)
    x = rng.standard_normal((2, 9, 8, 3))
    k = rng.standard_normal((kh, kw, 3, 4))
    b = rng.standard_normal(4)
    wts = rng.standard_normal(nn.conv2d(x, k, b, stride, padding).shape)
    ours = grad(lambda x, k, b: anp.sum(nn.conv2d(x, k, b, stride, padding) * wts),
                argnums=(0, 1, 2))(x, k, b)
    ref = jax.grad(lambda x, k, b: jnp.sum(_lax_conv(x, k, b, stride, padding) * wts),
                   argnums=(0, 1, 2))(x, k, b)
    for a, r in zip(ours, ref):
        np.testing.assert_allclose(a, np.asarray(r), rtol=1e-9, atol=1e-10)


@settings(max_examples=8, deadline=None)
@given(case=conv_cases(max_hw=5))
def test_conv2d_grads_match_central_differences(case):
    x, k, b, s, p = _conv_arrays(case)
    wts = _weights(case[-1], nn.conv2d(x, k, b, stride=s, padding=p).shape)
    if b is None:
        check_grads(lambda x, k: anp.sum(nn.conv2d(x, k, stride=s, padding=p) * wts), x, k,
                    verbose=False)
    else:
        check_grads(lambda x, k, b: anp.sum(nn.conv2d(x, k, b, s, p) * wts), x, k, b,
                    verbose=False)


def test_conv2d_weight_grad_when_input_is_data():
    """An untraced input skips its cotangent; the weight and bias gradients are unchanged."""
    rng = np.random.default_rng(3)
    x = rng.standard_normal((2, 8, 8, 3))
    k = rng.standard_normal((3, 3, 3, 5))
    b = rng.standard_normal(5)
    wts = rng.standard_normal((2, 4, 4, 5))
    gk, gb = grad(lambda k, b: anp.sum(nn.conv2d(x, k, b, 2, 1) * wts), argnums=(0, 1))(k, b)
    rk, rb = jax.grad(lambda k, b: jnp.sum(_lax_conv(x, k, b, 2, 1) * wts), argnums=(0, 1))(k, b)
    np.testing.assert_allclose(gk, np.asarray(rk), rtol=1e-10)
    np.testing.assert_allclose(gb, np.asarray(rb), rtol=1e-10)


def test_conv2d_float32_stays_float32_and_agrees_with_float64():
    rng = np.random.default_rng(4)
    x = rng.standard_normal((3, 10, 10, 4))
    k = rng.standard_normal((3, 3, 4, 6)) * 0.3
    b = rng.standard_normal(6)
    wts = rng.standard_normal((3, 5, 5, 6))

    def f(x, k, b):
        return anp.sum(nn.relu(nn.conv2d(x, k, b, stride=2, padding=1)) * wts)

    g64 = grad(f, argnums=(0, 1, 2))(x, k, b)
    args32 = [a.astype(np.float32) for a in (x, k, b)]
    assert nn.conv2d(*args32, stride=2, padding=1).dtype == np.float32
    g32 = grad(f, argnums=(0, 1, 2))(*args32)
    for a32, a64 in zip(g32, g64):
        assert a32.dtype == np.float32
        np.testing.assert_allclose(a32, a64, rtol=1e-4, atol=1e-4)


def test_conv2d_buffers_are_not_shared_between_live_calls():
    """Same-shape convolutions reuse pooled buffers: a chain of them, a plain call in the
    middle of a traced one, and a second gradient evaluation must all stay correct."""
    rng = np.random.default_rng(5)
    x = rng.standard_normal((2, 6, 6, 4))
    ks = [rng.standard_normal((3, 3, 4, 4)) * 0.4 for _ in range(3)]
    other = rng.standard_normal((2, 6, 6, 4))

    def ours(x, k0, k1, k2):
        h = x
        for k in (k0, k1, k2):
            h = nn.silu(nn.conv2d(h, k, stride=1, padding=1))
            nn.conv2d(other, k2, stride=1, padding=1)  # untraced, same shapes
        return anp.sum(h * h)

    def ref(x, k0, k1, k2):
        h = x
        for k in (k0, k1, k2):
            h = jax.nn.silu(_lax_conv(h, k, None, 1, 1))
        return jnp.sum(h * h)

    expected = jax.grad(ref, argnums=(0, 1, 2, 3))(x, *ks)
    for _ in range(2):
        got = grad(ours, argnums=(0, 1, 2, 3))(x, *ks)
        for a, r in zip(got, expected):
            np.testing.assert_allclose(a, np.asarray(r), rtol=1e-9, atol=1e-10)
    nn.clear_buffers()
    got = grad(ours, argnums=(0, 1, 2, 3))(x, *ks)
    np.testing.assert_allclose(got[0], np.asarray(expected[0]), rtol=1e-9, atol=1e-10)


def test_conv2d_output_size():
    assert nn.conv2d_output_size(64, 3, 2, 1) == 32
    assert nn.conv2d_output_size(5, 3, 1, 0) == 3
    assert nn.conv2d_output_size(7, 2, 3, 0) == 2


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"stride": 0}, "stride"),
        ({"stride": 1.5}, "stride"),
        ({"stride": True}, "stride"),
        ({"padding": -1}, "padding"),
        ({"padding": 0.5}, "padding"),
        ({"w": np.ones((3, 3, 2, 4))}, "channels"),
        ({"w": np.ones((3, 3, 3))}, "HWIO"),
        ({"x": np.ones((5, 5, 3))}, "NHWC"),
        ({"b": np.ones(3)}, "b must have shape"),
        ({"w": np.ones((7, 7, 3, 4))}, "does not fit"),
    ],
)
def test_conv2d_bad_input(kwargs, match):
    args = {"x": np.ones((1, 5, 5, 3)), "w": np.ones((3, 3, 3, 4)), "b": None, "stride": 1,
            "padding": 0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        nn.conv2d(args["x"], args["w"], args["b"], stride=args["stride"],
                  padding=args["padding"])
