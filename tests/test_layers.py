"""Tests for minimanc.layers: initialisers, forward functions, and one model code on two engines."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import layers
from minimanc.engine import get_engine
from minimanc.tree import tree_flatten

NP = get_engine("numpy")
JX = get_engine("jax")


def _max_leaf_diff(a, b) -> float:
    la, pa, _ = tree_flatten(a)
    lb, pb, _ = tree_flatten(b)
    assert pa == pb
    return max(float(np.max(np.abs(np.asarray(x) - np.asarray(y)))) for x, y in zip(la, lb))


# ---------------------------------------------------------------------------- initialisers
def test_init_shapes_dtypes_and_determinism():
    d = layers.init_dense(np.random.default_rng(0), 5, 3)
    c = layers.init_conv(np.random.default_rng(0), 3, 2, 4, 6, dtype=np.float32)
    lstm = layers.init_lstm(np.random.default_rng(0), 7, 4)
    assert d["w"].shape == (5, 3) and d["b"].shape == (3,) and d["w"].dtype == np.float64
    assert c["w"].shape == (3, 2, 4, 6) and c["b"].shape == (6,) and c["w"].dtype == np.float32
    assert lstm["wx"].shape == (7, 16) and lstm["wh"].shape == (4, 16) and lstm["b"].shape == (16,)
    np.testing.assert_array_equal(lstm["b"], [0] * 4 + [1] * 4 + [0] * 8)  # forget bias 1
    assert not np.any(d["b"]) and not np.any(c["b"])
    again = layers.init_dense(np.random.default_rng(0), 5, 3)
    np.testing.assert_array_equal(d["w"], again["w"])


def test_init_scales_follow_he_and_glorot():
    rng = np.random.default_rng(1)
    conv = layers.init_conv(rng, 3, 3, 64, 256)["w"]
    np.testing.assert_allclose(conv.std(), np.sqrt(2 / (9 * 64)), rtol=0.02)
    assert abs(conv.mean()) < 0.01 * conv.std() * 10
    dense = layers.init_dense(rng, 300, 500)["w"]
    limit = np.sqrt(6 / 800)
    assert dense.min() >= -limit and dense.max() <= limit
    np.testing.assert_allclose(dense.std(), limit / np.sqrt(3), rtol=0.02)


@pytest.mark.parametrize(
    "call,match",
    [
        (lambda: layers.init_dense(0, 2, 3), "rng"),
        (lambda: layers.init_dense(np.random.default_rng(0), 0, 3), "n_in"),
        (lambda: layers.init_dense(np.random.default_rng(0), 2, 2.5), "n_out"),
        (lambda: layers.init_conv(np.random.default_rng(0), 3, 3, 3, -1), "c_out"),
        (lambda: layers.init_conv(np.random.default_rng(0), 0, 3, 3, 4), "kh"),
        (lambda: layers.init_lstm(np.random.default_rng(0), 3, 0), "n_hidden"),
        (lambda: layers.init_dense(np.random.default_rng(0), 2, 3, dtype=np.int32), "dtype"),
        (lambda: layers.init_lstm_carry(0, 3), "batch"),
        (lambda: layers.lstm_cell(layers.init_lstm(np.random.default_rng(0), 2, 2),
                                  np.zeros((2, 2)), np.zeros((2, 2))), "carry"),
    ],
)
def test_bad_input_raises_value_error(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize("bad", [0, -2, 2.0, True, None])
@pytest.mark.parametrize(
    "name,call",
    [
        ("n_in", lambda v: layers.init_dense(np.random.default_rng(0), v, 3)),
        ("c_in", lambda v: layers.init_conv(np.random.default_rng(0), 3, 3, v, 4)),
        ("n_hidden", lambda v: layers.init_lstm(np.random.default_rng(0), 2, v)),
        ("batch", lambda v: layers.init_lstm_carry(v, 3)),
    ],
)
def test_sizes_are_checked_by_the_shared_validator(name, call, bad):
    """Sizes give the message of ``minimanc.checks.check_int``, as in vagn and cam."""
    with pytest.raises(ValueError, match=rf"^{name} must be an integer >= 1, got {name}="):
        call(bad)


# ---------------------------------------------------------------------------- forward pieces
def test_dense_flatten_gap():
    rng = np.random.default_rng(2)
    p = layers.init_dense(rng, 4, 3)
    p["b"] = rng.standard_normal(3)
    x = rng.standard_normal((2, 5, 4))
    np.testing.assert_allclose(layers.dense(p, x), x @ p["w"] + p["b"])
    img = rng.standard_normal((2, 3, 4, 5))
    assert layers.flatten(img).shape == (2, 60)
    np.testing.assert_array_equal(layers.flatten(img)[1], img[1].ravel())
    np.testing.assert_allclose(NP.nn.global_avg_pool(img), img.mean(axis=(1, 2)))
    np.testing.assert_allclose(np.asarray(JX.nn.global_avg_pool(img)), img.mean(axis=(1, 2)))


def test_conv_layer_uses_engine_conv2d():
    rng = np.random.default_rng(3)
    p = layers.init_conv(rng, 3, 3, 2, 4)
    p["b"] = rng.standard_normal(4)
    x = rng.standard_normal((2, 9, 9, 2))
    y = layers.conv(p, x, NP.nn, stride=2, padding=1)
    yj = layers.conv(p, x, JX.nn, stride=2, padding=1)
    assert y.shape == (2, 5, 5, 4)
    np.testing.assert_allclose(y, np.asarray(yj), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(layers.conv(p, x, stride=2, padding=1), y)  # default nn


def _lstm_reference(params, h, c, x):
    """Textbook LSTM with one weight matrix per gate, written with explicit loops."""
    n = params["wh"].shape[0]

    def sig(z):
        return 1 / (1 + np.exp(-z))

    gates = {}
    for k, name in enumerate("ifgo"):
        cols = slice(k * n, (k + 1) * n)
        z = x @ params["wx"][:, cols] + h @ params["wh"][:, cols] + params["b"][cols]
        gates[name] = np.tanh(z) if name == "g" else sig(z)
    c_new = gates["f"] * c + gates["i"] * gates["g"]
    return gates["o"] * np.tanh(c_new), c_new


@settings(max_examples=25, deadline=None)
@given(batch=st.integers(1, 4), n_in=st.integers(1, 5), n_h=st.integers(1, 5),
       seed=st.integers(0, 10_000))
def test_lstm_cell_matches_reference(batch, n_in, n_h, seed):
    rng = np.random.default_rng(seed)
    p = layers.init_lstm(rng, n_in, n_h)
    p["b"] = p["b"] + rng.standard_normal(4 * n_h)
    h, c = rng.standard_normal((batch, n_h)), rng.standard_normal((batch, n_h))
    x = rng.standard_normal((batch, n_in))
    got = layers.lstm_cell(p, (h, c), x)
    ref = _lstm_reference(p, h, c, x)
    for a, r in zip(got, ref):
        np.testing.assert_allclose(a, r, rtol=1e-12, atol=1e-14)


def test_lstm_unrolled_gradient_equals_jax():
    rng = np.random.default_rng(4)
    p = layers.init_lstm(rng, 3, 4)
    xs = rng.standard_normal((5, 2, 3))

    def loss(params, xs, eng):
        carry = layers.init_lstm_carry(2, 4, xp=eng.xp)
        for t in range(xs.shape[0]):
            carry = layers.lstm_cell(params, carry, xs[t], xp=eng.xp, nn=eng.nn)
        return eng.xp.sum(carry[0] ** 2) + eng.xp.mean(carry[1])

    v, g = NP.value_and_grad(loss)(p, xs, NP)
    vj, gj = jax.jit(lambda p, xs: JX.value_and_grad(loss)(p, xs, JX))(p, xs)
    assert abs(float(v) - float(vj)) < 1e-12
    assert _max_leaf_diff(g, gj) < 1e-10


def test_lstm_cell_default_nn_is_the_engine_of_xp():
    """With ``nn`` omitted, the primitives come from ``xp``'s engine (JAX's under jax.grad)."""
    rng = np.random.default_rng(5)
    p = layers.init_lstm(rng, 3, 4)
    x = rng.standard_normal((2, 3))

    def loss(params, eng, nn):
        h, c = layers.lstm_cell(params, layers.init_lstm_carry(2, 4, xp=eng.xp), x,
                                xp=eng.xp, nn=nn)
        return eng.xp.sum(h ** 2) + eng.xp.mean(c)

    want = JX.grad(loss)(p, JX, JX.nn)
    got = JX.grad(loss)(p, JX, None)
    assert _max_leaf_diff(got, want) == 0.0
    assert _max_leaf_diff(NP.grad(loss)(p, NP, None), want) < 1e-12


# ---------------------------------------------------------------------------- a small CNN
def _cnn_init(rng, dtype=np.float64):
    return {
        "convs": [layers.init_conv(rng, 3, 3, 3, 6, dtype=dtype),
                  layers.init_conv(rng, 3, 3, 6, 8, dtype=dtype)],
        "mid": layers.init_conv(rng, 2, 2, 8, 8, dtype=dtype),
        "out": layers.init_dense(rng, 8, 2, dtype=dtype),
    }


def _cnn_loss(params, x, y, eng):
    h = x
    for p in params["convs"]:
        h = eng.nn.silu(layers.conv(p, h, eng.nn, stride=2, padding=1))
    h = eng.nn.relu(layers.conv(params["mid"], h, eng.nn, stride=1, padding=0))
    logits = layers.dense(params["out"], eng.nn.global_avg_pool(h), xp=eng.xp)
    return -eng.xp.mean(eng.xp.sum(eng.nn.log_softmax(logits, axis=-1) * y, axis=-1))


def test_small_cnn_full_gradient_equals_jax():
    rng = np.random.default_rng(5)
    params = _cnn_init(rng)
    for p in (params["convs"][0], params["convs"][1], params["mid"]):
        p["b"] = 0.1 * rng.standard_normal(p["b"].shape)
    x = rng.standard_normal((4, 12, 12, 3))
    y = np.eye(2)[rng.integers(0, 2, 4)]
    # with respect to the parameters and to the input image (saliency, chapter 6)
    v, (g, gx) = NP.value_and_grad(_cnn_loss, argnums=(0, 1))(params, x, y, NP)
    vj, (gj, gxj) = jax.jit(lambda p, x, y: JX.value_and_grad(_cnn_loss, argnums=(0, 1))(
        p, x, y, JX))(params, x, y)
    assert abs(float(v) - float(vj)) < 1e-12
    assert _max_leaf_diff(g, gj) < 1e-6
    np.testing.assert_allclose(gx, np.asarray(gxj), rtol=1e-6, atol=1e-10)


def test_small_cnn_float32_on_numpy_engine():
    rng = np.random.default_rng(6)
    params = _cnn_init(rng, dtype=np.float32)
    x = rng.standard_normal((2, 12, 12, 3)).astype(np.float32)
    y = np.eye(2, dtype=np.float32)[[0, 1]]
    v, g = NP.value_and_grad(_cnn_loss)(params, x, y, NP)
    assert np.asarray(v).dtype == np.float32
    assert all(leaf.dtype == np.float32 for leaf in tree_flatten(g)[0])
    p64 = {k: v for k, v in _cnn_init(np.random.default_rng(6)).items()}
    v64, g64 = NP.value_and_grad(_cnn_loss)(p64, x.astype(np.float64), y.astype(np.float64), NP)
    assert abs(float(v) - float(v64)) < 1e-5
    assert _max_leaf_diff(g, g64) < 1e-4
