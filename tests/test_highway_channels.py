"""Tests for chapter 10 on a learner's raster: ``minimanc highway collect --raster channels``,
a model trained on it, and ``eval`` / ``render`` driving it closed loop with the raster its
checkpoint records (the route along the ego's lane, the past steps of the episode)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from PIL import Image

hw = pytest.importorskip("minimanc.highway")

from minimanc import rollout, train, world  # noqa: E402
from minimanc.cli import main  # noqa: E402
from minimanc.world.history import history_of  # noqa: E402
from minimanc.world.raster import ROUTE  # noqa: E402

STEPS = 3
COLLECT = ["--scenarios", "highway-fast", "--episodes", "1", "--steps", str(STEPS), "--quiet"]
CORRIDOR = world.RasterConfig.from_extent(30.0, 12.0, 1.25, metres_behind=30.0,
                                          encoding="channels", route=True, history=2)
"""A corridor that sees the ego's box two steps (25 m at highway speed) back."""


def _collect_and_train(tmp, argv: list[str]) -> tuple:
    """``highway collect`` with ``argv``, then ``highway train`` of a CNN for one epoch:
    ``(data path, checkpoint path)``."""
    data = tmp / "hw.npz"
    assert main(["highway", "collect", *COLLECT, *argv, "--out", str(data)]) == 0
    assert main(["highway", "train", "--data", str(data), "--models", "cnn", "--epochs", "1",
                 "--batch-size", "8", "--engine", "numpy", "--out", str(tmp / "runs"),
                 "--quiet"]) == 0
    return data, tmp / "runs" / "cnn" / train.CHECKPOINT_NAME


@pytest.fixture(scope="module")
def channels_run(tmp_path_factory):
    return _collect_and_train(tmp_path_factory.mktemp("channels"),
                              ["--raster", "channels", "--size", "48",
                               "--extent", "30", "30", "12"])


@pytest.fixture(scope="module")
def rgb_run(tmp_path_factory):
    return _collect_and_train(tmp_path_factory.mktemp("rgb"), ["--size", "16"])


def _spy_drive(monkeypatch) -> list:
    """Record the raster every closed loop of the CLI draws with."""
    seen, real = [], hw.drive_episodes

    def drive(policy, scenario, experts, cfg=None, **kw):
        seen.append(cfg)
        return real(policy, scenario, experts, cfg=cfg, **kw)

    monkeypatch.setattr(hw, "drive_episodes", drive)
    return seen


def test_collect_draws_the_learners_channels(channels_run):
    data, ck = channels_run
    ds = world.load(data)
    assert ds.raster == CORRIDOR and CORRIDOR.input_shape == (48, 19, 12)
    assert ds.bev.shape == (1, STEPS, *CORRIDOR.shape) and ds.goal_bev.shape == (1,
                                                                                  *CORRIDOR.shape)
    p = world.planes(ds.bev[0], CORRIDOR)
    k = {n: i for i, n in enumerate(CORRIDOR.channel_names)}
    # the route runs ahead of the ego along its lane: the ego's column, rows above it
    r, c = CORRIDOR.ego_pixel
    assert p[:, :r, c, k["route"]].all(axis=1).all()
    # the past is what the episode drove: none at its first step, then the last ones
    assert not p[0, ..., [k["ego_t-1"], k["ego_t-2"], k["vehicles_t-1"]]].any()
    assert p[1, ..., k["ego_t-1"]].any() and not p[1, ..., k["ego_t-2"]].any()
    assert p[2, ..., k["ego_t-2"]].any() and p[2, ..., k["vehicles_t-1"]].any()
    # the checkpoint records the raster its training data was drawn with
    fit = train.load_fit(ck)
    assert fit.raster == CORRIDOR and fit.cfg.input_shape == CORRIDOR.input_shape


def test_the_closed_loop_draws_the_checkpoints_raster_with_the_episodes_past(channels_run):
    """Each frame the policy sees is the learner's raster of its own pose, the past steps
    being its own poses and the ados' boxes of this episode (as the dataset draws them)."""
    _, ck = channels_run
    fit = train.load_fit(ck)
    experts, _ = hw.expert_episodes("highway-fast", 1, seed=hw.EVAL_SEED, steps=STEPS + 1,
                                    record_bev=False)
    res = hw.drive_episodes(rollout.ModelPolicy(fit, engine="numpy"), "highway-fast", experts,
                            cfg=fit.raster, record_bev=True)
    ep = res.episodes[0]
    assert ep.bev.shape == (STEPS + 1, *CORRIDOR.shape)
    past = history_of(ep.poses, ep.ado, ep.ado_valid, CORRIDOR.history)
    again = world.rasterize_batch(ep.map, ep.poses, ep.ado, ep.ado_valid, CORRIDOR,
                                  history=past)
    no_route = [i for i, n in enumerate(CORRIDOR.channel_names) if n != "route"]
    drawn, expected = world.planes(ep.bev, CORRIDOR), world.planes(again, CORRIDOR)
    np.testing.assert_array_equal(drawn[..., no_route], expected[..., no_route])
    assert drawn[STEPS, ..., CORRIDOR.channel_names.index("ego_t-2")].any()


