"""Tests for minimanc.rollout: human replay, closed-loop fidelity, batching, model state."""

from __future__ import annotations

import numpy as np
import pytest

from minimanc import metrics, models, rollout, world


@pytest.fixture(scope="module")
def ds():
    return world.generate(5, seed=3, raster=world.RasterConfig(size=32), workers=1)


class Logged:
    """Outputs the logged human controls: must reproduce the human trajectory."""

    model = None
    setting = "paper"

    def __init__(self, ds):
        self.ds = ds

    def initial_state(self, scenes):
        return {"calls": 0}

    def __call__(self, obs, state, t, scenes):
        return self.ds.controls[scenes, t], {"calls": state["calls"] + 1}, {}


class Pursuit:
    """A deterministic function of the observation only (steers at a lane-target point,
    speed from the previous motion), and records what it saw."""

    model = None
    setting = "parity"

    def __init__(self):
        self.seen = []

    def initial_state(self, scenes):
        return None

    def __call__(self, obs, state, t, scenes):
        self.seen.append((t, scenes.copy(), {k: np.array(v) for k, v in obs.items()}))
        p = obs["lane_target"][:, 2]
        psi = 2 * np.arctan2(p[:, 1], p[:, 0])
        v = np.clip(obs["motion"][:, 0] + 0.5, 0.0, 12.0)
        u = np.stack([v, psi / 1.5], -1)
        return u, state, {"q": np.stack([np.full(len(v), 0.25), np.full(len(v), 0.75)], -1)}


def test_human_replay_is_the_log(ds):
    h = rollout.human(ds)
    T = ds.ego.shape[1]
    assert h.ego.shape == ds.ego.shape and h.controls.shape == (len(ds), T - 1, 2)
    assert np.all(metrics.ade(h.ego, ds.ego) == 0.0)
    res = metrics.evaluate(h, ds)
    assert res["ade"] == 0.0
    # the logged goal distance: final pose to the goal, as the dataset stores it
    logged = np.linalg.norm(ds.goal[:, -1, :2], axis=-1)
    assert np.allclose(metrics.goal_distance(h.ego, ds.ego[:, -1]), logged, atol=1e-4)
    assert res["collision_rate"] == 0.0 and res["off_road_rate"] == 0.0  # data are clean


def test_logged_controls_reproduce_human_in_closed_loop(ds):
    r = rollout.simulate(Logged(ds), ds, progress=False)
    assert r.ego.shape == ds.ego.shape
    assert metrics.ade(r.ego, ds.ego).max() < 1e-3
    assert np.allclose(r.controls, ds.controls[:, :-1])
    assert np.all(r.scenes == np.arange(len(ds)))


def test_observations_come_from_the_policys_own_pose(ds):
    pol = Pursuit()
    r = rollout.simulate(pol, ds, scenes=[1, 3], steps=6, progress=False)
    assert r.ego.shape == (2, 7, 3) and r.aux["q"].shape == (2, 6, 2)
    cfg = ds.raster
    for t, scenes, obs in pol.seen:
        pose = r.ego[:, t]
        bev = world.rasterize_batch([ds.maps[s] for s in scenes], pose, ds.ado[scenes, t],
                                    ds.ado_valid[scenes, t], cfg)
        assert np.allclose(obs["bev"], bev / 255.0)
        goal = world.goal_in_ego_frame(ds.ego[scenes, -1].astype(np.float64), pose)
        assert np.allclose(obs["goal"], goal, atol=1e-4)
        lt = np.stack([world.lane_targets(ds.maps[s], pose[i]) for i, s in enumerate(scenes)])
        assert np.allclose(obs["lane_target"], lt, atol=1e-4)
        expect_motion = (ds.controls[scenes, 0] * [1, 0] if t == 0 else r.controls[:, t - 1])
        assert np.allclose(obs["motion"], expect_motion, atol=1e-5)
    # the policy deviates from the human: its poses are its own
    assert metrics.ade(r.ego, ds.ego[[1, 3], :7]).max() > 0.01


