"""research/why_it_crashes: its local modules against their oracles (MANC's heads on the
expert's perception, DAgger for the privileged learner, the modular learner, the regimes),
every script's ``--help`` from the repository's root, and its imports: minimanc's public
API only."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimanc import cli, layers, models, rollout, vagn, world
from minimanc.dagger.teachers import WorldTeacher
from minimanc.diagnose import policies
from minimanc.diagnose import privileged as P
from minimanc.models import dmp_head
from minimanc.studies import provenance
from minimanc.world.geometry import DT

ROOT = Path(__file__).resolve().parents[1]
HERE = ROOT / "research" / "why_it_crashes"
LOCAL = sorted(p.stem for p in HERE.glob("*.py"))


def load(name: str):
    """Import ``research/why_it_crashes/<name>.py`` as its scripts do (their folder first on
    the path, so that its siblings are this folder's)."""
    for m in LOCAL:
        mod = sys.modules.get(m)
        if mod is not None and Path(getattr(mod, "__file__", None) or "").parent != HERE:
            del sys.modules[m]  # a module of that name from elsewhere
    sys.path.insert(0, str(HERE))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(HERE))


H, R, M, G = (load(n) for n in ("heads", "rounds", "perceiving", "regimes"))


@pytest.fixture(scope="module")
def ds():
    return world.generate(6, seed=5, raster=world.RasterConfig(size=16), workers=1)


@pytest.fixture(scope="module")
def demos(ds):
    return P.demonstrations(ds)


# --------------------------------------------------------------------------- MANC's heads


def test_the_dmp_head_learns_the_controls_of_a_known_gain_map(ds, demos):
    """MANC's head on the expert's perception: a learner with ``head="dmp"`` recovers the
    controls that a fixed MLP → gains → DMP step produces in the logged states."""
    X, Y = demos
    lane, motion = H.head_inputs(ds)
    assert lane.shape == (len(X), np.asarray(ds.lane_target).shape[2], 2)
    # the motion is the speed the human had (the logged start's first control at t = 0)
    T = np.asarray(ds.ego).shape[1]
    v = X[:, P.FEATURES.index("v")].reshape(-1, T)
    np.testing.assert_allclose(motion[:, 0].reshape(-1, T)[:, 1:], v[:, 1:], atol=1e-4)
    teacher = H.fit_head(X, Y, lane, motion, steps=1, seed=1)
    last = teacher.net.params["l2"]
    last["w"] = last["w"] * 30.0  # far from the fixed gains, inside the gain box
    target, _ = H.predict_head(teacher, X, lane, motion)
    learner = H.fit_head(X, target, lane, motion, steps=400, seed=0)  # relative RMSE 0.05
    got, _ = H.predict_head(learner, X, lane, motion)
    err = np.sqrt(((got - target) ** 2).mean(0)) / target.std(0)
    assert np.all(err < 0.15), f"relative RMSE {err} (expected < 0.15 on a map the head holds)"
    # the same map through the dispatcher of every learner
    np.testing.assert_array_equal(H.predict_scenes(learner, X, lane, motion), got)


def test_the_dmp_head_needs_what_it_reads_and_a_known_head(demos):
    X, Y = demos
    with pytest.raises(ValueError, match="MANC's heads need lane"):
        H.fit_head(X, Y, None, None)
    with pytest.raises(ValueError, match=r"lane must have shape"):
        H.fit_head(X, Y, np.zeros((3, 10, 2)), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="head must be one of"):
        H.fit_head(X, Y, np.zeros((len(X), 10, 2)), np.zeros((len(X), 2)), head="gains")


