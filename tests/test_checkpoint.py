"""Tests for minimanc.train.checkpoint (chapter 8): a checkpoint records the raster its
training data was drawn with, gives it back, and refuses a file whose raster is missing
(written before it was recorded) or does not fit its model."""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import numpy as np
import pytest

from minimanc import models, train, world

CHANNELS = world.RasterConfig(size=16, encoding="channels", route=True, history=2)
CFG = models.ModelConfig(channels=(4, 8), hidden=8)  # the input shape is the data's
TC = train.TrainConfig(epochs=1, batch_size=8, max_steps_per_epoch=1)


@pytest.fixture(scope="module")
def ds():
    return world.generate(2, seed=0, raster=CHANNELS, workers=1)


@pytest.fixture()
def checkpoint(ds, tmp_path):
    train.fit("cnn", ds, CFG, TC, engine="numpy", checkpoint_dir=tmp_path / "run",
              progress=False)
    return tmp_path / "run" / train.CHECKPOINT_NAME


def _edit_meta(path: Path, edit) -> None:
    """Rewrite the checkpoint's JSON metadata with ``edit(meta)`` applied."""
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(bytes(arrays["meta"]).decode())
    edit(meta)
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def test_the_checkpoint_records_the_raster_of_the_training_data(ds, checkpoint, tmp_path):
    fit = train.load_fit(checkpoint)
    assert fit.raster == ds.raster == CHANNELS
    assert fit.cfg.input_shape == CHANNELS.input_shape == (16, 16, 12)
    assert train.load_checkpoint(checkpoint)["raster"] == CHANNELS
    # the result of fit carries it too, and save_checkpoint(path, fit) writes it
    res = train.fit("cnn", ds, CFG, TC, engine="numpy", progress=False)
    assert res.raster == CHANNELS
    assert train.load_fit(train.save_checkpoint(tmp_path / "again.npz", res)).raster == CHANNELS
    # a view of the same pixels with other metres is another raster
    corridor = world.RasterConfig.from_extent(30.0, 10.0, 2.5, encoding="channels",
                                              route=True, history=2)
    assert corridor.input_shape == (16, 8, 12)
    shaped = models.ModelConfig(channels=(4, 8), hidden=8, input_shape=corridor.input_shape)
    params = models.init("cnn", np.random.default_rng(0), shaped)
    path = train.save_checkpoint(tmp_path / "parts.npz", "cnn", params, shaped, raster=corridor)
    assert train.load_fit(path).raster == corridor


def test_a_checkpoint_is_written_only_with_a_raster_that_fits_the_model(tmp_path):
    cfg = models.ModelConfig(channels=(4, 8), hidden=8, input_shape=CHANNELS.input_shape)
    params = models.init("cnn", np.random.default_rng(0), cfg)
    with pytest.raises(ValueError, match=r"^raster must be the world.RasterConfig the training "
                                         r"data was drawn with"):
        train.save_checkpoint(tmp_path / "x.npz", "cnn", params, cfg)
    with pytest.raises(ValueError, match=r"raster's BEV planes \(16, 16, 3\).*\(16, 16, 12\)"):
        train.save_checkpoint(tmp_path / "x.npz", "cnn", params, cfg,
                              raster=world.RasterConfig(size=16))
    fit = train.FitResult(name="cnn", params=params, history=[], cfg=cfg,
                          train_cfg=train.TrainConfig())  # built by hand: no raster
    with pytest.raises(ValueError, match="raster must be"):
        train.save_checkpoint(tmp_path / "x.npz", fit)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("edit, why", [
    (lambda m: m.update(raster={**m["raster"], "encoding": "rgb", "route": False,
                                "history": 0}),
     r"ValueError: its raster's BEV planes \(16, 16, 3\) .* \(16, 16, 12\)"),
    (lambda m: m["raster"].update(size="sixteen"), "ValueError: size must be an integer"),
    (lambda m: m["raster"].update(colour="blue"), "TypeError: .*colour"),
    (lambda m: (m.pop("raster"), m.update(format=1)),  # as written before the raster
     "ValueError: checkpoint format 1, this version reads 2"),
    (lambda m: m.pop("raster"), "KeyError: 'raster'"),
])
def test_an_edited_or_older_checkpoint_is_refused_in_one_line(ds, checkpoint, edit, why):
    _edit_meta(checkpoint, edit)
    for call in (lambda: train.load_fit(checkpoint),
                 lambda: train.fit("cnn", ds, CFG, TC, engine="numpy", progress=False,
                                   checkpoint_dir=checkpoint.parent, resume=True)):
        with pytest.raises(train.CheckpointError) as info:
            call()
        msg = str(info.value)
        assert len(msg.splitlines()) == 1
        assert msg.startswith(f"{checkpoint}: unreadable checkpoint (truncated, corrupt or of "
                              f"another version: ")
        assert msg.endswith("to start again from epoch 0")
        assert re.search(why, msg), msg


def test_resuming_on_data_drawn_with_another_raster_is_refused(ds, checkpoint):
    """Same planes, another view: the checkpoint's model was trained on other pictures."""
    other = copy.copy(ds)
    other.meta = {**ds.meta, "raster": {**ds.meta["raster"], "metres_side": 20.0}}
    assert other.raster.input_shape == ds.raster.input_shape
    with pytest.raises(ValueError, match=r"checkpoint at checkpoint\.npz was trained on data "
                                         r"drawn with RasterConfig\(.*metres_side=25\.0"):
        train.fit("cnn", other, CFG, train.TrainConfig(epochs=2, batch_size=8,
                                                       max_steps_per_epoch=1),
                  engine="numpy", checkpoint_dir=checkpoint.parent, resume=True,
                  progress=False)
