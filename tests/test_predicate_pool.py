"""Tests for ``ModelConfig.predicate_pool``: "flat" predicates read the flattened feature map
and start as exactly eq. 7's ``Linear(GAP(f))``; CAM (which needs GAP) refuses them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from minimanc import engine, inputs, models

CFG = models.ModelConfig(image_size=16, channels=(4, 8), n_predicates=5, n_states=4, hidden=8,
                         k_targets=6)
FLAT = replace(CFG, predicate_pool="flat")
WITH_PREDICATES = ("manc", "vagn_only", "dmp_only")


def _obs(rng, b=3):
    k = CFG.k_targets
    return {"bev": rng.random((b, 16, 16, 3)), "goal": rng.normal(size=(b, 3)) * 20,
            "lane_target": np.stack([4.0 * np.arange(1, k + 1), np.zeros(k)], -1)
            + rng.normal(0, 0.5, (b, k, 2)),
            "motion": np.stack([rng.uniform(0, 12, b), rng.normal(0, 0.1, b)], -1)}


@pytest.mark.parametrize("name", WITH_PREDICATES)
def test_flat_predicates_start_as_the_global_ones(name):
    eng = engine("numpy")
    rng = np.random.default_rng(3)
    obs = inputs.select(_obs(rng), models.get(name), "paper")
    pg = models.init(name, np.random.default_rng(0), CFG)
    pf = models.init(name, np.random.default_rng(0), FLAT)
    cells = CFG.feature_size ** 2
    assert pf["predicates"]["w"].shape == (cells * CFG.channels[-1], CFG.n_predicates)
    state = models.initial_state(name, 3, CFG)
    ug, _, ag = models.step(name, pg, obs, state, CFG, eng)
    uf, _, af = models.step(name, pf, obs, state, FLAT, eng)
    np.testing.assert_allclose(np.asarray(af["predicates"]), np.asarray(ag["predicates"]),
                               rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(np.asarray(uf), np.asarray(ug), rtol=1e-5, atol=1e-7)
    # a weight of one cell changes only what that cell sees: the map's location matters
    pf["predicates"]["w"] = np.asarray(pf["predicates"]["w"]).copy()
    pf["predicates"]["w"][: CFG.channels[-1]] += 1.0
    _, _, moved = models.step(name, pf, obs, state, FLAT, eng)
    assert not np.allclose(np.asarray(moved["predicates"]), np.asarray(ag["predicates"]))


def test_both_engines_agree_on_flat_predicates():
    rng = np.random.default_rng(4)
    obs = inputs.select(_obs(rng), models.get("manc"), "paper")
    params = models.init("manc", np.random.default_rng(1), FLAT)
    state = models.initial_state("manc", 3, FLAT)
    a, _, _ = models.step("manc", params, obs, state, FLAT, engine("numpy"))
    b, _, _ = models.step("manc", params, obs, state, FLAT, engine("jax"))
    np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-6, atol=1e-8)


def test_bad_pool_and_cam_refuse_and_the_default_keeps_the_config_dict():
    with pytest.raises(ValueError, match="predicate_pool must be 'global' or 'flat'"):
        models.ModelConfig(predicate_pool="max")
    assert "predicate_pool" not in models.ModelConfig().to_dict()
    assert models.ModelConfig(predicate_pool="flat").to_dict()["predicate_pool"] == "flat"
    params = models.init("manc", np.random.default_rng(0), FLAT)
    with pytest.raises(ValueError, match="needs the predicates of global average pooling"):
        models.saliency(params, {"bev": np.zeros((1, 16, 16, 3))}, np.full((1, 4), 0.25), FLAT)