def test_a_dmp_head_policy_drives_and_records_what_its_head_read(ds, demos):
    X, Y = demos
    lane, motion = H.head_inputs(ds)
    model = H.fit_head(X, Y, lane, motion, steps=50, seed=0)
    policy = H.policy_of(model, WorldTeacher(ds, agents="reactive"), record=True)
    assert isinstance(policy, H.HeadPolicy) and policy.keys == ("lane_target", "motion")
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
    lane, motion = H.head_inputs(ds)
    T = np.asarray(ds.ego).shape[1]
    model = H.fit_head(X, Y, lane, motion, head="vagn", steps=120, seed=0, scene_steps=T)
    net = model.net
    assert np.mean(net.losses[-10:]) < 0.5 * np.mean(net.losses[:3])
    Z = (X[:4][:, net.keep] - net.mean) / net.std
    N = model.cfg.n_states
    q0 = np.full((4, N), 1.0 / N)
    pr = net.params
    h = np.tanh(layers.dense(pr["l1"], np.tanh(layers.dense(pr["l0"], Z))))
    pred = 1.0 / (1.0 + np.exp(-layers.dense(pr["l2"], h)))
    q1 = vagn.step(q0, pred, pr["vagn"]["W"])
    want, _ = dmp_head(layers.dense(pr["gains"], q1), lane[:4], motion[:4], model.cfg)
    got, q = H.advance(model, Z, lane[:4], motion[:4], q0)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(q, q1, rtol=1e-9, atol=1e-12)
    # along a scene q is carried: predict_scenes is predict_head step by step from uniform
    a = H.predict_scenes(model, X[:2 * T], lane[:2 * T], motion[:2 * T], scene_steps=T)
    qs = None
    for t in range(T):
        rows = [t, T + t]
        at, qs = H.predict_head(model, X[rows], lane[rows], motion[rows], qs)
        np.testing.assert_allclose(a[rows], at, rtol=1e-9, atol=1e-12)
    policy = H.policy_of(model, WorldTeacher(ds, agents="reactive"))
    np.testing.assert_allclose(policy.initial_state(np.array([0, 1])).sum(1), 1.0)
    m = policies.evaluate_policy(policy, ds, agents="reactive")
    assert np.isfinite(m["ade"])


def test_the_gains_read_the_predicates_beside_q_in_vagn_predicates(ds, demos):
    X, Y = demos
    lane, motion = H.head_inputs(ds)
    T = np.asarray(ds.ego).shape[1]
    model = H.fit_head(X, Y, lane, motion, head="vagn_predicates", steps=3, seed=0,
                       scene_steps=T)
    N, M = model.cfg.n_states, model.cfg.n_predicates
    pr = model.net.params
    assert pr["gains"]["w"].shape == (N + M, 4)
    Z = P.standardise(model.net, X[:3])
    h = np.tanh(layers.dense(pr["l1"], np.tanh(layers.dense(pr["l0"], Z))))
    pred = 1.0 / (1.0 + np.exp(-layers.dense(pr["l2"], h)))
    q1 = vagn.step(np.full((3, N), 1.0 / N), pred, pr["vagn"]["W"])
    logits = layers.dense(pr["gains"], np.concatenate([q1, pred], axis=1))
    want, _ = dmp_head(logits, lane[:3], motion[:3], model.cfg)
    got, _ = H.advance(model, Z, lane[:3], motion[:3], np.full((3, N), 1.0 / N))
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)


def test_the_vagn_head_refuses_what_it_cannot_train_on(ds, demos):
    X, Y = demos
    lane, motion = H.head_inputs(ds)
    with pytest.raises(ValueError, match="need scene_steps"):
        H.fit_head(X, Y, lane, motion, head="vagn")
    with pytest.raises(ValueError, match="need scene_steps"):
        H.fit_head(X, Y, lane, motion, head="vagn", scene_steps=7)
    with pytest.raises(ValueError, match="DAgger of the privileged learner"):
        R.dagger_rounds(ds, ds, 1, 1, head="vagn")


@pytest.mark.parametrize("head", ["acceleration", "dmp"])
def test_dagger_for_the_privileged_learner_aggregates_the_states_it_drove(ds, head):
    rounds = R.dagger_rounds(ds, ds, rounds=1, per_round=2, steps=20, head=head)
    S, T = np.asarray(ds.ego).shape[:2]
    assert [r.labels for r in rounds][0] == S * T
    # one labelled state per decision of the two scenes driven (fewer only where the expert
    # could not be asked)
    assert S * T < rounds[1].labels <= S * T + 2 * (T - 1)
    assert all(np.isfinite(r.metrics["ade"]) for r in rounds)


# --------------------------------------------------------------------------- the modular learner


@pytest.fixture(scope="module")
def pds():
    return world.generate(4, seed=3, raster=world.RasterConfig(size=16), workers=1)


@pytest.fixture(scope="module")
def perception(pds):
    return M.fit_perception(pds, epochs=3, lr=3e-3, cfg=models.ModelConfig(input_shape=(16, 16, 3)))


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


def test_the_perception_learns_its_training_states(pds, perception):
    y = P.perceived(pds, M.PERCEIVE).reshape(-1, len(M.PERCEIVE))
    read = M.read_dataset(perception, pds).reshape(y.shape)
    spread = y.std(0) > 1e-6
    r2 = 1 - ((read - y) ** 2).mean(0)[spread] / y.var(0)[spread]
    # trained on exactly these states: better than their mean on average
    assert r2.mean() > 0.0, f"mean R² of the read features on the training states {r2.mean()}"


