"""Tests for the auxiliary perception loss (``TrainConfig.perception_weight``,
:func:`minimanc.train.step.loss_fn`, :func:`minimanc.train.fit` with ``perception``) and its
targets (:func:`minimanc.dagger.privileged.perceived`)."""

from __future__ import annotations

import numpy as np
import pytest

from minimanc import engine, layers, models, train, world
from minimanc.dagger import privileged as P
from minimanc.train.batches import make_batch
from minimanc.train.step import loss_fn

NAMES = ("gap", "dv", "has_leader", "stop")


@pytest.fixture(scope="module")
def data():
    ds = world.generate(3, seed=5)
    return ds, P.perceived(ds, NAMES)


def test_perceived_is_the_demonstrations_features_by_state(data):
    ds, y = data
    X, _ = P.demonstrations(ds)
    assert y.shape == (3, 40, len(NAMES))
    for k, n in enumerate(NAMES):
        np.testing.assert_array_equal(y[..., k].reshape(-1), X[:, P.FEATURES.index(n)])
    with pytest.raises(ValueError, match="names must be some of"):
        P.perceived(ds, ("gap", "speed_of_light"))


@pytest.mark.parametrize("name", ["cnn", "manc"])
def test_the_loss_adds_the_weighted_mean_square_of_the_read_out(data, name):
    ds, y = data
    eng = engine("numpy")
    cfg = models.ModelConfig()
    params = models.init(name, np.random.default_rng(0), cfg, dtype=np.float32)
    rng = np.random.default_rng(1)
    n_in = cfg.n_predicates if name == "manc" else cfg.feature_size ** 2 * cfg.channels[-1]
    params["perception"] = layers.init_dense(rng, n_in, len(NAMES))
    s = np.array([[0, 1, 2]])
    t = np.array([[3, 10, 20]])
    batch = make_batch(name, ds, s, t, cfg, np.float32)
    if name == "manc":
        batch["q0"] = np.full((3, cfg.n_states), 1.0 / cfg.n_states, dtype=np.float32)
    target = rng.normal(size=(1, 3, len(NAMES))).astype(np.float32)
    inv = np.ones(2, dtype=np.float32)
    plain = float(loss_fn(name, params, batch, cfg, eng, inv))
    with_p = float(loss_fn(name, params, {**batch, "perception": target}, cfg, eng, inv,
                           perception_weight=0.5))
    _, _, aux = models.step(name, params, {k: v[0] for k, v in batch.items()
                                           if k not in ("controls", "q0")},
                            models.initial_state(name, 3, cfg), cfg, eng)
    seen = aux["predicates"] if name == "manc" else aux["features"]  # what MANC's head reads
    f = np.asarray(seen, dtype=np.float64).reshape(3, -1)
    read = f @ np.asarray(params["perception"]["w"]) + np.asarray(params["perception"]["b"])
    want = 0.5 * np.mean((read - target[0]) ** 2)
    assert with_p - plain == pytest.approx(want, rel=1e-3)


def test_fit_checks_the_targets_and_returns_the_controller_only(data):
    ds, y = data
    tc = train.TrainConfig(epochs=1, max_steps_per_epoch=1, perception_weight=1.0)
    with pytest.raises(ValueError, match="needs perception targets"):
        train.fit("cnn", ds, train_cfg=tc, progress=False)
    with pytest.raises(ValueError, match="perception_weight is 0"):
        train.fit("cnn", ds, train_cfg=train.TrainConfig(epochs=1, max_steps_per_epoch=1),
                  progress=False, perception=y)
    with pytest.raises(ValueError, match=r"shape \(S, T, K\)"):
        train.fit("cnn", ds, train_cfg=tc, progress=False, perception=y[:2])
    with pytest.raises(ValueError, match="finite"):
        train.fit("cnn", ds, train_cfg=tc, progress=False, perception=y * np.nan)
    with pytest.raises(ValueError, match="perception_weight must be"):
        train.TrainConfig(perception_weight=-1.0)
    res = train.fit("cnn", ds, train_cfg=tc, progress=False, perception=y)
    assert set(res.params) == set(models.init("cnn", np.random.default_rng(0)))
