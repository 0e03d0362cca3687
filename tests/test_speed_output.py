"""Tests for ``ModelConfig.speed_output`` (chapter 8): the direct heads' speed as itself
("absolute", unchanged) or as the change of the own speed of ``motion`` ("change"): the
head's arithmetic, gradients on both engines, the refusals, the closed loop and
checkpoints."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from minimanc import engine, inputs, models, rollout, train, tree, world
from minimanc.train.batches import check_motion_dropout

B = 3
CFG = models.ModelConfig(input_shape=(16, 16, 3), channels=(4, 8), n_predicates=5, n_states=4,
                         hidden=8, k_targets=6, setting="parity")
CHANGE = replace(CFG, speed_output="change")
DIRECT = ("cnn", "cnn_lstm", "rvs_g", "vagn_only")


def _obs(rng: np.random.Generator, cfg: models.ModelConfig = CFG, lead: tuple = (B,)) -> dict:
    straight = np.stack([4.0 * np.arange(1, cfg.k_targets + 1), np.zeros(cfg.k_targets)], -1)
    shape = cfg.bev_shape
    return {"bev": rng.random(lead + shape),
            "goal": rng.normal(size=lead + (3,)) * 20,
            "lane_target": straight + rng.normal(0, 0.5, lead + (cfg.k_targets, 2)),
            # speeds from 0 (a standing car) to 12 m/s
            "motion": np.stack([rng.uniform(0, 12, lead) * (rng.random(lead) > 0.2),
                                rng.normal(0, 0.1, lead)], -1),
            "goal_bev": np.broadcast_to(rng.random(lead[-1:] + shape), lead + shape).copy()}


@pytest.fixture(scope="module")
def eng_np():
    return engine("numpy")


@pytest.fixture(scope="module")
def eng_jax():
    return engine("jax")


@pytest.fixture(scope="module")
def small_world():
    return world.generate(2, seed=0, raster=world.RasterConfig(size=32), workers=1,
                          progress=False)


def test_the_default_is_absolute_and_a_bad_value_is_refused():
    assert models.ModelConfig().speed_output == "absolute"
    assert models.ModelConfig(speed_output="change").speed_output == "change"
    for bad in ("delta", "", None, 1):
        with pytest.raises(ValueError, match=r"speed_output must be one of \('absolute', "
                                             r"'change'\)"):
            models.ModelConfig(speed_output=bad)


def test_absolute_is_the_scaled_dense_output(eng_np):
    """"absolute" (the default): the cnn's controls are ``FC(2)(h) · CONTROL_SCALE``,
    ``h = silu(FC(64)(flatten(f) ⊕ n))``, computed here by hand from the parameters."""
    rng = np.random.default_rng(0)
    params = models.init("cnn", rng, CFG)
    obs = inputs.select(_obs(rng), models.get("cnn"), "parity")
    u, _, aux = models.step("cnn", params, obs, {}, CFG, eng_np)
    f = np.asarray(aux["features"]).reshape(B, -1)
    num = inputs.numeric_features(obs, models.get("cnn"), "parity")
    z = np.concatenate([f, num], -1) @ params["fc1"]["w"] + params["fc1"]["b"]
    h = z / (1.0 + np.exp(-z))
    o = h @ params["out"]["w"] + params["out"]["b"]
    np.testing.assert_allclose(np.asarray(u), o * np.array(models.CONTROL_SCALE),
                               rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", DIRECT)
def test_change_adds_the_absolute_heads_output_to_the_own_speed(name, eng_np):
    """With the same parameters, a "change" head's speed is ``max(v + o₀ s₀, 0)`` where
    ``o₀ s₀`` is exactly what the "absolute" head outputs, and its yaw rate is the same;
    over a window too (no feedback: the speed changed is the window's ``motion`` at that
    step)."""
    rng = np.random.default_rng(1)
    params = models.init(name, rng, CFG)
    obs = inputs.select(_obs(rng, lead=(3, B)), models.get(name), "parity")
    state = models.initial_state(name, B, CFG, dtype=np.float64)
    absolute, _ = models.sequence(name, params, obs, state, CFG, eng_np)
    change, _ = models.sequence(name, params, obs, state, CHANGE, eng_np, feedback_motion=True)
    absolute, change = np.asarray(absolute), np.asarray(change)
    speed = np.maximum(obs["motion"][..., 0] + absolute[..., 0], 0.0)
    assert np.array_equal(change[..., 0], speed)
    assert np.array_equal(change[..., 1], absolute[..., 1])
    assert (speed == 0.0).any() and (speed > 0.0).any()  # both sides of the clip were tried
    one = {k: v[1] for k, v in obs.items()}
    state1 = models.step(name, params, {k: v[0] for k, v in obs.items()}, state, CHANGE,
                         eng_np)[1]
    u, _, _ = models.step(name, params, one, state1, CHANGE, eng_np)
    np.testing.assert_allclose(np.asarray(u), change[1], rtol=1e-12, atol=1e-12)


def test_change_of_a_forced_dense_output_is_exact(eng_np):
    """The head's last layer forced to ``o = b`` (zero weights): the cnn drives at
    ``max(v + b₀ · 10 m/s, 0)`` and turns at ``b₁ · 0.5 rad/s``."""
    rng = np.random.default_rng(2)
    params = models.init("cnn", rng, CHANGE)
    b = np.array([-0.25, 0.3])
    params["out"] = {"w": np.zeros_like(params["out"]["w"]), "b": b}
    obs = inputs.select(_obs(rng), models.get("cnn"), "parity")
    u = np.asarray(models.step("cnn", params, obs, {}, CHANGE, eng_np)[0])
    assert np.array_equal(u[:, 0], np.maximum(obs["motion"][:, 0] + b[0] * 10.0, 0.0))
    assert np.array_equal(u[:, 1], np.full(B, b[1] * 0.5))


@pytest.mark.parametrize("name", ["cnn", "cnn_lstm"])
def test_gradients_numpy_equal_jax_with_change(name, eng_np, eng_jax):
    """The "change" head differentiated by our engine and by JAX agrees to 1e-6 (float64),
    with rows on both sides of the clip at 0."""
    rng = np.random.default_rng(3)
    params = models.init(name, rng, CHANGE)
    params["out"]["b"] = np.array([-0.3, 0.0])  # a change of about −3 m/s
    L = 2 if name == "cnn_lstm" else 1
    obs = inputs.select(_obs(rng, lead=(L, B)), models.get(name), "parity")
    obs["motion"][..., 0] = np.array([0.0, 6.0, 11.0])
    target = rng.normal(size=(L, B, 2)) + np.array([5.0, 0.0])

    def loss(p, eng):
        state = models.initial_state(name, B, CHANGE, xp=eng.xp, dtype=np.float64)
        out, _ = models.sequence(name, p, obs, state, CHANGE, eng)
        return eng.xp.mean((out - target) ** 2)

    v_np, g_np = eng_np.value_and_grad(lambda p: loss(p, eng_np))(params)
    v_jx, g_jx = eng_jax.jit(eng_jax.value_and_grad(lambda p: loss(p, eng_jax)))(params)
    out = np.asarray(models.sequence(name, params, obs, models.initial_state(
        name, B, CHANGE, dtype=np.float64), CHANGE, eng_np)[0])
    assert (out[..., 0] == 0.0).any() and (out[..., 0] > 0.0).any()
    assert abs(float(v_np) - float(v_jx)) < 1e-9
    leaves_np, leaves_jx = tree.leaves(g_np), tree.leaves(g_jx)
    assert len(leaves_np) == len(leaves_jx) == len(tree.leaves(params))
    for a, c in zip(leaves_np, leaves_jx):
        np.testing.assert_allclose(np.asarray(a), np.asarray(c), rtol=1e-6, atol=1e-9)
    assert np.abs(np.asarray(g_np["out"]["b"])).min() > 0.0  # both outputs get a gradient


def test_change_is_refused_where_the_head_has_no_speed_to_change(eng_np):
    """Refused for a direct head that does not see ``motion`` (cnn in "paper") and for the
    DMP models (their DMP already starts from ``motion``), by init, step and sequence; and
    with the training's dropout of ``motion``, which would zero the speed changed."""
    paper = replace(CHANGE, setting="paper")
    rng = np.random.default_rng(4)
    with pytest.raises(ValueError, match="does not see 'motion' in setting 'paper'"):
        models.init("cnn", rng, paper)
    params = models.init("cnn", rng, replace(paper, speed_output="absolute"))
    obs = inputs.select(_obs(rng), models.get("cnn"), "paper")
    with pytest.raises(ValueError, match="does not see 'motion'"):
        models.step("cnn", params, obs, {}, paper, eng_np)
    for name in models.dmp_models():
        with pytest.raises(ValueError, match="ends in the DMP head"):
            models.init(name, rng, CHANGE)
    manc = models.init("manc", rng, CFG)
    obs = inputs.select(_obs(rng, lead=(2, B)), models.get("manc"), "parity")
    state = models.initial_state("manc", B, CFG, dtype=np.float64)
    with pytest.raises(ValueError, match="ends in the DMP head"):
        models.sequence("manc", manc, obs, state, CHANGE, eng_np)
    with pytest.raises(ValueError, match="would zero the speed"):
        check_motion_dropout("cnn", CHANGE, train.TrainConfig(motion_dropout=0.5))
    check_motion_dropout("cnn", CFG, train.TrainConfig(motion_dropout=0.5))