def test_batching_equals_per_scene(ds):
    a = rollout.simulate(Pursuit(), ds, batch_size=len(ds), steps=8, progress=False)
    b = rollout.simulate(Pursuit(), ds, batch_size=1, steps=8, progress=False)
    c = rollout.simulate(Pursuit(), ds, batch_size=2, steps=8, progress=False)
    for other in (b, c):
        assert np.allclose(a.ego, other.ego, atol=1e-9)
        assert np.allclose(a.controls, other.controls, atol=1e-9)
        assert np.allclose(a.aux["q"], other.aux["q"])


def test_rollout_save_load_roundtrip(ds, tmp_path):
    r = rollout.simulate(Pursuit(), ds, scenes=[0, 2], steps=4, progress=False)
    path = r.save(tmp_path / "r.npz")
    back = rollout.Rollout.load(path)
    assert back.name == r.name and back.setting == r.setting
    assert np.array_equal(back.ego, r.ego) and np.array_equal(back.controls, r.controls)
    assert np.array_equal(back.aux["q"], r.aux["q"]) and np.array_equal(back.scenes, [0, 2])


def test_bad_input(ds):
    with pytest.raises(ValueError, match="steps"):
        rollout.simulate(Logged(ds), ds, steps=ds.ego.shape[1], progress=False)
    with pytest.raises(ValueError, match="scenes"):
        rollout.simulate(Logged(ds), ds, scenes=[len(ds)], progress=False)
    with pytest.raises(ValueError, match="batch_size"):
        rollout.simulate(Logged(ds), ds, batch_size=0, progress=False)
    with pytest.raises(ValueError, match="ego"):
        rollout.Rollout("x", "paper", np.zeros((2, 3)), np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match="controls"):
        rollout.Rollout("x", "paper", np.zeros((2, 5, 3)), np.zeros((2, 5, 2)))

    class Broken(Logged):
        def __call__(self, obs, state, t, scenes):
            return np.full((len(scenes), 2), np.nan), state, {}

    with pytest.raises(ValueError, match="controls"):
        rollout.simulate(Broken(ds), ds, steps=2, progress=False)


@pytest.mark.parametrize("name", ["manc", "cnn_lstm"])
def test_model_policy_batching_and_state_carry(ds, name):
    from minimanc import engine, models, vagn

    cfg = models.ModelConfig(input_shape=(32, 32, 3), n_states=4, setting="parity")
    params = models.init(name, np.random.default_rng(1), cfg)
    eng = engine("numpy")
    kw = dict(scenes=[0, 2, 4], steps=5, progress=False)
    a = rollout.closed_loop(name, params, ds, cfg, eng, batch_size=3, **kw)
    b = rollout.closed_loop(name, params, ds, cfg, eng, batch_size=1, **kw)
    assert np.allclose(a.ego, b.ego, atol=1e-5) and np.allclose(a.controls, b.controls, atol=1e-5)
    assert a.name == name and a.setting == "parity" and np.all(np.isfinite(a.ego))
    if name == "manc":
        q, p, W = a.aux["q"], a.aux["predicates"], params["vagn"]["W"]
        assert a.aux["alpha"].shape == (3, 5, 2) and np.allclose(q.sum(-1), 1.0, atol=1e-5)
        # the state carries over: q[t] = vAGN(q[t-1], p[t]) (eq. 9), q[-1] uniform
        for t in range(1, 5):
            assert np.allclose(q[:, t], vagn.step(q[:, t - 1], p[:, t], W), atol=1e-5)
        assert np.allclose(q[:, 0], vagn.step(np.full((3, 4), 0.25), p[:, 0], W), atol=1e-5)
    with pytest.raises(ValueError, match="setting"):
        rollout.closed_loop(name, params, ds, cfg, eng, setting="paper", **kw)


