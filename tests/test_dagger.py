"""DAgger (chapter 11): schedule, mixture, budget, aggregation, teachers, the loop, resume, CLI."""

from __future__ import annotations

import argparse
import copy
import dataclasses
import importlib.util
import json
import time

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from minimanc import dagger, inputs, rollout, train, world
from minimanc.dagger.expert import HumanExpert
from minimanc.errors import UsageError
from minimanc.world.datareader import load
from minimanc.world.datawriter import save

SIZE = 16
TC = train.TrainConfig(epochs=1, batch_size=64)


@pytest.fixture(scope="module")
def split():
    ds = world.generate(8, seed=0, raster=world.RasterConfig(size=SIZE))
    return ds.split(6)


@pytest.fixture(scope="module")
def teacher(split):
    pool, val = split
    return dagger.WorldTeacher(pool, val, agents="reactive")


def cfg_of(pool):
    return dagger.default_config(pool, channels=(4, 4, 4), hidden=8)


# --------------------------------------------------------------------------- schedule, mixture


def test_beta_schedule_literal():
    assert dagger.beta_schedule(0.5, 3) == [1.0, 0.5, 0.25, 0.125]
    assert dagger.beta_schedule(0.0, 2) == [1.0, 0.0, 0.0]
    assert dagger.beta_schedule(1.0, 2) == [1.0, 1.0, 1.0]


@given(st.floats(0.0, 1.0), st.integers(1, 12))
def test_beta_schedule_properties(p, rounds):
    b = dagger.beta_schedule(p, rounds)
    assert len(b) == rounds + 1 and b[0] == 1.0
    assert all(0.0 <= x <= 1.0 for x in b)
    assert all(b[i + 1] <= b[i] for i in range(rounds))
    assert b[1] == p


@pytest.mark.parametrize("p", [1.5, -0.1, float("nan"), True, "0.5", None])
def test_beta_outside_unit_interval_refused(p):
    with pytest.raises(ValueError, match="p must be a number in \\[0, 1\\]"):
        dagger.beta_schedule(p, 3)


@pytest.mark.parametrize("rounds", [0, -1, 2.0, True])
def test_rounds_below_one_refused(rounds):
    with pytest.raises(ValueError, match="rounds"):
        dagger.beta_schedule(0.5, rounds)


@given(st.floats(0.0, 1.0), st.lists(st.floats(0.0, 0.999), min_size=1, max_size=20))
def test_mix_takes_the_expert_exactly_where_the_coin_is_below_beta(beta, coins):
    u = np.array(coins)
    e = np.stack([np.arange(len(u)), np.ones(len(u))], 1).astype(float)
    p = -e - 1.0
    out = dagger.mix(e, p, beta, u)
    assert np.array_equal(out[u < beta], e[u < beta])
    assert np.array_equal(out[u >= beta], p[u >= beta])
    assert np.array_equal(dagger.mix(e, p, 1.0, u), e)
    assert np.array_equal(dagger.mix(e, p, 0.0, u), p)


def test_mix_checks_shapes():
    with pytest.raises(ValueError, match="one shape"):
        dagger.mix(np.zeros((3, 2)), np.zeros((2, 2)), 0.5, np.zeros(3))


# --------------------------------------------------------------------------- budget


def test_plan_budget_literal():
    b = dagger.plan_budget(400, 40, 3)
    assert (b.initial, b.per_round, b.scenes, b.used) == (4, (2, 2, 2), 10, 400)
    assert [b.labelled(i) for i in range(4)] == [160, 240, 320, 400]
    assert [b.round_scenes(i) for i in range(4)] == [(0, 4), (4, 6), (6, 8), (8, 10)]
    b = dagger.plan_budget(450, 40, 2, initial=5)  # 11 scenes: 5, then 3 + 3
    assert (b.initial, b.per_round, b.used) == (5, (3, 3), 440)


