"""Tests for ``TrainConfig.motion_dropout`` (chapter 8): the ``motion`` input a direct head reads
as numbers is replaced by zeros in training windows with probability p, seeded per step,
never where the model does not read it as a number."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimanc import dagger, models, train, tree, world
from minimanc.train.batches import drop_motion, motion_dropout_rng
from minimanc.train.fit import epoch_plan, start_run, step_batch

CFG = models.ModelConfig(input_shape=(32, 32, 3), channels=(4, 8), n_predicates=4, n_states=3,
                         hidden=8, setting="parity")


@pytest.fixture(scope="module")
def ds():
    return world.generate(3, seed=0, raster=world.RasterConfig(size=32))


def _tc(**kw):
    base = dict(epochs=1, batch_size=8, seq_len=4, dmp_seq_len=4, dtype="float64",
                max_steps_per_epoch=3)
    base.update(kw)
    return train.TrainConfig(**base)


def _epoch_batches(name, ds, tc, epochs):
    """``(plain, dropped)`` pairs of every step of ``epochs`` epochs: ``make_batch``'s batch and
    the training step's (:func:`step_batch`), as :func:`minimanc.train.fit` makes them."""
    run = start_run(name, ds, CFG, tc)
    out = []
    for epoch in range(epochs):
        q_rng = np.random.default_rng([tc.seed, epoch, 1])
        for s, t in epoch_plan(run, ds, epoch):
            plain = train.make_batch(name, ds, s, t, CFG, np.float64)
            out.append((plain, step_batch(run, ds, s, t, q_rng)))
            run.steps += 1
    return out


# --------------------------------------------------------------------------- the configuration


@pytest.mark.parametrize("p", [-0.1, 1.0, 1.5, math.nan, math.inf, True, "0.5", None])
def test_a_probability_outside_zero_to_one_is_refused(p):
    with pytest.raises(ValueError, match=r"motion_dropout must be a finite number in \[0, 1\)"):
        train.TrainConfig(motion_dropout=p)


@pytest.mark.parametrize("name, cfg, match", [
    ("manc", CFG, "initial state"),
    ("dmp_only", CFG, "initial state"),
    ("cnn", replace(CFG, setting="paper"), "does not in setting='paper'"),
    ("cnn_lstm", replace(CFG, setting="paper"), "does not in setting='paper'"),
])
def test_refused_where_the_model_does_not_read_motion_as_a_number(ds, name, cfg, match):
    tc = _tc(motion_dropout=0.5)
    with pytest.raises(ValueError, match=match):
        train.fit(name, ds, cfg, tc, engine="numpy", progress=False)
    with pytest.raises(ValueError, match=match):
        train.fit_seeds(name, ds, cfg, tc, seeds=[0, 1], engine="jax", progress=False)
    train.fit(name, ds, cfg, replace(tc, motion_dropout=0.0), engine="numpy", progress=False)


def test_dagger_refuses_it_before_training(ds):
    pool, val = ds.split(2)
    teacher = dagger.WorldTeacher(pool, val, agents="reactive")
    with pytest.raises(ValueError, match="initial state"):
        dagger.dagger("manc", teacher, budget=80, rounds=1, cfg=CFG,
                      train_cfg=_tc(motion_dropout=0.5), progress=False, evaluate=False)


# --------------------------------------------------------------------------- the batches


@pytest.mark.parametrize("name", ["cnn", "cnn_lstm", "rvs_g", "vagn_only"])
def test_without_dropout_the_training_batch_is_make_batch_s(ds, name):
    for plain, got in _epoch_batches(name, ds, _tc(max_steps_per_epoch=None), epochs=2):
        assert "motion" in got
        for k, v in plain.items():
            assert got[k].dtype == v.dtype and np.array_equal(got[k], v), k


@pytest.mark.parametrize("name, p", [("cnn", 0.75), ("cnn", 0.3), ("cnn_lstm", 0.75)])
def test_a_window_s_motion_is_zeroed_with_probability_p_and_nothing_else_changes(ds, name, p):
    """Over ≈ 2400 samples (cnn) or 600 windows (cnn_lstm) the zeroed share is within 0.06 of
    p (≥ 3 standard deviations of a binomial share; the seed is fixed, so the count is the
    same every run): it would be 0 without dropout and 1 with it always on."""
    tc = _tc(motion_dropout=p, max_steps_per_epoch=None, seed=3)
    dropped, windows = 0, 0
    for plain, got in _epoch_batches(name, ds, tc, epochs=20):
        assert set(got) == set(plain)
        for k, v in plain.items():
            if k != "motion":
                assert np.array_equal(got[k], v), k  # other inputs and the labels untouched
        m, m0 = got["motion"], plain["motion"]
        assert m.dtype == m0.dtype
        zero = np.all(m == 0, axis=(0, 2))  # (b,): the whole window
        kept = np.all(m == m0, axis=(0, 2))
        assert np.all(zero | kept)  # a window is dropped at every step or at none
        moving = np.any(m0 != 0, axis=(0, 2))  # a window at rest looks the same either way
        dropped += int(np.sum(zero & moving))
        windows += int(np.sum(moving))
    assert windows > (2000 if name == "cnn" else 500)
    assert abs(dropped / windows - p) < 0.06, (dropped, windows)


