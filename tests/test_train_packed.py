"""Tests for the packed raster in training batches: a ``"channels"`` raster's bytes go to the
jitted step as stored and are unpacked there (:func:`minimanc.world.encodings.unpack`,
:func:`minimanc.train.batches.unpack_batch`), giving the model the numbers the host's
:func:`minimanc.world.encodings.to_input` gives, and training the same parameters."""

from __future__ import annotations

import numpy as np
import pytest

from minimanc import diagnose, engine, inputs, models, train, tree, world
from minimanc.train.batches import unpack_batch
from minimanc.world.encodings import to_input, unpack

RASTER = world.RasterConfig(size=24, encoding="channels", route=True, history=2)
CFG = models.ModelConfig(input_shape=RASTER.input_shape, channels=(4, 8), n_predicates=4,
                         n_states=3, hidden=8)


@pytest.fixture(scope="module")
def ds():
    return world.generate(3, seed=0, raster=RASTER, workers=1)


def test_unpack_equals_to_input_on_every_stored_frame_in_numpy_and_jax(ds):
    bev = np.asarray(ds.bev)
    want = to_input(bev, RASTER)
    count = len(RASTER.channel_names)
    assert bev.shape[-1] == 2 and count == 12 and want.any()
    got = unpack(bev, count)
    assert got.dtype == np.float32 and np.array_equal(got, want)
    jeng = engine("jax")
    got_j = np.asarray(jeng.jit(lambda b: unpack(b, count))(bev))
    assert got_j.dtype == np.float32 and np.array_equal(got_j, want)
    assert np.array_equal(unpack(bev, count, dtype=np.float64), want.astype(np.float64))


def test_unpack_refuses_what_is_not_packed_planes():
    with pytest.raises(ValueError, match="uint8"):
        unpack(np.zeros((2, 2), np.float32), 3)
    with pytest.raises(ValueError, match="count"):
        unpack(np.zeros((2, 2), np.uint8), 17)


def test_from_dataset_keeps_the_channels_packed_on_request_and_rgb_as_floats(ds):
    s, t = np.array([0, 2, 1]), np.array([5, 0, 39])
    packed = inputs.from_dataset(ds, s, t, packed=True)["bev"]
    assert packed.dtype == np.uint8 and np.array_equal(packed, ds.bev[s, t])
    plain = inputs.from_dataset(ds, s, t)["bev"]
    assert plain.dtype == np.float32 and np.array_equal(plain, to_input(ds.bev[s, t], RASTER))
    rgb = world.generate(1, seed=0, raster=world.RasterConfig(size=24), workers=1)
    got = inputs.from_dataset(rgb, 0, [3, 4], packed=True)["bev"]
    assert got.dtype == np.float32 and np.array_equal(got, to_input(rgb.bev[0, 3:5],
                                                                    rgb.raster))


@pytest.mark.parametrize("name", ["cnn", "rvs_g"])
def test_make_batch_passes_the_bytes_and_unpack_batch_gives_the_hosts_floats(ds, name):
    cfg = models.ModelConfig(**{**CFG.to_dict(), "input_shape": RASTER.input_shape,
                                "channels": (4, 8)})
    s, t = np.array([[0, 1, 2, 2]]), np.array([[3, 17, 0, 39]])
    batch = train.make_batch(name, ds, s, t, cfg, np.float64)
    assert batch["bev"].dtype == np.uint8 and batch["bev"].shape == (1, 4, 24, 24, 2)
    host = inputs.from_dataset(ds, s.reshape(-1), t.reshape(-1), model=models.get(name))
    out = unpack_batch(batch, cfg)
    for key in ("bev", "goal_bev") if name == "rvs_g" else ("bev",):
        assert out[key].dtype == np.float64
        assert np.array_equal(out[key].reshape(host[key].shape), host[key])
    assert out["controls"] is batch["controls"] and batch["bev"].dtype == np.uint8


def _host_unpacked(monkeypatch):
    """Make the batches as before: the host unpacks every raster to float planes."""
    real = inputs.from_dataset
    monkeypatch.setattr(inputs, "from_dataset",
                        lambda *a, packed=False, **kw: real(*a, **kw))


@pytest.mark.parametrize("name", ["cnn", "manc"])
def test_a_fit_on_packed_batches_equals_the_fit_on_host_unpacked_ones(ds, name, monkeypatch):
    """JAX, with the auxiliary perception loss: the same parameters and losses bit for bit."""
    tc = train.TrainConfig(epochs=2, batch_size=8, dmp_seq_len=4, max_steps_per_epoch=3,
                           perception_weight=1.0, seed=1)
    targets = diagnose.perception_targets(ds)
    now = train.fit(name, ds, CFG, tc, engine="jax", progress=False, perception=targets)
    _host_unpacked(monkeypatch)
    before = train.fit(name, ds, CFG, tc, engine="jax", progress=False, perception=targets)
    assert now.history == before.history
    assert all(np.array_equal(a, b) for a, b in zip(tree.leaves(now.params),
                                                    tree.leaves(before.params)))


def test_the_numpy_loss_and_gradient_on_packed_and_float_batches_are_equal(ds):
    eng = engine("numpy")
    s, t = np.array([[0, 1, 2]]), np.array([[3, 17, 30]])
    batch = train.make_batch("cnn", ds, s, t, CFG, np.float64)
    floats = unpack_batch(batch, CFG)
    params = models.init("cnn", np.random.default_rng(0), CFG)
    inv = np.ones(2)

    def loss(p, b):
        return train.loss_fn("cnn", p, b, CFG, eng, inv)

    (la, ga), (lb, gb) = (eng.value_and_grad(loss)(params, b) for b in (batch, floats))
    assert float(la) == float(lb)
    assert all(np.array_equal(a, b) for a, b in zip(tree.leaves(ga), tree.leaves(gb)))
