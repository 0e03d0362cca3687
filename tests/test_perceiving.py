"""Chapter 11 — the modular learner (minimanc.dagger.perceiving): a perception trained on the
raster, the privileged learner trained on what it reads, and the two driving closed loop on
the raster alone."""

from __future__ import annotations

import numpy as np
import pytest

from minimanc import models, rollout, world
from minimanc.dagger import perceiving as M
from minimanc.dagger import privileged as P
from minimanc.dagger.teachers import WorldTeacher
from minimanc.world.geometry import DT


@pytest.fixture(scope="module")
def ds():
    return world.generate(4, seed=3, raster=world.RasterConfig(size=16), workers=1)


@pytest.fixture(scope="module")
def perception(ds):
    return M.fit_perception(ds, epochs=3, lr=3e-3, cfg=models.ModelConfig(image_size=16))


def test_the_last_acceleration_is_the_difference_of_perceived_speeds():
    rng = np.random.default_rng(0)
    read = rng.normal(size=(2, 5, len(M.PERCEIVE)))
    X = M.with_last_acceleration(read).reshape(2, 5, -1)
    for k, name in enumerate(M.PERCEIVE):
        assert np.array_equal(X[..., P.FEATURES.index(name)], read[..., k])
    a = X[..., P.FEATURES.index("a_prev")]
    v = read[..., M.PERCEIVE.index("v")]
    assert np.all(a[:, 0] == 0.0)
    np.testing.assert_allclose(a[:, 3], (v[:, 3] - v[:, 2]) / DT)


def test_the_perception_learns_its_training_states(ds, perception):
    y = P.perceived(ds, M.PERCEIVE).reshape(-1, len(M.PERCEIVE))
    read = M.read_dataset(perception, ds).reshape(y.shape)
    spread = y.std(0) > 1e-6
    r2 = 1 - ((read - y) ** 2).mean(0)[spread] / y.var(0)[spread]
    # trained on exactly these states: better than their mean on average
    assert r2.mean() > 0.0, f"mean R² of the read features on the training states {r2.mean()}"


def test_read_refuses_a_raster_of_the_wrong_size(perception):
    with pytest.raises(ValueError, match=r"bev must have shape \(B, 16, 16, 3\)"):
        perception.read(np.zeros((2, 32, 32, 3)))


def test_the_modular_learner_drives_on_the_raster_alone(ds, perception):
    driver = M.fit_driver(perception, ds, steps=50)
    policy = M.PerceivingPolicy(perception, driver)
    traj = rollout.simulate(policy, ds, scenes=[0, 1], agents="reactive", progress=False)
    assert traj.ego.shape[0] == 2 and np.all(np.isfinite(traj.ego))
    # its first control is the driver's on what the perception reads in the logged start
    bev0 = np.asarray(ds.bev[[0, 1], 0], dtype=np.float32) / 255.0
    read = perception.read(bev0)
    X = M.with_last_acceleration(read[:, None])
    a = P.predict(driver, X)
    v = read[:, M.PERCEIVE.index("v")]
    u0 = np.stack([np.clip(v + a[:, 0] * DT, 0.0, P.V_MAX), a[:, 1]], axis=1)
    got, _, _ = M.PerceivingPolicy(perception, driver)({"bev": bev0}, None, 0, np.array([0, 1]))
    np.testing.assert_allclose(got, u0)


def test_the_odometer_replaces_the_speed_and_the_last_acceleration_only():
    rng = np.random.default_rng(1)
    X, exact = rng.normal(size=(2, 6, len(P.FEATURES)))
    got = M.with_exact(X, exact)
    for k, name in enumerate(P.FEATURES):
        want = exact[:, k] if name in M.ODOMETER else X[:, k]
        assert np.array_equal(got[:, k], want), f"column {name!r}"
    assert not np.shares_memory(got, X)  # X itself is left as it was
    with pytest.raises(ValueError, match="must both have shape"):
        M.with_exact(X, exact[:3])
    with pytest.raises(ValueError, match="unknown feature 'speed'"):
        M.with_exact(X, exact, ("speed",))


def test_the_odometer_driver_reads_its_speed_from_the_motion_input(ds, perception):
    driver = M.fit_driver(perception, ds, steps=50, exact=M.ODOMETER)
    policy = M.PerceivingPolicy(perception, driver, odometer=True)
    assert policy.keys == ("bev", "motion")
    bev0 = np.asarray(ds.bev[[0, 1], 0], dtype=np.float32) / 255.0
    motion = np.array([[3.0, 0.1], [11.5, -0.2]], dtype=np.float32)
    X = M.with_last_acceleration(perception.read(bev0)[:, None])
    X[:, P.FEATURES.index("v")] = motion[:, 0]
    a = P.predict(driver, X)
    u0 = np.stack([np.clip(motion[:, 0] + a[:, 0] * DT, 0.0, P.V_MAX), a[:, 1]], axis=1)
    got, state, _ = policy({"bev": bev0, "motion": motion}, None, 0, np.array([0, 1]))
    np.testing.assert_allclose(got, u0, rtol=1e-6)
    np.testing.assert_allclose(state, motion[:, 0])
    # the next step's last acceleration is the difference of the two odometer speeds
    later = motion + np.float32(1.0)
    X[:, P.FEATURES.index("v")] = later[:, 0]
    X[:, P.FEATURES.index("a_prev")] = 1.0 / DT
    a = P.predict(driver, X)
    got, _, _ = policy({"bev": bev0, "motion": later}, state, 1, np.array([0, 1]))
    np.testing.assert_allclose(got[:, 0], np.clip(later[:, 0] + a[:, 0] * DT, 0.0, P.V_MAX),
                               rtol=1e-6)
    traj = rollout.simulate(policy, ds, scenes=[0, 1], agents="reactive", progress=False)
    assert traj.ego.shape[0] == 2 and np.all(np.isfinite(traj.ego))


