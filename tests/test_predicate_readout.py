"""Tests for minimanc.models.readout (chapter 8): eq. 7's read-out, "gap" (the paper's
``Linear(GAP(f))``, unchanged) or "flatten" (``Linear(flatten(f))``, which keeps where a
feature fires): shapes, the reference numbers of "gap", gradients on both engines, the CAM
identity, position, checkpoints and a short training run."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from minimanc import cam, engine, layers, models, train, tree, world
from minimanc.models import readout, zoo

CFG = models.ModelConfig(input_shape=(32, 32, 3), channels=(4, 8), n_predicates=5, n_states=4,
                         hidden=8, k_targets=6)
FLAT = replace(CFG, predicate_readout="flatten")
B = 3
EQ7_MODELS = ("manc", "vagn_only", "dmp_only")


def _obs(rng: np.random.Generator, cfg: models.ModelConfig = CFG, lead: tuple = (B,)) -> dict:
    straight = np.stack([4.0 * np.arange(1, cfg.k_targets + 1), np.zeros(cfg.k_targets)], -1)
    return {"bev": rng.random(lead + cfg.bev_shape),
            "goal": rng.normal(size=lead + (3,)) * 20,
            "lane_target": straight + rng.normal(0, 0.5, lead + (cfg.k_targets, 2)),
            "motion": np.stack([rng.uniform(0, 12, lead), rng.normal(0, 0.1, lead)], -1)}


def _trained_like(params: dict, seed: int) -> dict:
    """``params`` with flatten weights that differ from position to position (as after
    training; at initialisation every position has the same weights)."""
    w = np.asarray(params["predicates"]["w"])
    rng = np.random.default_rng(seed)
    return {**params, "predicates": {"w": rng.normal(0.0, 0.2, w.shape),
                                     "b": np.asarray(params["predicates"]["b"])}}


@pytest.mark.parametrize("name", EQ7_MODELS)
def test_parameter_shapes(name):
    h, w = CFG.feature_shape
    assert (h, w) == (8, 8)
    gap = models.init(name, np.random.default_rng(0), CFG)["predicates"]
    flat = models.init(name, np.random.default_rng(0), FLAT)["predicates"]
    assert gap["w"].shape == (8, 5) and gap["b"].shape == (5,)
    assert flat["w"].shape == (zoo.flat_size(FLAT), 5) == (h * w * 8, 5)
    assert flat["b"].shape == (5,)


def test_gap_is_the_reference_eq_7(eng_np):
    """"gap" is the default and computes what eq. 7 computed before the option, bit for bit:
    the same draw and ``σ(mean_h(mean_w(f)) @ w + b)`` in the forward and the saliency."""
    assert models.ModelConfig().predicate_readout == "gap"
    rng = np.random.default_rng(0)
    c_in = CFG.bev_shape[2]
    for c in CFG.channels:  # the backbone's draws come first
        layers.init_conv(rng, 3, 3, c_in, c)
        c_in = c
    want = layers.init_dense(rng, CFG.channels[-1], CFG.n_predicates)
    params = models.init("manc", np.random.default_rng(0), CFG)
    assert np.array_equal(params["predicates"]["w"], want["w"])
    assert np.array_equal(params["predicates"]["b"], want["b"])

    obs = _obs(np.random.default_rng(1))
    _, _, aux = models.step("manc", params, obs, models.initial_state("manc", B, CFG), CFG,
                            eng_np)
    xp = eng_np.xp
    f = aux["features"]
    z = xp.matmul(xp.mean(xp.mean(f, axis=1), axis=1), params["predicates"]["w"]) \
        + params["predicates"]["b"]
    assert np.array_equal(np.asarray(aux["predicates"]), np.asarray(eng_np.nn.sigmoid(z)))

    q_prev = np.full((B, CFG.n_states), 1.0 / CFG.n_states)
    ex = models.saliency(params, obs, q_prev, CFG, upsample_to_input=False)
    f64 = np.asarray(f, dtype=np.float64)
    w = params["predicates"]["w"]
    assert np.array_equal(ex["logits"], f64.mean(axis=(1, 2)) @ w + params["predicates"]["b"])
    assert np.array_equal(ex["cams"], cam.class_activation_maps(f64, w))


@pytest.mark.parametrize("name", EQ7_MODELS)
def test_flatten_starts_as_eq_7(name, eng_np):
    """Same draws: "flatten" starts as the same function as "gap", and the layers after
    the predicates are identical."""
    gap = models.init(name, np.random.default_rng(3), CFG)
    flat = models.init(name, np.random.default_rng(3), FLAT)
    for k in gap:
        if k != "predicates":
            for a, b in zip(tree.leaves(gap[k]),
                            tree.leaves(flat[k])):
                assert np.array_equal(a, b)
    obs = _obs(np.random.default_rng(4))
    outs = [models.step(name, p, obs, models.initial_state(name, B, c), c, eng_np)
            for p, c in ((gap, CFG), (flat, FLAT))]
    np.testing.assert_allclose(outs[1][2]["predicates"], outs[0][2]["predicates"],
                               rtol=0, atol=1e-13)
    np.testing.assert_allclose(outs[1][0], outs[0][0], rtol=0, atol=1e-10)


@pytest.mark.parametrize("name", ["manc", "vagn_only"])
def test_flatten_is_the_same_on_both_engines(name, eng_np, eng_jax):
    """Forward and gradient of a flatten model agree between our autodiff and JAX (float64)."""
    rng = np.random.default_rng(5)
    params = _trained_like(models.init(name, rng, FLAT), 6)
    L = 2
    obs = _obs(rng, FLAT, lead=(L, B))
    target = rng.normal(size=(L, B, 2))

    def loss(p, eng):
        state = models.initial_state(name, B, FLAT, xp=eng.xp, dtype=np.float64)
        out, _ = models.sequence(name, p, obs, state, FLAT, eng)
        return eng.xp.mean((out - target) ** 2)

    outs = [models.sequence(name, params, obs, models.initial_state(name, B, FLAT), FLAT, e,
                            return_aux=True) for e in (eng_np, eng_jax)]
    np.testing.assert_allclose(np.asarray(outs[0][0]), np.asarray(outs[1][0]), rtol=1e-10,
                               atol=1e-12)
    np.testing.assert_allclose(np.asarray(outs[0][2]["predicates"]),
                               np.asarray(outs[1][2]["predicates"]), rtol=1e-10, atol=1e-12)
    g_np = eng_np.grad(lambda p: loss(p, eng_np))(params)["predicates"]["w"]
    g_jax = eng_jax.grad(lambda p: loss(p, eng_jax))(params)["predicates"]["w"]
    g_np, g_jax = np.asarray(g_np), np.asarray(g_jax)
    assert np.abs(g_jax).max() > 1e-6
    np.testing.assert_allclose(g_np, g_jax, rtol=1e-6, atol=1e-10)
    # and against central differences on a few entries of the position-wise weights
    w = np.asarray(params["predicates"]["w"])
    for idx in [(0, 0), (137, 2), (w.shape[0] - 1, 4)]:
        eps = 1e-6
        plus, minus = w.copy(), w.copy()
        plus[idx] += eps
        minus[idx] -= eps
        num = (float(loss({**params, "predicates": {**params["predicates"], "w": plus}},
                          eng_np))
               - float(loss({**params, "predicates": {**params["predicates"], "w": minus}},
                            eng_np))) / (2 * eps)
        np.testing.assert_allclose(g_np[idx], num, rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("cfg", [CFG, FLAT], ids=["gap", "flatten"])
def test_cam_identity(cfg):
    """Each logit splits exactly over positions: logit − bias is the mean (gap) or the sum
    (flatten) of its map; the q-state saliency follows (Σ_i J_ji · that)."""
    rng = np.random.default_rng(7)
    params = models.init("manc", rng, cfg)
    if cfg.predicate_readout == "flatten":
        params = _trained_like(params, 8)
    obs = _obs(rng, cfg)
    q_prev = rng.dirichlet(np.ones(cfg.n_states), size=B)
    ex = models.saliency(params, obs, q_prev, cfg, upsample_to_input=False)
    assert ex["cams"].shape == (B, cfg.n_predicates) + cfg.feature_shape
    reduce = np.mean if cfg.predicate_readout == "gap" else np.sum
    contrib = ex["logits"] - params["predicates"]["b"]
    np.testing.assert_allclose(reduce(ex["cams"], axis=(-2, -1)), contrib, rtol=1e-10,
                               atol=1e-12)
    np.testing.assert_allclose(reduce(ex["saliency"], axis=(-2, -1)),
                               np.einsum("bji,bi->bj", ex["jacobian"], contrib), rtol=1e-9,
                               atol=1e-12)
    # the logits are the model's own (its predicates through the sigmoid)
    _, _, aux = models.step("manc", params, obs, {"q": q_prev}, cfg, engine("numpy"))
    np.testing.assert_allclose(ex["predicates"], aux["predicates"], rtol=1e-12)
    assert models.saliency(params, obs, q_prev, cfg)["cams"].shape[-2:] == cfg.bev_shape[:2]


def test_logit_maps_on_both_engines(eng_jax):
    rng = np.random.default_rng(9)
    f = rng.random((2, 4, 5, 3))
    w = rng.normal(size=(4 * 5 * 3, 6))
    maps = readout.logit_maps(f, w, "flatten")
    assert maps.shape == (2, 6, 4, 5)
    np.testing.assert_allclose(maps, np.einsum("byxc,yxcm->bmyx", f, w.reshape(4, 5, 3, 6)),
                               rtol=1e-12)
    np.testing.assert_allclose(np.asarray(readout.logit_maps(f, w, "flatten", xp=eng_jax.xp)),
                               maps, rtol=1e-12)
    with pytest.raises(ValueError, match=r"\(h·w·C, M\)"):
        readout.logit_maps(f, w[:-1], "flatten")


def test_flatten_keeps_position_gap_does_not(eng_np):
    """The same feature content at another position: GAP's predicates stay, flatten's move."""
    rng = np.random.default_rng(10)
    f = rng.random((1, 8, 8, 8))
    moved = np.roll(f, (3, -2), axis=(1, 2))  # every feature vector, at another position
    flipped = f[:, ::-1, ::-1]
    params = models.init("manc", rng, FLAT)
    gap_w = models.init("manc", rng, CFG)["predicates"]
    for g in (moved, flipped):
        np.testing.assert_allclose(readout.predicate_logits(gap_w, g, "gap"),
                                   readout.predicate_logits(gap_w, f, "gap"), rtol=1e-12)
        # at initialisation every position weighs alike: flatten is GAP's function still
        np.testing.assert_allclose(readout.predicate_logits(params["predicates"], g, "flatten"),
                                   readout.predicate_logits(params["predicates"], f, "flatten"),
                                   rtol=1e-12)
        trained = _trained_like(params, 11)["predicates"]
        change = np.abs(readout.predicate_logits(trained, g, "flatten")
                        - readout.predicate_logits(trained, f, "flatten"))
        assert change.min() > 1e-3

    # end to end: a bright square moved by 8 px (2 feature cells) on a black raster
    params = _trained_like(models.init("manc", rng, FLAT), 12)
    gap_params = models.init("manc", rng, CFG)
    bev = np.zeros((2,) + CFG.bev_shape)
    bev[0, 8:12, 12:16] = 1.0
    bev[1, 16:20, 12:16] = 1.0
    obs = {**_obs(rng, CFG, lead=(2,)), "bev": bev}
    state = models.initial_state("manc", 2, CFG)
    p_gap = models.step("manc", gap_params, obs, state, CFG, eng_np)[2]["predicates"]
    p_flat = models.step("manc", params, obs, state, FLAT, eng_np)[2]["predicates"]
    np.testing.assert_allclose(p_gap[0], p_gap[1], rtol=1e-12)
    assert np.abs(np.asarray(p_flat[0]) - np.asarray(p_flat[1])).max() > 1e-3


def test_bad_readout_is_refused():
    for bad in ("flat", "GAP", None, ""):
        with pytest.raises(ValueError, match=r"predicate_readout must be one of \('gap', "
                                             r"'flatten'\)"):
            models.ModelConfig(predicate_readout=bad)
        with pytest.raises(ValueError, match="predicate_readout must be one of"):
            readout.readout_input(np.ones((1, 2, 2, 3)), bad)


@pytest.fixture(scope="module")
def small_world():
    return world.generate(2, seed=0, raster=world.RasterConfig(size=32), workers=1,
                          progress=False)


def test_training_and_checkpoint_round_trip(small_world, tmp_path, eng_np):
    """One short epoch of MANC with flatten predicates trains and checkpoints; the loaded
    model is the same flatten model and predicts the same; a checkpoint whose config has no
    field is eq. 7 as written."""
    cfg = models.ModelConfig(channels=(4, 8), n_predicates=4, n_states=3, hidden=8,
                             predicate_readout="flatten")
    tc = train.TrainConfig(epochs=1, batch_size=4, dmp_seq_len=3, dtype="float64",
                           max_steps_per_epoch=2)
    fit = train.fit("manc", small_world, cfg, tc, engine="numpy", checkpoint_dir=tmp_path,
                    progress=False)
    assert np.isfinite(fit.history).all() and len(fit.history) == 1
    h, w = fit.cfg.feature_shape
    w_pred = np.asarray(fit.params["predicates"]["w"]).reshape(h, w, 8, 4)
    assert np.ptp(w_pred, axis=(0, 1)).max() > 0  # training made the positions differ
    path = tmp_path / train.CHECKPOINT_NAME
    back = train.load_fit(path)
    assert back.cfg == fit.cfg and back.cfg.predicate_readout == "flatten"
    obs = _obs(np.random.default_rng(13), back.cfg)
    state = models.initial_state("manc", B, back.cfg)
    a = models.step("manc", fit.params, obs, state, fit.cfg, eng_np)
    b = models.step("manc", back.params, obs, state, back.cfg, eng_np)
    assert np.array_equal(np.asarray(a[0]), np.asarray(b[0]))
    assert np.array_equal(np.asarray(a[2]["predicates"]), np.asarray(b[2]["predicates"]))

    gap_path = train.save_checkpoint(tmp_path / "gap.npz", "manc",
                                     models.init("manc", np.random.default_rng(0),
                                                 replace(fit.cfg, predicate_readout="gap")),
                                     replace(fit.cfg, predicate_readout="gap"),
                                     raster=fit.raster)
    with np.load(gap_path) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(bytes(arrays["meta"]).decode())
    assert meta["cfg"].pop("predicate_readout") == "gap"
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    with open(gap_path, "wb") as fh:
        np.savez(fh, **arrays)
    assert train.load_fit(gap_path).cfg.predicate_readout == "gap"