def test_fixed_gains_is_dmp_only_with_a_constant_head(ds):
    """The DMP prior equals DMP-only whose gains layer ignores the predicates (weights 0,
    bias = the gains' logits): the same controls, step by step."""
    from minimanc import dmp, engine, models

    cfg = models.ModelConfig(input_shape=(32, 32, 3), n_states=4)
    gains = (1.5, 0.4, 2.0, 1.0)
    prior = rollout.fixed_gains(ds, scenes=[0, 3], cfg=cfg, gains=gains)
    params = models.init("dmp_only", np.random.default_rng(0), cfg)
    params["gains"]["w"] = np.zeros_like(params["gains"]["w"])
    za, zb = dmp.logits_from_gains(gains[0], gains[1])
    zqa, zqb = dmp.logits_from_gains(gains[2], gains[3])
    params["gains"]["b"] = np.array([za, zb, zqa, zqb])
    model = rollout.closed_loop("dmp_only", params, ds, cfg, engine("numpy"), scenes=[0, 3],
                                progress=False)
    assert prior.name == "dmp_prior" and prior.ego.shape == model.ego.shape
    np.testing.assert_allclose(prior.controls, model.controls, atol=1e-4)
    np.testing.assert_allclose(prior.aux["alpha"][..., 0], gains[0], rtol=1e-9)
    np.testing.assert_allclose(prior.aux["beta"][..., 1], gains[3], rtol=1e-9)
    # the default gains are the ones MANC starts training from
    manc_bias = models.init("manc", np.random.default_rng(0), cfg)["gains"]["b"]
    np.testing.assert_allclose(rollout.FixedGainsPolicy(cfg).logits, manc_bias)


@pytest.mark.parametrize("gains", [(1.0, 0.4, 2.0), (1.0, np.nan, 2.0, 1.0),
                                   (100.0, 0.4, 2.0, 1.0)])
def test_fixed_gains_rejects_bad_gains(gains):
    with pytest.raises(ValueError):
        rollout.FixedGainsPolicy(gains=gains)


def test_a_policy_may_name_its_observation_keys(ds):
    """``keys`` on a policy decides what ``simulate`` builds: the fixed-gain reference reads
    no image, so no BEV is drawn for it; unknown keys are refused."""
    seen = []

    class LaneOnly(rollout.FixedGainsPolicy):
        def __call__(self, obs, state, t, scenes):
            seen.append(sorted(obs))
            return super().__call__(obs, state, t, scenes)

    from minimanc import models

    rollout.simulate(LaneOnly(models.ModelConfig(input_shape=(32, 32, 3))), ds, scenes=[1], steps=2,
                     progress=False)
    assert seen == [["lane_target", "motion"]] * 2
    from minimanc import inputs

    with pytest.raises(ValueError, match="keys"):
        inputs.from_state(ds.maps[0], ds.ego[:1, 0], ds.ado[:1, 0], ds.ado_valid[:1, 0],
                          ds.ego[:1, -1], motion=np.zeros((1, 2)), keys=("bev", "speed"))


class _ToySim:
    """A minimal Simulator: a batch of egos on an empty straight road, no ados."""

    def __init__(self, ds, n):
        self.scenes = np.arange(n)
        self.raster = world.RasterConfig(size=32)
        self.k_targets = None
        self.maps = [ds.maps[0]] * n
        self.steps = []

    def reset(self):
        self.pose = np.zeros((len(self.scenes), 3))
        return np.full((len(self.scenes), 2), [3.0, 0.0], np.float32)

    def observe(self):
        B = len(self.scenes)
        return rollout.SceneState(self.maps, self.pose, np.zeros((B, 1, 5)),
                                  np.zeros((B, 1), bool), self.pose + [10.0, 0.0, 0.0])

    def step(self, controls):
        self.steps.append(controls)
        self.pose = self.pose + np.c_[controls[:, :1] * 0.5, np.zeros((len(controls), 2))]


class _Echo:
    """Asks for the motion only and drives at its previous speed + 1."""

    model = None
    setting = "paper"
    keys = ("motion",)

    def initial_state(self, scenes):
        return 0

    def __call__(self, obs, state, t, scenes):
        assert set(obs) == {"motion"}
        return obs["motion"] + [1.0, 0.0], state + 1, {}


def test_drive_runs_any_simulator_and_carries_motion_and_state(ds):
    sim = _ToySim(ds, 2)
    run = rollout.drive(_Echo(), sim, 4)
    assert run.controls.shape == (2, 4, 2) and run.aux == {}
    assert np.array_equal(run.controls[0, :, 0], [4.0, 5.0, 6.0, 7.0])
    assert len(sim.steps) == 4 and np.allclose(sim.pose[:, 0], 0.5 * (4 + 5 + 6 + 7))
    with pytest.raises(ValueError, match="steps"):
        rollout.drive(_Echo(), sim, 0)


