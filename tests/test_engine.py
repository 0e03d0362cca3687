"""Tests for minimanc.engine (chapter 1): one model code, two engines."""

from __future__ import annotations

import importlib
import os
import shutil
import subprocess
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
from minimanc.tree import tree_flatten

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


# --------------------------------------------------------------------------- scan
def _rnn_loss(params, h0, xs, eng, use_scan=True):
    """A pytree carry ({"h", "n"}, an integer counter) and a pytree y, params closed over."""
    xp = eng.xp

    def f(carry, x):
        h = xp.tanh(carry["h"] @ params["W"] + x["u"] * params["b"])
        h = xp.where(carry["n"] > 0, h, h * 0.5)
        return {"h": h, "n": carry["n"] + 1}, {"s": xp.sum(h * h, axis=-1), "h": h}

    carry = {"h": h0, "n": 0}
    if use_scan:
        carry, ys = eng.scan(f, carry, {"u": xs})
    else:
        outs = []
        for i in range(xs.shape[0]):
            carry, y = f(carry, {"u": xs[i]})
            outs.append(y)
        ys = {k: xp.stack([y[k] for y in outs]) for k in outs[0]}
    return xp.sum(carry["h"] ** 3) + xp.sum(ys["s"] * ys["s"]) + xp.mean(ys["h"])


@settings(max_examples=15, deadline=None)
@given(L=st.integers(1, 6), B=st.integers(1, 3), H=st.integers(1, 4), seed=st.integers(0, 999))
def test_scan_equals_the_loop_and_lax_scan_with_gradients(L, B, H, seed):
    rng = np.random.default_rng(seed)
    params = {"W": rng.normal(size=(H, H)) * 0.7, "b": rng.normal(size=H)}
    h0, xs = rng.normal(size=(B, H)), rng.normal(size=(L, B, H))
    eng, jeng = get_engine("numpy"), get_engine("jax")
    args = (0, 1, 2)
    v_scan, g_scan = eng.value_and_grad(_rnn_loss, args)(params, h0, xs, eng)
    v_loop, g_loop = eng.value_and_grad(_rnn_loss, args)(params, h0, xs, eng, False)
    v_jax, g_jax = jeng.value_and_grad(_rnn_loss, args)(params, h0, xs, jeng)
    np.testing.assert_allclose(v_scan, v_loop, rtol=1e-12)
    np.testing.assert_allclose(v_scan, float(v_jax), rtol=1e-10)
    for ours, loop, jx in zip(g_scan, g_loop, g_jax):
        for a, b, c in zip(*(tree_flatten(t)[0] for t in (ours, loop, jx))):
            np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)
            np.testing.assert_allclose(a, np.asarray(c), rtol=1e-8, atol=1e-10)


def test_scan_is_one_node_of_the_tape():
    eng = get_engine("numpy")
    seen = []

    def loss(w, xs):
        carry, ys = eng.scan(lambda c, x: (anp.sin(c * w + x), c * w), anp.zeros(3), xs)
        seen.append(carry)
        return anp.sum(carry) + anp.sum(ys)

    eng.grad(loss)(np.ones(3), np.ones((50, 3)))
    nodes = autodiff.toposort(seen[0])
    names = [b.primitive_name for b in nodes]
    assert names.count("_scan_node") == 1 and len(nodes) <= 5  # select, scan, w, xs


def test_scan_without_tracing_and_with_length():
    eng = get_engine("numpy")
    carry, ys = eng.scan(lambda c, _: (c + 1.0, c * 2.0), np.float64(0.0), None, length=4)
    assert float(carry) == 4.0 and ys.tolist() == [0.0, 2.0, 4.0, 6.0]
    carry, ys = get_engine("jax").scan(lambda c, _: (c + 1.0, c * 2.0), 0.0, None, length=4)
    assert float(carry) == 4.0 and np.asarray(ys).tolist() == [0.0, 2.0, 4.0, 6.0]


def test_scan_float32_stays_float32():
    eng = get_engine("numpy")
    w = np.float32([0.5, -1.0])
    xs = np.ones((4, 2), np.float32)

    def loss(w, h0, xs):
        h, ys = eng.scan(lambda h, x: (anp.tanh(h * w + x), h * h), h0, xs)
        assert h.value.dtype == np.float32 and ys.value.dtype == np.float32
        return anp.sum(h) + anp.sum(ys)

    g = eng.grad(loss, (0, 1, 2))(w, np.zeros(2, np.float32), xs)
    assert all(x.dtype == np.float32 for x in g)


def test_scan_bad_arguments():
    eng = get_engine("numpy")
    with pytest.raises(TypeError, match="shape and dtype"):
        eng.scan(lambda c, x: (c.astype(np.float32), x), np.zeros(2), np.zeros((3, 2)))
    with pytest.raises(TypeError, match="structure of init"):
        eng.scan(lambda c, x: ((c, c), x), np.zeros(2), np.zeros((3, 2)))
    with pytest.raises(TypeError, match="pair"):
        eng.scan(lambda c, x: c, np.zeros(2), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="different leading lengths"):
        eng.scan(lambda c, x: (c, x), np.zeros(2), {"a": np.zeros((3, 2)), "b": np.zeros(4)})
    with pytest.raises(ValueError, match="length="):
        eng.scan(lambda c, x: (c, x), np.zeros(2), None)
    with pytest.raises(ValueError, match="length=0"):
        eng.scan(lambda c, x: (c, x), np.zeros(2), None, length=0)
    with pytest.raises(ValueError, match="length=2 but xs"):
        eng.scan(lambda c, x: (c, x), np.zeros(2), np.zeros((3, 2)), length=2)