def test_read_refuses_a_raster_of_the_wrong_size(perception):
    with pytest.raises(ValueError, match=r"bev must have shape \(B, 16, 16, 3\)"):
        perception.read(np.zeros((2, 32, 32, 3)))


def test_the_modular_learner_drives_on_the_raster_alone(pds, perception):
    driver = M.fit_driver(perception, pds, steps=50)
    policy = M.PerceivingPolicy(perception, driver)
    traj = rollout.simulate(policy, pds, scenes=[0, 1], agents="reactive", progress=False)
    assert traj.ego.shape[0] == 2 and np.all(np.isfinite(traj.ego))
    # its first control is the driver's on what the perception reads in the logged start
    bev0 = np.asarray(pds.bev[[0, 1], 0], dtype=np.float32) / 255.0
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


def test_the_odometer_driver_reads_its_speed_from_the_motion_input(pds, perception):
    driver = M.fit_driver(perception, pds, steps=50, exact=M.ODOMETER)
    policy = M.PerceivingPolicy(perception, driver, odometer=True)
    assert policy.keys == ("bev", "motion")
    bev0 = np.asarray(pds.bev[[0, 1], 0], dtype=np.float32) / 255.0
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
    traj = rollout.simulate(policy, pds, scenes=[0, 1], agents="reactive", progress=False)
    assert traj.ego.shape[0] == 2 and np.all(np.isfinite(traj.ego))


def test_the_oracle_diagnostic_takes_the_named_features_from_the_world(pds, perception):
    """With every feature exact the oracle policy is the privileged policy of the same
    driver, control for control; with the leader exact its controls differ from both."""
    exact = M.ODOMETER + tuple(f for f in P.FEATURES if f not in M.ODOMETER)
    driver = M.fit_driver(perception, pds, steps=50, exact=exact)
    teacher = WorldTeacher(pds, agents="reactive")
    oracle = rollout.simulate(M.OraclePerceivingPolicy(perception, driver, teacher, exact),
                              pds, scenes=[0, 1], agents="reactive", progress=False)
    privileged = rollout.simulate(policies.PrivilegedPolicy(driver, teacher), pds, scenes=[0, 1],
                                  agents="reactive", progress=False)
    np.testing.assert_allclose(oracle.ego, privileged.ego, atol=1e-4)
    leader = M.fit_driver(perception, pds, steps=50, exact=M.ODOMETER + ("gap", "dv"))
    part = M.OraclePerceivingPolicy(perception, leader, teacher, ("gap", "dv"))
    assert part.keys == ("bev", "motion")
    traj = rollout.simulate(part, pds, scenes=[0, 1], agents="reactive", progress=False)
    assert np.all(np.isfinite(traj.ego)) and not np.allclose(traj.ego, privileged.ego)
    with pytest.raises(ValueError, match="unknown feature"):
        M.OraclePerceivingPolicy(perception, leader, teacher, ("leader",))


@pytest.fixture(scope="module")
def route_perception(pds):
    return M.fit_perception(pds, epochs=4, lr=3e-3, cfg=models.ModelConfig(input_shape=(16, 16, 3)),
                            hidden=16, route=True, batch=16)


def test_a_hidden_read_out_with_the_route_learns_its_training_states(pds, route_perception):
    per = route_perception
    assert per.route and per.keys == ("bev", "lane_target") and len(per.readout) == 2
    y = P.perceived(pds, M.PERCEIVE).reshape(-1, len(M.PERCEIVE))
    read = M.read_dataset(per, pds).reshape(y.shape)
    spread = y.std(0) > 1e-6
    r2 = 1 - ((read - y) ** 2).mean(0)[spread] / y.var(0)[spread]
    assert r2.mean() > 0.0, f"mean R² of the read features on the training states {r2.mean()}"
    # the read-out does read the route: other lane targets, other features
    bev, lane = M.observe_states(pds, np.array([0, 1]), np.array([5, 5]), route=True)
    assert lane.shape == (2, 10, 2)
    assert not np.allclose(per.read(bev, lane), per.read(bev, lane + 3.0))


def test_a_route_perception_refuses_a_call_without_the_route(pds, route_perception):
    bev, lane = M.observe_states(pds, np.array([0]), np.array([0]), route=True)
    with pytest.raises(ValueError, match="pass lane_target"):
        route_perception.read(bev)
    with pytest.raises(ValueError, match=r"lane_target must have shape \(1, K, 2\)"):
        route_perception.read(bev, lane[:, :, 0])