@given(st.integers(1, 5000), st.integers(1, 50), st.integers(1, 6))
def test_plan_budget_spends_at_most_the_budget(total, steps, rounds):
    if total // steps < rounds + 1:
        with pytest.raises(ValueError, match="budget too small"):
            dagger.plan_budget(total, steps, rounds)
        return
    b = dagger.plan_budget(total, steps, rounds)
    assert b.used <= total < b.used + steps  # every whole scene the budget pays for is used
    assert b.scenes == total // steps and b.rounds == rounds
    assert min(b.per_round) >= 1 and max(b.per_round) - min(b.per_round) <= 1
    assert b.initial >= max(b.per_round)
    assert b.labelled(rounds) == b.used
    assert [b.round_scenes(i)[0] for i in range(1, rounds + 1)] == [
        b.round_scenes(i - 1)[1] for i in range(1, rounds + 1)]


def test_budget_fixed_extends_with_more_rounds():
    b2, b3 = dagger.Budget.fixed(40, 2, 1, 2), dagger.Budget.fixed(40, 2, 1, 3)
    assert [b2.round_scenes(i) for i in range(3)] == [b3.round_scenes(i) for i in range(3)]
    assert (b3.used, b3.total) == (200, 200)


def test_budget_too_small_for_the_rounds(teacher):
    with pytest.raises(ValueError, match="budget too small"):
        dagger.dagger("manc", teacher, 3 * 40 - 1, rounds=2, engine="numpy", progress=False)
    with pytest.raises(ValueError, match="budget"):
        dagger.dagger("manc", teacher, 0, rounds=2, engine="numpy", progress=False)
    with pytest.raises(ValueError, match="pool holds 6"):
        dagger.dagger("manc", teacher, dagger.Budget.fixed(40, 4, 2, 2), rounds=2,
                      engine="numpy", progress=False)


@pytest.mark.parametrize("kw, match", [
    (dict(name="no_such_model"), "name must be one of"),
    (dict(beta=1.5), "beta must be a number in \\[0, 1\\]"),
    (dict(beta=-0.2), "beta must be a number"),
    (dict(beta=[1.0, 0.5]), "rounds \\+ 1 = 3 weights"),
    (dict(beta=[0.5, 0.5, 0.5]), "starting with 1.0"),
    (dict(rounds=0), "rounds must be an integer >= 1"),
    (dict(engine="torch"), "engine must be one of"),
    (dict(round_cfg={"epochs": 1}), "round_cfg must be a minimanc.train.TrainConfig"),
])
def test_dagger_refuses_bad_input(teacher, kw, match):
    args = dict(name="manc", teacher=teacher, budget=240, rounds=2, engine="numpy",
                progress=False)
    args.update(kw)
    with pytest.raises(ValueError, match=match):
        dagger.dagger(**args)


# --------------------------------------------------------------------------- aggregation


def test_concat_counts_scenes_and_metadata(split):
    pool, val = split
    agg = dagger.concat([pool.subset([0, 1]), val, pool.subset([3])])
    assert len(agg) == 5 and agg.ego.shape[1:] == pool.ego.shape[1:]
    for key in ("recipes", "tags", "attempts", "scene_index"):
        assert len(agg.meta[key]) == 5
    assert np.array_equal(agg.controls[2:4], val.controls)
    assert np.array_equal(agg.bev[4], pool.bev[3])
    assert agg.maps[4] is pool.maps[3]
    assert dagger.concat([val]) is val
    with pytest.raises(ValueError, match="at least one"):
        dagger.concat([])
    small = world.generate(1, seed=1, raster=world.RasterConfig(size=8))
    with pytest.raises(ValueError, match="bev has shape"):
        dagger.concat([pool, small])


# --------------------------------------------------------------------------- driving, labels


def test_beta_one_drives_the_expert_and_labels_the_log(teacher, split):
    pool, _ = split
    col = dagger.collect(None, teacher, [0, 2, 4], 1.0, seed=0)
    T = pool.n_steps
    assert col.labelled == 3 * T and col.expert_share == 1.0 and not col.refusals
    assert col.kept.tolist() == [0, 2, 4] and len(col.data) == 3
    # the human driven by its own answers is the log (float32 rounding of the poses)
    assert np.abs(col.data.ego - pool.ego[[0, 2, 4]]).max() < 1e-4
    assert np.abs(col.data.controls - pool.controls[[0, 2, 4]]).max() < 1e-5
    assert np.array_equal(col.data.bev, pool.bev[[0, 2, 4]])
    assert np.allclose(col.data.lane_target, pool.lane_target[[0, 2, 4]], atol=1e-3)
    assert [t["dagger"]["pool_scene"] for t in col.data.tags] == [0, 2, 4]


