"""Tests for chapter 10: the highway-env sandbox (minimanc.highway, minimanc.cli.highway)."""

from __future__ import annotations

import importlib
import json
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

hw = pytest.importorskip("minimanc.highway")

from minimanc import inputs, rollout, world  # noqa: E402
from minimanc.world.raster import BACKGROUND, DRIVABLE, EGO, VEHICLE  # noqa: E402

# --------------------------------------------------------------------------- optional dependency


def test_missing_dependency_gives_the_install_command(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "highway_env", None)  # import highway_env -> ImportError
    monkeypatch.delitem(sys.modules, "minimanc.highway")
    with pytest.raises(ImportError, match=r"pip install 'minimanc\[highway\]'"):
        importlib.import_module("minimanc.highway")
    # the CLI plugin stays importable, registers its commands, and reports the missing piece
    monkeypatch.delitem(sys.modules, "minimanc.cli.highway", raising=False)
    cli = importlib.import_module("minimanc.cli.highway")
    from minimanc.cli import build_parser

    args = build_parser().parse_args(["highway", "collect", "--episodes", "2"])
    assert args.func is cli.cmd_collect
    assert args.func(args) == 2
    assert "pip install 'minimanc[highway]'" in capsys.readouterr().err


# --------------------------------------------------------------------------- environments, frames


def test_roundabout_accepts_continuous_actions():
    env = hw.make_env("roundabout", steps=4)
    env.reset(seed=0)
    _, reward, terminated, truncated, info = env.step(np.array([0.2, 0.0], dtype=np.float32))
    assert np.isfinite(reward) and not terminated and not truncated
    assert env.config["policy_frequency"] == 2 and env.destination in env.EXITS


def test_to_world_mirrors_y_and_heading():
    p, yaw = hw.to_world(np.array([[3.0, 4.0]]), np.array([0.5]))
    assert np.allclose(p, [[3.0, -4.0]]) and np.allclose(yaw, [-0.5])
    assert np.allclose(hw.to_world(p), [[3.0, 4.0]])  # its own inverse


# --------------------------------------------------------------------------- BEV observation


def _allowed_colour(px: np.ndarray) -> np.ndarray:
    """Background, drivable, vehicle, ego or a lane hue (saturation = value = 1)."""
    fixed = [np.all(px == np.array(c), axis=-1) for c in (BACKGROUND, DRIVABLE, VEHICLE, EGO)]
    hue = (px.max(axis=-1) == 255) & (px.min(axis=-1) == 0)
    return np.any(fixed, axis=0) | hue


def test_bev_wrapper_shape_dtype_colours_and_ego_pixel():
    cfg = world.RasterConfig(size=64)
    env = hw.BEVObservation(hw.make_env("roundabout", steps=4), cfg)
    obs, _ = env.reset(seed=1)
    assert obs.shape == (64, 64, 3) and obs.dtype == np.uint8
    assert env.observation_space.contains(obs)
    r, c = cfg.ego_pixel
    assert tuple(obs[r, c]) == EGO
    assert _allowed_colour(obs).all()
    assert (np.all(obs == DRIVABLE, axis=-1)).sum() > 50  # the road is drawn
    obs2, *_ = env.step(np.zeros(2, np.float32))
    assert tuple(obs2[r, c]) == EGO and not np.array_equal(obs, obs2)
    # every visible ado away from the ego box is yellow at the pixel of its centre
    ado, valid = hw.ado_boxes(env, 16)
    pose = hw.ego_pose(env)
    seen = 0
    for box in ado[valid]:
        e = world.to_ego_frame(box[:2], pose)
        rr, cc = cfg.ego_to_pixel(e)
        near_ego = abs(e[0]) < 6.0 and abs(e[1]) < 3.0
        if 0 <= rr < 64 and 0 <= cc < 64 and not near_ego:
            assert tuple(obs2[rr, cc]) == VEHICLE, (box, e)
            seen += 1
    assert seen >= 1