def test_cli_eval_and_render_drive_a_channels_checkpoint(channels_run, tmp_path, monkeypatch,
                                                         capsys):
    _, ck = channels_run
    seen = _spy_drive(monkeypatch)
    assert main(["highway", "eval", "--checkpoints", str(ck), "--scenarios", "highway-fast",
                 "--episodes", "1", "--steps", str(STEPS), "--engine", "numpy",
                 "--out", str(tmp_path / "e.json")]) == 0
    assert seen == [CORRIDOR]
    report = json.loads((tmp_path / "e.json").read_text())["highway-fast"]
    assert set(report) == {"expert_seeds_tried", "expert", "cnn"}
    assert np.isfinite(report["cnn"]["ade"]) and report["cnn"]["mean_speed"] > 0
    capsys.readouterr()
    out = tmp_path / "frames"
    assert main(["highway", "render", "--checkpoint", str(ck), "--scenario", "highway-fast",
                 "--steps", str(STEPS), "--engine", "numpy", "--out", str(out)]) == 0
    assert f"wrote {STEPS + 1} frames" in capsys.readouterr().out
    with Image.open(out / "bev.gif") as gif:  # the checkpoint's corridor, 4x, in colours
        assert gif.n_frames == STEPS + 1 and gif.size == (4 * CORRIDOR.width, 4 * CORRIDOR.size)
        assert np.all(np.array(gif.convert("RGB")) == ROUTE, axis=-1).any()


def test_an_rgb_checkpoint_works_as_before(rgb_run, monkeypatch):
    """``collect`` without the new options draws what it drew (the same dataset as the
    library's RGB raster of ``--size``), and eval drives its checkpoint with that raster."""
    data, ck = rgb_run
    cfg = world.RasterConfig(size=16)
    ds = world.load(data)
    assert ds.meta["raster"] == cfg.as_meta() == world.RasterConfig(size=16).as_meta()
    direct = hw.collect_demonstrations(["highway-fast"], n_episodes=1, steps=STEPS, cfg=cfg)
    assert ds.content_hash() == direct.content_hash()
    assert train.load_fit(ck).raster == cfg
    seen = _spy_drive(monkeypatch)
    assert main(["highway", "eval", "--checkpoints", str(ck), "--scenarios", "highway-fast",
                 "--episodes", "1", "--steps", str(STEPS), "--engine", "numpy"]) == 0
    assert seen == [cfg]


def test_cli_refuses_an_edited_checkpoint_and_a_bad_view(channels_run, tmp_path, capsys):
    _, ck = channels_run
    with np.load(ck) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(bytes(arrays["meta"]).decode())
    meta["raster"]["route"] = False  # one plane fewer than the model reads
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    edited = tmp_path / "edited.npz"
    with open(edited, "wb") as fh:
        np.savez(fh, **arrays)
    for argv, expected in (
        (["eval", "--checkpoints", str(edited)], f"--checkpoints {edited}: unreadable checkpoint"),
        (["render", "--checkpoint", str(edited), "--out", str(tmp_path / "f")],
         f"--checkpoint {edited}: unreadable checkpoint"),
        (["collect", "--raster", "channels", "--extent", "30", "10", "-1", "--out",
          str(tmp_path / "x.npz")], "--extent SIDE must be > 0, got --extent SIDE=-1.0"),
        (["collect", "--extent", "30", "-5", "12", "--out", str(tmp_path / "x.npz")],
         "--extent BEHIND must be >= 0, got --extent BEHIND=-5.0"),
        (["collect", "--extent", "30", "nan", "12", "--out", str(tmp_path / "x.npz")],
         "--extent AHEAD + BEHIND must be finite"),
        (["collect", "--size", "16", "--extent", "30", "10", "2", "--out",
          str(tmp_path / "x.npz")], "--extent 30 10 2: cols must be an integer >= 8, got cols=2"),
    ):
        code = main(["highway", *argv])
        err = capsys.readouterr().err
        assert code == 2 and len(err.splitlines()) == 1 and expected in err, err
    assert not (tmp_path / "x.npz").exists() and not list((tmp_path / "f").iterdir())


def test_episodes_without_their_bev_are_drawn_with_their_past():
    """``to_dataset`` draws an episode recorded without its BEV as the episode drew it (its
    past steps included), and refuses a route, which follows the lane of each step."""
    cfg = world.RasterConfig(size=32, encoding="channels", history=2)
    eps, _ = hw.expert_episodes("roundabout", 1, seed=0, steps=4, cfg=cfg)
    bare = [dataclasses.replace(ep, bev=None) for ep in eps]
    assert np.array_equal(hw.to_dataset(bare, cfg).bev, hw.to_dataset(eps, cfg).bev)
    with pytest.raises(ValueError, match="^episodes drawn with a route must carry their BEV"):
        hw.to_dataset(bare, dataclasses.replace(cfg, route=True))