def _policy_cfg(ds) -> models.ModelConfig:
    return models.ModelConfig(input_shape=inputs.raster_of(ds).input_shape, channels=(4, 8),
                              hidden=8, setting="parity", speed_output="change")


def test_closed_loop_applies_the_previous_speed_plus_the_change(small_world):
    """In closed loop the policy's motion is its own previous control: with the dense output
    forced to ``b``, every applied speed is the previous applied speed plus ``b₀ · 10 m/s``
    (in the policy's float32), from the logged initial speed, clipped at 0 and never
    negative; the yaw rate is ``b₁ · 0.5``. A freshly initialised policy drives finitely."""
    ds = small_world
    cfg = _policy_cfg(ds)
    eng = engine("numpy")
    params = models.init("cnn", np.random.default_rng(5), cfg)
    fresh = rollout.closed_loop("cnn", params, ds, cfg, eng, steps=4, progress=False)
    assert np.isfinite(fresh.controls).all() and np.isfinite(fresh.ego).all()
    assert (fresh.controls[..., 0] >= 0.0).all()
    v0 = inputs.initial_motion(ds)[:, 0].astype(np.float32)
    for b in ([0.05, 0.1], [-0.3, -0.2]):
        b = np.asarray(b)
        forced = {**params, "out": {"w": np.zeros_like(params["out"]["w"]), "b": b}}
        run = rollout.closed_loop("cnn", forced, ds, cfg, eng, steps=6, progress=False)
        change = np.float32(b[0]) * np.float32(models.CONTROL_SCALE[0])
        prev = v0
        for t in range(6):
            expected = np.maximum(prev + change, np.float32(0.0))
            assert np.array_equal(run.controls[:, t, 0], expected.astype(np.float64))
            prev = expected
        assert np.array_equal(run.controls[..., 1], np.full((2, 6), np.float32(b[1])
                                                           * np.float32(0.5)))
        assert (run.controls[..., 0] >= 0.0).all()
    assert (run.controls[:, -1, 0] == 0.0).all()  # −3 m/s a step stops the car