def test_drive_in_log_replay_is_simulate(ds):
    policy = rollout.FixedGainsPolicy()
    sim = rollout.LogReplay(ds, [1, 3])
    run = rollout.drive(policy, sim, 5)
    ref = rollout.simulate(policy, ds, scenes=[1, 3], steps=5, progress=False)
    assert np.array_equal(sim.trajectory(), ref.ego)
    assert np.array_equal(run.controls, ref.controls)
    assert np.array_equal(run.aux["alpha"], ref.aux["alpha"])


def test_check_controls_names_the_policy_and_the_step():
    u = rollout.check_controls([[1, 2]], 1, 0)
    assert u.dtype == np.float64 and u.shape == (1, 2)
    with pytest.raises(rollout.BadControls, match="step 3"):
        rollout.check_controls([[np.nan, 0.0]], 1, 3, rollout.FixedGainsPolicy())
    with pytest.raises(rollout.BadControls, match=r"shape \(2,\)"):
        rollout.check_controls([1.0, 0.0], 1, 0)


# --------------------------------------------------------------------------- open loop on drive


def _replay_loop(name, params, ds, scene, cfg, eng, q_mode):
    """The open-loop trace written as its own loop (as it was written before it ran on
    rollout.drive): the dataset's observations, one models.step per time step."""
    from minimanc import inputs, models

    rng = None if q_mode == "uniform" else np.random.default_rng(0)
    state = models.initial_state(name, 1, cfg, xp=eng.xp, rng=rng, mode=q_mode)
    keep = {"controls": []}
    for t in range(np.asarray(ds.ego).shape[1]):
        obs = inputs.from_dataset(ds, scene, t, cfg.setting, model=models.get(name))
        controls, state, aux = models.step(name, params, obs, state, cfg, eng)
        keep["controls"].append(np.asarray(controls)[0])
        for k in rollout.AUX_KEYS:
            if k in aux:
                keep.setdefault(k, []).append(np.asarray(aux[k])[0])
    out = {k: np.stack(v) for k, v in keep.items()}
    out["human"] = np.asarray(ds.controls[scene], dtype=np.float64)
    return out


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("name,setting,q_mode", [("manc", "paper", "uniform"),
                                                  ("manc", "paper", "random"),
                                                  ("vagn_only", "parity", "random"),
                                                  ("cnn_lstm", "parity", "uniform"),
                                                  ("rvs_g", "paper", "uniform")])
def test_replay_is_drive_following_the_log_and_equals_the_step_loop(ds, name, setting, q_mode,
                                                                     dtype):
    from minimanc import engine, models

    eng = engine("numpy")
    cfg = models.ModelConfig(input_shape=(32, 32, 3), setting=setting, n_states=4, channels=(4, 8))
    params = models.init(name, np.random.default_rng(1), cfg, dtype=dtype)
    want = _replay_loop(name, params, ds, 2, cfg, eng, q_mode)
    got = rollout.replay(name, params, ds, 2, cfg, eng, q_mode=q_mode)
    assert set(got) == set(want)
    for k in want:
        assert got[k].dtype == want[k].dtype and got[k].shape == want[k].shape, k
        np.testing.assert_array_equal(got[k], want[k], err_msg=k)


def test_log_replay_that_follows_the_log_shows_the_logged_observations(ds):
    from minimanc import inputs

    class Record:
        model, setting = "rvs_g", "parity"

        def __init__(self):
            self.seen = []

        def initial_state(self, scenes):
            return None

        def __call__(self, obs, state, t, scenes):
            self.seen.append(obs)
            return np.full((len(scenes), 2), 99.0), state, {}

    sim = rollout.LogReplay(ds, [1, 3], follow_log=True)
    pol = Record()
    run = rollout.drive(pol, sim, ds.n_steps)
    np.testing.assert_array_equal(sim.trajectory(), np.asarray(ds.ego)[[1, 3]])
    assert np.all(run.controls == 99.0)  # what the policy said, not what the ego did
    for t, obs in enumerate(pol.seen):
        want = inputs.from_dataset(ds, [1, 3], [t, t], "parity", model=models.get("rvs_g"))
        assert set(obs) == set(want)
        for k in want:
            np.testing.assert_array_equal(obs[k], want[k], err_msg=f"{k} at t={t}")


# --------------------------------------------------------------------------- aux dtypes