def test_bev_channels_with_history():
    """The learner's encoding: binary planes, the ego's and the ados' past boxes drawn from
    what the wrapper saw (none at reset), the same rasteriser as the world's."""
    cfg = world.RasterConfig.from_extent(60.0, 16.0, 0.5, metres_behind=40.0,
                                         encoding="channels", history=2)  # 1 s at 30 m/s
    env = hw.BEVObservation(hw.make_env("highway-fast", steps=4), cfg)
    obs, _ = env.reset(seed=0)
    k = {n: i for i, n in enumerate(cfg.channel_names)}
    assert obs.shape == cfg.input_shape and obs.dtype == np.uint8
    assert env.observation_space.contains(obs) and env.observation_space.high.max() == 1
    assert obs[..., k["vehicles"]].any() and obs[cfg.ego_pixel + (k["ego"],)] == 1
    assert not obs[..., [k["ego_t-1"], k["vehicles_t-1"]]].any()
    pose0 = hw.ego_pose(env)
    for _ in range(2):
        obs, *_ = env.step(np.zeros(2, np.float32))
    # the ego's box two steps back is drawn where its pose then is in today's ego frame
    e = world.to_ego_frame(pose0[:2], hw.ego_pose(env))
    assert obs[cfg.ego_to_pixel(e) + (k["ego_t-2"],)] == 1
    assert obs[..., k["vehicles_t-1"]].any() and obs[..., k["vehicles_t-2"]].any()
    # a new episode starts without a past
    obs, _ = env.reset(seed=1)
    assert not obs[..., k["ego_t-1"]].any()


def test_bev_keeps_right_hand_traffic_on_the_right():
    # ego in highway-env's lane 0 (top of its screen = the driver's left): the other lanes
    # must be to the ego's right in the BEV, i.e. at larger column indices.
    cfg = world.RasterConfig(size=64)
    env = hw.BEVObservation(hw.make_env("highway-fast", steps=4,
                                        config={"vehicles_count": 0, "initial_lane_id": 0}), cfg)
    obs, _ = env.reset(seed=0)
    r, c = cfg.ego_pixel
    road = ~np.all(obs[r] == BACKGROUND, axis=-1)
    cols = np.nonzero(road)[0]
    lane_px = 4.0 / cfg.res_col
    assert cols.max() > c + 2 * lane_px  # two more lanes on the right
    assert cols.min() >= c - lane_px  # only half a lane on the left


# --------------------------------------------------------------------------- action adapter


@settings(max_examples=40, deadline=None)
@given(v=st.floats(2.0, 30.0), frac=st.floats(-0.95, 0.95), dv=st.floats(-2.0, 2.0))
def test_adapter_inverts_the_bicycle(v, frac, dv):
    L, dt, h = 5.0, 0.5, 0.1
    v_cmd = v + dv
    a = (v_cmd - v) / dt  # |a| <= 4 m/s^2: unsaturated
    v_mean = v + a * (dt - h) / 2
    omega = frac * 0.447 * v_mean / (L / 2)  # within the steering limit
    act = hw.controls_to_action(np.array([v_cmd, omega]), v, length=L, dt=dt, substep=h)
    assert np.all(np.abs(act) <= 1.0)
    acc, delta = act[0] * 5.0, act[1] * np.pi / 4
    assert acc == pytest.approx(a, abs=1e-5)
    beta = np.arctan(np.tan(delta) / 2)
    heading_rate = v_mean * np.sin(beta) / (L / 2)
    assert -heading_rate == pytest.approx(omega, abs=1e-5)  # world yaw rate is mirrored


def test_adapter_saturates_and_rejects_bad_input():
    act = hw.controls_to_action(np.array([40.0, 5.0]), 10.0)
    assert np.allclose(np.abs(act), 1.0)
    assert np.allclose(hw.controls_to_action(np.array([0.0, 1.0]), 0.0), [-1.0 + 1.0, 0.0])
    with pytest.raises(ValueError, match="controls"):
        hw.controls_to_action(np.array([1.0, np.nan]), 5.0)
    with pytest.raises(ValueError, match="speed_gain"):
        hw.controls_to_action(np.array([1.0, 0.0]), 5.0, speed_gain=-1.0)
    with pytest.raises(ValueError, match="length"):
        hw.controls_to_action(np.array([1.0, 0.0]), 5.0, length=0.0)