def test_beta_zero_drives_the_policy_among_reactive_ados(teacher, split):
    pool, _ = split
    policy = rollout.FixedGainsPolicy()
    col = dagger.collect(policy, teacher, [2, 3], 0.0, seed=0)
    ref = rollout.simulate(policy, pool, scenes=[2, 3], progress=False, agents="reactive")
    assert col.expert_share == 0.0 and len(col.data) == 2
    assert np.allclose(col.data.ego, ref.ego.astype(np.float32), atol=1e-5)
    assert np.allclose(col.data.ado, np.where(ref.ado_valid[..., None], ref.ado, 0.0),
                       atol=1e-4)
    assert np.abs(col.data.ego - pool.ego[[2, 3]]).max() > 1.0  # not the human's states
    assert np.abs(col.data.controls[:, 0] - pool.controls[[2, 3], 0]).max() < 1e-5


def test_a_scene_the_driver_cannot_label_is_not_aggregated_but_counted(teacher, split):
    pool, _ = split
    # the fixed-gain DMP leaves the drivable area in scene 1 at step 23
    col = dagger.collect(rollout.FixedGainsPolicy(), teacher, [1, 2], 0.0)
    assert col.kept.tolist() == [2] and len(col.data) == 1
    assert col.labelled == 2 * pool.n_steps  # the expert was asked in both scenes
    assert len(col.refusals) == 1 and col.refusals[0].startswith("scene 1: cannot label")
    assert "off the drivable area" in col.refusals[0]


def test_beta_zero_labels_every_visited_state_with_the_driver(split):
    pool, _ = split
    policy = rollout.FixedGainsPolicy()
    col = dagger.collect(policy, dagger.WorldTeacher(pool, agents="replay"), [2, 3], 0.0)
    ref = rollout.simulate(policy, pool, scenes=[2, 3], progress=False)
    assert np.allclose(col.data.ego, ref.ego.astype(np.float32), atol=1e-5)
    expert = HumanExpert(pool)  # the oracle: ask the driver in each visited state
    for b, s in enumerate([2, 3]):
        for t in range(pool.n_steps):
            speed = expert.steps(s)[0].speed if t == 0 else ref.controls[b, t - 1, 0]
            want = expert(s, t, ref.ego[b, t], float(speed))
            assert np.allclose(col.data.controls[b, t], want, atol=1e-5), (s, t)


def test_beta_mixture_takes_the_expert_where_the_coin_says(teacher, split):
    pool, _ = split
    col = dagger.collect(rollout.FixedGainsPolicy(), teacher, [0, 2, 3], 0.5, seed=7)
    T = pool.n_steps
    u = np.random.default_rng(7).random((T - 1, 3))
    assert col.expert_share == pytest.approx(float(np.mean(u < 0.5)))
    assert 0.0 < col.expert_share < 1.0


def test_collect_refuses_bad_scenes_and_beta(teacher):
    with pytest.raises(ValueError, match="scenes must lie in"):
        dagger.collect(None, teacher, [6], 1.0)
    with pytest.raises(ValueError, match="beta must be a number"):
        dagger.collect(None, teacher, [0], 2.0)
    with pytest.raises(ValueError, match="only the expert can drive"):
        dagger.collect(None, teacher, [0], 0.5)


def test_world_teacher_checks_its_arguments(split):
    pool, _ = split
    with pytest.raises(ValueError, match="agents must be one of"):
        dagger.WorldTeacher(pool, agents="frozen")
    with pytest.raises(ValueError, match="pool must be a minimanc.world.Dataset"):
        dagger.WorldTeacher(pool.ego)


def test_replay_protocol_labels_the_log_too(split):
    pool, _ = split
    col = dagger.collect(None, dagger.WorldTeacher(pool, agents="replay"), [5], 1.0)
    assert np.abs(col.data.controls - pool.controls[[5]]).max() < 1e-5
    assert np.abs(col.data.ego - pool.ego[[5]]).max() < 1e-4


# --------------------------------------------------------------------------- the loop


