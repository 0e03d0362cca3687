"""Tests for minimanc.vagn.fused (chapter 5): one vAGN update (eqs. 8–9) as one tape node
with a hand-written VJP, used by :func:`minimanc.vagn.step` on the NumPy engine.

Oracles: JAX's own reverse mode through the plain jnp code of :func:`vagn.step` (float64),
central differences, the plain NumPy values (to rounding), and the tape's node count.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import engine, vagn
from minimanc.autodiff import Box, grad, value_and_grad
from minimanc.autodiff.check import numerical_grad
from minimanc.vagn.fused import fused_step, step_plain

NP, JAX = engine("numpy"), engine("jax")

# (q batch, p batch, M, N): the model's (same batch), broadcast either way, unbatched
SHAPES = [((5,), (5,), 3, 4), ((), (4,), 2, 3), ((3,), (), 3, 2), ((2, 1), (1, 3), 2, 5),
          ((), (), 1, 1)]


def _args(seed: int, case: int, relu_ties: bool = False):
    qb, pb, M, N = SHAPES[case]
    rng = np.random.default_rng(seed)
    q = rng.dirichlet(np.ones(N), size=qb) if qb else rng.dirichlet(np.ones(N))
    p = rng.random(pb + (M,))
    W = rng.normal(size=(M, N, N))
    if relu_ties:  # some entries of W^p exactly zero: the ReLU's tie (weight 1/2)
        W[:, 0, :] = 0.0
    return q, p, W


def _weights(q, p, W):
    shape = np.broadcast_shapes(q.shape[:-1], p.shape[:-1]) + (W.shape[1],)
    return np.linspace(-1.0, 2.0, int(np.prod(shape))).reshape(shape)


def _loss(xp, w):
    def loss(q, p, W):
        return xp.sum(vagn.step(q, p, W, xp=xp) * w)
    return loss


cases = st.tuples(st.integers(0, 2**31 - 1), st.sampled_from(range(len(SHAPES))),
                  st.booleans())


@settings(max_examples=40, deadline=None)
@given(cases)
def test_fused_vjp_equals_jax_reverse_mode_of_the_plain_code(case):
    seed, shape, ties = case
    q, p, W = _args(seed, shape, ties)
    w = _weights(q, p, W)
    ours = NP.grad(_loss(NP.xp, w), argnums=(0, 1, 2))(q, p, W)
    ref = jax.grad(_loss(jnp, jnp.asarray(w)), argnums=(0, 1, 2))(
        jnp.asarray(q), jnp.asarray(p), jnp.asarray(W))
    for a, b, x in zip(ours, ref, (q, p, W)):
        assert a.shape == x.shape and a.dtype == np.float64
        np.testing.assert_allclose(a, np.asarray(b), rtol=1e-10, atol=1e-12)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**31 - 1), st.sampled_from(range(len(SHAPES))))
def test_fused_vjp_equals_central_differences(seed, shape):
    q, p, W = _args(seed, shape)
    w = _weights(q, p, W)
    ours = NP.grad(_loss(NP.xp, w), argnums=(0, 1, 2))(q, p, W)
    # the plain code without checks: a moved q need not sum to one
    def plain(*args):
        return float(np.sum(step_plain(*args) * w))
    for k in range(3):
        want = numerical_grad(plain, [q, p, W], k, 1e-6)[0]
        np.testing.assert_allclose(ours[k], want, rtol=1e-6, atol=1e-8)


def test_fused_values_equal_the_plain_numpy_code_to_rounding():
    for dtype in (np.float32, np.float64):
        q, p, W = (a.astype(dtype) for a in _args(3, 0))
        seen: dict = {}

        def f(q, p, W, seen=seen):
            out = vagn.step(q, p, W, xp=NP.xp)
            seen["out"] = out.value
            return NP.xp.sum(out)

        value_and_grad(f, argnums=(0, 1, 2))(q, p, W)
        assert seen["out"].dtype == dtype
        tol = 8 * np.finfo(dtype).eps  # a few roundings: the sums are taken in another order
        np.testing.assert_allclose(seen["out"], vagn.step(q, p, W), rtol=tol, atol=tol)
        np.testing.assert_allclose(step_plain(q, p, W), vagn.step(q, p, W), rtol=tol, atol=tol)


def test_float32_cotangents_stay_float32_and_match_float64():
    q, p, W = _args(7, 0)
    w = _weights(q, p, W)
    g64 = NP.grad(_loss(NP.xp, w), argnums=(0, 1, 2))(q, p, W)
    g32 = NP.grad(_loss(NP.xp, w.astype(np.float32)), argnums=(0, 1, 2))(
        *(a.astype(np.float32) for a in (q, p, W)))
    for a, b in zip(g32, g64):
        assert a.dtype == np.float32
        np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-5)


def test_step_is_one_tape_node_on_numpy():
    q, p, W = _args(1, 0)
    nodes = {}

    def f(q, p, W):
        out = vagn.step(q, p, W, xp=NP.xp)
        nodes["prim"] = out.primitive_name
        nodes["parents"] = [b.primitive_name for _, b in out.parents]
        return NP.xp.sum(out)

    grad(f, argnums=(0, 1, 2))(q, p, W)
    assert nodes["prim"] == "step_plain"
    assert nodes["parents"] == [None, None, None]  # straight from the three leaves


def test_only_traced_arguments_get_cotangents():
    q, p, W = _args(2, 0)
    w = _weights(q, p, W)
    g_W = NP.grad(lambda W: _loss(NP.xp, w)(q, p, W))(W)
    ref = jax.grad(lambda W: _loss(jnp, jnp.asarray(w))(jnp.asarray(q), jnp.asarray(p), W))(
        jnp.asarray(W))
    np.testing.assert_allclose(g_W, np.asarray(ref), rtol=1e-10, atol=1e-12)
    assert not isinstance(fused_step(q, p, W), Box)  # nothing traced: plain NumPy


def test_traced_step_keeps_the_shape_checks():
    q, p, W = _args(2, 0)
    with pytest.raises(ValueError, match="p must have shape"):
        NP.grad(lambda p: NP.xp.sum(vagn.step(q, p, W, xp=NP.xp)))(p[:, :2])
    with pytest.raises(ValueError, match="W must have shape"):
        NP.grad(lambda W: NP.xp.sum(vagn.step(q, p, W, xp=NP.xp)))(W[:, :, :2])
