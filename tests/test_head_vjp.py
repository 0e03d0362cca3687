"""Tests for minimanc.models.head_vjp (chapter 8): the DMP head (eqs. 10–11) as one tape node
with a hand-written VJP, used by :func:`minimanc.models.dmp_head` on the NumPy engine.

Oracles: the same head traced operation by operation (:func:`head_ops`, the engine's own
reverse mode, ties included), JAX's reverse mode through the plain jnp code (float64, away
from ties: JAX's ``|u|′`` at 0 is 1, the engine's ``sign(0) = 0``), central differences,
the plain NumPy values (bit for bit) and the tape's node count.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import engine, models
from minimanc.autodiff import Box, grad
from minimanc.autodiff.check import numerical_grad
from minimanc.models.dmp_head import dmp_head, head_ops
from minimanc.models.head_vjp import fused_head, head_plain

NP = engine("numpy")
CFG = models.ModelConfig()
CRIT = models.ModelConfig(critically_damped=True)


def _args(seed: int, ties: bool = False, batch: int = 6, dtype=np.float64):
    """Logits, a lane target curving left or right, and motion. ``ties``: standing cars
    (``v₀ = 0``: both look-ahead distances on their lower bound, ``|u| = 0`` in the hat
    weights) and a clipped yaw goal."""
    rng = np.random.default_rng(seed)
    K = CFG.k_targets
    logits = rng.normal(scale=1.5, size=(batch, 4))
    s = 4.0 * np.arange(1, K + 1)
    bend = rng.normal(scale=0.01, size=(batch, 1))
    lateral = rng.normal(scale=0.5, size=(batch, 1)) + bend * s**2
    lt = np.stack([np.broadcast_to(s, (batch, K)), lateral], axis=-1)
    motion = np.stack([rng.uniform(0.5, 15.0, batch), rng.normal(scale=0.2, size=batch)], -1)
    if ties:
        motion[: batch // 2, 0] = 0.0
        lt[-1, :, 1] = 40.0 * s / s[-1]  # a sharp bend: the yaw goal is clipped at pi/2
    return tuple(a.astype(dtype) for a in (logits, lt, motion))


def _weights(batch: int, seed: int = 0) -> list:
    rng = np.random.default_rng(seed)
    return [rng.normal(size=shape) for shape in ((batch, 2), (batch, 2), (batch, 2),
                                                 (batch, 2), (batch,))]


def _loss(head, xp, w, cfg=CFG):
    """A weighted sum of every output: controls and all the aux values."""
    def loss(logits, lt, motion):
        controls, aux = head(logits, lt, motion, cfg, xp=xp)
        parts = (controls, aux["alpha"], aux["beta"] ** 2, aux["g"], aux["psi_g"])
        total = 0.0
        for part, wk in zip(parts, w):
            total = total + xp.sum(part * wk)
        return total
    return loss


cases = st.tuples(st.integers(0, 2**31 - 1), st.booleans(), st.booleans())


@settings(max_examples=40, deadline=None)
@given(cases)
def test_fused_vjp_equals_the_tape_through_the_plain_code(case):
    seed, ties, crit = case
    cfg = CRIT if crit else CFG
    args = _args(seed, ties)
    w = _weights(args[0].shape[0], seed)
    ours = NP.grad(_loss(dmp_head, NP.xp, w, cfg), argnums=(0, 1, 2))(*args)
    ref = NP.grad(_loss(head_ops, NP.xp, w, cfg), argnums=(0, 1, 2))(*args)
    for a, b, x in zip(ours, ref, args):
        assert a.shape == x.shape and a.dtype == np.float64
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    if crit:
        assert np.all(ours[0][:, 1::2] == 0.0)  # the beta logits are ignored


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.booleans())
def test_fused_vjp_equals_jax_reverse_mode_of_the_plain_code(seed, crit):
    cfg = CRIT if crit else CFG
    args = _args(seed)
    w = _weights(args[0].shape[0], seed)
    ours = NP.grad(_loss(dmp_head, NP.xp, w, cfg), argnums=(0, 1, 2))(*args)
    ref = jax.grad(_loss(head_ops, jnp, [jnp.asarray(v) for v in w], cfg),
                   argnums=(0, 1, 2))(*(jnp.asarray(a) for a in args))
    for a, b in zip(ours, ref):
        np.testing.assert_allclose(a, np.asarray(b), rtol=1e-10, atol=1e-12)


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_fused_vjp_equals_central_differences(seed):
    args = _args(seed, batch=3)
    w = _weights(3, seed)

    def plain(*a):
        controls, alpha, beta, g, psi_g = head_plain(*a, CFG)
        return float(sum(np.sum(p * wk) for p, wk in zip((controls, alpha, beta**2, g, psi_g),
                                                        w)))

    ours = NP.grad(_loss(dmp_head, NP.xp, w), argnums=(0, 1, 2))(*args)
    for k in range(3):
        want = numerical_grad(plain, list(args), k, 1e-6)[0]
        np.testing.assert_allclose(ours[k], want, rtol=1e-6, atol=1e-7)


def test_fused_values_equal_the_plain_code_bit_for_bit():
    for dtype in (np.float32, np.float64):
        for cfg in (CFG, CRIT):
            args = _args(4, ties=True, dtype=dtype)
            seen: dict = {}

            def f(logits, lt, motion, seen=seen, cfg=cfg):
                controls, aux = dmp_head(logits, lt, motion, cfg, xp=NP.xp)
                seen.update(controls=controls.value, **{k: v.value for k, v in aux.items()})
                return NP.xp.sum(controls)

            grad(f, argnums=(0, 2))(*args)
            controls, aux = head_ops(*args, cfg)
            for key, want in dict(controls=controls, **aux).items():
                assert seen[key].dtype == dtype
                np.testing.assert_array_equal(seen[key], want, err_msg=key)


def test_float32_cotangents_stay_float32_and_match_float64():
    args = _args(7)
    w = _weights(args[0].shape[0])
    g64 = NP.grad(_loss(dmp_head, NP.xp, w), argnums=(0, 1, 2))(*args)
    g32 = NP.grad(_loss(dmp_head, NP.xp, [v.astype(np.float32) for v in w]),
                  argnums=(0, 1, 2))(*(a.astype(np.float32) for a in args))
    for a, b in zip(g32, g64):
        assert a.dtype == np.float32
        np.testing.assert_allclose(a, b, rtol=2e-4, atol=2e-4)


def test_head_is_one_tape_node_on_numpy_and_plain_elsewhere():
    args = _args(1)
    nodes = {}

    def f(logits, motion):
        controls, aux = dmp_head(logits, args[1], motion, CFG, xp=NP.xp)
        nodes["controls"] = controls.parents[0][1].primitive_name
        nodes["alpha"] = aux["alpha"].parents[0][1].primitive_name
        return NP.xp.sum(controls)

    grad(f, argnums=(0, 1))(args[0], args[2])
    assert nodes == {"controls": "head_plain", "alpha": "head_plain"}
    assert not isinstance(fused_head(*args, CFG)[0], Box)  # nothing traced: plain NumPy


def test_quaternion_orientation_keeps_the_plain_code_and_agrees_with_yaw():
    cfg_q = models.ModelConfig(orientation="quaternion")
    args = _args(5)
    w = _weights(args[0].shape[0])
    yaw = NP.grad(_loss(dmp_head, NP.xp, w), argnums=(0, 2))(*args)
    quat = NP.grad(_loss(dmp_head, NP.xp, w, cfg_q), argnums=(0, 2))(*args)
    for a, b in zip(yaw, quat):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)


def test_a_broadcast_row_of_logits_gets_its_summed_cotangent():
    logits, lt, motion = _args(6)
    one = logits[:1]
    w = _weights(logits.shape[0])
    ours = NP.grad(_loss(dmp_head, NP.xp, w), argnums=0)(one, lt, motion)
    ref = NP.grad(_loss(head_ops, NP.xp, w), argnums=0)(one, lt, motion)
    assert ours.shape == (1, 4)
    np.testing.assert_allclose(ours, ref, rtol=1e-12, atol=1e-12)
