"""Tests for minimanc.dmp.flow (chapter 3): one DMP step (all its sub-steps) as one function
with a hand-written VJP, built by each engine's custom_vjp.

Oracles: central differences on the NumPy engine, JAX's own reverse mode through the
plain sub-steps (:func:`dmp.flow.flow`), and the plain sub-steps' values.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import dmp, engine
from minimanc.autodiff import Box
from minimanc.autodiff.check import numerical_grad
from minimanc.dmp.flow import flow, flow_for, force_times

NP, JAX = engine("numpy"), engine("jax")

# the argument shapes of a step: y, dy, goal, alpha, beta (all broadcast to one batch)
SHAPES = [
    ((3, 2), (3, 2), (3, 2), (3, 1), (3, 1)),       # the model's: per-sample gains
    ((2,), (4, 2), (2,), (), ()),                   # one start, many velocities, scalar gains
    ((1, 1), (2, 1), (2, 1), (2, 1), (1, 1)),       # yaw-like, gains broadcast over the batch
    ((4, 3), (4, 3), (4, 3), (4, 3), (4, 3)),       # MANC's: one shape (the stacked backward)
]


def _args(rng, shapes, with_forces, method, n):
    y, dy, g, a, b = (rng.normal(size=s) for s in shapes)
    a = 2.0 + 6.0 * rng.random(shapes[3])  # α in [2, 8], β in [0.5, 2]: a stable step
    b = 0.5 + 1.5 * rng.random(shapes[4])
    forces = None
    if with_forces:
        out = np.broadcast_shapes(*shapes)
        forces = [rng.normal(size=out) for _ in force_times(0.1, method, n)]
    return [np.asarray(v, dtype=float) for v in (y, dy, g, a, b)], forces


def _loss(f, xp, weights):
    def loss(y, dy, g, a, b, forces, dt, method, n):
        y1, v1, ddy = f(y, dy, g, a, b, forces, dt, method, n)
        return (xp.sum(y1 * weights[0]) + xp.sum(v1 * weights[1])
                + xp.sum(ddy * weights[2]))
    return loss


step_cases = st.tuples(
    st.sampled_from(dmp.METHODS),
    st.integers(1, 12),
    st.floats(0.05, 0.5),
    st.sampled_from(range(len(SHAPES))),
    st.booleans(),
    st.integers(0, 2**31 - 1),
)


@settings(max_examples=30, deadline=None)
@given(step_cases)
def test_fused_step_gradients_equal_central_differences(case):
    method, n, dt, k, with_forces, seed = case
    rng = np.random.default_rng(seed)
    (y, dy, g, a, b), forces = _args(rng, SHAPES[k], with_forces, method, n)
    out = np.broadcast_shapes(*SHAPES[k])
    weights = [rng.normal(size=out) for _ in range(3)]
    loss = _loss(flow_for(NP), NP.xp, weights)
    arrays = [y, dy, g, a, b] + ([] if forces is None else forces)

    def f(*vals):
        fs = None if forces is None else list(vals[5:])
        return loss(*vals[:5], fs, dt, method, n)

    for i in range(len(arrays)):
        got = NP.grad(f, argnums=i)(*arrays)
        want = numerical_grad(lambda *v: float(f(*v)), arrays, i, 1e-6)
        want = want[0] if isinstance(want, list) else want
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6,
                                   err_msg=f"argument {i}, method {method}")


@settings(max_examples=30, deadline=None)
@given(step_cases)
def test_fused_step_equals_jax_autodiff_of_the_plain_substeps(case):
    method, n, dt, k, with_forces, seed = case
    rng = np.random.default_rng(seed)
    (y, dy, g, a, b), forces = _args(rng, SHAPES[k], with_forces, method, n)
    out = np.broadcast_shapes(*SHAPES[k])
    weights = [rng.normal(size=out) for _ in range(3)]
    nums = tuple(range(6 if forces is not None else 5))
    ours = NP.grad(_loss(flow_for(NP), NP.xp, weights), argnums=nums)(
        y, dy, g, a, b, forces, dt, method, n)
    theirs = jax.grad(_loss(flow, JAX.xp, weights), argnums=nums)(
        y, dy, g, a, b, forces, dt, method, n)
    jax_custom = jax.jit(jax.grad(_loss(flow_for(JAX), JAX.xp, weights), argnums=nums),
                         static_argnums=(6, 7, 8))(y, dy, g, a, b, forces, dt, method, n)
    for i, (u, v, w) in enumerate(zip(ours, theirs, jax_custom)):
        for uu, vv, ww in zip(*(x if isinstance(x, list) else [x] for x in (u, v, w))):
            np.testing.assert_allclose(uu, vv, rtol=1e-6, atol=1e-9, err_msg=f"argument {i}")
            np.testing.assert_allclose(ww, vv, rtol=1e-6, atol=1e-9, err_msg=f"argument {i}")


@pytest.mark.parametrize("method", dmp.METHODS)
def test_fused_step_values_equal_the_plain_substeps(method):
    rng = np.random.default_rng(0)
    (y, dy, g, a, b), forces = _args(rng, SHAPES[0], True, method, 5)
    plain = flow(y, dy, g, a, b, forces, 0.5, method, 5)
    for eng in (NP, JAX):
        fused = flow_for(eng)(y, dy, g, a, b, forces, 0.5, method, 5)
        for u, v in zip(fused, plain):
            np.testing.assert_allclose(np.asarray(u), v, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("with_forces", [False, True])
@pytest.mark.parametrize("method", dmp.METHODS)
@pytest.mark.parametrize("k", range(len(SHAPES)))
def test_traced_forward_values_equal_the_plain_substeps_bit_for_bit(method, with_forces, k):
    rng = np.random.default_rng(k)
    (y, dy, g, a, b), forces = _args(rng, SHAPES[k], with_forces, method, 7)
    seen = []

    def loss(y):
        out = flow_for(NP)(y, dy, g, a, b, forces, 0.3, method, 7)
        seen.append([o.value for o in out])
        return NP.xp.sum(out[0]) + NP.xp.sum(out[1]) + NP.xp.sum(out[2])

    NP.grad(loss)(y)
    for u, v in zip(seen[0], flow(y, dy, g, a, b, forces, 0.3, method, 7)):
        np.testing.assert_array_equal(u, v)


def test_dmp_step_is_one_tape_node_per_call_on_numpy():
    """The speed-up itself: a 10-sub-step step is one node (plus its selected outputs)."""
    seen = []

    def loss(a):
        y1, _, _ = dmp.step(np.zeros((2, 2)), np.ones((2, 2)), np.ones((2, 2)), a, 1.0,
                            xp=NP.xp)
        seen.append(y1)
        return NP.xp.sum(y1)

    NP.grad(loss)(np.full((2, 1), 5.0))
    y1 = seen[0]
    assert isinstance(y1, Box) and y1.primitive_name == "select_output"
    (_, node), = y1.parents
    assert node.primitive_name == "_flow_plain"
    assert [p.primitive_name for _, p in node.parents] == [None]  # alpha, a leaf


@pytest.mark.parametrize("method", dmp.METHODS)
def test_rollout_with_forcing_gradients_equal_jax(method):
    """The forcing-term variant (eq. 1) through rollout: weights and goal, both engines."""
    forcing = dmp.fit_forcing_weights(np.sin(np.linspace(0, 2, 11))[:, None] + 1.0, 0.2)

    def loss(goal, alpha, xp):
        r = dmp.rollout(xp.zeros(1), xp.zeros(1), goal, alpha, 1.0, 0.2, 10, method=method,
                        substeps=3, xp=xp, forcing=forcing)
        return xp.sum(r.y ** 2) + xp.sum(r.ddy)

    goal, alpha = np.array([1.5]), np.array([4.0])
    ours = NP.grad(lambda g, a: loss(g, a, NP.xp), argnums=(0, 1))(goal, alpha)
    theirs = JAX.grad(lambda g, a: loss(g, a, JAX.xp), argnums=(0, 1))(goal, alpha)
    for u, v in zip(ours, theirs):
        np.testing.assert_allclose(u, np.asarray(v), rtol=1e-9, atol=1e-12)
    want = numerical_grad(lambda g: float(loss(g, alpha, np)), [goal], 0, 1e-6)
    np.testing.assert_allclose(ours[0], want[0] if isinstance(want, list) else want,
                               rtol=1e-6, atol=1e-8)


def test_traced_dt_takes_the_plain_substeps():
    """A traced dt cannot be a static argument: the step falls back to op-by-op tracing."""
    g = NP.grad(lambda dt: NP.xp.sum(dmp.step(np.zeros(1), np.ones(1), 1.0, 4.0, 1.0, dt,
                                              xp=NP.xp)[0]))(0.5)
    gj = jax.grad(lambda dt: dmp.step(np.zeros(1), np.ones(1), 1.0, 4.0, 1.0, dt,
                                      xp=JAX.xp)[0].sum())(0.5)
    np.testing.assert_allclose(g, float(gj), rtol=1e-9)


def test_forward_mode_on_jax_needs_the_plain_substeps():
    """jax.custom_vjp has no forward mode: jvp goes through dmp.flow.flow instead."""
    args = (np.zeros(1), np.ones(1), np.ones(1), np.array([4.0]), np.array([1.0]), None)
    _, t = jax.jvp(lambda a: flow(*args[:3], a, args[4], None, 0.5, "semi_implicit", 10)[0],
                   (args[3],), (np.ones(1),))
    g = NP.grad(lambda a: NP.xp.sum(flow_for(NP)(*args[:3], a, args[4], None, 0.5,
                                                 "semi_implicit", 10)[0]))(args[3])
    np.testing.assert_allclose(np.asarray(t), g, rtol=1e-9)
