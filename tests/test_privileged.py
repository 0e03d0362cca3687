"""Chapter 11 — the learners that read the world's own numbers (minimanc.dagger.privileged)
and the bounds of Table I (minimanc.studies.bounds): the expert driven closed loop is the
log, the perception features are what the human saw, the MLP learns a known map, the
style floor re-drives the log with the scene's own style."""

from __future__ import annotations

import numpy as np
import pytest

from minimanc import layers, metrics, rollout, vagn, world
from minimanc.dagger import privileged as P
from minimanc.dagger.teachers import AGENTS, WorldTeacher
from minimanc.models import dmp_head
from minimanc.studies.bounds import expert_rollout, floor_rollout, median_style
from minimanc.world.geometry import DT

LOG_POSE = 1e-3
"""The expert re-driving a scene ends on the logged poses up to float32 rounding of the
dataset's start state (measured 2e-5 m)."""


@pytest.fixture(scope="module")
def ds():
    return world.generate(6, seed=5, raster=world.RasterConfig(size=16), workers=1)


@pytest.fixture(scope="module")
def demos(ds):
    return P.demonstrations(ds)


@pytest.mark.parametrize("agents", AGENTS)
def test_the_expert_driven_closed_loop_is_the_log(ds, agents):
    traj, refused = expert_rollout(ds, agents)
    assert refused == 0
    err = float(np.abs(traj.ego[..., :2] - np.asarray(ds.ego)[..., :2]).max())
    assert err < LOG_POSE, f"the expert's closed loop left the log by {err:.3g} m"
    m = metrics.evaluate(traj, ds)
    assert m["at_fault_collision_rate"] == 0.0


def test_demonstrations_are_the_logged_controls(ds, demos):
    X, Y = demos
    S, T = np.asarray(ds.ego).shape[:2]
    assert X.shape == (S * T, len(P.FEATURES)) and Y.shape == (S * T, 2)
    ctrl = np.asarray(ds.controls, dtype=np.float64).reshape(-1, 2)
    v = X[:, P.FEATURES.index("v")]
    np.testing.assert_allclose(v + Y[:, 0] * DT, ctrl[:, 0], atol=1e-9)
    np.testing.assert_allclose(Y[:, 1], ctrl[:, 1], atol=0)
    # the speed feature is the logged speed: the previous step's logged control
    np.testing.assert_allclose(v.reshape(S, T)[:, 1:], ctrl.reshape(S, T, 2)[:, :-1, 0],
                               atol=1e-4)
    # the human drives near its path, facing along it
    assert np.abs(X[:, P.FEATURES.index("lateral")]).max() < 1.0
    assert np.abs(X[:, P.FEATURES.index("heading")]).max() < 0.5
    lead = X[:, P.FEATURES.index("has_leader")]
    assert set(np.unique(lead)) <= {0.0, 1.0}
    assert np.all(X[lead == 0.0, P.FEATURES.index("gap")] == P.FAR)


def test_groups_drop_what_they_name():
    assert len(P.kept()) == len(P.FEATURES)
    idx = P.kept(["leader"])
    assert [P.FEATURES[i] for i in idx if P.FEATURES[i] in P.FEATURE_GROUPS["leader"]] == []
    assert len(idx) == len(P.FEATURES) - len(P.FEATURE_GROUPS["leader"])
    with pytest.raises(ValueError, match="unknown feature groups"):
        P.kept(["radar"])
    assert P.FEATURES.index("dv") not in P.kept(without=["dv"])
    assert len(P.kept(without=["dv", "v"])) == len(P.FEATURES) - 2
    with pytest.raises(ValueError, match="unknown features"):
        P.kept(without=["speed"])
    with pytest.raises(ValueError, match="every feature"):
        P.kept(list(P.FEATURE_GROUPS))


