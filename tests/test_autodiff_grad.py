"""Tests for minimanc.autodiff (chapter 1): what ``grad`` and ``value_and_grad`` do
(pytrees, argnums, has_aux, dtypes, determinism, custom VJPs), regression tests for the
classic bugs of small autodiff engines, and the fast paths of the common cases."""

from __future__ import annotations

import sys
from collections import namedtuple

import hypothesis.extra.numpy as hnp
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from autodiff_strategies import SETTINGS, pairs, seeds
from hypothesis import given
from hypothesis import strategies as st

import minimanc.autodiff.numpy as anp
from minimanc.autodiff import (
    Box,
    check_grads,
    defvjp,
    defvjp_fwd,
    grad,
    primitive,
    unbroadcast,
    value_and_grad,
)
from minimanc.engine import get_engine

get_engine("jax")  # turns on jax_enable_x64


# ---------------------------------------------------------------------------
# grad / value_and_grad semantics and regressions
# ---------------------------------------------------------------------------
def test_node_used_twice():
    np.testing.assert_allclose(grad(lambda x: anp.sum(x * x))(np.array([1.0, -3.0])), [2, -6])
    np.testing.assert_allclose(grad(lambda x: anp.sum(x + x + x))(np.array([1.0])), [3.0])

    def diamond(x):
        a = anp.sin(x)
        return anp.sum(a * anp.exp(a) + a)

    x = np.array([0.3, -0.7])
    np.testing.assert_allclose(grad(diamond)(x), jax.grad(
        lambda x: jnp.sum(jnp.sin(x) * jnp.exp(jnp.sin(x)) + jnp.sin(x)))(x), rtol=1e-12)


def test_gradient_function_called_twice_gives_the_same_result():
    df = grad(lambda x: anp.sum(anp.tanh(x) ** 2))
    x = np.array([0.1, 0.2, 0.3])
    first, second = df(x), df(x)
    np.testing.assert_array_equal(first, second)
    np.testing.assert_allclose(df(2 * x), jax.grad(lambda x: jnp.sum(jnp.tanh(x) ** 2))(2 * x))


def test_broadcasting_in_both_operands():
    x, y = np.arange(3.0).reshape(3, 1), np.arange(4.0).reshape(1, 4) + 1
    gx, gy = grad(lambda x, y: anp.sum(x * y), argnums=(0, 1))(x, y)
    np.testing.assert_allclose(gx, np.full((3, 1), 10.0))
    np.testing.assert_allclose(gy, np.full((1, 4), 3.0))


def test_deep_chain_does_not_hit_the_recursion_limit():
    n = 10_000
    assert n > sys.getrecursionlimit()

    def chain(x):
        for _ in range(n):
            x = x * 1.0001 + 0.0
        return anp.sum(x)

    g = grad(chain)(np.ones(2))
    np.testing.assert_allclose(g, np.full(2, 1.0001**n), rtol=1e-9)


def test_integer_inputs_raise_a_clear_error():
    with pytest.raises(TypeError, match="grad requires real floating-point inputs, got int64 "
                                        "for argument 0"):
        grad(lambda x: anp.sum(x * 1.0))(np.arange(3))
    with pytest.raises(TypeError, match="got int for argument 1"):
        grad(lambda x, y: x * y, argnums=1)(1.0, 2)
    with pytest.raises(TypeError, match=r"argument 0 at \['b'\]"):
        grad(lambda p: p["a"] * 1.0)({"a": 1.0, "b": np.arange(2)})


def test_non_scalar_output_raises():
    with pytest.raises(TypeError, match=r"scalar output.*shape \(3,\)"):
        grad(lambda x: x * 2)(np.ones(3))


def test_mismatched_shapes_name_the_operation_and_shapes():
    with pytest.raises(ValueError, match=r"^matmul: shapes \(3, 4\) and \(5, 2\) are not aligned"):
        grad(lambda a, b: anp.sum(a @ b))(np.ones((3, 4)), np.ones((5, 2)))
    with pytest.raises(ValueError, match=r"^matmul: shapes \(3, 4\) and \(5, 2\) are not aligned"):
        anp.matmul(np.ones((3, 4)), np.ones((5, 2)))
    with pytest.raises(ValueError, match=r"^add: .*\(3,\).*\(4,\)"):
        grad(lambda a: anp.sum(a + np.ones(4)))(np.ones(3))
    with pytest.raises(ValueError, match=r"^dot: shapes \(2, 3\) and \(2,\) are not aligned"):
        anp.dot(np.ones((2, 3)), np.ones(2))