def test_the_route_driver_gets_the_lane_targets_in_closed_loop(pds, route_perception):
    driver = M.fit_driver(route_perception, pds, steps=50, exact=M.ODOMETER)
    policy = M.PerceivingPolicy(route_perception, driver, odometer=True)
    assert policy.keys == ("bev", "lane_target", "motion")
    traj = rollout.simulate(policy, pds, scenes=[0, 1], agents="reactive", progress=False)
    assert traj.ego.shape[0] == 2 and np.all(np.isfinite(traj.ego))
    with pytest.raises(ValueError, match="hidden must be"):
        M.fit_perception(pds, epochs=1, cfg=models.ModelConfig(input_shape=(16, 16, 3)), hidden=-1)


def test_dagger_for_the_driver_aggregates_what_it_read_where_it_drove(pds, perception):
    rounds = M.dagger_driver(perception, pds, pds, rounds=1, per_round=2, steps=20)
    assert len(rounds) == 2
    S, T = np.asarray(pds.ego).shape[:2]
    assert rounds[0].labels == S * T
    # the second round adds one labelled state per step of the two scenes it drove
    # (fewer only where the expert could not be asked)
    assert S * T < rounds[1].labels <= S * T + 2 * T
    for r in rounds:
        assert 0.0 <= r.metrics["at_fault_collision_rate"] <= 100.0
        assert np.isfinite(r.metrics["ade"])


def test_the_recording_driver_labels_each_state_with_the_expert(pds, perception):
    driver = M.fit_driver(perception, pds, steps=20, exact=M.ODOMETER)
    teacher = WorldTeacher(pds, agents="reactive")
    policy = M.OraclePerceivingPolicy(perception, driver, teacher, record=True)
    rollout.simulate(policy, pds, scenes=[0], agents="reactive", progress=False)
    X, Y = policy.visited()
    T = np.asarray(pds.ego).shape[1]
    # one decision per step but the last pose, less any the expert could not be asked in
    assert X.shape == (T - 1 - policy.refused, len(P.FEATURES)) and Y.shape == (len(X), 2)
    # at the first step the expert is asked in the logged start: its label is the log's
    exact, Y_log = P.demonstrations(pds, scenes=[0])
    np.testing.assert_allclose(Y[0], Y_log[0], atol=1e-6)
    np.testing.assert_allclose(X[0, :2], exact[0, :2])   # v and a_prev from the world


# --------------------------------------------------------------------------- the regimes


def test_regimes_by_hand():
    inf = np.inf
    lab = G.regimes(speed=[10.0, 10.0, 10.0, 10.0, 2.0],
                  gap=[inf, 20.0, inf, 20.0, 9.0],
                  stop=[inf, inf, inf, 10.0, inf],
                  acceleration=[0.0, 0.0, -2.0, -2.0, 0.0])
    assert [G.REGIMES[i] for i in lab] == ["cruising", "following", "braking", "yielding",
                                         "following"]


def test_regimes_refuse_bad_input():
    with pytest.raises(ValueError, match="NaN"):
        G.regimes([np.nan], [1.0], [1.0], [0.0])
    with pytest.raises(ValueError, match="2 states"):
        G.regimes([1.0, 2.0], [1.0], [1.0, 1.0], [0.0, 0.0])


@given(st.lists(st.integers(0, len(G.REGIMES) - 1), min_size=1, max_size=40),
       st.integers(0, 2**31 - 1))
def test_the_split_adds_up(labels, seed):
    rng = np.random.default_rng(seed)
    lab = np.array(labels)
    p, y = rng.normal(size=(len(lab), 2)), rng.normal(size=(len(lab), 2))
    out = G.error_by_regime(p, y, lab)
    assert set(out) == {G.REGIMES[i] for i in set(labels)}
    assert sum(r["states"] for r in out.values()) == len(lab)
    # the regimes' mean squared errors, weighted by their shares, are the total's
    total = ((p - y) ** 2).mean(axis=0)
    parts = sum(r["share"] * np.array([r["rmse_0"], r["rmse_1"]]) ** 2 for r in out.values())
    np.testing.assert_allclose(parts, total, rtol=1e-9)


def test_error_by_regime_refuses_bad_input():
    with pytest.raises(ValueError, match="shape"):
        G.error_by_regime(np.zeros((3, 2)), np.zeros((3, 1)), np.zeros(3, int))
    with pytest.raises(ValueError, match="finite"):
        G.error_by_regime(np.full((1, 2), np.nan), np.zeros((1, 2)), np.zeros(1, int))


# --------------------------------------------------------------------------- scripts and imports


SCRIPTS = sorted(p for p in HERE.glob("*.py") if 'if __name__ == "__main__":' in p.read_text())
"""The folder's scripts (its other files are modules they import)."""