def test_rollout_keeps_the_models_dtype_and_explain_needs_no_dtype_guess(ds, tmp_path):
    """A float32 model's q is recorded as float32 and checked with float32 tolerances
    (checks.value_dtype is the array's own dtype, no guess); explain takes it as q'
    directly."""
    from minimanc import checks, models, vagn

    cfg = models.ModelConfig(input_shape=(32, 32, 3), n_states=5, channels=(4, 8))
    params = models.init("manc", np.random.default_rng(2), cfg, dtype=np.float32)
    traj = rollout.closed_loop("manc", params, ds, cfg, "numpy", scenes=[0, 1], steps=5,
                               progress=False)
    for k in ("q", "alpha", "beta", "predicates"):
        assert traj.aux[k].dtype == np.float32, k
    assert traj.controls.dtype == np.float64 and traj.ego.dtype == np.float64
    back = rollout.Rollout.load(traj.save(tmp_path / "r.npz"))
    assert back.aux["q"].dtype == np.float32
    np.testing.assert_array_equal(back.aux["q"], traj.aux["q"])
    checks.check_distribution("q", traj.aux["q"], 5)
    trace = rollout.replay("manc", params, ds, 1, cfg)  # the logged observations, float32
    assert trace["q"].dtype == np.float32
    obs = {"bev": np.asarray(ds.bev[[1], 3], dtype=np.float32) / np.float32(255.0)}
    q_prev = trace["q"][None, 2]
    out = models.saliency(params, obs, q_prev, cfg)
    q64 = q_prev.astype(np.float64) / q_prev.astype(np.float64).sum(axis=-1, keepdims=True)
    np.testing.assert_allclose(out["q"], vagn.step(q64, out["predicates"],
                                                   np.asarray(params["vagn"]["W"], np.float64)),
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(out["q"].sum(axis=-1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["q"][0], trace["q"][3], rtol=0, atol=1e-5)  # float32 path
    with pytest.raises(ValueError, match="q_prev"):
        models.saliency(params, obs, np.full((1, 5), 0.3, dtype=np.float32), cfg)


# --------------------------------------------------------------------------- protocols


def test_human_under_reactive_agents_is_the_log_without_collisions(ds):
    h = rollout.human(ds, agents="reactive")
    assert h.agents == "reactive" and h.name == "human" and h.ado is not None
    assert np.allclose(h.ego, ds.ego, atol=1e-4)  # the float32 log's controls, integrated again
    res = metrics.evaluate(h, ds)
    assert res["collision_rate"] == 0.0 and res["at_fault_collision_rate"] == 0.0
    log = rollout.human(ds)
    assert log.agents == "replay" and log.ado is None


def test_agents_choose_the_protocol_of_every_closed_loop(ds):
    from minimanc import engine, models

    kw = dict(scenes=[0, 3], progress=False)
    rep = rollout.fixed_gains(ds, **kw)
    rea = rollout.fixed_gains(ds, agents="reactive", **kw)
    assert rep.agents == "replay" and rep.ado is None
    assert rea.agents == "reactive" and rea.name == "dmp_prior"
    T = ds.ego.shape[1]
    assert rea.ado.shape[:2] == (2, T) and rea.ado_valid.shape == rea.ado.shape[:3]
    # the ados start where the log has them; from then on they react to this ego
    assert np.allclose(np.where(rea.ado_valid[:, 0, :, None], rea.ado[:, 0], 0),
                       np.where(ds.ado_valid[[0, 3], 0, :, None], ds.ado[[0, 3], 0], 0),
                       atol=1e-4)
    # the metrics score a reactive rollout on its own ados, not on the log's
    sub = ds.subset([0, 3])
    assert metrics.evaluate(rea, sub)["collision_rate"] <= 100.0
    cfg = models.ModelConfig(input_shape=(32, 32, 3), n_states=3)
    params = models.init("manc", np.random.default_rng(0), cfg)
    a = rollout.closed_loop("manc", params, ds, cfg, engine("numpy"), steps=3,
                            agents="reactive", **kw)
    assert a.agents == "reactive" and a.ado.shape[1] == 4 and a.aux["q"].shape[:2] == (2, 3)
    b = rollout.closed_loop("manc", params, ds, cfg, engine("numpy"), steps=3, **kw)
    assert b.ado is None


def test_bad_agents_are_refused_by_name(ds):
    from minimanc import engine, models

    cfg = models.ModelConfig(input_shape=(32, 32, 3))
    params = models.init("cnn", np.random.default_rng(0), cfg)
    calls = [lambda: rollout.simulate(Logged(ds), ds, progress=False, agents="ideal"),
             lambda: rollout.fixed_gains(ds, agents="ideal"),
             lambda: rollout.human(ds, agents="ideal"),
             lambda: rollout.closed_loop("cnn", params, ds, cfg, engine("numpy"),
                                         agents="ideal"),
             lambda: rollout.Rollout("x", "paper", np.zeros((1, 2, 3)), np.zeros((1, 1, 2)),
                                     agents="ideal")]
    for call in calls:
        with pytest.raises(ValueError, match="agents must be one of"):
            call()
    with pytest.raises(ValueError, match="together"):
        rollout.Rollout("x", "paper", np.zeros((1, 2, 3)), np.zeros((1, 1, 2)),
                        ado=np.zeros((1, 2, 4, 5)))
    with pytest.raises(ValueError, match="ado must have shape"):
        rollout.Rollout("x", "paper", np.zeros((1, 2, 3)), np.zeros((1, 1, 2)),
                        ado=np.zeros((1, 3, 4, 5)), ado_valid=np.zeros((1, 3, 4), bool))


def test_a_reactive_rollout_saves_its_ados_and_an_old_file_loads_as_replay(ds, tmp_path):
    rea = rollout.fixed_gains(ds, scenes=[1, 2], agents="reactive")
    back = rollout.Rollout.load(rea.save(tmp_path / "r.npz"))
    assert back.agents == "reactive"
    assert np.array_equal(back.ado, rea.ado) and np.array_equal(back.ado_valid, rea.ado_valid)
    assert metrics.evaluate(back, ds.subset([1, 2])) == metrics.evaluate(rea, ds.subset([1, 2]))
    # a file written before the protocols existed: no agents, no ados
    old = tmp_path / "old.npz"
    np.savez(old, name=np.array("x"), setting=np.array("paper"), ego=rea.ego,
             controls=rea.controls, scenes=rea.scenes)
    back = rollout.Rollout.load(old)
    assert back.agents == "replay" and back.ado is None


def test_rollout_subset_keeps_rows_aux_and_ados(ds):
    rea = rollout.fixed_gains(ds, scenes=[0, 1, 4], agents="reactive")
    sub = rea.subset([2, 0])
    assert sub.scenes.tolist() == [4, 0] and sub.agents == "reactive"
    assert np.array_equal(sub.ego, rea.ego[[2, 0]]) and np.array_equal(sub.ado, rea.ado[[2, 0]])
    assert np.array_equal(sub.aux["alpha"], rea.aux["alpha"][[2, 0]])


def test_open_loop_is_replay_on_many_scenes(ds):
    from minimanc import engine, models
    from minimanc.models.forward import cast_tree

    cfg = models.ModelConfig(input_shape=(32, 32, 3), n_states=3)
    params = models.init("manc", np.random.default_rng(2), cfg)
    params32 = cast_tree(params, np.float32)  # open_loop runs in float32, replay in params'
    many = rollout.open_loop("manc", params, ds, cfg, engine("numpy"), scenes=[1, 3, 4],
                             batch_size=2)
    T = ds.ego.shape[1]
    assert many["q"].shape == (3, T, 3) and many["controls"].shape == (3, T, 2)
    for row, s in enumerate([1, 3, 4]):
        one = rollout.replay("manc", params32, ds, s, cfg)
        assert np.allclose(many["q"][row], one["q"], atol=1e-5)
        assert np.allclose(many["controls"][row], one["controls"], atol=1e-4)


def test_the_training_result_is_accepted_where_its_parts_are(ds):
    """``closed_loop(fit, ds)`` (and open_loop, replay, ModelPolicy) equal the explicit form
    ``(name, params, ds, cfg)``; a result given with its parts again is refused."""
    from minimanc import train

    cfg = models.ModelConfig(input_shape=(32, 32, 3), n_states=3)
    params = models.init("manc", np.random.default_rng(4), cfg)
    fit = train.FitResult(name="manc", params=params, history=[], cfg=cfg,
                          train_cfg=train.TrainConfig(), steps=7)  # Adam steps, not the loop's
    kw = dict(scenes=[0, 3], steps=3, progress=False)
    whole = rollout.closed_loop(fit, ds, engine="numpy", agents="reactive", **kw)
    parts = rollout.closed_loop("manc", params, ds, cfg, "numpy", agents="reactive", **kw)
    assert whole.name == "manc" and whole.agents == "reactive"
    np.testing.assert_array_equal(whole.ego, parts.ego)
    np.testing.assert_array_equal(whole.aux["q"], parts.aux["q"])
    assert rollout.closed_loop(fit, ds, engine="numpy", scenes=[1], progress=False
                               ).ego.shape == (1, ds.ego.shape[1], 3)  # every step of the log
    a = rollout.open_loop(fit, ds, scenes=[1])
    b = rollout.open_loop("manc", params, ds, cfg, "numpy", scenes=[1])
    np.testing.assert_array_equal(a["controls"], b["controls"])
    np.testing.assert_array_equal(rollout.replay(fit, ds, 2)["controls"],
                                  rollout.replay("manc", params, ds, 2, cfg)["controls"])
    policy = rollout.ModelPolicy(fit, engine="numpy")
    assert (policy.model, policy.cfg, policy.engine.name) == ("manc", cfg, "numpy")
    with pytest.raises(TypeError, match="leave out params and cfg"):
        rollout.closed_loop(fit, params, ds, cfg)
    with pytest.raises(TypeError, match="leave out params and cfg"):
        rollout.ModelPolicy(fit, cfg=cfg)
    with pytest.raises(TypeError, match="leave out params and cfg"):
        rollout.open_loop(fit, ds, "numpy")  # options after the result are keywords


def test_drive_on_route_drives_a_bare_head_along_the_route_and_refuses_bad_controls():
    from minimanc import dmp

    cfg = models.ModelConfig()
    m = world.random_map(np.random.default_rng(3), "curved")
    p, h = m.route_pose(m.start_s)
    start, motion = np.array([p[0], p[1], h]), np.array([5.0, 0.0])
    logits = np.array([[*dmp.logits_from_gains(4.0, 0.45), *dmp.logits_from_gains(3.0, 1.0)]])

    def head(lane, mot):
        return models.dmp_head(logits, lane, mot, cfg)[0]

    poses, u = rollout.drive_on_route(head, m, start, motion, 12)
    assert poses.shape == (13, 3) and u.shape == (12, 2)
    np.testing.assert_allclose(poses[1], world.unicycle_step(start, u[0], world.DT))
    s, lat = world.project_to_route(m, poses[:, :2], poses[:, 2])
    assert np.all(np.diff(s) > 0) and np.abs(lat).max() < 1.0   # it follows the route
    with pytest.raises(ValueError, match="shape \\(1, 2\\)"):
        rollout.drive_on_route(lambda lane, mot: np.zeros(3), m, start, motion, 2)


def test_the_drivers_of_one_model_share_one_jitted_step(ds):
    """``rollout.policies.jitted_policy_step`` gives one jitted step per (model, ModelConfig,
    engine): a second driver of that model (the next DAgger round, another evaluation)
    reuses its compilations; another configuration has its own; the reused step drives to
    the same numbers."""
    from minimanc import engine, models
    from minimanc.rollout.policies import jitted_policy_step

    eng = engine("jax")
    cfg = models.ModelConfig(input_shape=(32, 32, 3), channels=(4, 8), n_states=3)
    step = jitted_policy_step("manc", cfg, eng)
    assert jitted_policy_step("manc", models.ModelConfig(**cfg.to_dict()), eng) is step
    assert jitted_policy_step("manc", models.ModelConfig(**{**cfg.to_dict(), "n_states": 4}),
                              eng) is not step
    assert jitted_policy_step("cnn", cfg, eng) is not step
    params = models.init("manc", np.random.default_rng(1), cfg)
    kw = dict(scenes=[0, 1], steps=4, progress=False)
    first = rollout.closed_loop("manc", params, ds, cfg, eng, **kw)
    again = rollout.closed_loop("manc", params, ds, cfg, eng, **kw)
    assert np.array_equal(first.ego, again.ego)