def test_fit_learns_a_smooth_map():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(2000, len(P.FEATURES)))
    Y = np.stack([np.tanh(X[:, 0] - 0.5 * X[:, 3]), 0.3 * X[:, 8] + 0.1 * X[:, 1]], axis=1)
    model = P.fit_privileged(X, Y, steps=1500, seed=0)
    err = np.sqrt(((P.predict(model, X) - Y) ** 2).mean(0)) / Y.std(0)
    assert np.all(err < 0.1), f"relative RMSE {err} (expected < 0.1 on a smooth map)"
    assert np.mean(model.losses[-50:]) < 0.1 * model.losses[0]


def test_fit_refuses_bad_data():
    X = np.zeros((4, len(P.FEATURES)))
    with pytest.raises(ValueError, match="shape"):
        P.fit_privileged(X[:, :3], np.zeros((4, 2)))
    with pytest.raises(ValueError, match="finite"):
        P.fit_privileged(X, np.full((4, 2), np.nan))


def test_a_recording_policy_labels_what_it_visited(ds, demos):
    X, Y = demos
    model = P.fit_privileged(X, Y, steps=50, seed=0)
    teacher = WorldTeacher(ds, agents="reactive")
    policy = P.PrivilegedPolicy(model, teacher, record=True)
    rollout.simulate(policy, ds, scenes=[0, 1], agents="reactive", progress=False)
    Xv, Yv = policy.visited()
    T = np.asarray(ds.ego).shape[1]
    assert len(Xv) == 2 * (T - 1) - policy.refused
    assert np.all(np.isfinite(Xv)) and np.all(np.isfinite(Yv))
    # the first state of each scene is the logged start: its label is the human's
    np.testing.assert_allclose(Yv[0], Y[0], atol=1e-3)


def test_the_dmp_head_learns_the_controls_of_a_known_gain_map(ds, demos):
    """MANC's head on the expert's perception: a learner with ``head="dmp"`` recovers the
    controls that a fixed MLP → gains → DMP step produces in the logged states."""
    X, Y = demos
    lane, motion = P.head_inputs(ds)
    assert lane.shape == (len(X), np.asarray(ds.lane_target).shape[2], 2)
    # the motion is the speed the human had (the logged start's first control at t = 0)
    T = np.asarray(ds.ego).shape[1]
    v = X[:, P.FEATURES.index("v")].reshape(-1, T)
    np.testing.assert_allclose(motion[:, 0].reshape(-1, T)[:, 1:], v[:, 1:], atol=1e-4)
    teacher = P.fit_privileged(X, Y, steps=1, seed=1, head="dmp", lane=lane, motion=motion)
    last = teacher.params["l2"]
    last["w"] = last["w"] * 30.0  # far from the fixed gains, inside the gain box
    target = P.predict(teacher, X, lane, motion)
    learner = P.fit_privileged(X, target, steps=1500, seed=0, head="dmp", lane=lane,
                               motion=motion)
    err = np.sqrt(((P.predict(learner, X, lane, motion) - target) ** 2).mean(0)) / target.std(0)
    assert np.all(err < 0.15), f"relative RMSE {err} (expected < 0.15 on a map the head holds)"


def test_the_dmp_head_needs_what_it_reads_and_a_known_head(demos):
    X, Y = demos
    with pytest.raises(ValueError, match="head='dmp' or 'vagn' needs lane"):
        P.fit_privileged(X, Y, head="dmp")
    with pytest.raises(ValueError, match=r"lane must have shape"):
        P.fit_privileged(X, Y, head="dmp", lane=np.zeros((3, 10, 2)), motion=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="head must be one of"):
        P.fit_privileged(X, Y, head="gains")