Params = namedtuple("Params", ["w", "b"])


def test_pytrees_and_argnums():
    rng = np.random.default_rng(0)
    params = {"layers": [Params(rng.normal(size=(3, 2)), rng.normal(size=2)),
                         Params(rng.normal(size=(2, 1)), None)],
              "scale": 1.5}
    x = rng.normal(size=(4, 3))

    def model(xp, params, x):
        h = xp.tanh(x @ params["layers"][0].w + params["layers"][0].b)
        return xp.sum((h @ params["layers"][1].w) ** 2) * params["scale"]

    g = grad(lambda p, x: model(anp, p, x))(params, x)
    ref = jax.grad(lambda p, x: model(jnp, p, x))(params, x)
    assert isinstance(g["layers"][0], Params) and g["layers"][1].b is None
    assert isinstance(g["scale"], float)
    for a, b in zip(jax.tree_util.tree_leaves(g), jax.tree_util.tree_leaves(ref)):
        np.testing.assert_allclose(a, b, rtol=1e-10)

    gp, gx = grad(lambda p, x: model(anp, p, x), argnums=(0, 1))(params, x)
    rp, rx = jax.grad(lambda p, x: model(jnp, p, x), argnums=(0, 1))(params, x)
    np.testing.assert_allclose(gx, rx, rtol=1e-10)
    np.testing.assert_allclose(gp["layers"][1].w, rp["layers"][1].w, rtol=1e-10)
    assert isinstance(grad(lambda p, x: model(anp, p, x), argnums=(1,))(params, x), tuple)

    val, (gp2, gx2) = value_and_grad(lambda p, x: model(anp, p, x), argnums=(0, 1))(params, x)
    np.testing.assert_allclose(val, model(np, params, x), rtol=1e-14)
    np.testing.assert_array_equal(gx2, gx)


def test_value_and_grad_has_aux_and_unused_arguments():
    def f(x, y):
        return anp.sum(x**2), {"x2": x * 2}

    (val, aux), g = value_and_grad(f, has_aux=True)(np.array([1.0, 2.0]), 3.0)
    assert float(val) == 5.0 and not isinstance(aux["x2"], Box)
    np.testing.assert_array_equal(aux["x2"], [2.0, 4.0])
    g2, aux2 = grad(f, has_aux=True)(np.array([1.0, 2.0]), 3.0)
    np.testing.assert_array_equal(g, g2)
    gy = grad(lambda x, y: anp.sum(x), argnums=1)(np.ones(2), np.ones((2, 2)))
    np.testing.assert_array_equal(gy, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="argnums"):
        grad(lambda x: x, argnums=3)(1.0)
    with pytest.raises(ValueError, match="argnums=.*twice"):
        grad(lambda x, y: x * y, argnums=(1, -1))(1.0, 2.0)
    assert grad(lambda x, y: x * y, argnums=-1)(3.0, 2.0) == 3.0


def test_determinism_bit_identical():
    rng = np.random.default_rng(3)
    w = {"a": rng.normal(size=(16, 16)), "b": rng.normal(size=16)}
    x = rng.normal(size=(32, 16))

    def loss(w):
        h = x
        for _ in range(5):  # every layer re-uses w: cotangents are summed many times
            h = anp.tanh(h @ w["a"] + w["b"]) + 0.1 * h
        return anp.mean(h**2) + anp.sum(w["a"] * w["a"]) * 1e-3

    g1, g2 = grad(loss)(w), grad(loss)(w)
    for k in w:
        assert g1[k].tobytes() == g2[k].tobytes()


def test_float32_stays_float32():
    rng = np.random.default_rng(0)
    w = rng.normal(size=(3, 2)).astype(np.float32)
    x = rng.normal(size=(5, 3)).astype(np.float32)

    def loss(w):
        h = anp.tanh(x @ w) * 0.5 + anp.exp(-(x @ w) ** 2)
        return anp.mean(h**2) + anp.sum(anp.sqrt(w * w + 1.0))

    val, g = value_and_grad(loss)(w)
    assert val.dtype == np.float32 and g.dtype == np.float32
    ref = jax.grad(lambda w: jnp.mean((jnp.tanh(x @ w) * 0.5 + jnp.exp(-(x @ w) ** 2)) ** 2)
                   + jnp.sum(jnp.sqrt(w * w + 1.0)))(w.astype(np.float64))
    np.testing.assert_allclose(g, ref, rtol=1e-4)