def test_adapter_tracks_speed_and_yaw_rate_in_highway_env():
    """Stated tolerance: once the acceleration is not saturated, the speed at the end of each
    step equals the command to 1e-6 m/s and the mean yaw rate over the step to 1e-6 rad/s.
    In steady state the unicycle speed (displacement along the heading / DT) is the command
    times cos(beta + omega DT / 2) (sideslip and turning within the step): within 2 %."""
    env = hw.make_env("highway-fast", steps=30, config={"vehicles_count": 0})
    env.reset(seed=0)
    adapter = hw.ActionAdapter(env)
    commands = [(15.0, 0.0)] * 8 + [(15.0, 0.15)] * 6 + [(18.0, -0.1)] * 6 + [(8.0, 0.3)] * 8
    poses, speeds = [hw.ego_pose(env)], [env.vehicle.speed]
    for cmd in commands:
        env.step(adapter(np.array(cmd)))
        poses.append(hw.ego_pose(env))
        speeds.append(env.vehicle.speed)
    poses, speeds, cmd = np.array(poses), np.array(speeds), np.array(commands)
    yaw_rate = world.wrap_angle(np.diff(poses[:, 2])) / world.DT
    settled = np.abs(cmd[:, 0] - speeds[:-1]) <= 5.0 * world.DT  # |a| <= 5 m/s^2
    assert settled.sum() >= 20 and not settled[0]  # 25 -> 15 m/s first saturates
    assert np.abs(speeds[1:][settled] - cmd[settled, 0]).max() < 1e-6
    assert np.abs(yaw_rate - cmd[:, 1]).max() < 1e-6
    unicycle = world.controls_from_poses(poses)[:, 0]
    steady = np.abs(cmd[:, 0] - speeds[:-1]) < 1e-6
    assert steady.sum() >= 15
    assert np.all(np.abs(unicycle[steady] / cmd[steady, 0] - 1) < 0.02)


# --------------------------------------------------------------------------- demonstrations


@pytest.fixture(scope="module")
def small_dataset():
    return hw.collect_demonstrations(["roundabout", "highway-fast"], n_episodes=1, seed=0, steps=6)


def test_collected_demonstrations_follow_the_chapter7_format(small_dataset):
    ds = small_dataset
    S, T = 2, 6
    assert isinstance(ds, world.Dataset) and len(ds) == S and ds.n_steps == T
    assert ds.bev.shape == (S, T, 64, 64, 3) and ds.bev.dtype == np.uint8
    assert ds.controls.shape == (S, T, 2) and ds.goal.shape == (S, T, 3)
    assert ds.lane_target.shape == (S, T, world.K_TARGETS, 2)
    assert ds.ado.shape[:2] == (S, T) and ds.ado.shape[3] == 5
    assert ds.goal_bev.shape == (S, 64, 64, 3)
    assert np.allclose(ds.goal[:, -1], 0.0, atol=1e-5)  # the goal is the last pose
    # controls: speed reached at t+1 and the yaw rate from t to t+1
    yaw_rate = world.wrap_angle(np.diff(ds.ego[:, :, 2], axis=1)) / world.DT
    assert np.allclose(ds.controls[:, :-1, 1], yaw_rate, atol=1e-4)
    step = np.linalg.norm(np.diff(ds.ego[:, :, :2], axis=1), axis=-1) / world.DT
    assert np.allclose(step, ds.controls[:, :-1, 0], atol=6.0 * world.DT / 2)  # |a| <= 6
    # lane targets every 4 m ahead, near the ego's lane centre at the start
    assert np.allclose(ds.lane_target[:, 0, 0, 0], 4.0, atol=0.5)
    assert [t["scenario"] for t in ds.tags] == ["roundabout", "highway-fast"]
    json.dumps(ds.meta)  # JSON-able metadata (the file header)
    obs = inputs.from_dataset(ds, np.array([0, 1]), np.array([0, 3]))
    assert obs["bev"].shape == (2, 64, 64, 3) and obs["motion"].shape == (2, 2)


def test_collected_demonstrations_load_with_the_chapter7_loader(small_dataset, tmp_path):
    path = world.save(small_dataset, tmp_path / "highway.npz")
    back = world.load(path)
    assert back.content_hash() == small_dataset.content_hash()
    for m0, m1 in zip(small_dataset.maps, back.maps):
        assert m0.key == m1.key
        assert np.allclose(m0.route_points, m1.route_points)
        img0 = world.rasterize(m0, back.ego[0, 0].astype(float))
        assert np.array_equal(img0, world.rasterize(m1, back.ego[0, 0].astype(float)))


def test_explicit_recipe_rebuilds_the_same_map(small_dataset):
    m = small_dataset.maps[0]
    again = hw.explicit_map(json.loads(json.dumps(m.recipe)))
    assert again.key == m.key and len(again.lanes) == len(m.lanes)
    assert np.array_equal(again.route_points, m.route_points)
    with pytest.raises(ValueError, match="recipe"):
        hw.explicit_map({"kind": "roundabout"})