def test_a_dmp_head_policy_drives_and_records_what_its_head_read(ds, demos):
    X, Y = demos
    lane, motion = P.head_inputs(ds)
    model = P.fit_privileged(X, Y, steps=50, seed=0, head="dmp", lane=lane, motion=motion)
    policy = P.PrivilegedPolicy(model, WorldTeacher(ds, agents="reactive"), record=True)
    assert policy.keys == ("lane_target", "motion")
    traj = rollout.simulate(policy, ds, scenes=[0, 1], agents="reactive", progress=False)
    Xv, Yv = policy.visited()
    ln, mo = policy.visited_head_inputs()
    assert len(ln) == len(mo) == len(Xv) and np.all(np.isfinite(ln))
    # the motion it read is the control it applied one step before (rows: step, scene)
    assert policy.refused == 0
    np.testing.assert_allclose(mo.reshape(-1, 2, 2)[1:].swapaxes(0, 1), traj.controls[:, :-1],
                               atol=1e-5)
    # the first state of each scene is the logged start: its label is the human's
    np.testing.assert_allclose(Yv[0], Y[0], atol=1e-3)


def test_the_vagn_head_is_manc_on_the_expert_s_perception(ds, demos):
    """``head="vagn"``: predicates σ(MLP(features)) → vAGN → FC(q) → DMP step; trained on
    whole scenes, it lowers its loss, carries q along a scene, and drives closed loop."""
    X, Y = demos
    lane, motion = P.head_inputs(ds)
    T = np.asarray(ds.ego).shape[1]
    model = P.fit_privileged(X, Y, steps=120, seed=0, head="vagn", lane=lane, motion=motion,
                             scene_steps=T)
    assert np.mean(model.losses[-10:]) < 0.5 * np.mean(model.losses[:3])
    Z = (X[:4][:, model.keep] - model.mean) / model.std
    N = model.cfg.n_states
    q0 = np.full((4, N), 1.0 / N)
    pr = model.params
    h = np.tanh(layers.dense(pr["l1"], np.tanh(layers.dense(pr["l0"], Z))))
    pred = 1.0 / (1.0 + np.exp(-layers.dense(pr["l2"], h)))
    q1 = vagn.step(q0, pred, pr["vagn"]["W"])
    want, _ = dmp_head(layers.dense(pr["gains"], q1), lane[:4], motion[:4], model.cfg)
    got, q = P.advance(model, Z, lane[:4], motion[:4], q0)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(q, q1, rtol=1e-9, atol=1e-12)
    # along a scene q is carried: predict_scenes is predict step by step from uniform
    a = P.predict_scenes(model, X[:2 * T], lane[:2 * T], motion[:2 * T], scene_steps=T)
    qs = None
    for t in range(T):
        rows = [t, T + t]
        at, qs = P.predict(model, X[rows], lane[rows], motion[rows], qs)
        np.testing.assert_allclose(a[rows], at, rtol=1e-9, atol=1e-12)
    policy = P.PrivilegedPolicy(model, WorldTeacher(ds, agents="reactive"))
    np.testing.assert_allclose(policy.initial_state(np.array([0, 1])).sum(1), 1.0)
    m = P.evaluate_policy(policy, ds, "reactive")
    assert np.isfinite(m["ade"])


def test_the_gains_read_the_predicates_beside_q_in_vagn_predicates(ds, demos):
    X, Y = demos
    lane, motion = P.head_inputs(ds)
    T = np.asarray(ds.ego).shape[1]
    model = P.fit_privileged(X, Y, steps=3, seed=0, head="vagn_predicates", lane=lane,
                             motion=motion, scene_steps=T)
    N, M = model.cfg.n_states, model.cfg.n_predicates
    assert model.params["gains"]["w"].shape == (N + M, 4)
    Z = (X[:3][:, model.keep] - model.mean) / model.std
    pr = model.params
    h = np.tanh(layers.dense(pr["l1"], np.tanh(layers.dense(pr["l0"], Z))))
    pred = 1.0 / (1.0 + np.exp(-layers.dense(pr["l2"], h)))
    q1 = vagn.step(np.full((3, N), 1.0 / N), pred, pr["vagn"]["W"])
    logits = layers.dense(pr["gains"], np.concatenate([q1, pred], axis=1))
    want, _ = dmp_head(logits, lane[:3], motion[:3], model.cfg)
    got, _ = P.advance(model, Z, lane[:3], motion[:3], np.full((3, N), 1.0 / N))
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)


