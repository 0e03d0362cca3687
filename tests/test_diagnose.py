"""Chapter 12 — the room of the crash investigation (minimanc.diagnose): the expert driven
closed loop is the log, the style floor re-drives the log with each scene's own style, the
perception features are what the human saw, the privileged MLP learns a known map, the
linear probe reads a linear quantity and not noise, and a drive into a standing car is a
collision of the ego's fault, faster than the human."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from minimanc import metrics, rollout, world
from minimanc.dagger.teachers import AGENTS, WorldTeacher
from minimanc.diagnose import (
    ExpertRollout,
    collision_taxonomy,
    expert_rollout,
    floor_rollout,
    linear_probe,
    median_style,
    policies,
)
from minimanc.diagnose import privileged as P
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
    traj = expert_rollout(ds, agents=agents)
    assert isinstance(traj, rollout.Rollout) and isinstance(traj, ExpertRollout)
    assert traj.refused == 0 and traj.agents == agents
    assert (traj.ado is None) == (agents == "replay")
    err = float(np.abs(traj.ego[..., :2] - np.asarray(ds.ego)[..., :2]).max())
    assert err < LOG_POSE, f"the expert's closed loop left the log by {err:.3g} m"
    m = metrics.evaluate(traj, ds)
    assert m["at_fault_collision_rate"] == 0.0


def test_the_expert_drives_the_scenes_it_is_given(ds):
    part = expert_rollout(ds, agents="reactive", scenes=[1, 3])
    assert part.scenes.tolist() == [1, 3] and part.ego.shape[0] == 2
    np.testing.assert_allclose(part.ego, np.asarray(ds.ego)[[1, 3]], atol=LOG_POSE)
    with pytest.raises(ValueError, match="agents"):
        expert_rollout(ds, agents="frozen")


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
    policy = policies.PrivilegedPolicy(model, teacher, record=True)
    rollout.simulate(policy, ds, scenes=[0, 1], agents="reactive", progress=False)
    Xv, Yv = policy.visited()
    T = np.asarray(ds.ego).shape[1]
    assert len(Xv) == 2 * (T - 1) - policy.refused
    assert np.all(np.isfinite(Xv)) and np.all(np.isfinite(Yv))
    # the first state of each scene is the logged start: its label is the human's
    np.testing.assert_allclose(Yv[0], Y[0], atol=1e-3)


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
    runs = [rollout.simulate(policies.PrivilegedPolicy(model, teacher, noise=n), ds, scenes=[0, 1],
                             agents="reactive", progress=False).ego
            for n in (None, {"gap": 0.0, "v": 0.0}, {"v": 3.0})]
    assert np.array_equal(runs[0], runs[1])
    assert not np.allclose(runs[0], runs[2])


def test_the_floor_with_each_scene_s_own_style_is_the_log(ds):
    own = floor_rollout(ds, None, scenes=[0, 1])
    assert isinstance(own, rollout.Rollout) and own.agents == "reactive"
    assert own.scenes.tolist() == [0, 1] and own.controls.shape == (2, ds.n_steps - 1, 2)
    np.testing.assert_allclose(own.ego, np.asarray(ds.ego)[:2], atol=LOG_POSE)
    # the human re-drove its own log: the controls it applied are the logged ones
    np.testing.assert_allclose(own.controls, np.asarray(ds.controls)[:2, :-1], atol=1e-4)
    assert own.ado.shape[:2] == own.ego.shape[:2]
    med = floor_rollout(ds, median_style(200), scenes=[0, 1])
    assert med.ego.shape == own.ego.shape
    np.testing.assert_allclose(med.ego[:, 0], own.ego[:, 0], atol=0)  # same start
    assert not np.allclose(med.ego, own.ego)  # another style drives otherwise


def test_the_floor_re_simulates_its_ados_and_refuses_a_replayed_log(ds):
    with pytest.raises(ValueError, match="agents must be 'reactive'"):
        floor_rollout(ds, None, agents="replay", scenes=[0])
    with pytest.raises(ValueError, match="agents"):
        floor_rollout(ds, None, agents="frozen", scenes=[0])


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


def test_a_drive_into_a_standing_car():
    T = 10
    t = np.arange(T) * 0.5
    ego = np.zeros((1, T, 3))
    ego[0, :, 0] = 10.0 * t  # 10 m/s along x
    human = np.zeros((1, T, 3))
    human[0, :, 0] = np.minimum(4.0 * t, 20.0)  # slower, stops before the car
    ado = np.zeros((1, T, 1, 5))
    ado[..., 0], ado[..., 3], ado[..., 4] = 30.0, 4.5, 1.9  # standing 30 m ahead
    valid = np.ones((1, T, 1), bool)
    out = collision_taxonomy(ego, ado, valid, human)
    assert out["stopped_ado"] == 1.0 and out["at_fault"] == 1.0
    assert sum(out[k] for k in ("stopped_ego", "stopped_ado", "rear", "front", "lateral")) == 1
    assert out["ego_speed"] == pytest.approx(10.0) and out["faster"] == 1.0
    assert out["human_speed"] < 10.0
    # the human's own drive touches nothing
    clean = collision_taxonomy(human, ado, valid, human)
    assert clean["at_fault"] == 0.0 and np.isnan(clean["ego_speed"])


def test_taxonomy_refuses_another_shape():
    with pytest.raises(ValueError, match="human"):
        collision_taxonomy(np.zeros((1, 4, 3)), np.zeros((1, 4, 1, 5)),
                           np.zeros((1, 4, 1), bool), np.zeros((1, 5, 3)))


def test_linear_probe_reads_a_linear_quantity_and_not_noise():
    rng = np.random.default_rng(0)
    z = rng.normal(size=(600, 20))
    w = rng.normal(size=(20,))
    y = np.stack([z @ w + 3.0, rng.normal(size=600)], axis=1)  # linear, and independent noise
    out = linear_probe(z[:400], y[:400], z[400:], y[400:], ridge=1e-3)
    assert out["r2"][0] > 0.999 and out["rmse"][0] < 0.05 * out["std"][0]
    assert out["r2"][1] < 0.1
    img = z.reshape(600, 5, 2, 2)  # features of any shape are flattened per state
    same = linear_probe(img[:400], y[:400], img[400:], y[400:], ridge=1e-3)
    np.testing.assert_allclose(same["r2"], out["r2"])
    with pytest.raises(ValueError, match="must agree"):
        linear_probe(z[:400], y[:300], z[400:], y[400:])
    with pytest.raises(ValueError, match="finite"):
        linear_probe(np.full((4, 2), np.nan), y[:4], z[:4, :2], y[:4])


def test_every_rollout_takes_the_scenes_then_the_protocol_by_keyword():
    """One calling convention: ``(ds, [policy or style,] scenes, *, agents=...)``."""
    for fn in (expert_rollout, floor_rollout, rollout.human, rollout.simulate):
        params = inspect.signature(fn).parameters
        assert params["agents"].kind is inspect.Parameter.KEYWORD_ONLY, fn.__name__
        assert params["scenes"].kind is inspect.Parameter.POSITIONAL_OR_KEYWORD, fn.__name__