def test_same_seed_gives_the_same_rollout():
    a = hw.run_episode("intersection", 3, "expert", steps=5)
    b = hw.run_episode("intersection", 3, "expert", steps=5)
    assert np.array_equal(a.poses, b.poses) and np.array_equal(a.bev, b.bev)
    assert np.array_equal(a.ado, b.ado)

    def policy(obs):
        return np.array([obs["speed"] + 1.0, 0.05 * obs["lane_target"][2, 1]])

    c = hw.run_episode("roundabout", 5, policy, steps=5, record_bev=False)
    d = hw.run_episode("roundabout", 5, policy, steps=5, record_bev=False)
    assert np.array_equal(c.poses, d.poses) and np.array_equal(c.actions, d.actions)
    e = hw.run_episode("roundabout", 6, policy, steps=5, record_bev=False)
    assert not np.array_equal(c.poses, e.poses)


class _Replay:
    """A chapter-9 Policy that replays logged controls (the perfect imitator)."""

    model = None
    setting = "paper"

    def __init__(self, controls):
        self.controls = controls

    def initial_state(self, scenes):
        return {}

    def __call__(self, obs, state, t, scenes):
        assert obs["bev"].shape[0] == len(scenes) and obs["lane_target"].shape[1:] == (10, 2)
        return self.controls[scenes, t], state, {}


def test_closed_loop_replaying_the_expert_matches_it():
    experts, tries = hw.expert_episodes("highway-fast", 2, seed=hw.EVAL_SEED, steps=6,
                                        record_bev=False)
    assert tries >= 2 and all(not ep.collided for ep in experts)
    controls = np.stack([ep.controls for ep in experts])
    res = hw.drive_episodes(_Replay(controls), "highway-fast", experts)
    m = res.metrics
    assert set(m) == {"collision_rate", "off_road_rate", "ade", "goal_distance", "mean_speed",
                      "episodes_per_second"}
    assert m["collision_rate"] == 0.0 and m["off_road_rate"] == 0.0
    assert m["ade"] < 1.0 and m["mean_speed"] > 15.0
    ref = hw.expert_result("highway-fast", experts).metrics
    assert ref["ade"] == 0.0 and ref["collision_rate"] == 0.0
    # a policy that veers off is far from the expert
    res2 = hw.drive_episodes(_Replay(controls + np.array([0.0, 0.2])), "highway-fast", experts)
    assert res2.metrics["ade"] > 2.0 and res2.metrics["ade"] > 4 * m["ade"]


def test_lane_target_follows_the_lane_the_ego_is_in():
    turns = [0.1] * 3 + [-0.1] * 3 + [0.0] * 2
    ep = hw.run_episode("highway-fast", 0, lambda o: np.array([25.0, turns[o["t"]]]), steps=8,
                        record_bev=False, config={"vehicles_count": 0})
    assert ep.poses[-1, 1] - ep.poses[0, 1] > 4.0  # moved one 4 m lane to the left
    first = ep.lane_target[:, 0]
    assert np.all(np.abs(first[:, 1]) <= 2.0 + 1e-6)  # never more than half a lane away
    moved = ep.poses[-1, 1] - ep.poses[0, 1]  # now nearest to the lane 4 m left of the start
    assert np.allclose(first[-1], [4.0, 4.0 - moved], atol=0.05)


def test_plain_policy_drives_like_the_closed_loop():
    experts, _ = hw.expert_episodes("roundabout", 1, seed=hw.EVAL_SEED, steps=5,
                                    record_bev=False)
    pol = _Replay(np.stack([ep.controls for ep in experts]) + np.array([1.0, 0.05]))
    res = hw.drive_episodes(pol, "roundabout", experts)
    goal = experts[0].poses[experts[0].steps - 1]
    ep = hw.run_episode("roundabout", experts[0].seed, hw.plain_policy(pol, goal), steps=4,
                        goal=goal, record_bev=False)
    assert np.array_equal(ep.poses, res.episodes[0].poses)


def test_cli_collect_and_expert_eval(tmp_path, capsys):
    from minimanc.cli import main

    out = tmp_path / "hw.npz"
    assert main(["highway", "collect", "--scenarios", "roundabout", "--episodes", "1",
                 "--steps", "3", "--out", str(out), "--quiet"]) == 0
    assert "wrote 1 expert episodes of 3 steps" in capsys.readouterr().out
    assert world.load(out).bev.shape == (1, 3, 64, 64, 3)
    assert main(["highway", "eval", "--scenarios", "roundabout", "--episodes", "1",
                 "--steps", "3", "--out", str(tmp_path / "e.json")]) == 0
    report = json.loads((tmp_path / "e.json").read_text())
    assert report["roundabout"]["expert"]["ade"] == 0.0


