"""Chapter 8 — the model registry: a model is one ModelSpec, and everything follows from it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from minimanc import engine, inputs, layers, metrics, models, rollout, studies, train, world
from minimanc.layers import dense, flatten
from minimanc.models import registry, zoo
from minimanc.viz import style


@pytest.fixture(scope="module")
def ds():
    return world.generate(3, seed=0, raster=world.RasterConfig(size=32))


def _toy_init(rng, cfg, n_num):
    flat = zoo.flat_size(cfg)
    return {"out": layers.init_dense(rng, flat + n_num, 2)}


def _toy_encode(params, obs, f, num, cfg, eng):
    return {"pre": eng.xp.concatenate([flatten(f, eng.xp), num], axis=-1)}


def _toy_head(params, enc, state, cfg, eng):
    return dense(params["out"], enc["pre"], eng.xp), dict(state), {}


TOY = models.ModelSpec("toy_linear", "Toy", "feedforward", registry.observes_goal(),
                       _toy_init, _toy_encode, _toy_head, window="seq_len", colour="#000000")


# MANC whose gains read q and the predicates, FC(q ⊕ p), from MANC's public pieces
# (the example of minimanc.models.zoo's docstring)
def _qp_init(rng, cfg, n_num):
    return {"predicates": zoo.predicate_layer(rng, cfg), "vagn": zoo.vagn_layer(rng, cfg),
            "gains": zoo.gains_layer(rng, cfg.n_states + cfg.n_predicates, cfg)}


def _qp_head(params, enc, state, cfg, eng):
    q = zoo.vagn_step(params, enc, state, eng)
    x = eng.xp.concatenate([q, enc["predicates"]], axis=-1)
    controls, aux = zoo.dmp_step(zoo.gains_fc(params, x, eng), enc, cfg, eng)
    return controls, {"q": q}, {"q": q, **aux}


MANC_QP = models.ModelSpec("manc_qp", "MANC FC(q ⊕ p)", "vagn", registry.observes_structured(),
                           _qp_init, zoo.dmp_encode, _qp_head, window="dmp_seq_len", dmp=True)


def test_a_new_model_is_one_entry_and_runs_through_the_public_api(ds):
    cfg = models.ModelConfig(input_shape=(32, 32, 3), channels=(4, 8), setting="parity")
    eng = engine("numpy")
    assert "toy_linear" not in models.names()
    with models.registered(TOY):
        assert models.names()[-1] == "toy_linear"
        assert "toy_linear" not in models.vagn_models() + models.lstm_models() + models.dmp_models()
        toy = models.get("toy_linear")
        assert inputs.visible(toy, "parity") == ("bev", "goal", "lane_target", "motion")
        assert inputs.numeric_size(toy, "parity", 10) == 25
        assert style.model_label("toy_linear") == "Toy"
        assert style.model_labels()["toy_linear"] == "Toy"
        assert style.model_colours()["toy_linear"] == "#000000"
        assert train.window_len("toy_linear", train.TrainConfig(seq_len=3)) == 3

        params = models.init("toy_linear", np.random.default_rng(0), cfg)
        assert params["out"]["w"].shape == (8 * 8 * 8 + 25, 2)  # 32 → 16 → 8, 8 channels
        obs = inputs.from_dataset(ds, [0, 1], [3, 7], "parity", model=toy)
        u, state, aux = models.step("toy_linear", params, obs, {}, cfg, eng)
        assert np.asarray(u).shape == (2, 2) and state == {} and "features" in aux
        seq = inputs.from_dataset(ds, [0, 0, 0], [0, 1, 2], "parity", model=toy)
        seq = {k: v[:, None] for k, v in seq.items()}  # (L = 3, B = 1, ...)
        out, _ = models.sequence("toy_linear", params, seq, {}, cfg, eng)
        one = [np.asarray(models.step("toy_linear", params, {k: v[i] for k, v in seq.items()},
                                      {}, cfg, eng)[0]) for i in range(3)]
        np.testing.assert_allclose(np.asarray(out), np.stack(one), rtol=1e-12, atol=1e-12)

        tc = train.TrainConfig(epochs=2, batch_size=6, seq_len=3, dtype="float64", lr=1e-2)
        res = train.fit("toy_linear", ds, cfg, tc, engine="numpy", progress=False)
        assert res.steps > 0 and np.all(np.isfinite(res.history))
        assert res.history[-1] < res.history[0]
        traj = rollout.closed_loop("toy_linear", res.params, ds, cfg, "numpy", steps=2,
                                   progress=False)
        assert traj.ego.shape == (3, 3, 3) and traj.aux == {}
    assert "toy_linear" not in models.names() and "toy_linear" not in style.model_labels()
    with pytest.raises(ValueError, match="name must be one of"):
        models.init("toy_linear", np.random.default_rng(0), cfg)
    with pytest.raises(ValueError, match="name must be one of"):
        models.get("toy_linear")


def test_a_manc_variant_registered_outside_the_package_trains_and_drives_closed_loop():
    """MANC with gains FC(q ⊕ p), registered here from the public pieces: it trains two steps
    on the tiny preset's data and drives its validation scenes among reactive ados."""
    c = studies.PRESETS["tiny"]
    n = c.n_train + c.n_tune + c.n_val
    data = world.generate(n, seed=c.data_seed, raster=c.raster, workers=1)
    train_ds, val_ds = data.subset(slice(0, c.n_train)), data.subset(slice(c.n_train + c.n_tune, n))
    cfg = models.ModelConfig(input_shape=data.raster.input_shape, n_states=4)
    with models.registered(MANC_QP):
        assert models.vagn_models()[-1] == "manc_qp" and "manc_qp" in models.dmp_models()
        params = models.init("manc_qp", np.random.default_rng(0), cfg)
        manc = models.init("manc", np.random.default_rng(0), cfg)
        assert params["gains"]["w"].shape == (cfg.n_states + cfg.n_predicates, 4)
        np.testing.assert_array_equal(params["vagn"]["W"], manc["vagn"]["W"])  # same draws
        fit = train.fit("manc_qp", train_ds, cfg, replace(c.training, batch_size=8),
                        engine="numpy", progress=False)
        assert fit.name == "manc_qp" and fit.steps == 2 and np.all(np.isfinite(fit.history))
        traj = rollout.closed_loop(fit, val_ds, engine="numpy", progress=False,
                                   agents="reactive")
        assert traj.name == "manc_qp" and traj.ego.shape == val_ds.ego.shape
        assert set(traj.aux) == {"q", "alpha", "beta", "predicates"}
        np.testing.assert_allclose(traj.aux["q"].sum(-1), 1.0, atol=1e-5)
        assert np.isfinite(metrics.evaluate(traj, val_ds)["ade"])
    assert "manc_qp" not in models.names()


