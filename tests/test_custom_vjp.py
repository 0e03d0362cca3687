"""Tests for minimanc.autodiff.custom (chapter 1): custom_vjp, jax.custom_vjp's API on the
NumPy engine, and engine.engine_of / Engine.custom_vjp."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import minimanc.autodiff.numpy as anp
from minimanc import engine
from minimanc.autodiff import Box, custom_vjp, grad, scan
from minimanc.engine import engine_of


def _make(eng_custom_vjp):
    """``f(x, y, k) = (k·x·y, x + y)`` with its VJP written by hand (``k`` static)."""
    def fun(x, y, k):
        return k * x * y, x + y

    def fwd(x, y, k):
        return fun(x, y, k), (x, y)

    def bwd(k, res, g):
        x, y = res
        g0, g1 = g
        return g0 * k * y + g1, g0 * k * x + g1

    f = eng_custom_vjp(fun, nondiff_argnums=(2,))
    f.defvjp(fwd, bwd)
    return f


JAX = engine("jax")  # turns on float64 in JAX
f_ours = _make(custom_vjp)
f_jax = _make(jax.custom_vjp)


@settings(max_examples=40, deadline=None)
@given(hnp.arrays(np.float64, (3,), elements=st.floats(-10, 10)),
       hnp.arrays(np.float64, (3,), elements=st.floats(-10, 10)),
       st.floats(-3, 3), st.sampled_from([(1.0, 0.0), (0.0, 1.0), (0.5, -2.0)]))
def test_custom_vjp_gradients_equal_jax_custom_vjp(x, y, k, w):
    def loss(f, xp):
        return lambda x, y: xp.sum(w[0] * f(x, y, k)[0] ** 2 + w[1] * f(x, y, k)[1])

    ours = grad(loss(f_ours, anp), argnums=(0, 1))(x, y)
    theirs = jax.grad(loss(f_jax, jax.numpy), argnums=(0, 1))(x, y)
    for u, v in zip(ours, theirs):
        np.testing.assert_allclose(u, np.asarray(v), rtol=1e-12, atol=1e-12)


def test_custom_vjp_is_one_node_and_unused_outputs_get_zero_cotangents():
    calls = []

    def fun(x):
        return x * 2.0, x * 3.0

    def bwd(res, g):
        calls.append(g)
        return (2.0 * g[0] + 3.0 * g[1],)

    f = custom_vjp(fun)
    f.defvjp(lambda x: (fun(x), None), bwd)
    out = grad(lambda x: anp.sum(f(x)[0]))(np.ones(2))  # the second output is unused
    np.testing.assert_allclose(out, [2.0, 2.0])
    (g0, g1), = calls
    np.testing.assert_array_equal(g1, np.zeros(2))


def test_custom_vjp_without_traced_arguments_just_calls_the_function():
    f = custom_vjp(lambda x, y: x * y)  # no defvjp needed when nothing is traced
    assert f(2.0, 3.0) == 6.0
    jx = jax.numpy.ones(2)  # any array type passes through, JAX's included
    np.testing.assert_allclose(np.asarray(f(jx, 2.0)), [2.0, 2.0])


def test_custom_vjp_accepts_lists_of_traced_values():
    f = custom_vjp(lambda xs: xs[0] * xs[1])
    f.defvjp(lambda xs: (xs[0] * xs[1], xs), lambda res, g: ([g * res[1], g * res[0]],))
    gx = grad(lambda a, b: anp.sum(f([a, b])), argnums=(0, 1))(np.array([2.0]), np.array([5.0]))
    np.testing.assert_allclose(gx[0], [5.0])
    np.testing.assert_allclose(gx[1], [2.0])


def test_custom_vjp_inside_scan_matches_the_unrolled_loop():
    def body(c, x):
        y, _ = f_ours(c, x, 0.5)
        return y, y

    def loss(c0, xs):
        c, ys = scan(body, c0, xs)
        return anp.sum(c) + anp.sum(ys)

    def unrolled(c0, xs):
        c, total = c0, 0.0
        for i in range(xs.shape[0]):
            c = 0.5 * c * xs[i]
            total = total + anp.sum(c)
        return anp.sum(c) + total

    c0, xs = np.array([1.0, 2.0]), np.linspace(0.5, 1.5, 8).reshape(4, 2)
    a = grad(loss, argnums=(0, 1))(c0, xs)
    b = grad(unrolled, argnums=(0, 1))(c0, xs)
    for u, v in zip(a, b):
        np.testing.assert_allclose(u, v, rtol=1e-12)


def test_custom_vjp_errors_name_the_problem():
    f = custom_vjp(lambda x, k: x * k, nondiff_argnums=(1,))
    with pytest.raises(NotImplementedError, match="defvjp"):
        grad(lambda x: anp.sum(f(x, 2.0)))(np.ones(2))
    f.defvjp(lambda x, k: (x * k, None), lambda k, res, g: (g * k,))
    with pytest.raises(TypeError, match="nondiff_argnums"):
        grad(lambda x: anp.sum(f(x, x)))(np.ones(2))
    with pytest.raises(TypeError, match="positional"):
        f(np.ones(2), k=2.0)
    bad = custom_vjp(lambda x: x * 2.0)
    bad.defvjp(lambda x: (x * 2.0, None), lambda res, g: (g, g))
    with pytest.raises(TypeError, match="2 cotangents for 1"):
        grad(lambda x: anp.sum(bad(x)))(np.ones(2))
    wrong_shape = custom_vjp(lambda x: x * 2.0)
    wrong_shape.defvjp(lambda x: (x * 2.0, None), lambda res, g: (g[:1],))
    with pytest.raises(ValueError, match="shape"):
        grad(lambda x: anp.sum(wrong_shape(x)))(np.ones(2))


def test_engine_of_finds_the_engine_of_a_namespace():
    assert engine_of(np) is engine("numpy")
    assert engine_of(anp) is engine("numpy")
    assert engine_of(engine("jax").xp) is engine("jax")
    assert engine_of(object()) is None
    assert engine("numpy").custom_vjp is custom_vjp
    assert engine("jax").custom_vjp is jax.custom_vjp


def test_untraced_scan_inputs_stay_plain_inside_the_loop():
    """Data in xs is not boxed per step (no tape, no VJP for it); traced xs still are."""
    kinds = []

    def body(c, x):
        kinds.append((isinstance(x["data"], Box), isinstance(x["w"], Box)))
        return c + x["data"] * x["w"], None

    data, w = np.ones((3, 2)), np.full((3, 2), 2.0)
    g = grad(lambda w: anp.sum(scan(body, np.zeros(2), {"data": data, "w": w})[0]))(w)
    assert kinds == [(False, True)] * 3
    np.testing.assert_allclose(g, data)