def test_missing_vjp_raises_naming_the_primitive():
    @primitive
    def mystery(x):
        return x * 2

    assert mystery(np.ones(2)).tolist() == [2.0, 2.0]  # untraced: just runs
    with pytest.raises(NotImplementedError, match="mystery"):
        grad(lambda x: anp.sum(mystery(x)))(np.ones(2))

    @primitive
    def half(x, y):
        return x * y

    defvjp(half, lambda g, ans, x, y: g * y)  # no VJP for y
    np.testing.assert_array_equal(grad(lambda x: half(x, 3.0))(2.0), 3.0)
    with pytest.raises(NotImplementedError, match="half.*argument 1"):
        grad(lambda y: half(2.0, y))(1.0)


def test_wrong_vjp_shape_is_reported():
    @primitive
    def bad(x):
        return x.sum()

    defvjp(bad, lambda g, ans, x: g)  # forgot to broadcast back
    with pytest.raises(ValueError, match="VJP of 'bad'.*shape"):
        grad(bad)(np.ones(3))


def test_defvjp_fwd_keeps_residuals_only_when_traced():
    calls = {"fwd": 0}

    @primitive
    def softplus(x):
        return np.log1p(np.exp(x))

    def fwd(x):
        calls["fwd"] += 1
        e = np.exp(x)
        return np.log1p(e), e / (1 + e)

    defvjp_fwd(softplus, fwd, lambda g, sig: (g * sig,))
    x = np.array([-1.0, 0.5, 2.0])
    softplus(x)
    assert calls["fwd"] == 0
    g = grad(lambda x: anp.sum(softplus(x) * x))(x)
    assert calls["fwd"] == 1
    np.testing.assert_allclose(g, jax.grad(lambda x: jnp.sum(jax.nn.softplus(x) * x))(x))


def test_higher_order_is_refused_clearly():
    with pytest.raises(NotImplementedError, match="higher-order"):
        grad(lambda x: grad(lambda y: y * y)(x))(1.0)


def test_unbroadcast():
    g = np.ones((2, 3, 4))
    assert unbroadcast((3, 1), g).shape == (3, 1) and unbroadcast((3, 1), g)[0, 0] == 8
    assert unbroadcast(np.ones(4, np.float32), g).dtype == np.float32
    assert unbroadcast((), g) == 24.0
    np.testing.assert_array_equal(unbroadcast((2, 3, 4), g), g)


def test_check_grads_reports_and_catches_a_wrong_vjp():
    rng = np.random.default_rng(0)
    report = check_grads(lambda x, p: anp.sum(anp.sin(x) * p["w"]), rng.normal(size=(2, 3)),
                         {"w": rng.normal(size=3)}, verbose=False)
    assert report.passed and report.n_checked == 9 and report.max_abs_err < 1e-8

    @primitive
    def wrong_sin(x):
        return np.sin(x)

    defvjp(wrong_sin, lambda g, ans, x: g * np.cos(x) * 1.01)  # a 1 % error
    with pytest.raises(AssertionError, match=r"FAILED.*argument 1\['w'\] index \("):
        check_grads(lambda x, p: anp.sum(x) + anp.sum(wrong_sin(p["w"])),
                    rng.normal(size=2), {"w": rng.normal(size=3)}, verbose=False)
    with pytest.raises(ValueError, match="eps"):
        check_grads(lambda x: x, 1.0, eps=0.0)