def test_the_oracle_diagnostic_takes_the_named_features_from_the_world(ds, perception):
    """With every feature exact the oracle policy is the privileged policy of the same
    driver, control for control; with the leader exact its controls differ from both."""
    exact = M.ODOMETER + tuple(f for f in P.FEATURES if f not in M.ODOMETER)
    driver = M.fit_driver(perception, ds, steps=50, exact=exact)
    teacher = WorldTeacher(ds, agents="reactive")
    oracle = rollout.simulate(M.OraclePerceivingPolicy(perception, driver, teacher, exact),
                              ds, scenes=[0, 1], agents="reactive", progress=False)
    privileged = rollout.simulate(P.PrivilegedPolicy(driver, teacher), ds, scenes=[0, 1],
                                  agents="reactive", progress=False)
    np.testing.assert_allclose(oracle.ego, privileged.ego, atol=1e-4)
    leader = M.fit_driver(perception, ds, steps=50, exact=M.ODOMETER + ("gap", "dv"))
    part = M.OraclePerceivingPolicy(perception, leader, teacher, ("gap", "dv"))
    assert part.keys == ("bev", "motion")
    traj = rollout.simulate(part, ds, scenes=[0, 1], agents="reactive", progress=False)
    assert np.all(np.isfinite(traj.ego)) and not np.allclose(traj.ego, privileged.ego)
    with pytest.raises(ValueError, match="unknown feature"):
        M.OraclePerceivingPolicy(perception, leader, teacher, ("leader",))


@pytest.fixture(scope="module")
def route_perception(ds):
    return M.fit_perception(ds, epochs=4, lr=3e-3, cfg=models.ModelConfig(image_size=16),
                            hidden=16, route=True, batch=16)


def test_a_hidden_read_out_with_the_route_learns_its_training_states(ds, route_perception):
    per = route_perception
    assert per.route and per.keys == ("bev", "lane_target") and len(per.readout) == 2
    y = P.perceived(ds, M.PERCEIVE).reshape(-1, len(M.PERCEIVE))
    read = M.read_dataset(per, ds).reshape(y.shape)
    spread = y.std(0) > 1e-6
    r2 = 1 - ((read - y) ** 2).mean(0)[spread] / y.var(0)[spread]
    assert r2.mean() > 0.0, f"mean R² of the read features on the training states {r2.mean()}"
    # the read-out does read the route: other lane targets, other features
    bev, lane = M.observe_states(ds, np.array([0, 1]), np.array([5, 5]), route=True)
    assert lane.shape == (2, 10, 2)
    assert not np.allclose(per.read(bev, lane), per.read(bev, lane + 3.0))


def test_a_route_perception_refuses_a_call_without_the_route(ds, route_perception):
    bev, lane = M.observe_states(ds, np.array([0]), np.array([0]), route=True)
    with pytest.raises(ValueError, match="pass lane_target"):
        route_perception.read(bev)
    with pytest.raises(ValueError, match=r"lane_target must have shape \(1, K, 2\)"):
        route_perception.read(bev, lane[:, :, 0])


def test_the_route_driver_gets_the_lane_targets_in_closed_loop(ds, route_perception):
    driver = M.fit_driver(route_perception, ds, steps=50, exact=M.ODOMETER)
    policy = M.PerceivingPolicy(route_perception, driver, odometer=True)
    assert policy.keys == ("bev", "lane_target", "motion")
    traj = rollout.simulate(policy, ds, scenes=[0, 1], agents="reactive", progress=False)
    assert traj.ego.shape[0] == 2 and np.all(np.isfinite(traj.ego))
    with pytest.raises(ValueError, match="hidden must be"):
        M.fit_perception(ds, epochs=1, cfg=models.ModelConfig(image_size=16), hidden=-1)


def test_dagger_for_the_driver_aggregates_what_it_read_where_it_drove(ds, perception):
    rounds = M.dagger_driver(perception, ds, ds, rounds=1, per_round=2, steps=20)
    assert len(rounds) == 2
    S, T = np.asarray(ds.ego).shape[:2]
    assert rounds[0].labels == S * T
    # the second round adds one labelled state per step of the two scenes it drove
    # (fewer only where the expert could not be asked)
    assert S * T < rounds[1].labels <= S * T + 2 * T
    for r in rounds:
        assert 0.0 <= r.metrics["at_fault_collision_rate"] <= 100.0
        assert np.isfinite(r.metrics["ade"])


def test_the_recording_driver_labels_each_state_with_the_expert(ds, perception):
    driver = M.fit_driver(perception, ds, steps=20, exact=M.ODOMETER)
    teacher = WorldTeacher(ds, agents="reactive")
    policy = M.OraclePerceivingPolicy(perception, driver, teacher, record=True)
    rollout.simulate(policy, ds, scenes=[0], agents="reactive", progress=False)
    X, Y = policy.visited()
    T = np.asarray(ds.ego).shape[1]
    # one decision per step but the last pose, less any the expert could not be asked in
    assert X.shape == (T - 1 - policy.refused, len(P.FEATURES)) and Y.shape == (len(X), 2)
    # at the first step the expert is asked in the logged start: its label is the log's
    exact, Y_log = P.demonstrations(ds, scenes=[0])
    np.testing.assert_allclose(Y[0], Y_log[0], atol=1e-6)
    np.testing.assert_allclose(X[0, :2], exact[0, :2])   # v and a_prev from the world