def test_end_to_end_budget_and_bc_at_equal_labels(teacher, split):
    pool, _ = split
    t0 = time.perf_counter()
    plan = dagger.plan_budget(6 * 40, 40, 2)  # 2 + 2 + 2 scenes
    res = dagger.dagger("manc", teacher, plan, rounds=2, beta=0.5, cfg=cfg_of(pool),
                        train_cfg=TC, engine="numpy", progress=False)
    bc = dagger.behaviour_cloning("manc", teacher, plan, rounds=2, cfg=cfg_of(pool),
                                  train_cfg=TC, engine="numpy", progress=False)
    assert time.perf_counter() - t0 < 30.0
    assert [r.labelled for r in res.rounds] == [80, 160, 240]
    assert [r.beta for r in res.rounds] == [1.0, 0.5, 0.25]
    # no refusal here: every labelled sample is aggregated
    assert [r.samples for r in res.rounds] == [80, 160, 240]
    assert bc.labelled == res.rounds[-1].labelled == plan.used == 240
    driven = sorted(s for r in res.rounds for s in r.scenes)
    assert driven == sorted(bc.scenes) and len(set(driven)) == 6  # the same six scene starts
    for r in [*res.rounds, bc]:
        assert {"ade", "collision_rate", "at_fault_collision_rate"} <= set(r.metrics)
        assert np.isfinite(r.metrics["ade"])
    assert "| 2 | 0.250 | 240 | 240 |" in res.table()


def test_resume_loads_finished_rounds_and_does_not_retrain(teacher, split, tmp_path,
                                                           monkeypatch):
    pool, _ = split
    kw = dict(cfg=cfg_of(pool), train_cfg=TC, engine="numpy", progress=False, evaluate=False,
              out=tmp_path)
    first = dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 2), rounds=2, **kw)
    assert (tmp_path / "round_002" / dagger.ROUND_FILE).exists()
    fits, collects = [], []
    real_fit, real_collect = train.fit, dagger.loop.collect
    monkeypatch.setattr(train, "fit", lambda *a, **k: fits.append(1) or real_fit(*a, **k))
    monkeypatch.setattr(dagger.loop, "collect",
                        lambda *a, **k: collects.append(1) or real_collect(*a, **k))
    again = dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 3), rounds=3, **kw)
    assert [r.loaded for r in again.rounds] == [True, True, True, False]
    assert (len(fits), len(collects)) == (1, 1)  # round 3 only
    for a, b in zip(first.params_per_round, again.params_per_round[:3]):
        assert all(np.array_equal(x, y) for x, y in zip(_leaves(a), _leaves(b)))
    assert again.rounds[3].samples == 5 * 40
    # a round of another configuration in the same folder is refused
    with pytest.raises(ValueError, match="another configuration"):
        dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 2), rounds=2, beta=0.9, **kw)


def test_resume_after_a_kill_during_training_reuses_the_collected_scenes(
        teacher, split, tmp_path, monkeypatch):
    pool, _ = split
    kw = dict(cfg=cfg_of(pool), train_cfg=TC, engine="numpy", progress=False, evaluate=False,
              out=tmp_path)
    real_fit = train.fit
    calls = []

    def dies_in_round_1(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real_fit(*a, **k)

    monkeypatch.setattr(train, "fit", dies_in_round_1)
    with pytest.raises(KeyboardInterrupt):
        dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 1), rounds=1, **kw)
    assert (tmp_path / "round_001" / "data.npz").exists()
    assert not (tmp_path / "round_001" / dagger.ROUND_FILE).exists()
    monkeypatch.setattr(train, "fit", real_fit)
    # the unfinished round's data and checkpoint are not mixed into another configuration
    with pytest.raises(ValueError, match="round_001 holds a round of another configuration"):
        dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 1), rounds=1, beta=0.9,
                      **kw)
    monkeypatch.setattr(dagger.loop, "collect", lambda *a, **k: pytest.fail("recollected"))
    res = dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 1), rounds=1, **kw)
    assert [r.loaded for r in res.rounds] == [True, False]
    assert res.rounds[1].kept == res.rounds[1].scenes and res.rounds[1].samples == 3 * 40


