"""Tests for minimanc.train (chapter 8): Algorithm 1 on both engines, checkpoints, divergence."""

from __future__ import annotations

import copy
import os

import numpy as np
import pytest

from minimanc import models, train, tree, world

CFG = models.ModelConfig(input_shape=(32, 32, 3), channels=(4, 8), n_predicates=4, n_states=3,
                         hidden=8)


@pytest.fixture(scope="module")
def ds():
    return world.generate(3, seed=0, raster=world.RasterConfig(size=32))


def _tc(**kw):
    base = dict(epochs=1, batch_size=8, seq_len=4, dmp_seq_len=4, dtype="float64",
                max_steps_per_epoch=3)
    base.update(kw)
    return train.TrainConfig(**base)


@pytest.mark.parametrize("name", ["manc", "cnn_lstm"])
def test_equal_losses_on_both_engines(name, ds):
    """Same code, same data order: our engine and jitted JAX give the same losses (float64)."""
    tc = _tc(epochs=2, q_init="random", dmp_seq_len=2, seq_len=2)
    a = train.fit(name, ds, CFG, tc, engine="numpy", progress=False)
    b = train.fit(name, ds, CFG, tc, engine="jax", progress=False)
    assert a.steps == b.steps == 6
    np.testing.assert_allclose(a.history, b.history, rtol=1e-5, atol=1e-8)
    for x, y in zip(tree.leaves(a.params), tree.leaves(b.params)):
        np.testing.assert_allclose(x, y, rtol=1e-5, atol=1e-7)


def test_overfit_a_handful_of_samples(ds):
    """Algorithm 1's step on the same 8 samples again and again drives the loss down.

    A direct head memorises them (loss ÷ 100). MANC starts far lower — its DMP
    already follows the lane — and can only move its gains through q, so it
    improves less (still more than halves its loss).
    """
    from minimanc import engine, optim

    eng = engine("numpy")
    s = np.array([[0, 0, 0, 1, 1, 1, 2, 2]])
    t = np.array([[3, 17, 36, 5, 22, 30, 2, 25]])
    inv = 1.0 / train.control_std(ds)
    for name, lr, factor in (("cnn", 3e-3, 0.01), ("manc", 1e-2, 0.5)):
        tc = train.TrainConfig(lr=lr, dtype="float64")
        batch = train.make_batch(name, ds, s, t, CFG, np.float64)
        q0 = train.initial_q(name, 8, CFG, tc, np.random.default_rng(0), np.float64)
        if q0 is not None:
            batch["q0"] = q0
        params = models.init(name, np.random.default_rng(0), CFG)
        opt = optim.adam_init(params)
        step = train.make_step(name, CFG, tc, eng, inv)
        losses = []
        for _ in range(150):
            params, opt, loss = step(params, opt, batch)
            losses.append(float(loss))
        assert losses[-1] < factor * losses[0], (name, losses[0], losses[-1])


def test_checkpoint_resume_equals_uninterrupted(ds, tmp_path):
    tc2 = _tc(epochs=2, q_init="random")
    full = train.fit("manc", ds, CFG, tc2, engine="numpy", progress=False)
    d = tmp_path / "run"
    first = train.fit("manc", ds, CFG, _tc(epochs=1, q_init="random"), engine="numpy",
                      checkpoint_dir=d, progress=False)
    assert len(first.history) == 1 and (d / train.CHECKPOINT_NAME).exists()
    resumed = train.fit("manc", ds, CFG, tc2, engine="numpy", checkpoint_dir=d, resume=True,
                        progress=False)
    assert resumed.history == pytest.approx(full.history, rel=1e-12)
    for x, y in zip(tree.leaves(full.params), tree.leaves(resumed.params)):
        np.testing.assert_array_equal(x, y)
    assert sorted(os.listdir(d)) == [train.CHECKPOINT_NAME]  # no temporary files left
    back = train.load_fit(d / train.CHECKPOINT_NAME)
    assert back.name == "manc" and back.cfg == CFG and back.history == resumed.history
    for x, y in zip(tree.leaves(back.params), tree.leaves(resumed.params)):
        np.testing.assert_array_equal(x, y)
    # a checkpoint of another model is refused
    with pytest.raises(ValueError, match="checkpoint"):
        train.fit("cnn", ds, CFG, tc2, engine="numpy", checkpoint_dir=d, resume=True,
                  progress=False)