@pytest.mark.parametrize("argv,expected", [
    (["collect", "--seed", "-1"], "--seed must be an integer >= 0, got --seed=-1"),
    (["collect", "--episodes", "0"], "--episodes must be an integer >= 1, got --episodes=0"),
    (["collect", "--steps", "-2"], "--steps must be an integer >= 1, got --steps=-2"),
    (["collect", "--size", "0"], "--size must be an integer >= 8, got --size=0"),
    (["train", "--data", "x.npz", "--epochs", "0"],
     "--epochs must be an integer >= 1, got --epochs=0"),
    (["train", "--data", "x.npz", "--lr", "-1"], "--lr must be > 0, got --lr=-1.0"),
    (["train", "--data", "x.npz", "--models", "gpt"], "--models: unknown model(s) gpt"),
    (["train", "--data", "{tmp}/none.npz", "--out", "{tmp}/runs"], "none.npz: no such file"),
    (["train", "--data", "{tmp}/x.npy", "--out", "{tmp}/runs"],
     "x.npy: is a single NumPy array (.npy file); expected a dataset archive"),
    (["eval", "--episodes", "0"], "--episodes must be an integer >= 1, got --episodes=0"),
    (["eval", "--checkpoints", "{tmp}/none.npz"], "no checkpoint at path="),
    (["eval", "--checkpoints", "{tmp}/x.npy"], "x.npy: unreadable checkpoint"),
    (["render", "--seed", "-5"], "--seed must be an integer >= 0, got --seed=-5"),
    (["render", "--checkpoint", "{tmp}/x.npy", "--out", "{tmp}/f"],
     "--checkpoint {tmp}/x.npy: unreadable checkpoint"),
])
def test_cli_user_errors_are_one_line_exit_2(tmp_path, capsys, argv, expected):
    from minimanc.cli import main

    np.save(tmp_path / "x.npy", np.zeros(3))
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    code = main(["highway", *argv])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith("minimanc highway: error: ")
    assert expected.replace("{tmp}", str(tmp_path)) in err


def test_cli_unwritable_out_is_refused_before_collecting(tmp_path, capsys, monkeypatch):
    from minimanc.cli import main

    monkeypatch.setattr(hw, "collect_demonstrations",
                        lambda *a, **k: pytest.fail("collected anyway"))
    blocker = tmp_path / "file"
    blocker.write_text("x")
    for out, expected in ((blocker / "hw.npz", "file: exists and is not a directory"),
                          (blocker / "sub" / "hw.npz", "cannot create the directory"),
                          (tmp_path, "is a directory, expected a file name")):
        code = main(["highway", "collect", "--out", str(out), "--quiet"])
        err = capsys.readouterr().err
        assert code == 2 and len(err.splitlines()) == 1 and expected in err, err


# --------------------------------------------------------------------------- rendering


def test_headless_frames_png_and_gif(tmp_path):
    from PIL import Image

    env = hw.make_env("roundabout", steps=4, render=True)
    env.reset(seed=0)
    frame = hw.render_frame(env)
    assert frame.ndim == 3 and frame.dtype == np.uint8 and frame.mean() > 20  # not black
    assert env.unwrapped.enable_auto_render is False
    env.step(np.zeros(2, np.float32))
    frames = [frame, hw.render_frame(env)]
    png = hw.save_png(frames[1], tmp_path / "f.png")
    gif = hw.save_gif(frames, tmp_path / "e.gif", fps=2)
    assert Image.open(png).size == (frame.shape[1], frame.shape[0])
    with Image.open(gif) as im:
        assert im.n_frames == 2
    with pytest.raises(ValueError, match="render_mode"):
        hw.render_frame(hw.make_env("roundabout"))
    with pytest.raises(ValueError, match="frames"):
        hw.save_gif([], tmp_path / "x.gif")


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="scenario"):
        hw.make_env("parking")
    with pytest.raises(ValueError, match="steps"):
        hw.run_episode("roundabout", 0, "expert", steps=1)
    with pytest.raises(ValueError, match="policy"):
        hw.run_episode("roundabout", 0, "human", steps=3)
    with pytest.raises(ValueError, match="max_ado"):
        hw.ado_boxes(hw.make_env("roundabout"), -1)
    with pytest.raises(ValueError, match="n_episodes"):
        hw.collect_demonstrations("roundabout", n_episodes=0)
    with pytest.raises(ValueError, match="scenario"):
        hw.collect_demonstrations(["roundabout", "merge"], n_episodes=1)



