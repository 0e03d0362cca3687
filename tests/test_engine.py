"""Tests for minimanc.engine (chapter 1): one model code, two engines."""

from __future__ import annotations

import importlib
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import minimanc
import minimanc.autodiff.numpy as anp
from minimanc import autodiff
from minimanc.engine import ENGINES, get_engine

engine_module = importlib.import_module("minimanc.engine")


def naive_conv2d(x, w, b, stride, padding):
    """Reference NHWC/HWIO cross-correlation with explicit loops."""
    n, h, wd, c = x.shape
    kh, kw, _, o = w.shape
    xp = np.zeros((n, h + 2 * padding, wd + 2 * padding, c))
    xp[:, padding:padding + h, padding:padding + wd] = x
    ho, wo = (h + 2 * padding - kh) // stride + 1, (wd + 2 * padding - kw) // stride + 1
    out = np.zeros((n, ho, wo, o))
    for i in range(ho):
        for j in range(wo):
            patch = xp[:, i * stride:i * stride + kh, j * stride:j * stride + kw, :]
            out[:, i, j, :] = np.einsum("nhwc,hwco->no", patch, w)
    return out if b is None else out + b


def test_get_engine_names_and_errors():
    assert ENGINES == ("numpy", "jax")
    for name in ENGINES:
        eng = get_engine(name)
        assert eng.name == name and get_engine(name) is eng
        assert minimanc.engine(name) is eng
    with pytest.raises(ValueError, match=r"name='torch'.*numpy, jax"):
        get_engine("torch")


def test_minimanc_engine_stays_the_function_after_importing_the_module():
    # a plain `import minimanc.engine` must not rebind the package attribute
    importlib.import_module("minimanc.engine")
    assert callable(minimanc.engine) and minimanc.engine("numpy") is get_engine("numpy")
    from minimanc import engine

    assert engine("jax").name == "jax"


def test_numpy_engine_attributes():
    eng = get_engine("numpy")
    assert eng.xp is anp and eng.grad is autodiff.grad
    assert eng.value_and_grad is autodiff.value_and_grad

    def f(x):
        return x

    assert eng.jit(f) is f and eng.jit(static_argnums=(1,))(f) is f
    assert eng.nn.__name__ == "minimanc.autodiff.nn"


def test_jax_engine_attributes_and_x64():
    eng = get_engine("jax")
    assert eng.xp is jnp and eng.grad is jax.grad and eng.value_and_grad is jax.value_and_grad
    assert eng.xp.asarray(1.0).dtype == jnp.float64

    @eng.jit(static_argnums=(1,))
    def power(x, k):
        return x**k

    assert float(power(2.0, 3)) == 8.0
    assert float(eng.jit(lambda x: x * 2)(1.5)) == 3.0


def test_missing_jax_gives_install_hint(monkeypatch):
    monkeypatch.setitem(sys.modules, "jax", None)
    with pytest.raises(ImportError, match="pip install"):
        engine_module._jax_engine()