@pytest.mark.parametrize("warm", [False, True])
def test_rounds_start_fresh_or_continue_from_the_previous_round(teacher, split, tmp_path,
                                                               monkeypatch, warm):
    pool, _ = split
    round_cfg = dataclasses.replace(TC, lr=1e-4) if warm else None
    seen = []
    real_fit = train.fit

    def recording_fit(name, data, cfg, tc, **k):
        seen.append((tc, None if k.get("params") is None else _leaves(k["params"])))
        return real_fit(name, data, cfg, tc, **k)

    monkeypatch.setattr(train, "fit", recording_fit)
    res = dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 2), rounds=2,
                        cfg=cfg_of(pool), train_cfg=TC, engine="numpy", progress=False,
                        evaluate=False, out=tmp_path, round_cfg=round_cfg)
    assert [tc for tc, _ in seen] == [TC, round_cfg or TC, round_cfg or TC]
    assert seen[0][1] is None
    for i in (1, 2):
        if not warm:
            assert seen[i][1] is None
            continue
        previous = _leaves(res.params_per_round[i - 1])
        assert all(np.array_equal(a, b) for a, b in zip(seen[i][1], previous))
    # the round folders belong to one way of training: the other is refused there
    other = None if warm else dataclasses.replace(TC, lr=1e-4)
    with pytest.raises(ValueError, match="another configuration"):
        dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 2), rounds=2,
                      cfg=cfg_of(pool), train_cfg=TC, engine="numpy", progress=False,
                      evaluate=False, out=tmp_path, round_cfg=other)


def _leaves(tree):
    from minimanc.tree import leaves

    return [np.asarray(x) for x in leaves(tree)]


# --------------------------------------------------------------------------- highway-env


@pytest.mark.skipif(importlib.util.find_spec("highway_env") is None, reason="needs highway-env")
def test_highway_teacher_labels_the_expert_states():
    from minimanc import highway as hw

    cfg = world.RasterConfig(size=SIZE)
    pool = hw.collect_demonstrations("roundabout", n_episodes=2, seed=0, steps=8, cfg=cfg)
    teacher = dagger.HighwayTeacher(pool)
    col = dagger.collect(None, teacher, [0, 1], 1.0)
    # at t = 0 the state is the expert's own: its label is the logged control
    assert np.abs(col.data.controls[:, 0] - pool.controls[:, 0]).max() < 1e-4
    # driven by its labels through the action adapter, the ego stays on the expert's path
    assert np.abs(col.data.ego[..., :2] - pool.ego[..., :2]).max() < 1.0
    assert col.labelled == 2 * 8 and len(col.data) == 2
    with pytest.raises(ValueError, match="highway-env demonstrations"):
        dagger.HighwayTeacher(world.generate(2, seed=0, raster=cfg))


# --------------------------------------------------------------------------- command line


def _parser():
    from minimanc.cli import dagger as cli

    p = argparse.ArgumentParser(prog="minimanc")
    cli.register(p.add_subparsers(dest="command"))
    return p


def _run(argv):
    args = _parser().parse_args(["dagger", *argv])
    return args.func(args)


@pytest.mark.parametrize("argv, message", [
    (["--beta", "1.5"], "--beta must be a number in [0, 1], got 1.5"),
    (["--rounds", "0"], "--rounds must be an integer >= 1, got --rounds=0"),
    (["--model", "gpt"], "--model: unknown model gpt; choose from"),
    (["--sim", "carla"], "--sim: unknown simulator carla; choose from world, highway"),
    (["--agents", "frozen"], "--agents: unknown protocol frozen"),
    (["--budget", "0"], "--budget must be an integer >= 1, got --budget=0"),
    (["--initial", "2"], "--initial and --per-round go together"),
    (["--budget", "40", "--scenes", "4", "--val-scenes", "0", "--size", "16"],
     "budget too small: total=40 labelled samples give 1 scenes"),
])
def test_cli_bad_arguments_are_usage_errors(argv, message, tmp_path):
    with pytest.raises(UsageError) as e:
        _run([*argv, "--out", str(tmp_path / "o"), "--quiet"])
    assert message in str(e.value) and "\n" not in str(e.value)