def test_a_head_sees_the_same_inputs_in_a_step_and_in_a_training_window(ds):
    """The head contract of ModelSpec: ``enc`` holds what ``encode`` returned and the
    predicates, never the backbone features, in models.step as in models.sequence."""
    seen = []

    def head(params, enc, state, cfg, eng):
        seen.append(sorted(enc))
        return zoo.manc_head(params, enc, state, cfg, eng)

    spec = models.ModelSpec("manc_seen", "seen", "vagn", registry.observes_structured(),
                            zoo.manc_init, zoo.dmp_encode, head, window="dmp_seq_len", dmp=True)
    cfg = models.ModelConfig(input_shape=(32, 32, 3), channels=(4, 8), n_states=3)
    eng = engine("numpy")
    with models.registered(spec):
        params = models.init("manc_seen", np.random.default_rng(0), cfg)
        obs = inputs.from_dataset(ds, [0, 1], [3, 7], "paper", model=spec)
        state = models.initial_state("manc_seen", 2, cfg, dtype=np.float64)
        models.step("manc_seen", params, obs, state, cfg, eng)
        seq = {k: v[None] for k, v in obs.items()}  # (L = 1, B = 2, ...)
        models.sequence("manc_seen", params, seq, state, cfg, eng, feedback_motion=True)
    assert seen[0] == seen[-1] == ["lane_target", "motion", "predicates"]


def test_the_families_and_windows_of_the_six_models_come_from_their_specs():
    assert models.names() == ("cnn", "cnn_lstm", "rvs_g", "manc", "vagn_only", "dmp_only")
    assert models.vagn_models() == ("manc", "vagn_only")
    assert models.lstm_models() == ("cnn_lstm", "rvs_g")
    assert models.dmp_models() == ("manc", "dmp_only")
    tc = train.TrainConfig(seq_len=5, dmp_seq_len=7, q_seq_len=2)
    assert {n: train.window_len(n, tc) for n in models.names()} == {
        "cnn": 1, "cnn_lstm": 5, "rvs_g": 5, "manc": 7, "vagn_only": 2, "dmp_only": 7}
    assert [style.model_label(n) for n in models.names()] == [
        "CNN", "CNN-LSTM", "RvS-G", "MANC", "vAGN-only", "DMP-only"]
    assert style.model_label("human") == "Human" and style.model_label("other") == "other"


def test_the_registry_refuses_bad_specs():
    args = (_toy_init, _toy_encode, _toy_head)
    with pytest.raises(ValueError, match="already registered"):
        models.register_model(models.ModelSpec("manc", "M", "vagn", registry.observes_structured(),
                                               *args, dmp=True))
    with pytest.raises(ValueError, match="family"):
        models.ModelSpec("t", "T", "gru", registry.observes_goal(), *args)
    with pytest.raises(ValueError, match="observes"):
        models.ModelSpec("t", "T", "feedforward", {"paper": ("bev",)}, *args)
    with pytest.raises(ValueError, match="'bev'"):
        models.ModelSpec("t", "T", "feedforward", {"paper": ("goal",), "parity": ("goal",)},
                         *args)
    with pytest.raises(ValueError, match="dmp model"):
        models.ModelSpec("t", "T", "feedforward", registry.observes_goal(), *args, dmp=True)
    with pytest.raises(ValueError, match="window"):
        models.ModelSpec("t", "T", "feedforward", registry.observes_goal(), *args, window="L")
    with pytest.raises(ValueError, match="name"):
        models.ModelSpec("no spaces", "T", "feedforward", registry.observes_goal(), *args)
    with pytest.raises(TypeError, match="head"):
        models.ModelSpec("t", "T", "feedforward", registry.observes_goal(), _toy_init,
                         _toy_encode, None)
    with pytest.raises(TypeError, match="ModelSpec"):
        models.register_model("toy")
    assert models.names() == ("cnn", "cnn_lstm", "rvs_g", "manc", "vagn_only", "dmp_only")