def test_training_and_checkpoint_round_trip(small_world, tmp_path, eng_np):
    """One short epoch of cnn_lstm with "change" trains and checkpoints; the loaded model is
    the same "change" model and predicts the same; a checkpoint whose config has no
    ``speed_output`` loads as "absolute"."""
    cfg = replace(_policy_cfg(small_world), input_shape=None)
    tc = train.TrainConfig(epochs=1, batch_size=4, seq_len=3, dtype="float64",
                           max_steps_per_epoch=2)
    fit = train.fit("cnn_lstm", small_world, cfg, tc, engine="numpy", checkpoint_dir=tmp_path,
                    progress=False)
    assert np.isfinite(fit.history).all() and len(fit.history) == 1
    path = tmp_path / train.CHECKPOINT_NAME
    back = train.load_fit(path)
    assert back.cfg == fit.cfg and back.cfg.speed_output == "change"
    obs = inputs.select(_obs(np.random.default_rng(6), back.cfg), models.get("cnn_lstm"),
                        "parity")
    state = models.initial_state("cnn_lstm", B, back.cfg, dtype=np.float64)
    a = models.step("cnn_lstm", fit.params, obs, state, fit.cfg, eng_np)[0]
    c = models.step("cnn_lstm", back.params, obs, state, back.cfg, eng_np)[0]
    assert np.array_equal(np.asarray(a), np.asarray(c))

    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(bytes(arrays["meta"]).decode())
    assert meta["cfg"].pop("speed_output") == "change"
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    old = tmp_path / "old.npz"
    with open(old, "wb") as fh:
        np.savez(fh, **arrays)
    assert train.load_fit(old).cfg.speed_output == "absolute"

