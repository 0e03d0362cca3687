"""The auxiliary perception loss on-policy (chapters 8 and 11): the teacher records what the
human perceives in every state it labels (:func:`minimanc.diagnose.state_targets`), DAgger
aggregates those targets with the demonstrations' and trains every round on them, resumes
them from its round folders, and refuses what cannot work; the targets' own file and
operations (:class:`minimanc.train.PerceptionTargets`)."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from minimanc import dagger, diagnose, rollout, train, world
from minimanc.dagger.expert import HumanExpert
from minimanc.studies.executors import train_on_policy

SIZE = 16
TC = train.TrainConfig(epochs=1, batch_size=64, perception_weight=0.5)


@pytest.fixture(scope="module")
def pool():
    return world.generate(8, seed=0, raster=world.RasterConfig(size=SIZE)).split(6)[0]


@pytest.fixture(scope="module")
def view(pool):
    return pool.raster


@pytest.fixture(scope="module")
def targets(pool, view):
    return diagnose.perception_targets(pool, view=view)


def perceiving(pool, view, agents="reactive"):
    return dagger.WorldTeacher(pool, agents=agents,
                               perceive=partial(diagnose.state_targets, view=view))


def cfg_of(pool):
    return dagger.default_config(pool, channels=(4, 4, 4), hidden=8)


def test_the_teacher_records_what_the_human_perceives_in_each_visited_state(pool, view):
    """Oracle: the expert asked again in every state the policy visited (log replay, so the
    state is the pose and the speed of the controls applied last)."""
    policy = rollout.FixedGainsPolicy()
    col = dagger.collect(policy, perceiving(pool, view, "replay"), [2, 3], 0.0)
    ref = rollout.simulate(policy, pool, scenes=[2, 3], progress=False)
    values, mask = col.perceived
    T, K = pool.n_steps, len(diagnose.TARGETS)
    assert values.shape == mask.shape == (2, T, K) and mask.dtype == bool
    expert = HumanExpert(pool)
    for b, s in enumerate([2, 3]):
        for t in range(T):
            speed = expert.steps(s)[0].speed if t == 0 else ref.controls[b, t - 1, 0]
            want, want_mask = diagnose.state_targets(
                expert.situation(s, t, ref.ego[b, t], float(speed)), view)
            np.testing.assert_allclose(values[b, t], want, atol=1e-5, err_msg=f"{s}, {t}")
            np.testing.assert_array_equal(mask[b, t], want_mask)
    lead = values[..., diagnose.TARGETS.index("has_leader")]
    assert (lead == 1).any() and (lead == 0).any()


def test_driving_as_the_human_perceives_the_logged_targets(pool, view, targets):
    """β = 1: the human driven by its own answers is its log, and what it perceives there
    is :func:`minimanc.diagnose.perception_targets` of those scenes (float32 poses)."""
    col = dagger.collect(None, perceiving(pool, view), [0, 2, 4], 1.0)
    values, mask = col.perceived
    want = targets.subset([0, 2, 4])
    flags = np.asarray(want.logit)
    np.testing.assert_array_equal(values[..., flags], want.values[..., flags])
    np.testing.assert_array_equal(mask, want.mask)
    np.testing.assert_allclose(values[..., ~flags], want.values[..., ~flags], atol=1e-2)


def test_label_is_label_and_perceive_without_the_targets(pool, view):
    sim = rollout.LogReplay(pool, np.array([0, 1]))
    sim.reset()
    plain = dagger.WorldTeacher(pool, agents="replay")
    labels, why = plain.label(sim, 0, None)
    again, why2, seen = perceiving(pool, view, "replay").label_and_perceive(sim, 0, None)
    np.testing.assert_array_equal(labels, again)
    assert why == why2 == [None, None]
    assert plain.label_and_perceive(sim, 0, None)[2] is None
    assert seen[0].shape == (2, len(diagnose.TARGETS))
    assert plain.perceive is None and dagger.collect(None, plain, [0], 1.0).perceived is None


def test_a_refused_state_perceives_nothing_and_its_scene_is_dropped(pool, view):
    # the fixed-gain DMP leaves the drivable area in scene 1 (tests/test_dagger.py)
    col = dagger.collect(rollout.FixedGainsPolicy(), perceiving(pool, view), [1, 2], 0.0)
    assert col.kept.tolist() == [2]
    assert col.perceived[0].shape[0] == len(col.data) == 1
    assert np.all(np.isfinite(col.perceived[0]))


def test_every_round_trains_on_the_targets_of_its_aggregate(pool, view, targets, tmp_path,
                                                            monkeypatch):
    seen = []
    real_fit = train.fit

    def fit(name, data, cfg, tc, **kw):
        seen.append((len(data), kw["perception"]))
        return real_fit(name, data, cfg, tc, **kw)

    monkeypatch.setattr(train, "fit", fit)
    kw = dict(cfg=cfg_of(pool), train_cfg=TC, engine="numpy", progress=False, evaluate=False,
              out=tmp_path, perception=targets)
    teacher = perceiving(pool, view)
    res = dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 2), rounds=2, **kw)
    assert [n for n, _ in seen] == [2, 3, 4]
    first = dagger.scene_order(len(pool), 0)[:2]
    np.testing.assert_array_equal(seen[0][1].values, targets.subset(np.sort(first)).values)
    for i, (n, got) in enumerate(seen[1:], start=1):
        saved = train.load_targets(dagger.round_dir(tmp_path, i) / dagger.PERCEPTION_FILE)
        assert saved.values.shape == (1, pool.n_steps, len(diagnose.TARGETS))
        assert got.values.shape[0] == n
        np.testing.assert_array_equal(got.values[-1:], saved.values)  # the newest scene last
        np.testing.assert_array_equal(got.values[:n - 1], seen[i - 1][1].values)
    assert "perception" not in res.params  # the controller, without the read-out
    # resumed: the collected targets come from the round folders, nothing is retrained
    seen.clear()
    monkeypatch.setattr(dagger.loop, "collect", lambda *a, **k: pytest.fail("recollected"))
    again = dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 2), rounds=2, **kw)
    assert seen == [] and all(r.loaded for r in again.rounds)
    # a round folder trained without the targets is another configuration
    with pytest.raises(ValueError, match="another configuration"):
        dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 2), rounds=2,
                      **{**kw, "perception": None, "train_cfg": train.TrainConfig(
                          epochs=1, batch_size=64)})


def test_a_killed_round_resumes_its_collected_targets(pool, view, targets, tmp_path,
                                                      monkeypatch):
    real_fit = train.fit
    calls = []

    def dies_in_round_1(*a, **k):
        calls.append(k["perception"])
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real_fit(*a, **k)

    monkeypatch.setattr(train, "fit", dies_in_round_1)
    kw = dict(cfg=cfg_of(pool), train_cfg=TC, engine="numpy", progress=False, evaluate=False,
              out=tmp_path, perception=targets)
    with pytest.raises(KeyboardInterrupt):
        dagger.dagger("cnn", perceiving(pool, view), dagger.Budget.fixed(40, 2, 1, 1),
                      rounds=1, **kw)
    collected = calls[1]
    calls.clear()
    monkeypatch.setattr(train, "fit", lambda *a, **k: calls.append(k["perception"])
                        or real_fit(*a, **k))
    monkeypatch.setattr(dagger.loop, "collect", lambda *a, **k: pytest.fail("recollected"))
    dagger.dagger("cnn", perceiving(pool, view), dagger.Budget.fixed(40, 2, 1, 1), rounds=1,
                  **kw)
    assert len(calls) == 1
    np.testing.assert_array_equal(calls[0].values, collected.values)
    np.testing.assert_array_equal(calls[0].mask, collected.mask)


@pytest.mark.parametrize(("make", "match"), [
    (lambda pool, view, t: (dagger.WorldTeacher(pool), t), "teacher that perceives"),
    (lambda pool, view, t: (perceiving(pool, view), t.subset([0, 1])), r"covers \(S, T\)"),
    (lambda pool, view, t: (perceiving(pool, view), t.values), "must be minimanc.train"),
])
def test_targets_dagger_cannot_use_are_refused(pool, view, targets, make, match):
    teacher, perception = make(pool, view, targets)
    with pytest.raises(ValueError, match=match):
        dagger.dagger("cnn", teacher, dagger.Budget.fixed(40, 2, 1, 1), rounds=1,
                      cfg=cfg_of(pool), train_cfg=TC, engine="numpy", progress=False,
                      evaluate=False, perception=perception)


def test_a_teacher_refuses_a_perceive_that_is_not_a_function(pool):
    with pytest.raises(ValueError, match="perceive must be a function"):
        dagger.WorldTeacher(pool, perceive=3)


def test_a_studys_on_policy_run_learns_the_perception_of_its_rounds(pool, targets, tmp_path):
    """:func:`minimanc.studies.executors.train_on_policy` with a targets file: every round
    folder holds its collected targets, and the run's checkpoint is written."""
    path = train.save_targets(targets, tmp_path / "targets.npz")
    checkpoint = tmp_path / "run" / train.CHECKPOINT_NAME
    job = {"model": "cnn", "cfg": cfg_of(pool), "engine": "numpy", "dagger_rounds": 1,
           "round_epochs": 1, "beta": 0.5, "perception": str(path)}
    assert train_on_policy(pool, job, TC, checkpoint) == checkpoint and checkpoint.exists()
    saved = train.load_targets(tmp_path / "run" / "dagger" / "round_001" /
                               dagger.PERCEPTION_FILE)
    assert saved.names == targets.names and saved.values.shape[1] == pool.n_steps


def test_targets_subset_concat_and_file(targets, tmp_path):
    a, b = targets.subset([3, 1]), targets.subset(slice(0, 2))
    both = train.concat_targets([a, b])
    np.testing.assert_array_equal(both.values, targets.values[[3, 1, 0, 1]])
    np.testing.assert_array_equal(both.mask, targets.mask[[3, 1, 0, 1]])
    assert train.concat_targets([a]) is a
    with pytest.raises(ValueError, match="at least one"):
        train.concat_targets([])
    other = train.PerceptionTargets(("v",), np.zeros((1, 2, 1)), np.ones((1, 2, 1), bool),
                                    (False,))
    with pytest.raises(ValueError, match=r"parts\[1\] has names"):
        train.concat_targets([a, other])
    path = train.save_targets(a, tmp_path / "t.npz")
    back = train.load_targets(path)
    assert back.names == a.names and back.logit == a.logit
    np.testing.assert_array_equal(back.values, a.values)
    path.write_bytes(path.read_bytes()[:100])
    with pytest.raises(ValueError, match="not perception targets"):
        train.load_targets(path)