@given(st.floats(0.0, 0.99), st.integers(0, 2**31), st.integers(0, 10**6))
def test_drop_motion_zeroes_exactly_the_coins_below_p(p, seed, step):
    motion = np.random.default_rng(0).normal(size=(3, 50, 2)).astype(np.float32)
    coins = motion_dropout_rng(seed, step).random(50)
    got = drop_motion(motion, p, motion_dropout_rng(seed, step))
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, np.where((coins < p)[None, :, None], 0.0, motion))
    assert not np.signbit(got[:, coins < p]).any()  # +0, not −0


def test_drop_motion_refuses_a_motion_without_windows():
    with pytest.raises(ValueError, match=r"shape \(L, b, 2\)"):
        drop_motion(np.zeros((5, 2)), 0.5, np.random.default_rng(0))


def test_one_seed_gives_one_set_of_batches_another_seed_another(ds):
    tc = _tc(motion_dropout=0.75, max_steps_per_epoch=None)
    a = [b["motion"] for _, b in _epoch_batches("cnn", ds, tc, epochs=2)]
    again = [b["motion"] for _, b in _epoch_batches("cnn", ds, tc, epochs=2)]
    assert all(np.array_equal(x, y) for x, y in zip(a, again))
    other = [b["motion"] for _, b in _epoch_batches("cnn", ds, replace(tc, seed=1), epochs=2)]
    zeros = [np.all(m == 0, axis=(0, 2)) for m in a]
    zeros_other = [np.all(m == 0, axis=(0, 2)) for m in other]
    assert not all(np.array_equal(x, y) for x, y in zip(zeros, zeros_other))
    # each step draws its own coins: the epochs do not repeat one pattern
    per_step = {tuple(z) for z in zeros}
    assert len(per_step) > len(zeros) // 2


# --------------------------------------------------------------------------- training


def test_resume_equals_uninterrupted(ds, tmp_path):
    tc2 = _tc(epochs=2, motion_dropout=0.75)
    full = train.fit("cnn", ds, CFG, tc2, engine="numpy", progress=False)
    d = tmp_path / "run"
    train.fit("cnn", ds, CFG, replace(tc2, epochs=1), engine="numpy", checkpoint_dir=d,
              progress=False)
    resumed = train.fit("cnn", ds, CFG, tc2, engine="numpy", checkpoint_dir=d, resume=True,
                        progress=False)
    assert resumed.history == full.history
    for x, y in zip(tree.leaves(full.params), tree.leaves(resumed.params)):
        np.testing.assert_array_equal(x, y)
    assert train.load_fit(d / train.CHECKPOINT_NAME).train_cfg == tc2
    with pytest.raises(ValueError, match="only epochs and lr may change"):
        train.fit("cnn", ds, CFG, replace(tc2, epochs=3, motion_dropout=0.5), engine="numpy",
                  checkpoint_dir=d, resume=True, progress=False)


def test_a_checkpoint_written_before_the_field_loads_with_no_dropout(ds, tmp_path):
    res = train.fit("cnn", ds, CFG, _tc(), engine="numpy", progress=False)
    path = train.save_checkpoint(tmp_path / "old.npz", res)
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(bytes(arrays["meta"]).decode())
    del meta["train_cfg"]["motion_dropout"]
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    np.savez(path, **arrays)
    assert train.load_fit(path).train_cfg == _tc()


@pytest.mark.parametrize("name", ["cnn", "cnn_lstm", "vagn_only"])
def test_a_fit_with_dropout_trains_alike_on_both_engines_and_differs_from_none(ds, name):
    tc = _tc(epochs=2, motion_dropout=0.75, seq_len=2, q_seq_len=2)
    a = train.fit(name, ds, CFG, tc, engine="numpy", progress=False)
    b = train.fit(name, ds, CFG, tc, engine="jax", progress=False)
    assert a.steps == b.steps == 6 and a.train_cfg.motion_dropout == 0.75
    assert all(math.isfinite(x) for x in a.history)
    np.testing.assert_allclose(a.history, b.history, rtol=1e-5, atol=1e-8)
    for x, y in zip(tree.leaves(a.params), tree.leaves(b.params)):
        np.testing.assert_allclose(x, y, rtol=1e-5, atol=1e-7)
    none = train.fit(name, ds, CFG, replace(tc, motion_dropout=0.0), engine="numpy",
                     progress=False)
    assert not np.allclose(a.history, none.history)


def test_runs_trained_together_drop_as_each_alone(ds):
    tc = _tc(epochs=2, motion_dropout=0.75)
    together = train.fit_seeds("cnn", ds, CFG, tc, seeds=[0, 1], engine="jax", progress=False)
    for seed, res in zip([0, 1], together):
        alone = train.fit("cnn", ds, CFG, replace(tc, seed=seed), engine="jax", progress=False)
        np.testing.assert_allclose(res.history, alone.history, rtol=1e-6)