def test_every_script_answers_help_from_the_repository_root():
    """``python research/why_it_crashes/<script>.py --help`` in a fresh interpreter, as a
    fresh clone runs it (the scripts import their sibling modules by path)."""
    assert {p.stem for p in SCRIPTS} >= {"bounds", "fixes", "perceive_drive", "privileged"}
    runs = {p.name: subprocess.Popen([sys.executable, str(p.relative_to(ROOT)), "--help"],
                                     cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True) for p in SCRIPTS}
    for name, proc in runs.items():
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0 and out.startswith("usage: "), f"{name}: {err[-2000:]}"


def public_imports(source: str) -> list[tuple[str, str | None]]:
    """``(module, name)`` of every ``import minimanc…`` (name ``None``) and ``from minimanc…
    import name`` of a source."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(a.name, None) for a in node.names if a.name.startswith("minimanc")]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("minimanc"):
            out += [(node.module, a.name) for a in node.names]
    return out


def unpublished(source: str) -> list[str]:
    """The names a source imports from minimanc that are neither a module nor published: in
    their module's ``__all__`` (not ``_private`` where the module has none)."""
    bad = []
    for module, name in public_imports(source):
        mod = importlib.import_module(module)
        if name is None or hasattr(mod, "__path__") \
                and importlib.util.find_spec(f"{module}.{name}") is not None:
            continue  # a module
        published = getattr(mod, "__all__", None)
        if name.startswith("_") or (published is not None and name not in published):
            bad.append(f"{module}.{name}")
    return bad


def test_unpublished_finds_private_and_unlisted_names():
    source = ("import minimanc.models\nfrom minimanc import diagnose, cli\n"
              "from minimanc.models.zoo import _dmp_inputs, gains_layer\n"
              "from minimanc.world.geometry import DT, _private\n"
              "from minimanc.dagger.expert import MAX_OFFSET, copy\n")
    assert unpublished(source) == ["minimanc.models.zoo._dmp_inputs",
                                   "minimanc.world.geometry._private",
                                   "minimanc.dagger.expert.copy"]


@pytest.mark.parametrize("path", sorted(HERE.glob("*.py")), ids=lambda p: p.name)
def test_the_folder_uses_minimanc_s_public_api_only(path):
    """That no module of minimanc exists for the folder alone is ``tests/test_imports.py``'s
    check: every module is reached from a notebook or the command line."""
    bad = unpublished(path.read_text())
    assert bad == [], f"{path.name} imports names minimanc does not publish: {bad}"


# --------------------------------------------------------------------------- the record

REPORT = HERE / "REPORT.md"


def test_the_report_quotes_this_folder_s_results_and_reproduce_s_outputs():
    """(``tests/test_provenance.py`` checks every quote against its file.)"""
    quoted = {q.path for q in provenance.quotes(REPORT.read_text(encoding="utf-8"))}
    # this folder's results and reproduce's outputs, two levels up
    assert "results/privileged.md" in quoted and "../../results/paper-paper/table1.md" in quoted
    assert all((HERE / q).is_file() for q in quoted)


def test_the_report_check_fails_on_a_stale_quote(tmp_path, capsys):
    """``minimanc results check`` on a copy of the folder (and of reproduce's outputs two
    levels up) passes, and fails (exit 1) once one number of a quote is changed (the file
    measured anew, the record not updated) or a quoted file has moved away."""
    copy = tmp_path / "research" / "why_it_crashes"
    shutil.copytree(HERE / "results", copy / "results")
    shutil.copytree(ROOT / "results", tmp_path / "results")
    text = REPORT.read_text(encoding="utf-8")
    report = copy / "REPORT.md"
    report.write_text(text, encoding="utf-8")
    assert cli.main(["results", "check", str(report)]) == 0
    first = provenance.quotes(text)[0]
    lines = text.splitlines()
    row = next(i for i in range(first.begin + 1, first.end)
               if any(c in "0123456789" for c in lines[i]))
    digit = next(c for c in lines[row] if c in "0123456789")
    lines[row] = lines[row].replace(digit, str((int(digit) + 1) % 10), 1)
    report.write_text("\n".join(lines) + "\n", encoding="utf-8")
    capsys.readouterr()
    assert cli.main(["results", "check", str(report)]) == 1
    err = capsys.readouterr().err
    assert f"line {first.begin + 1}: the quote of {first.path}#" in err and "differs" in err
    report.write_text(text.replace("<!-- quote: results/privileged.md#",
                                   "<!-- quote: results/gone/privileged.md#"), encoding="utf-8")
    assert cli.main(["results", "check", str(report)]) == 1
    assert "does not exist" in capsys.readouterr().err