def test_device_put():
    tree = {"a": np.ones(2), "b": [np.zeros(3)]}
    assert get_engine("numpy").device_put(tree) is tree
    out = get_engine("jax").device_put(tree)
    assert isinstance(out["b"][0], jax.Array)


def test_scan_nested_and_closed_over_computed_values_match_jax():
    """A scan inside a scan's step, closing over a value computed from the parameters."""
    rng = np.random.default_rng(3)
    w, xs = rng.normal(size=3), rng.normal(size=(4, 2, 3))

    def loss(w, xs, eng):
        xp = eng.xp
        w2 = xp.sin(w) * 2.0  # traced, made outside both loops

        def inner(c, x):
            return c * w2 + x, xp.sum(c)

        def outer(c, x):
            c2, ys = eng.scan(inner, c, x)
            return xp.tanh(c2), ys * w[0]

        c, ys = eng.scan(outer, xp.zeros(3) + w, xs)
        return xp.sum(c * c) + xp.sum(ys ** 2)

    ours = get_engine("numpy").value_and_grad(loss, (0, 1))(w, xs, get_engine("numpy"))
    ref = get_engine("jax").value_and_grad(loss, (0, 1))(w, xs, get_engine("jax"))
    np.testing.assert_allclose(ours[0], float(ref[0]), rtol=1e-12)
    for a, b in zip(ours[1], ref[1]):
        np.testing.assert_allclose(a, np.asarray(b), rtol=1e-10, atol=1e-12)


# ----------------------------------------------------------------- XLA's threads

XLA_PROBE = """
import os
import numpy as np
from minimanc.engine import get_engine
eng = get_engine("jax")
import jax.numpy as jnp
x = jnp.asarray(np.random.default_rng(0).normal(size=(64, 64, 64, 16)).astype(np.float32))
w = jnp.asarray(np.random.default_rng(1).normal(size=(3, 3, 16, 32)).astype(np.float32))
y = eng.nn.conv2d(x, w, stride=2, padding=1)
bits = float(jnp.mean(y * y)).hex()
tasks = os.listdir("/proc/self/task")
pool = sum("Eigen" in open(f"/proc/self/task/{t}/comm").read() for t in tasks)
masks = sorted({len(os.sched_getaffinity(int(t))) for t in tasks})
print(pool, len(tasks), ",".join(map(str, masks)), bits)
"""


def _probe(cpus=None, threads=None):
    """``(threads named as XLA's pool, all threads, CPUs per thread, result bits)`` of
    :data:`XLA_PROBE` in a fresh process (on the CPUs ``cpus`` if given, with ``threads``
    XLA threads if given). Older jaxlib releases leave the pool's threads unnamed."""
    env = dict(os.environ)
    env.pop("MINIMANC_XLA_THREADS", None)
    if threads is not None:
        env["MINIMANC_XLA_THREADS"] = str(threads)
    cmd = [sys.executable, "-c", XLA_PROBE]
    if cpus is not None:
        cmd = ["taskset", "-c", cpus] + cmd
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    pool, n_threads, masks, bits = out.stdout.split()
    return int(pool), int(n_threads), masks, bits


needs_two_cpus = pytest.mark.skipif(
    not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2
    or shutil.which("taskset") is None,
    reason="needs CPU masks, two usable CPUs and taskset")


@needs_two_cpus
def test_jax_starts_with_one_xla_thread_and_the_cpus_given_back():
    """``get_engine("jax")`` starts XLA's pool with one thread (two with the variable), and
    afterwards every thread of the process may again run on all the CPUs it could use."""
    pool, n_threads, masks, _ = _probe()
    pool2, n_threads2, _, _ = _probe(threads=2)
    assert masks == str(len(os.sched_getaffinity(0)))
    if pool or pool2:  # the pool's threads carry XLA's name (jaxlib ≥ 0.4.31 or so)
        assert (pool, pool2) == (1, 2)
    else:  # unnamed: the second pool thread is one more thread of the process
        assert n_threads < n_threads2


@needs_two_cpus
def test_float32_results_do_not_depend_on_the_cores():
    """The same float32 reduction gives the same bits on one core and on two, since XLA
    runs one thread either way."""
    assert _probe(cpus="0")[3] == _probe()[3]


@pytest.mark.parametrize("value", ["0", "-1", "two", ""])
def test_bad_xla_threads_variable(monkeypatch, value):
    from minimanc.engine import xla_threads

    monkeypatch.setenv("MINIMANC_XLA_THREADS", value)
    with pytest.raises(ValueError, match="MINIMANC_XLA_THREADS must be a positive integer"):
        xla_threads()
    monkeypatch.setenv("MINIMANC_XLA_THREADS", "3")
    assert xla_threads() == 3
