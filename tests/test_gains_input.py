"""Tests for what MANC's gains FC of eq. 11 reads (``ModelConfig.gains_input``): "q", the
paper's ``FC(q)``, unchanged; "q_p", ``FC(q ⊕ p)``: shapes, the identity with ``FC(q)`` when
the predicates' weights are zero, the gradient on both engines and against central
differences, and the refusal of a name that is not one."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from minimanc import models, tree

CFG = models.ModelConfig(input_shape=(32, 32, 3), channels=(4, 8), n_predicates=5, n_states=4,
                         hidden=8, k_targets=6, predicate_readout="flatten")
QP = replace(CFG, gains_input="q_p")
B = 3


def _obs(rng: np.random.Generator, lead: tuple = (B,)) -> dict:
    straight = np.stack([4.0 * np.arange(1, CFG.k_targets + 1), np.zeros(CFG.k_targets)], -1)
    return {"bev": rng.random(lead + CFG.bev_shape),
            "lane_target": straight + rng.normal(0, 0.5, lead + (CFG.k_targets, 2)),
            "motion": np.stack([rng.uniform(0, 12, lead), rng.normal(0, 0.1, lead)], -1)}


def test_the_paper_reads_q_and_q_p_widens_only_the_gains_layer():
    assert models.ModelConfig().gains_input == "q" and models.GAINS_INPUTS == ("q", "q_p")
    q = models.init("manc", np.random.default_rng(0), CFG)
    qp = models.init("manc", np.random.default_rng(0), QP)
    assert q["gains"]["w"].shape == (4, 4) and qp["gains"]["w"].shape == (4 + 5, 4)
    for k in q:  # the same draws before the gains layer, and the same bias
        if k != "gains":
            for a, b in zip(tree.leaves(q[k]), tree.leaves(qp[k])):
                assert np.array_equal(a, b)
    assert np.array_equal(q["gains"]["b"], qp["gains"]["b"])
    # the models without eq. 11's FC(q) do not change
    counts = models.param_counts(CFG), models.param_counts(QP)
    for name in ("dmp_only", "vagn_only", "cnn"):
        assert counts[0][name] == counts[1][name]
    assert counts[1]["manc"] == counts[0]["manc"] + 5 * 4


def test_q_p_with_zero_predicate_weights_is_fc_of_q(eng_np):
    rng = np.random.default_rng(1)
    q = models.init("manc", rng, CFG)
    qp = {**q, "gains": {"w": np.concatenate([q["gains"]["w"], np.zeros((5, 4))]),
                         "b": q["gains"]["b"]}}
    obs = _obs(np.random.default_rng(2), lead=(2, B))
    outs = [models.sequence("manc", p, obs, models.initial_state("manc", B, c), c, eng_np)[0]
            for p, c in ((q, CFG), (qp, QP))]
    np.testing.assert_allclose(np.asarray(outs[1]), np.asarray(outs[0]), rtol=0, atol=1e-12)
    # and with weights on the predicates the controls move
    qp["gains"]["w"][4:] = rng.normal(0, 1.0, (5, 4))
    moved = models.sequence("manc", qp, obs, models.initial_state("manc", B, QP), QP, eng_np)[0]
    assert np.abs(np.asarray(moved) - np.asarray(outs[0])).max() > 1e-3


def test_q_p_gradient_on_both_engines_and_by_central_differences(eng_np, eng_jax):
    rng = np.random.default_rng(3)
    params = models.init("manc", rng, QP)
    params["gains"]["w"] = rng.normal(0, 0.5, params["gains"]["w"].shape)
    obs = _obs(rng, lead=(2, B))
    target = rng.normal(size=(2, B, 2))

    def loss(p, eng):
        state = models.initial_state("manc", B, QP, xp=eng.xp, dtype=np.float64)
        out, _ = models.sequence("manc", p, obs, state, QP, eng)
        return eng.xp.mean((out - target) ** 2)

    g_np = np.asarray(eng_np.grad(lambda p: loss(p, eng_np))(params)["gains"]["w"])
    g_jax = np.asarray(eng_jax.grad(lambda p: loss(p, eng_jax))(params)["gains"]["w"])
    assert np.abs(g_np[4:]).max() > 1e-8  # the predicates' rows learn
    np.testing.assert_allclose(g_np, g_jax, rtol=1e-6, atol=1e-10)
    w = params["gains"]["w"]
    for idx in [(0, 1), (5, 0), (8, 3)]:
        eps = 1e-6
        plus, minus = w.copy(), w.copy()
        plus[idx] += eps
        minus[idx] -= eps
        num = (float(loss({**params, "gains": {**params["gains"], "w": plus}}, eng_np))
               - float(loss({**params, "gains": {**params["gains"], "w": minus}}, eng_np))
               ) / (2 * eps)
        np.testing.assert_allclose(g_np[idx], num, rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("bad", ["p", "q+p", "", None])
def test_a_gains_input_not_named_is_refused(bad):
    with pytest.raises(ValueError, match=r"gains_input must be one of \('q', 'q_p'\)"):
        models.ModelConfig(gains_input=bad)
