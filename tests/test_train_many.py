"""Tests for minimanc.train.fit_many / fit_seeds: runs of one configuration trained in one
vmapped JAX step give each run's own :func:`minimanc.train.fit` result (float32 rounding),
with their checkpoints, resume, masked short epochs and per-run divergence."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from minimanc import models, train, tree, world

CFG = models.ModelConfig(input_shape=(32, 32, 3), channels=(4, 8), n_predicates=4, n_states=3,
                         hidden=8)
RTOL, ATOL = 2e-4, 2e-6  # float32: XLA may sum a vmapped batch in another order


@pytest.fixture(scope="module")
def ds():
    return world.generate(3, seed=0, raster=world.RasterConfig(size=32))


def _tc(**kw):
    base = dict(epochs=2, batch_size=8, seq_len=4, dmp_seq_len=4, max_steps_per_epoch=3)
    base.update(kw)
    return train.TrainConfig(**base)


def assert_same(a: train.FitResult, b: train.FitResult) -> None:
    assert a.steps == b.steps
    assert a.train_cfg == b.train_cfg
    np.testing.assert_allclose(a.history, b.history, rtol=RTOL, atol=ATOL)
    np.testing.assert_array_equal(a.control_std, b.control_std)
    for x, y in zip(tree.leaves(a.params), tree.leaves(b.params), strict=True):
        assert x.dtype == y.dtype
        np.testing.assert_allclose(x, y, rtol=RTOL, atol=ATOL)


@pytest.mark.parametrize("name", ["manc", "cnn"])
def test_seeds_together_equal_separate_fits(name, ds):
    """Three seeds in one vmapped step: each seed's parameters and losses are those of its
    own ``fit`` (different initialisations, data orders, q' draws and subsets)."""
    tc = _tc(q_init="random", subset=0.7)
    together = train.fit_seeds(name, ds, CFG, tc, [0, 1, 2], progress=False)
    assert [r.train_cfg.seed for r in together] == [0, 1, 2]
    for s, r in enumerate(together):
        assert_same(r, train.fit(name, ds, CFG, replace(tc, seed=s), progress=False))
    # the seeds really differ (the stacking kept them apart)
    assert not np.allclose(together[0].history, together[1].history)


def test_short_epochs_are_masked(ds):
    """LSTM windows tile each scene from a random offset, so seeds can have different numbers
    of minibatches in an epoch; the seed with fewer is left unchanged for the extra steps."""
    tc = _tc(max_steps_per_epoch=None, epochs=1, seq_len=12, batch_size=24)
    alone = [train.fit("cnn_lstm", ds, CFG, replace(tc, seed=s), progress=False)
             for s in range(4)]
    steps = [r.steps for r in alone]
    assert len(set(steps)) > 1, f"the test needs seeds with unequal epochs, got {steps}"
    together = train.fit_seeds("cnn_lstm", ds, CFG, tc, range(4), progress=False)
    for a, b in zip(together, alone):
        assert_same(a, b)


def test_learning_rates_together(ds):
    """A sweep (same seed, several learning rates) is one vmapped run too."""
    tcs = [_tc(lr=lr) for lr in (3e-4, 1e-3, 3e-3)]
    together = train.fit_many("cnn", ds, CFG, tcs, progress=False)
    for r, tc in zip(together, tcs):
        assert_same(r, train.fit("cnn", ds, CFG, tc, progress=False))


def test_checkpoints_and_resume_from_different_epochs(ds, tmp_path):
    """Each run writes its own checkpoint; a resume continues runs that stopped at different
    epochs and ends where uninterrupted runs end."""
    dirs = [tmp_path / "s0", tmp_path / "s1"]
    train.fit("manc", ds, CFG, _tc(epochs=1, seed=0), checkpoint_dir=dirs[0], progress=False)
    train.fit("manc", ds, CFG, _tc(epochs=2, seed=1), checkpoint_dir=dirs[1], progress=False)
    resumed = train.fit_seeds("manc", ds, CFG, _tc(epochs=3), [0, 1], checkpoint_dirs=dirs,
                              resume=True, progress=False)
    for s, r in enumerate(resumed):
        assert_same(r, train.fit("manc", ds, CFG, _tc(epochs=3, seed=s), progress=False))
        ck = train.load_checkpoint(dirs[s] / train.CHECKPOINT_NAME)
        assert ck["epoch"] == 3 and len(ck["history"]) == 3
        assert_same(train.load_fit(dirs[s] / train.CHECKPOINT_NAME), r)


def test_a_diverged_run_does_not_stop_the_others(ds, tmp_path):
    tcs = [_tc(lr=1e-3), _tc(lr=1e30)]
    dirs = [tmp_path / "a", tmp_path / "b"]
    out = train.fit_many("cnn", ds, CFG, tcs, checkpoint_dirs=dirs, errors="return",
                         progress=False)
    assert isinstance(out[1], train.TrainingDiverged) and "lr=1e+30" in str(out[1])
    assert_same(out[0], train.fit("cnn", ds, CFG, tcs[0], progress=False))
    assert not (dirs[1] / train.CHECKPOINT_NAME).exists()
    with pytest.raises(train.TrainingDiverged, match="diverged"):
        train.fit_many("cnn", ds, CFG, tcs, progress=False)


def test_numpy_engine_trains_one_after_the_other(ds):
    tc = _tc(dtype="float64", epochs=1, max_steps_per_epoch=2)
    out = train.fit_seeds("cnn", ds, CFG, tc, [0, 1], engine="numpy", progress=False)
    for s, r in enumerate(out):
        ref = train.fit("cnn", ds, CFG, replace(tc, seed=s), engine="numpy", progress=False)
        np.testing.assert_array_equal(r.history, ref.history)


def test_bad_arguments(ds, tmp_path):
    with pytest.raises(ValueError, match="differ only in seed and lr"):
        train.fit_many("cnn", ds, CFG, [_tc(), _tc(batch_size=4)], progress=False)
    with pytest.raises(ValueError, match="at least one"):
        train.fit_many("cnn", ds, CFG, [], progress=False)
    with pytest.raises(ValueError, match="one directory per run"):
        train.fit_seeds("cnn", ds, CFG, _tc(), [0, 1], checkpoint_dirs=[tmp_path],
                        progress=False)
    with pytest.raises(ValueError, match="errors must be one of"):
        train.fit_seeds("cnn", ds, CFG, _tc(), [0, 1], errors="ignore", progress=False)
    with pytest.raises(ValueError, match="resume=True needs checkpoint_dirs"):
        train.fit_seeds("cnn", ds, CFG, _tc(), [0, 1], resume=True, progress=False)
    with pytest.raises(ValueError, match="train_cfg must be"):
        train.fit_seeds("cnn", ds, CFG, {"epochs": 1}, [0], progress=False)
    with pytest.raises(ValueError, match="input_shape"):
        train.fit_seeds("cnn", ds, replace(CFG, input_shape=(64, 64, 3)), _tc(), [0, 1],
                        progress=False)