def test_divergence_stops_and_keeps_the_last_good_checkpoint(ds, tmp_path):
    d = tmp_path / "run"
    train.fit("cnn", ds, CFG, _tc(epochs=1), engine="numpy", checkpoint_dir=d, progress=False)
    path = d / train.CHECKPOINT_NAME
    before = path.read_bytes()
    # lr may change on resume: epoch 2 explodes the parameters
    with pytest.raises(train.TrainingDiverged,
                       match=r"diverged.*epoch 2.*the checkpoint of epoch 1 is kept"):
        train.fit("cnn", ds, CFG, _tc(epochs=2, lr=1e30), engine="numpy",
                  checkpoint_dir=d, resume=True, progress=False)
    assert path.read_bytes() == before
    assert sorted(os.listdir(d)) == [train.CHECKPOINT_NAME]
    # ... and the message is true: the kept checkpoint is epoch 1's, with sane parameters
    ck = train.load_checkpoint(path)
    assert ck["epoch"] == 1 and train.bad_params(ck["params"]) is None


@pytest.mark.parametrize("name", ["cnn", "manc"])
def test_exploded_parameters_are_never_checkpointed(ds, tmp_path, name):
    """lr = 1e30 keeps the loss of epoch 1 finite, but |param| reaches 1e30."""
    d = tmp_path / "run"
    with pytest.raises(train.TrainingDiverged,
                       match=r"after epoch 1.*max \|param\| = .*e\+30.*this run wrote no "
                             r"checkpoint"):
        train.fit(name, ds, CFG, _tc(epochs=2, lr=1e30), engine="numpy", checkpoint_dir=d,
                  progress=False)
    assert not d.exists() or os.listdir(d) == []
    with pytest.raises(train.TrainingDiverged, match="no checkpoint_dir"):
        train.fit(name, ds, CFG, _tc(epochs=1, lr=1e30), engine="numpy", progress=False)
    # save() itself refuses such parameters
    params = models.init("cnn", np.random.default_rng(0), CFG)
    params["out"]["b"] = np.full_like(params["out"]["b"], np.nan)
    with pytest.raises(ValueError, match="non-finite value in 'out/b'"):
        train.save_checkpoint(tmp_path / "x.npz", "cnn", params, CFG)
    assert not list(tmp_path.glob("x.npz*"))


def test_non_finite_data_is_refused_naming_scene_and_step(ds):
    bad = copy.copy(ds)
    bad.controls = ds.controls.copy()
    bad.controls[1, 5, 0] = np.nan
    with pytest.raises(ValueError, match=r"train_ds.*controls\[scene 1, step 5, 0\] = nan"):
        train.fit("cnn", bad, CFG, _tc(), engine="numpy", progress=False)
    with pytest.raises(ValueError, match=r"val_ds.*controls\[scene 1, step 5"):
        train.fit("cnn", ds, CFG, _tc(), engine="numpy", progress=False, val_ds=bad)