@settings(max_examples=15, deadline=None)
@given(k=st.integers(1, 3), stride=st.integers(1, 3), padding=st.integers(0, 2),
       hw=st.integers(3, 7), bias=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_jax_conv2d_matches_loops(k, stride, padding, hw, bias, seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(2, hw, hw + 1, 3))
    w = rng.normal(size=(k, k, 3, 4))
    b = rng.normal(size=4) if bias else None
    out = np.asarray(get_engine("jax").nn.conv2d(x, w, b, stride=stride, padding=padding))
    expected_hw = ((hw + 2 * padding - k) // stride + 1, (hw + 1 + 2 * padding - k) // stride + 1)
    assert out.shape == (2, *expected_hw, 4)
    np.testing.assert_allclose(out, naive_conv2d(x, w, b, stride, padding), rtol=1e-10,
                               atol=1e-10)


@pytest.mark.parametrize("name", ENGINES)
def test_conv2d_bad_arguments(name):
    nn = get_engine(name).nn
    x, w = np.ones((1, 5, 5, 2)), np.ones((3, 3, 2, 4))
    with pytest.raises(ValueError, match="stride"):
        nn.conv2d(x, w, stride=0)
    with pytest.raises(ValueError, match="padding"):
        nn.conv2d(x, w, padding=-1)


def test_jax_nn_activations():
    nn = get_engine("jax").nn
    x = np.array([[-2.0, 0.0, 3.0], [1.0, 1.0, -1.0]])
    np.testing.assert_allclose(nn.relu(x), np.maximum(x, 0))
    np.testing.assert_allclose(nn.sigmoid(x), 1 / (1 + np.exp(-x)))
    np.testing.assert_allclose(nn.silu(x), x / (1 + np.exp(-x)))
    e = np.exp(x - x.max(axis=0))
    np.testing.assert_allclose(nn.softmax(x, axis=0), e / e.sum(axis=0))
    np.testing.assert_allclose(nn.log_softmax(x),
                               np.log(np.exp(x) / np.exp(x).sum(-1, keepdims=True)))
    np.testing.assert_allclose(nn.global_avg_pool(np.ones((2, 3, 4, 5)) * 2), np.full((2, 5), 2.0))


def cnn_loss(params, images, targets, eng):
    """A conv → SiLU → conv → ReLU → GAP → linear → softmax model (cf. eq. 7, 9)."""
    xp, nn = eng.xp, eng.nn
    h = nn.silu(nn.conv2d(images, params["c1"], params["b1"], stride=2, padding=1))
    h = nn.relu(nn.conv2d(h, params["c2"], None, stride=1, padding=0))
    feats = nn.global_avg_pool(h)
    logits = feats @ params["w"] + params["b"]
    p = nn.softmax(logits, axis=-1)
    nll = -xp.mean(xp.sum(nn.log_softmax(logits, axis=-1) * targets, axis=-1))
    return nll + xp.mean(nn.sigmoid(p))


def _cnn_params(rng, dtype=np.float64):
    return {
        "c1": rng.normal(size=(3, 3, 3, 4)) * 0.5,
        "b1": rng.normal(size=4) * 0.1,
        "c2": rng.normal(size=(3, 3, 4, 5)) * 0.3,
        "w": rng.normal(size=(5, 3)),
        "b": rng.normal(size=3) * 0.1,
    } if dtype == np.float64 else {
        k: v.astype(dtype) for k, v in _cnn_params(rng).items()
    }


def test_same_model_code_same_gradients_on_both_engines():
    rng = np.random.default_rng(0)
    params = _cnn_params(rng)
    images = rng.normal(size=(2, 9, 8, 3))
    targets = np.eye(3)[[0, 2]]
    results = {}
    for name in ENGINES:
        eng = get_engine(name)
        val, g = eng.value_and_grad(cnn_loss)(params, images, targets, eng)
        results[name] = (float(val), {k: np.asarray(v) for k, v in g.items()})
    assert abs(results["numpy"][0] - results["jax"][0]) < 1e-10
    for k in params:
        np.testing.assert_allclose(results["numpy"][1][k], results["jax"][1][k], rtol=1e-6,
                                   atol=1e-10)


def test_numpy_engine_float32_network_gives_float32_gradients():
    rng = np.random.default_rng(1)
    params = _cnn_params(rng, np.float32)
    images = rng.normal(size=(2, 9, 8, 3)).astype(np.float32)
    targets = np.eye(3, dtype=np.float32)[[1, 2]]
    eng = get_engine("numpy")
    g = eng.grad(cnn_loss)(params, images, targets, eng)
    assert all(v.dtype == np.float32 for v in g.values())
    ref = get_engine("jax").grad(cnn_loss)(
        {k: v.astype(np.float64) for k, v in params.items()}, images.astype(np.float64),
        targets.astype(np.float64), get_engine("jax"))
    for k in params:
        np.testing.assert_allclose(g[k], ref[k], rtol=2e-3, atol=2e-5)