def test_the_vagn_head_refuses_what_it_cannot_train_on(ds, demos):
    X, Y = demos
    lane, motion = P.head_inputs(ds)
    with pytest.raises(ValueError, match="needs scene_steps"):
        P.fit_privileged(X, Y, head="vagn", lane=lane, motion=motion)
    with pytest.raises(ValueError, match="needs scene_steps"):
        P.fit_privileged(X, Y, head="vagn", lane=lane, motion=motion, scene_steps=7)
    with pytest.raises(ValueError, match="DAgger of the privileged learner"):
        P.dagger_rounds(ds, ds, 1, 1, head="vagn")


def test_blur_adds_the_named_errors_and_nothing_else(demos):
    X, _ = demos
    rng = np.random.default_rng(0)
    noisy = np.tile(X, (40, 1))
    B = P.blur(noisy, {"gap": 2.0, "dv": 0.5}, rng)
    err = B - noisy
    other = [i for i, f in enumerate(P.FEATURES) if f not in ("gap", "dv")]
    assert np.array_equal(B[:, other], noisy[:, other])
    assert np.array_equal(noisy, np.tile(X, (40, 1)))  # the input is not changed
    dv = err[:, P.FEATURES.index("dv")]
    # 40 copies of every state: the sample std of N draws is within 4 standard errors
    assert abs(dv.std() - 0.5) < 4 * 0.5 / np.sqrt(2 * len(dv))
    assert abs(dv.mean()) < 4 * 0.5 / np.sqrt(len(dv))
    gap = B[:, P.FEATURES.index("gap")]
    assert gap.max() <= P.FAR
    assert np.array_equal(P.blur(X, {"gap": 0.0}, rng), X)


@pytest.mark.parametrize("noise, match", [({"speed": 1.0}, "unknown feature"),
                                          ({"gap": -1.0}, "finite number >= 0"),
                                          ({"gap": float("nan")}, "finite number >= 0")])
def test_blur_refuses_bad_noise(demos, noise, match):
    with pytest.raises(ValueError, match=match):
        P.blur(demos[0], noise, np.random.default_rng(0))


def test_a_policy_without_noise_and_with_zero_noise_drive_alike(ds, demos):
    model = P.fit_privileged(*demos, steps=50, seed=0)
    teacher = WorldTeacher(ds, agents="reactive")
    runs = [rollout.simulate(P.PrivilegedPolicy(model, teacher, noise=n), ds, scenes=[0, 1],
                             agents="reactive", progress=False).ego
            for n in (None, {"gap": 0.0, "v": 0.0}, {"v": 3.0})]
    assert np.array_equal(runs[0], runs[1])
    assert not np.allclose(runs[0], runs[2])


def test_the_floor_with_each_scene_s_own_style_is_the_log(ds):
    own = floor_rollout(ds, None, scenes=[0, 1])
    np.testing.assert_allclose(own.ego, np.asarray(ds.ego)[:2], atol=LOG_POSE)
    med = floor_rollout(ds, median_style(200), scenes=[0, 1])
    assert med.ego.shape == own.ego.shape
    np.testing.assert_allclose(med.ego[:, 0], own.ego[:, 0], atol=0)  # same start
    assert not np.allclose(med.ego, own.ego)  # another style drives otherwise


def test_median_style_is_a_median():
    st = median_style(101, seed=1)
    assert 7.5 <= st.v0 <= 15.0 and 0.8 <= st.T <= 2.4
    with pytest.raises(ValueError):
        median_style(0)


def test_the_floor_refuses_a_dataset_that_was_not_generated(ds):
    sub = ds.subset([0])
    sub.meta = {k: v for k, v in sub.meta.items() if k != "attempts"}
    with pytest.raises(ValueError, match="generated dataset"):
        floor_rollout(sub, None)