# ---------------------------------------------------------------------------
# The fast paths of the common cases give the general paths' answers
# ---------------------------------------------------------------------------
def test_value_and_grad_pauses_the_garbage_collector_and_restores_it():
    import gc

    seen = []

    def f(x):
        seen.append(gc.isenabled())
        return anp.sum(x * x)

    def fails(x):
        raise ValueError("inside the traced function")

    was = gc.isenabled()
    try:
        gc.enable()
        np.testing.assert_allclose(grad(f)(np.ones(3)), 2.0 * np.ones(3))
        assert seen == [False] and gc.isenabled()  # paused while tracing, restored after
        with pytest.raises(ValueError, match="inside the traced function"):
            grad(fails)(np.ones(3))
        assert gc.isenabled()  # restored after an error too
        gc.disable()
        grad(f)(np.ones(3))
        assert not gc.isenabled()  # a caller's disabled collector stays disabled
        gc.enable()
        inner = []

        def outer(x):  # a gradient taken (of plain values) inside another one's trace
            grad(f)(np.ones(2))
            inner.append(gc.isenabled())  # the inner call left the outer pause alone
            return anp.sum(x)

        grad(outer)(np.ones(2))
        assert seen[-1] is False and inner == [False] and gc.isenabled()
    finally:
        (gc.enable if was else gc.disable)()


@SETTINGS
@given(shapes2=pairs, seed=seeds, which=st.sampled_from(["maximum", "minimum", "clip"]))
def test_maximum_minimum_ties_share_like_jax(shapes2, seed, which):
    # values on a grid of three, so ties between x and y are frequent (and sometimes absent)
    (sx, sy), _ = shapes2
    rng = np.random.default_rng(seed)
    x = rng.integers(-1, 2, size=sx).astype(np.float64)
    y = rng.integers(-1, 2, size=sy).astype(np.float64)
    w = rng.normal(size=np.broadcast_shapes(sx, sy))
    ops = {"maximum": lambda xp, a, b: xp.maximum(a, b),
           "minimum": lambda xp, a, b: xp.minimum(a, b),
           "clip": lambda xp, a, b: xp.clip(a + 0 * b, 0.0, 1.0) * b}
    op = ops[which]
    ours = grad(lambda a, b: anp.sum(op(anp, a, b) * w), argnums=(0, 1))(x, y)
    ref = jax.grad(lambda a, b: jnp.sum(op(jnp, a, b) * w), argnums=(0, 1))(x, y)
    for g, r in zip(ours, ref):
        # weights 1, 1/2, 0; only the order of the broadcasting sums may differ
        np.testing.assert_allclose(g, np.asarray(r), rtol=1e-12, atol=1e-12)


@SETTINGS
@given(shape=hnp.array_shapes(min_dims=1, max_dims=3, min_side=1, max_side=3), seed=seeds,
       data=st.data())
def test_concatenate_gradient_splits_along_any_axis(shape, seed, data):
    axis = data.draw(st.integers(-len(shape), len(shape) - 1))
    sizes = data.draw(st.lists(st.integers(1, 3), min_size=1, max_size=3))
    rng = np.random.default_rng(seed)
    parts = []
    for n in sizes:
        s = list(shape)
        s[axis] = n
        parts.append(rng.normal(size=s))
    total = np.concatenate(parts, axis=axis)
    w = rng.normal(size=total.shape)
    nums = tuple(range(len(parts)))
    ours = grad(lambda *p: anp.sum(anp.concatenate(p, axis=axis) * w), argnums=nums)(*parts)
    pieces = np.split(w, np.cumsum(sizes)[:-1], axis=axis)
    for g, ref in zip(ours, pieces):
        np.testing.assert_array_equal(g, ref)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_reduction_and_index_gradients_are_fresh_writable_arrays_of_the_input_dtype(dtype):
    x = np.arange(24, dtype=dtype).reshape(2, 3, 4)
    max_hit = np.zeros((2, 3, 4), dtype)
    max_hit[:, 2, 3] = 1.0  # the largest entry of each x[i]
    index_hit = np.zeros((2, 3, 4), dtype)
    index_hit[1, 2] += 1.0
    index_hit[..., 0] += 1.0
    cases = [
        (lambda v: anp.sum(anp.sum(v, axis=(0, -1)) * 2.0), np.full(x.shape, 2.0, dtype)),
        (lambda v: anp.sum(anp.mean(v, axis=-2, keepdims=True)),
         np.full(x.shape, dtype(1.0) / dtype(3.0), dtype)),
        (lambda v: anp.sum(anp.max(v, axis=(1, 2))), max_hit),
        (lambda v: v[1, np.int64(2)].sum() + v[..., 0].sum(), index_hit),
    ]
    for f, want in cases:
        g = grad(f)(x)
        assert g.dtype == dtype and g.shape == x.shape and g.flags.writeable
        np.testing.assert_array_equal(g, want)