def test_cli_usage_error_exits_2_with_one_line(tmp_path, capsys, monkeypatch):
    from minimanc import cli

    monkeypatch.setitem(cli.PLUGINS, "minimanc.cli.dagger", "minimanc.dagger")
    code = cli.main(["dagger", "--beta", "-1", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.strip().count("\n") == 0 and "--beta" in err


def test_cli_tiny_run_writes_table_json_and_figures(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["--model", "cnn", "--engine", "numpy", "--scenes", "3", "--val-scenes", "1",
            "--rounds", "2", "--size", "16", "--epochs", "1", "--out", str(out), "--quiet"]
    assert _run(argv) == 0
    summary = json.loads((out / "dagger.json").read_text())
    assert [r["labelled"] for r in summary["rounds"]] == [40, 80, 120]
    assert summary["bc"]["labelled"] == 120 and summary["budget"]["used"] == 120
    assert (out / "figures" / "dagger_ade.png").stat().st_size > 0
    assert "| BC | 1.000 | 120 | 120 |" in (out / "dagger.md").read_text()
    for i in range(3):
        assert (out / f"round_{i:03d}" / dagger.ROUND_FILE).exists()
    # rerun: everything loaded from the checkpoints
    assert _run(argv) == 0
    assert json.loads((out / "dagger.json").read_text())["rounds"] == summary["rounds"]


# ---------------------------------------------------------------------- perturbed demonstrations


def test_perturbation_offsets_are_an_ornstein_uhlenbeck_process():
    p = dagger.Perturbation(speed=2.0, yaw_rate=0.1, tau=1.5)
    assert p.decay == pytest.approx(np.exp(-0.5 / 1.5))
    rng = np.random.default_rng(0)
    x = np.zeros((4000, 2))
    for _ in range(40):  # 20 s, many correlation times: stationary
        x = p.step(x, rng)
    assert np.allclose(x.std(0), [2.0, 0.1], rtol=0.05)
    y = p.step(x, rng)  # lag-one correlation of the stationary process is the decay
    assert np.corrcoef(x[:, 0], y[:, 0])[0, 1] == pytest.approx(p.decay, abs=0.03)
    applied = p.apply(np.array([[1.0, 0.0], [5.0, 0.2]]), np.array([[-3.0, 0.1], [1.0, -0.1]]))
    assert applied.tolist() == [[0.0, 0.1], [6.0, 0.1]]  # the speed command never below 0


@pytest.mark.parametrize("kw", [dict(speed=-1.0, yaw_rate=0.1, tau=1.0),
                                dict(speed=1.0, yaw_rate=float("nan"), tau=1.0),
                                dict(speed=1.0, yaw_rate=0.1, tau=0.0),
                                dict(speed=[1.0, 2.0], yaw_rate=0.1, tau=1.0)])
def test_perturbation_refuses_bad_parameters(kw):
    with pytest.raises((ValueError, TypeError)):
        dagger.Perturbation(**kw)


def test_perturbed_demonstrations_leave_the_log_and_are_labelled_there(teacher, split):
    pool, _ = split
    scenes = np.array([0, 2, 4])
    zero = dagger.collect(None, teacher, scenes, 1.0, seed=3,
                          perturb=dagger.Perturbation(0.0, 0.0, 1.0))
    assert np.abs(zero.data.ego - pool.ego[scenes]).max() < 1e-4  # σ = 0: the log
    assert not inputs.driven_rows(zero.data).any()  # applied = labels: nothing to record
    p = dagger.Perturbation(1.5, 0.03, 2.0)
    col = dagger.collect(None, teacher, scenes, 1.0, seed=3, perturb=p)
    assert col.kept.tolist() == scenes.tolist() and col.expert_share == 1.0
    assert col.data.tags[0]["dagger"]["perturb"] == {"speed": 1.5, "yaw_rate": 0.03, "tau": 2.0}
    assert np.abs(col.data.ego - pool.ego[scenes]).max() > 1.0  # off the logged path
    # Re-drive the scenes independently: the applied controls are the stored labels plus the
    # offsets of the same stream (coins first, then offsets), and in every state reached the
    # driver's answer is the stored label.
    rng = np.random.default_rng(3)
    sim = teacher.simulator(scenes)
    sim.reset()
    offset, prev = np.zeros((len(scenes), 2)), None
    driven = inputs.driven_controls(col.data)
    assert inputs.driven_rows(col.data).all()
    for t in range(pool.n_steps - 1):
        assert np.abs(np.asarray(sim.observe().pose) - col.data.ego[:, t]).max() < 1e-4
        label, why = teacher.label(sim, t, prev)
        assert why == [None] * len(scenes)
        assert np.abs(label - col.data.controls[:, t]).max() < 1e-5
        rng.random(len(scenes))
        offset = p.step(offset, rng)
        prev = p.apply(label, offset)
        # the record holds what was applied, and the next state's motion is that control
        np.testing.assert_allclose(driven[:, t], prev, rtol=1e-6, atol=1e-6)
        motion = inputs.motion_at(col.data, np.arange(len(scenes)), np.full(len(scenes), t + 1))
        np.testing.assert_allclose(motion, prev, rtol=1e-6, atol=1e-6)
        sim.step(prev)
    assert np.abs(np.asarray(sim.observe().pose) - col.data.ego[:, -1]).max() < 1e-4
    np.testing.assert_array_equal(driven[:, -1], col.data.controls[:, -1])


def test_a_policy_driven_scene_records_the_applied_controls_and_they_survive_a_file(
        teacher, split, tmp_path):
    pool, _ = split
    policy = rollout.FixedGainsPolicy()
    col = dagger.collect(policy, teacher, [2, 3], 0.0, seed=0)
    ref = rollout.simulate(policy, pool, scenes=[2, 3], progress=False, agents="reactive")
    driven = inputs.driven_controls(col.data)
    np.testing.assert_allclose(driven[:, :-1], ref.controls, rtol=1e-6, atol=1e-6)
    assert np.abs(driven[:, :-1] - col.data.controls[:, :-1]).max() > 0.1  # not the labels
    agg = dagger.concat([pool.subset([0, 1]), col.data])
    assert inputs.driven_rows(agg).tolist() == [False, False, True, True]
    np.testing.assert_array_equal(inputs.driven_controls(agg)[:2], pool.controls[[0, 1]])
    save(agg, tmp_path / "agg.npz")
    back = load(tmp_path / "agg.npz")
    np.testing.assert_array_equal(inputs.driven_controls(back), inputs.driven_controls(agg))


def test_a_driven_record_of_the_wrong_length_is_refused(teacher, split):
    col = dagger.collect(rollout.FixedGainsPolicy(), teacher, [2], 0.0, seed=0)
    tags = copy.deepcopy(col.data.meta["tags"])
    tags[0]["dagger"][inputs.DRIVEN_TAG] = tags[0]["dagger"][inputs.DRIVEN_TAG][:-1]
    edited = dataclasses.replace(col.data, meta={**col.data.meta, "tags": tags})
    with pytest.raises(ValueError, match=r"scene 0: tags\['dagger'\]\['driven'\] must hold"):
        inputs.driven_controls(edited)


def test_a_dmp_model_is_trained_from_the_driven_speed_in_a_driven_scene(teacher, split):
    """A batch of a DMP model marks the windows of driven scenes (``driven``), whose motion
    is then the applied control at every step; a CNN's batch and a demonstrations-only
    batch are as before."""
    pool, _ = split
    col = dagger.collect(rollout.FixedGainsPolicy(), teacher, [2, 3], 0.0, seed=0)
    agg = dagger.concat([pool.subset([0, 1]), col.data])
    cfg = cfg_of(pool)
    T = pool.n_steps
    s_idx = np.broadcast_to(np.arange(4), (T, 4))
    t_idx = np.broadcast_to(np.arange(T)[:, None], (T, 4))
    batch = train.make_batch("manc", agg, s_idx, t_idx, cfg, np.float64)
    assert batch["driven"].tolist() == [False, False, True, True]
    np.testing.assert_allclose(batch["motion"][1:, 2:], np.swapaxes(
        inputs.driven_controls(agg)[2:, :-1], 0, 1), rtol=1e-6)
    assert "driven" not in train.make_batch("cnn", agg, s_idx, t_idx, cfg, np.float64)
    assert "driven" not in train.make_batch("manc", pool, s_idx, t_idx, cfg, np.float64)