@pytest.mark.parametrize("call, name, minimum", [
    (lambda p: hw.make_env("roundabout", steps=2.5), "steps", 1),
    (lambda p: hw.run_episode("roundabout", 0, "expert", steps=True), "steps", 2),
    (lambda p: hw.ado_boxes(hw.make_env("roundabout"), 1.5), "max_ado", 0),
    (lambda p: hw.BEVObservation(hw.make_env("roundabout"), max_ado=2.5), "max_ado", 0),
    (lambda p: hw.expert_episodes("roundabout", 1.0, steps=2), "n", 1),
    (lambda p: hw.collect_demonstrations("roundabout", n_episodes=True), "n_episodes", 1),
    (lambda p: hw.save_png(np.zeros((4, 4, 3), np.uint8), p / "f.png", scale=1.5), "scale", 1),
    (lambda p: hw.save_gif([np.zeros((4, 4, 3), np.uint8)], p / "f.gif", scale=0), "scale", 1),
])
def test_integer_arguments_are_integers_not_truncated_floats(tmp_path, call, name, minimum):
    """2.5 steps or a 1.5x scale is refused naming the argument, never truncated to 2 or 1."""
    with pytest.raises(ValueError, match=rf"^{name} must be an integer >= {minimum}, got {name}="):
        call(tmp_path)
    assert not list(tmp_path.iterdir())


def test_demonstrations_are_built_by_the_world_builder(monkeypatch):
    """to_dataset goes through world.Dataset.build (one builder, one meta) and keeps its maps."""
    eps, _ = hw.expert_episodes("highway-fast", 2, seed=0, steps=3)
    calls = []
    real = world.Dataset.build.__func__
    monkeypatch.setattr(world.Dataset, "build",
                        classmethod(lambda cls, *a, **k: (calls.append(k.get("what")),
                                                          real(cls, *a, **k))[1]))
    ds = hw.to_dataset(eps, seed=0)
    assert calls == ["demonstrations"]
    assert list(ds.meta)[:8] == list(world.fileformat.META_KEYS)
    assert ds.meta["source"] == "highway-env"
    assert ds.meta["scene_index"] == [ep.seed for ep in eps]
    assert all(ds.maps[i] is ep.map for i, ep in enumerate(eps))
    eps[0].speeds[1] = np.nan  # controls[0, 0] is the speed reached at step 1
    with pytest.raises(ValueError, match=r"^demonstrations holds a non-finite number: "
                                         r"controls\[scene 0, step 0, 0\] = nan"):
        hw.to_dataset(eps, seed=0)

class _NoImage(_Replay):
    """A replaying policy that names its keys: the closed loop draws no BEV for it."""

    keys = ("lane_target", "motion")

    def __call__(self, obs, state, t, scenes):
        assert set(obs) == {"lane_target", "motion"}
        return self.controls[scenes, t], state, {}


def test_highway_closed_loop_honours_keys_and_checks_controls():
    experts, _ = hw.expert_episodes("roundabout", 1, seed=hw.EVAL_SEED, steps=4,
                                    record_bev=False)
    controls = np.stack([ep.controls for ep in experts])
    res = hw.drive_episodes(_NoImage(controls), "roundabout", experts)
    ref = hw.drive_episodes(_Replay(controls), "roundabout", experts)
    assert np.array_equal(res.episodes[0].poses, ref.episodes[0].poses)
    with pytest.raises(rollout.BadControls, match="step 0"):
        hw.drive_episodes(_Replay(controls * np.nan), "roundabout", experts)
    with pytest.raises(rollout.BadControls, match="step 0"):
        hw.run_episode("roundabout", 0, lambda o: np.array([np.inf, 0.0]), steps=3)


def test_highway_sim_is_a_simulator_of_one_or_more_rows():
    sim = hw.HighwaySim("roundabout", [0, 1], 3)
    motion = sim.reset()
    scene = sim.observe()
    assert motion.shape == (2, 2) and motion.dtype == np.float32 and np.all(motion[:, 1] == 0)
    assert scene.pose.shape == (2, 3) and scene.ado.shape[0] == 2 and len(scene.maps) == 2
    assert np.array_equal(scene.goal, scene.pose)  # no goal given: the start pose
    sim.step(np.array([[8.0, 0.0], [8.0, 0.0]]))
    eps = sim.finish()
    assert [ep.steps for ep in eps] == [1, 1] and eps[0].seed == 0
