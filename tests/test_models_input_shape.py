"""The models read what the raster draws: the input shape comes from the data (the binary
channels with the route and the history, a non-square corridor, the RGB default), is kept in
checkpoints and refused where it disagrees."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from minimanc import engine, layers, models, rollout, train, tree, world
from minimanc.layers import dense, flatten
from minimanc.models import registry, zoo

TC = train.TrainConfig(epochs=1, batch_size=4, max_steps_per_epoch=1, seq_len=2, q_seq_len=2,
                       dmp_seq_len=2)
SMALL = dict(channels=(4, 8), hidden=8, n_predicates=4, n_states=3)
RASTERS = {
    "channels": world.RasterConfig(size=32, encoding="channels", route=True, history=2),
    "corridor": world.RasterConfig.from_extent(40.0, 10.0, 1.25),
}

BUILTIN_NAMES = ["cnn", "cnn_lstm", "rvs_g", "manc", "vagn_only", "dmp_only"]


def _toy_init(rng, cfg, n_num):
    return {"out": layers.init_dense(rng, zoo.flat_size(cfg) + n_num, 2)}


def _toy_encode(params, obs, f, num, cfg, eng):
    return {"pre": eng.xp.concatenate([flatten(f, eng.xp), num], axis=-1)}


def _toy_head(params, enc, state, cfg, eng):
    return dense(params["out"], enc["pre"], eng.xp), dict(state), {}


USER = models.ModelSpec("user_flat", "User", "feedforward", registry.observes_goal(), _toy_init,
                        _toy_encode, _toy_head, colour="#000000")


@pytest.fixture(scope="module", params=sorted(RASTERS))
def data(request):
    ds = world.generate(4, seed=0, raster=RASTERS[request.param], workers=1)
    return ds.split(3)


@pytest.mark.parametrize("name", BUILTIN_NAMES)
def test_the_default_model_reads_the_default_raster(name):
    """An unset input shape is the default raster's 64 × 64 RGB: the same parameters, leaf
    for leaf, as the shape given explicitly, and the shapes a 64 × 64 × 3 input implies."""
    cfg = models.ModelConfig()
    assert cfg.input_shape is None and cfg.bev_shape == world.RasterConfig().input_shape
    default = models.init(name, np.random.default_rng(0), cfg)
    given = models.init(name, np.random.default_rng(0),
                        models.ModelConfig(input_shape=(64, 64, 3)))
    assert tree.to_flat_dict(default).keys() == tree.to_flat_dict(given).keys()
    for a, b in zip(tree.leaves(default), tree.leaves(given), strict=True):
        np.testing.assert_array_equal(a, b)
    assert default["backbone"]["convs"][0]["w"].shape == (3, 3, 3, cfg.channels[0])
    assert cfg.feature_shape == (8, 8) and zoo.flat_size(cfg) == 8 * 8 * cfg.channels[-1]


@pytest.mark.parametrize("name", [s.name for s in models.BUILTIN] + [USER.name])
def test_every_model_trains_and_drives_on_the_data_s_planes(name, data):
    train_ds, val_ds = data
    shape = train_ds.raster.input_shape
    with models.registered(USER):
        fit = train.fit(name, train_ds, models.ModelConfig(**SMALL), TC, engine="numpy",
                        progress=False)
        assert fit.cfg.input_shape == shape
        assert fit.cfg.bev_shape == (train_ds.raster.size, train_ds.raster.width,
                                     len(train_ds.raster.channel_names))
        assert fit.params["backbone"]["convs"][0]["w"].shape[2] == shape[2]
        assert np.all(np.isfinite(fit.history))
        out = rollout.closed_loop(fit, val_ds, engine="numpy", steps=3, progress=False)
    assert np.all(np.isfinite(out.controls)) and np.all(np.isfinite(out.ego))


def test_the_raster_under_test_is_what_the_brief_asks(data):
    shape = data[0].raster.input_shape
    assert shape in ((32, 32, 12), (40, 16, 3))  # 12 planes: 7 map and ego, vehicles at t..t-2
    if shape[2] == 12:
        assert {"route", "vehicles", "vehicles_t-1", "vehicles_t-2"} <= set(
            data[0].raster.channel_names)


def test_manc_drives_among_reactive_ados_on_the_channels():
    ds = world.generate(2, seed=1, raster=RASTERS["channels"], workers=1)
    fit = train.fit("manc", ds, models.ModelConfig(**SMALL), TC, engine="numpy", progress=False)
    out = rollout.closed_loop(fit, ds, engine="numpy", steps=3, progress=False,
                              agents="reactive")
    assert np.all(np.isfinite(out.controls))


def test_a_shape_that_disagrees_with_the_data_is_refused_in_one_line(data):
    train_ds, val_ds = data
    shape = train_ds.raster.input_shape
    other = (shape[0], shape[1], 3 if shape[2] != 3 else 5)
    with pytest.raises(ValueError, match=r"train_ds's BEV planes .* do not match") as e:
        train.fit("cnn", train_ds, models.ModelConfig(input_shape=other, **SMALL), TC,
                  engine="numpy", progress=False)
    assert "\n" not in str(e.value) and "models.ModelConfig without input_shape" in str(e.value)
    rgb = world.generate(1, seed=0, raster=world.RasterConfig(size=shape[0]), workers=1)
    if shape[2] != 3 or shape[0] != shape[1]:
        with pytest.raises(ValueError, match="val_ds's BEV planes"):
            train.fit("cnn", train_ds, models.ModelConfig(**SMALL), TC, val_ds=rgb,
                      engine="numpy", progress=False)
    fit = train.fit("cnn", train_ds, models.ModelConfig(**SMALL), TC, engine="numpy",
                    progress=False)
    with pytest.raises(ValueError, match="^ds's BEV planes"):
        rollout.closed_loop(fit, rgb, engine="numpy", steps=2, progress=False)
    obs = {"bev": np.zeros((1, *other)), "goal": np.zeros((1, 3))}
    with pytest.raises(ValueError, match=r"obs\['bev'\]'s BEV planes"):
        models.step("cnn", fit.params, obs, {}, fit.cfg, engine("numpy"))


@pytest.mark.parametrize("bad", [(32, 32), (0, 32, 3), (32.0, 32, 3), 64, (True, 4, 3)])
def test_a_bad_input_shape_is_refused(bad):
    with pytest.raises(ValueError, match="input_shape must be three positive integers"):
        models.ModelConfig(input_shape=bad)


def test_the_checkpoint_keeps_the_shape_and_is_refused_on_other_data(data, tmp_path):
    train_ds, val_ds = data
    fit = train.fit("manc", train_ds, models.ModelConfig(**SMALL), TC, engine="numpy",
                    progress=False, checkpoint_dir=tmp_path)
    back = train.load_fit(tmp_path / train.CHECKPOINT_NAME)
    assert back.cfg == fit.cfg and back.cfg.input_shape == train_ds.raster.input_shape
    assert models.ModelConfig(**fit.cfg.to_dict()) == fit.cfg
    assert models.ModelConfig(**models.ModelConfig().to_dict()) == models.ModelConfig()
    a = rollout.closed_loop(fit, val_ds, engine="numpy", steps=2, progress=False)
    b = rollout.closed_loop(back, val_ds, engine="numpy", steps=2, progress=False)
    np.testing.assert_array_equal(a.controls, b.controls)
    other = world.generate(2, seed=2, raster=world.RasterConfig(size=16), workers=1)
    with pytest.raises(ValueError, match="^ds's BEV planes"):
        rollout.closed_loop(back, other, engine="numpy", steps=2, progress=False)
    with pytest.raises(ValueError, match="checkpoint at"):
        train.fit("manc", other, models.ModelConfig(**SMALL), TC, engine="numpy",
                  progress=False, checkpoint_dir=tmp_path, resume=True)
    assert replace(fit.cfg, input_shape=None).bev_shape == models.DEFAULT_INPUT_SHAPE