def test_corrupt_checkpoint_names_the_file_and_how_to_restart(ds, tmp_path):
    d = tmp_path / "run"
    train.fit("cnn", ds, CFG, _tc(epochs=1), engine="numpy", checkpoint_dir=d, progress=False)
    path = d / train.CHECKPOINT_NAME
    raw = path.read_bytes()
    for broken in (raw[: len(raw) // 2], b"", raw[:-30], b"garbage" * 10):
        path.write_bytes(broken)
        for call in (lambda: train.load_fit(path),
                     lambda: train.fit("cnn", ds, CFG, _tc(epochs=2), engine="numpy",
                                       checkpoint_dir=d, resume=True, progress=False)):
            with pytest.raises(train.CheckpointError,
                               match=r"run/checkpoint\.npz: unreadable checkpoint.*delete it"):
                call()
    # what the message says works: without resume the run starts again from epoch 0
    res = train.fit("cnn", ds, CFG, _tc(epochs=1), engine="numpy", checkpoint_dir=d,
                    progress=False)
    assert len(res.history) == 1 and train.load_checkpoint(path)["epoch"] == 1


def test_temporary_checkpoint_files_are_cleaned(ds, tmp_path, monkeypatch):
    d = tmp_path / "run"
    d.mkdir()
    # what a killed run leaves: an empty and a partial temporary file
    (d / "checkpoint.npz.a1b2c3.tmp").write_bytes(b"")
    (d / "checkpoint.npz.d4e5f6.tmp").write_bytes(b"PK\x03\x04partial")
    (d / "notes.txt").write_text("kept")
    train.fit("cnn", ds, CFG, _tc(epochs=1), engine="numpy", checkpoint_dir=d, progress=False)
    assert sorted(os.listdir(d)) == [train.CHECKPOINT_NAME, "notes.txt"]
    # a save that fails half-way removes its temporary file
    real = np.savez

    def crash(fh, **arrays):
        fh.write(b"PK\x03\x04half")
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(np, "savez", crash)  # what train.checkpoint writes with
    with pytest.raises(OSError, match="No space"):
        train.fit("cnn", ds, CFG, _tc(epochs=2), engine="numpy", checkpoint_dir=d, resume=True,
                  progress=False)
    monkeypatch.setattr(np, "savez", real)
    assert sorted(os.listdir(d)) == [train.CHECKPOINT_NAME, "notes.txt"]
    assert train.load_checkpoint(d / train.CHECKPOINT_NAME)["epoch"] == 1


def test_subsets_are_nested():
    a = train.subset_scenes(650, 0.25, seed=3)
    b = train.subset_scenes(650, 0.5, seed=3)
    c = train.subset_scenes(650, 1.0, seed=3)
    assert len(a) == 163 and len(b) == 325 and len(c) == 650
    assert set(a) <= set(b) <= set(c)
    assert not np.array_equal(a, train.subset_scenes(650, 0.25, seed=4))


def test_batches_cover_windows(ds):
    tc = train.TrainConfig(batch_size=8, seq_len=4, seed=1)
    plan = train.batches("cnn_lstm", ds, np.arange(3), tc, epoch=0)
    assert all(s.shape == t.shape == (4, 2) for s, t in plan)
    for s, t in plan:  # consecutive steps of one scene
        assert np.all(np.diff(t, axis=0) == 1) and np.all(s == s[0])
    ff = train.batches("cnn", ds, np.arange(3), tc, epoch=0)
    pairs = {(int(s[0, i]), int(t[0, i])) for s, t in ff for i in range(s.shape[1])}
    assert len(pairs) == 8 * len(ff) == 120  # every sample once per epoch
    again = train.batches("cnn", ds, np.arange(3), tc, epoch=0)
    assert all(np.array_equal(x[1], y[1]) for x, y in zip(ff, again))  # seeded


def test_sweep_lr_picks_the_best(ds):
    res = train.sweep_lr("dmp_only", ds, ds, CFG, lrs=(1e-4, 3e-3), train_cfg=_tc(epochs=1),
                         engine="numpy", score=lambda r: r.train_cfg.lr)
    assert res.best_lr == 1e-4 and set(res.scores) == {1e-4, 3e-3}
    default = train.sweep_lr("dmp_only", ds, ds, CFG, lrs=(1e-3,), train_cfg=_tc(epochs=1),
                             engine="numpy")
    assert np.isfinite(default.scores[1e-3])


def test_evaluate_matches_training_loss_definition(ds):
    params = models.init("cnn", np.random.default_rng(0), CFG)
    std = train.control_std(ds)
    val = train.open_loop_loss("cnn", params, ds, CFG, engine="numpy", std=std, dtype=np.float64)
    from minimanc import engine, inputs

    obs = inputs.from_dataset(ds, np.repeat(np.arange(3), 40), np.tile(np.arange(40), 3),
                              model=models.get("cnn"))
    pred, _, _ = models.step("cnn", params, obs, {}, CFG, engine("numpy"))
    ref = np.mean(((pred - ds.controls.reshape(-1, 2)) / std) ** 2)
    assert val == pytest.approx(ref, rel=1e-6)


def test_evaluate_runs_dmp_models_on_whole_scenes_with_their_own_speed(ds):
    """MANC's evaluation loss is its training loss on whole scenes from t = 0: q carried
    from uniform, the DMP fed its own speed (or the logged one without feedback)."""
    from minimanc import engine, inputs

    params = models.init("manc", np.random.default_rng(0), CFG)
    std = train.control_std(ds)
    S, T = ds.ego.shape[:2]
    obs = inputs.from_dataset(ds, np.tile(np.arange(S), T), np.repeat(np.arange(T), S),
                              model=models.get("manc"))
    obs = {k: v.reshape((T, S) + v.shape[1:]) for k, v in obs.items()}
    target = np.swapaxes(np.asarray(ds.controls), 0, 1)
    for feedback in (True, False):
        state = models.initial_state("manc", S, CFG, dtype=np.float64)
        pred, _ = models.sequence("manc", params, obs, state, CFG, engine("numpy"),
                                  feedback_motion=feedback)
        ref = np.mean(((pred - target) / std) ** 2)
        val = train.open_loop_loss("manc", params, ds, CFG, engine="numpy", std=std,
                             dtype=np.float64, motion_feedback=feedback)
        assert val == pytest.approx(ref, rel=1e-6)


def test_without_a_config_the_model_takes_the_data_s_input_shape(ds):
    fit = train.fit("cnn", ds, None, _tc(), engine="numpy", progress=False)
    assert fit.cfg.input_shape == ds.raster.input_shape == (32, 32, 3)
    unset = train.fit("cnn", ds, models.ModelConfig(n_states=3), _tc(), engine="numpy",
                      progress=False)
    assert unset.cfg.input_shape == (32, 32, 3) and unset.cfg.n_states == 3


def test_bad_config_raises(ds):
    with pytest.raises(ValueError, match="lr"):
        train.TrainConfig(lr=-1.0)
    with pytest.raises(ValueError, match="subset"):
        train.TrainConfig(subset=0.0)
    with pytest.raises(ValueError, match="q_init"):
        train.TrainConfig(q_init="zeros")
    with pytest.raises(ValueError, match=r"train_ds's BEV planes \(32, 32, 3\) .* \(64, 64, 3\)"):
        train.fit("cnn", ds, models.ModelConfig(input_shape=(64, 64, 3)), _tc(), engine="numpy",
                  progress=False)
    with pytest.raises(ValueError, match="engine"):
        train.fit("cnn", ds, CFG, _tc(), engine="torch", progress=False)
    with pytest.raises(ValueError, match="resume"):
        train.fit("cnn", ds, CFG, _tc(), engine="numpy", resume=True, progress=False)


def test_the_training_result_is_accepted_where_its_parts_are(ds, tmp_path):
    """``open_loop_loss(fit, ds)`` is the loss as trained (the fit's normalisation);
    ``save_checkpoint(path, fit)`` writes what ``load_fit`` reads back."""
    fit = train.fit("manc", ds, CFG, _tc(epochs=2), engine="numpy", progress=False)
    assert train.open_loop_loss(fit, ds, engine="numpy") == train.open_loop_loss(
        "manc", fit.params, ds, CFG, "numpy", std=fit.control_std)
    assert train.open_loop_loss(fit, ds, engine="numpy", std=np.ones(2)) == \
        train.open_loop_loss("manc", fit.params, ds, CFG, "numpy", std=np.ones(2))
    back = train.load_fit(train.save_checkpoint(tmp_path / "fit.npz", fit))
    assert (back.name, back.cfg, back.train_cfg, back.history, back.steps) == \
        (fit.name, fit.cfg, fit.train_cfg, fit.history, fit.steps)
    assert train.load_checkpoint(tmp_path / "fit.npz")["epoch"] == 2
    np.testing.assert_array_equal(back.control_std, fit.control_std)
    for x, y in zip(tree.leaves(back.params), tree.leaves(fit.params)):
        np.testing.assert_array_equal(x, y)
    with pytest.raises(TypeError, match="accepts_fit needs"):
        train.accepts_fit()(lambda name, params: None)
    with pytest.raises(TypeError, match="lacks \\['std'\\]"):
        train.accepts_fit({"std": lambda f: f.control_std})(lambda name, params, cfg: None)


def test_fits_of_one_configuration_share_one_jitted_step(ds):
    """``train.jitted_step`` gives one jitted function per (model, ModelConfig, TrainConfig,
    engine), so a model trained again with them (each DAgger round) reuses its compilations;
    another configuration gets its own, and the reused step trains to the same numbers."""
    from minimanc import engine

    eng = engine("jax")
    tc = _tc(dtype="float32")
    step = train.jitted_step("cnn", CFG, tc, eng)
    assert train.jitted_step("cnn", models.ModelConfig(**CFG.to_dict()), _tc(dtype="float32"),
                             eng) is step
    assert train.jitted_step("cnn", CFG, _tc(dtype="float32", perception_weight=1.0),
                             eng) is not step
    assert train.jitted_step("manc", CFG, tc, eng) is not step
    first = train.fit("cnn", ds, CFG, tc, engine="jax", progress=False)
    again = train.fit("cnn", ds, CFG, tc, engine="jax", progress=False)
    assert again.history == first.history
