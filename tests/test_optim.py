"""Tests for minimanc.optim: Adam and SGD against hand-computed references, on both engines."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import optim, tree
from minimanc.engine import get_engine
from minimanc.tree import tree_flatten

get_engine("jax")  # float64 in JAX


def _tree(rng, dtype=np.float64):
    return {"a": rng.standard_normal((2, 3)).astype(dtype),
            "layers": [{"w": rng.standard_normal(4).astype(dtype)},
                       {"w": rng.standard_normal((1,)).astype(dtype)}]}


def _leaves(tree):
    return [np.asarray(v) for v in tree_flatten(tree)[0]]


def _adam_reference(p0, grads_seq, lr, b1, b2, eps):
    """Kingma & Ba (2015), Algorithm 1, one scalar at a time in plain Python floats."""
    out = []
    for k, p in enumerate(p0):
        theta, m, v = float(p), 0.0, 0.0
        for t, gs in enumerate(grads_seq, start=1):
            g = float(gs[k])
            m = b1 * m + (1 - b1) * g
            v = b2 * v + (1 - b2) * g * g
            m_hat = m / (1 - b1 ** t)
            v_hat = v / (1 - b2 ** t)
            theta = theta - lr * m_hat / (v_hat ** 0.5 + eps)
        out.append(theta)
    return np.array(out)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), steps=st.integers(1, 6),
       lr=st.sampled_from([1e-3, 0.01, 0.3]), b1=st.sampled_from([0.0, 0.5, 0.9]),
       b2=st.sampled_from([0.9, 0.999]), eps=st.sampled_from([1e-8, 1e-3]))
def test_adam_matches_hand_computed_reference(seed, steps, lr, b1, b2, eps):
    rng = np.random.default_rng(seed)
    params = _tree(rng)
    grads_seq = [_tree(rng) for _ in range(steps)]
    state = optim.adam_init(params)
    p = params
    for g in grads_seq:
        p, state = optim.adam_update(g, state, p, lr=lr, b1=b1, b2=b2, eps=eps)
    assert state["step"] == steps
    flat = np.concatenate([v.ravel() for v in _leaves(params)])
    gflat = [np.concatenate([v.ravel() for v in _leaves(g)]) for g in grads_seq]
    ref = _adam_reference(flat, gflat, lr, b1, b2, eps)
    got = np.concatenate([v.ravel() for v in _leaves(p)])
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-14)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), steps=st.integers(1, 6),
       momentum=st.sampled_from([0.0, 0.5, 0.9]), nesterov=st.booleans())
def test_sgd_matches_hand_computed_reference(seed, steps, momentum, nesterov):
    rng = np.random.default_rng(seed)
    params = _tree(rng)
    grads_seq = [_tree(rng) for _ in range(steps)]
    state = optim.sgd_init(params)
    p = params
    for g in grads_seq:
        p, state = optim.sgd_update(g, state, p, lr=0.1, momentum=momentum, nesterov=nesterov)
    flat = np.concatenate([v.ravel() for v in _leaves(params)])
    for k in range(flat.size):
        theta, vel = float(flat[k]), 0.0
        for g in grads_seq:
            gk = float(np.concatenate([v.ravel() for v in _leaves(g)])[k])
            vel = momentum * vel + gk
            theta -= 0.1 * ((gk + momentum * vel) if nesterov else vel)
        flat[k] = theta
    got = np.concatenate([v.ravel() for v in _leaves(p)])
    np.testing.assert_allclose(got, flat, rtol=1e-12, atol=1e-14)


def test_optimisers_minimise_a_quadratic():
    target = np.array([1.0, -2.0, 3.0])

    def grad(p):
        return {"x": 2 * (p["x"] - target)}

    for init, update, kw in ((optim.adam_init, optim.adam_update, {"lr": 0.1}),
                             (optim.sgd_init, optim.sgd_update, {"lr": 0.05})):
        p = {"x": np.zeros(3)}
        state = init(p)
        for _ in range(300):
            p, state = update(grad(p), state, p, **kw)
        np.testing.assert_allclose(p["x"], target, atol=1e-3)


def test_adam_on_jax_arrays_under_jit_equals_numpy():
    rng = np.random.default_rng(1)
    params, g1, g2 = _tree(rng), _tree(rng), _tree(rng)
    p_np, s_np = params, optim.adam_init(params)
    for g in (g1, g2):
        p_np, s_np = optim.adam_update(g, s_np, p_np, lr=0.01)

    step = jax.jit(lambda g, s, p: optim.adam_update(g, s, p, lr=0.01))
    to_jax = lambda t: tree.map(jnp.asarray, t)  # noqa: E731
    p_j = to_jax(params)
    s_j = optim.adam_init(p_j, xp=jnp)
    for g in (g1, g2):
        p_j, s_j = step(to_jax(g), s_j, p_j)
    assert int(s_j["step"]) == 2
    for a, b in zip(_leaves(p_np), _leaves(p_j)):
        np.testing.assert_allclose(a, b, rtol=1e-12)


@pytest.mark.parametrize("which", ["adam", "sgd"])
def test_float32_parameters_stay_float32(which):
    rng = np.random.default_rng(2)
    params, g = _tree(rng, np.float32), _tree(rng, np.float32)
    init, update = ((optim.adam_init, optim.adam_update) if which == "adam"
                    else (optim.sgd_init, optim.sgd_update))
    state = init(params)
    state = {**state, "step": np.int64(3)} if which == "adam" else state  # e.g. from a checkpoint
    p, state = update(g, state, params)
    assert all(v.dtype == np.float32 for v in _leaves(p))
    assert all(v.dtype == np.float32 for v in _leaves({k: v for k, v in state.items()
                                                        if k != "step"}))


def test_matches_optax_when_installed():
    optax = pytest.importorskip("optax")
    rng = np.random.default_rng(3)
    params, grads = _tree(rng), [_tree(rng) for _ in range(3)]
    for ours_init, ours_update, tx in (
        (optim.adam_init, optim.adam_update, optax.adam(0.01)),
        (optim.sgd_init, lambda g, s, p: optim.sgd_update(g, s, p, lr=0.01, momentum=0.9),
         optax.sgd(0.01, momentum=0.9)),
    ):
        p, s = params, ours_init(params)
        po, so = params, tx.init(params)
        for g in grads:
            p, s = ours_update(g, s, p) if ours_update is not optim.adam_update else \
                optim.adam_update(g, s, p, lr=0.01)
            upd, so = tx.update(g, so, po)
            po = optax.apply_updates(po, upd)
        for a, b in zip(_leaves(p), _leaves(po)):
            np.testing.assert_allclose(a, b, rtol=1e-6)


@pytest.mark.parametrize(
    "kwargs,match",
    [({"lr": 0.0}, "lr"), ({"lr": -1.0}, "lr"), ({"b1": 1.0}, "b1"), ({"b2": -0.1}, "b2"),
     ({"eps": 0.0}, "eps")],
)
def test_adam_bad_hyperparameters(kwargs, match):
    p = {"w": np.ones(2)}
    with pytest.raises(ValueError, match=match):
        optim.adam_update(p, optim.adam_init(p), p, **kwargs)


def test_bad_state_raises():
    p = {"w": np.ones(2)}
    with pytest.raises(ValueError, match="state"):
        optim.adam_update(p, p, p)  # arguments in the wrong order
    with pytest.raises(ValueError, match="state"):
        optim.sgd_update(p, optim.adam_init(p), p)
    with pytest.raises(ValueError, match="momentum"):
        optim.sgd_update(p, optim.sgd_init(p), p, momentum=1.0)
    with pytest.raises(ValueError, match="step"):
        optim.adam_update(p, {**optim.adam_init(p), "step": 1.5}, p)


def test_adam_takes_lr_as_a_scalar_array_and_rejects_bad_ones():
    p = {"w": np.array([1.0, -2.0])}
    g = {"w": np.array([0.5, 0.25])}
    a, _ = optim.adam_update(g, optim.adam_init(p), p, lr=0.1)
    b, _ = optim.adam_update(g, optim.adam_init(p), p, lr=np.asarray(0.1))
    np.testing.assert_allclose(a["w"], b["w"], rtol=0, atol=0)
    for bad in (np.asarray(-0.1), np.asarray([0.1, 0.2]), "0.1", None, True):
        with pytest.raises(ValueError, match="lr"):
            optim.adam_update(g, optim.adam_init(p), p, lr=bad)
