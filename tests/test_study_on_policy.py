"""Tests for a study's on-policy runs (``StudyConfig.dagger_rounds``): the settings and their
errors, the cache names that stay those of behaviour cloning, DAgger's rounds under a run's
checkpoint (its last round is the run), resuming a killed run between rounds, the sweeps
that stay behaviour cloning, the count of trainings and the words of ``table1.md``."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, replace

import numpy as np
import pytest

from minimanc import dagger, models, studies, train
from minimanc.dagger import loop
from minimanc.studies import config as study_config
from minimanc.studies.config import plan
from minimanc.tree import to_flat_dict

TINY = studies.PRESETS["tiny"]
NEW_FIELDS = ("dagger_rounds", "round_epochs", "model")
FLAT = models.ModelConfig(predicate_readout="flatten")


def small(**kw) -> studies.StudyConfig:
    """``tiny`` with CNN alone in Table I, in the paper setting, and no other study."""
    base = {"table_models": ("cnn",), "settings": ("paper",), "ablation_models": (),
            "sample_models": ()}
    return replace(TINY, **{**base, **kw})


def study_of(c: studies.StudyConfig, out, **kw) -> studies.Study:
    return studies.Study(c, out, engine="numpy", workers=0, progress=False, **kw)


def same_params(a: dict, b: dict) -> bool:
    fa, fb = to_flat_dict(a), to_flat_dict(b)
    return fa.keys() == fb.keys() and all(np.array_equal(fa[k], fb[k]) for k in fa)


# --------------------------------------------------------------------------- settings


@pytest.mark.parametrize(("kw", "match"), [
    ({"dagger_rounds": -1}, "dagger_rounds must be an integer >= 0"),
    ({"dagger_rounds": 1.0}, "dagger_rounds must be an integer"),
    ({"dagger_rounds": True}, "dagger_rounds must be an integer"),
    ({"round_epochs": 0}, "round_epochs must be an integer >= 1"),
    ({"round_epochs": "1"}, "round_epochs must be an integer"),
    ({"model": {"predicate_readout": "flatten"}}, "model must be a minimanc.models.ModelConfig"),
    ({"model": models.ModelConfig(n_states=3)}, "model.n_states is each run's"),
    ({"model": models.ModelConfig(setting="parity")}, "model.setting is each run's"),
    ({"model": models.ModelConfig(input_shape=(32, 32, 3))}, "model.input_shape is each run's"),
    # tiny: 4 training scenes, 2 of them at the data fraction 0.5; 2 rounds need 3
    ({"dagger_rounds": 2}, r"needs at least 3 training scenes .* fraction 0.5\) has 2"),
])
def test_bad_on_policy_settings_are_one_clear_error(kw, match):
    with pytest.raises(ValueError, match=match):
        replace(TINY, **kw)


def test_good_on_policy_settings_are_kept():
    assert not TINY.on_policy and (TINY.dagger_rounds, TINY.round_epochs) == (0, 1)
    c = replace(TINY, dagger_rounds=1, round_epochs=3, model=FLAT)
    assert c.on_policy and (c.dagger_rounds, c.round_epochs) == (1, 3)
    assert replace(small(), dagger_rounds=3).on_policy  # every run has all 4 scenes
    # the perception loss, by behaviour cloning and on-policy
    assert replace(TINY, training=replace(TINY.training, perception_weight=1.0)).fingerprint()
    assert replace(TINY, dagger_rounds=1,
                   training=replace(TINY.training, perception_weight=1.0)).on_policy


def test_the_runs_read_the_studys_model(tmp_path):
    learner = studies.config.LEARNER_MODEL
    study = study_of(replace(small(), model=learner), tmp_path)
    run = studies.Run("manc", "parity", 3, 1.0, 0, 1e-3)
    assert study.model_config(run) == replace(learner, n_states=3, setting="parity")
    assert study_of(small(), tmp_path / "gap").model_config(run) == models.ModelConfig(
        n_states=3, setting="parity")
    study = study_of(replace(small(), model=FLAT), tmp_path / "flat")
    # Fig. 5b counts the parameters of the runs: eq. 7's layer reads h·w·C features, not C
    flat = study.param_counts()["paper"]["manc"]
    assert flat > study_of(small(), tmp_path / "gap").param_counts()["paper"]["manc"]


def test_the_fixed_gains_row_is_the_librarys_dmp_head_whatever_the_studys_model(
        tmp_path, monkeypatch):
    """The bar stays the paper's goal rule at the default gains: under the learner's fixed
    goal those gains would crawl (about 4.5 m/s), a bar no driver needs to clear."""
    from minimanc import rollout

    seen = {}

    def fake(val, cfg, agents):
        seen["cfg"] = cfg
        raise RuntimeError("driven")

    monkeypatch.setattr(rollout, "fixed_gains", fake)
    study = study_of(replace(small(), model=studies.config.LEARNER_MODEL), tmp_path)
    with pytest.raises(RuntimeError, match="driven"):
        study.references.score("dmp_prior", "replay")
    assert seen["cfg"] == models.ModelConfig(n_states=TINY.n_states)


def test_the_privileged_bound_is_capped_where_the_studys_training_is(tmp_path, monkeypatch):
    from minimanc.diagnose import bounds

    seen = {}

    def fake(train_ds, seed, steps):
        seen[seed] = steps
        raise RuntimeError("trained")

    monkeypatch.setattr(bounds, "privileged_learner", fake)
    for seed, c in ((0, small()),
                    (1, replace(small(), training=replace(TINY.training,
                                                          max_steps_per_epoch=None)))):
        with pytest.raises(RuntimeError, match="trained"):
            study_of(c, tmp_path / str(seed)).references.privileged(seed)
    assert seen == {0: TINY.training.epochs * TINY.training.max_steps_per_epoch, 1: None}


def test_recorded_data_trains_by_behaviour_cloning_only(tmp_path):
    recorded = replace(TINY, data_file=str(tmp_path / "scenes.npz"), data_hash="0" * 12,
                       data_source="nuscenes")
    study_of(recorded, tmp_path, agents=("replay",))  # behaviour cloning: accepted
    with pytest.raises(ValueError, match="not available on recorded data: DAgger"):
        study_of(replace(recorded, dagger_rounds=1), tmp_path, agents=("replay",))


def test_fingerprints_are_those_of_behaviour_cloning_without_dagger():
    """Without DAgger and with the paper's read-out, a cache keeps the name it had before
    these fields existed (the hash of the configuration without them)."""
    paper_form = [studies.with_form(p, "paper") if study_config.form_of(p) else p
                  for p in studies.PRESETS.values()]
    for c in (*paper_form, studies.StudyConfig()):
        d = asdict(c)
        for k in ("preset", "n_seeds", "explain_scenes", "data_file", "data_hash",
                  "data_source", *NEW_FIELDS):
            d.pop(k)
        d["model_defaults"] = models.ModelConfig().to_dict()
        d["default_gains"] = list(models.DEFAULT_GAINS)
        before = hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]
        assert c.fingerprint() == before
        assert replace(c, dagger_rounds=0).fingerprint() == before
        assert replace(c, round_epochs=4).fingerprint() == before  # unused without DAgger
    base = studies.StudyConfig()
    on = replace(base, dagger_rounds=2)
    names = {c.fingerprint() for c in (base, on, replace(on, dagger_rounds=3),
                                       replace(on, round_epochs=2),
                                       replace(base, model=FLAT))}
    assert len(names) == 5


def test_the_presets_table_names_dagger_only_where_a_preset_trains_on_policy(monkeypatch):
    table = studies.presets_table()
    rows = {name: next(line for line in table.splitlines() if f"`{name}`" in line)
            for name in studies.PRESETS}
    assert "on-policy" not in rows["tiny"] and "| `tiny` | 4 / 1 / 2 |" in table
    for name in ("quick", "full", "paper"):
        assert "trained on-policy: DAgger with the world's expert, 10 rounds" in rows[name]
    # the sweep is named only where a preset has one
    assert "(the learning-rate sweep by behaviour cloning)" not in rows["quick"]
    assert "(the learning-rate sweep by behaviour cloning)" in rows["paper"]
    monkeypatch.setitem(study_config.PRESETS, "tiny", replace(TINY, dagger_rounds=1))
    row = next(line for line in studies.presets_table().splitlines() if "`tiny`" in line)
    assert ("| 1; trained on-policy: DAgger with the world's expert, 1 round, each after the "
            "first continuing 1 epoch |") in row
    assert studies.presets_table().replace(row, "") == table.replace(rows["tiny"], "")


# --------------------------------------------------------------------------- training


def test_an_on_policy_table_run_is_daggers_last_round(tmp_path):
    c = small(dagger_rounds=2, round_epochs=2)
    study = study_of(c, tmp_path)
    (run,) = study.runs("cnn")
    assert run.on_policy and run.key.endswith("-dagger")
    ck = study.fit(run)
    assert ck == study.checkpoint(run)
    out = ck.parent / "dagger"
    assert sorted(p.name for p in out.iterdir()) == ["round_000", "round_001", "round_002"]
    assert all((p / dagger.ROUND_FILE).exists() for p in out.iterdir())
    assert (dagger.round_dir(out, 1) / "data.npz").exists()  # states the policy visited
    last = dagger.round_dir(out, 2) / train.CHECKPOINT_NAME
    assert ck.read_bytes() == last.read_bytes()
    assert same_params(train.load_fit(ck).params, train.load_fit(last).params)
    first = train.load_checkpoint(dagger.round_dir(out, 0) / train.CHECKPOINT_NAME)
    assert not same_params(first["params"], train.load_fit(ck).params)
    # round 0 trains the study's epochs on demonstrations, every later round round_epochs
    assert first["epoch"] == c.training.epochs and train.load_checkpoint(last)["epoch"] == 2
    assert (first["train_cfg"].seed, first["train_cfg"].lr) == (run.seed, run.lr)
    fp = json.loads((dagger.round_dir(out, 2) / dagger.ROUND_FILE).read_text())["fingerprint"]
    assert (fp["sim"], fp["agents"], fp["pool"], fp["seed"]) == ("world", "reactive",
                                                                 c.n_train, run.seed)
    assert fp["betas"] == [1.0, 0.5, 0.25] and fp["round_cfg"]["epochs"] == 2
    assert (fp["cfg"]["predicate_readout"], fp["cfg"]["gains_input"]) == ("gap", "q")
    # done: asked again, nothing trains
    again = study_of(c, tmp_path)
    assert again.files.complete(run) and again.fit(run) == ck


def test_a_run_on_part_of_the_data_drives_the_scenes_fit_would_train_on(tmp_path, monkeypatch):
    c = replace(small(), sample_models=("cnn",), fractions=(0.5, 1.0), dagger_rounds=1)
    study = study_of(c, tmp_path)
    pools = []

    class Spy(dagger.WorldTeacher):
        def __init__(self, pool, *args, **kw):
            pools.append(pool)
            super().__init__(pool, *args, **kw)

    monkeypatch.setattr(dagger, "WorldTeacher", Spy)
    (run,) = study.runs("cnn", fraction=0.5)
    study.fit(run)
    train_ds = study.datasets()[0]
    scenes = train.subset_scenes(len(train_ds), 0.5, run.seed)
    assert len(pools) == 1 and len(pools[0]) == len(scenes) == 2
    assert list(scenes) != [0, 1]  # not simply the first scenes
    np.testing.assert_array_equal(pools[0].ego, np.asarray(train_ds.ego)[scenes])
    assert pools[0].tags == [train_ds.tags[i] for i in scenes]


def test_a_killed_on_policy_run_resumes_after_its_last_finished_round(tmp_path, monkeypatch):
    c = small(dagger_rounds=2)
    study = study_of(c, tmp_path)
    (run,) = study.runs("cnn")
    out = study.checkpoint(run).parent / "dagger"

    class Killed(Exception):
        pass

    collect = loop.collect

    def killed_in_round_2(*args, **kw):
        if kw["seed"][1] == 2:
            raise Killed
        return collect(*args, **kw)

    monkeypatch.setattr(loop, "collect", killed_in_round_2)
    with pytest.raises(Killed):
        study.fit(run)
    assert not study.checkpoint(run).exists() and not study.files.complete(run)
    finished = {i: (dagger.round_dir(out, i) / dagger.ROUND_FILE).stat().st_mtime_ns
                for i in (0, 1)}
    assert not (dagger.round_dir(out, 2) / dagger.ROUND_FILE).exists()

    calls = {"collect": 0, "fit": 0}
    fit = train.fit

    def counted(name, real):
        def call(*args, **kw):
            calls[name] += 1
            return real(*args, **kw)
        return call

    monkeypatch.setattr(loop, "collect", counted("collect", collect))
    monkeypatch.setattr(train, "fit", counted("fit", fit))
    ck = study_of(c, tmp_path).fit(run)
    assert calls == {"collect": 1, "fit": 1}  # round 2 only
    assert {i: (dagger.round_dir(out, i) / dagger.ROUND_FILE).stat().st_mtime_ns
            for i in (0, 1)} == finished
    assert ck.read_bytes() == (dagger.round_dir(out, 2) / train.CHECKPOINT_NAME).read_bytes()


def test_a_diverged_on_policy_run_is_recorded_and_scored_inf(tmp_path, monkeypatch):
    c = small(dagger_rounds=1)
    study = study_of(c, tmp_path)
    (run,) = study.runs("cnn")
    fit = train.fit

    def diverge_in_round_1(*args, **kw):
        if kw.get("params") is not None:  # a round that continues from the previous one
            raise train.TrainingDiverged("loss is nan")
        return fit(*args, **kw)

    monkeypatch.setattr(train, "fit", diverge_in_round_1)
    study.fit(run)
    assert study.files.diverged(run) and not study.checkpoint(run).exists()
    assert "loss is nan" in (study.checkpoint(run).parent / "diverged.json").read_text()
    assert study.files.complete(run)
    assert study.result(run)["ade"] == float("inf")


def test_the_sweep_runs_train_by_behaviour_cloning(tmp_path):
    c = small(dagger_rounds=1, lrs=(1e-3, 3e-3))
    study = study_of(c, tmp_path)
    (run,) = study.runs("cnn")  # tunes the learning rate first
    sweep = [studies.Run("cnn", "paper", c.n_states, 1.0, 0, lr) for lr in c.lrs]
    for r in sweep:
        ck = study.checkpoint(r)
        assert ck.exists() and not (ck.parent / "dagger").exists()
        assert train.load_checkpoint(ck)["epoch"] == c.training.epochs
    winner = next(r for r in sweep if r.lr == run.lr)
    assert run == replace(winner, on_policy=True)
    assert not study.checkpoint(run).exists()  # the winner does not double as Table I's run
    ck = study.fit(run)
    assert (ck.parent / "dagger").is_dir()
    assert not same_params(train.load_fit(ck).params,
                           train.load_fit(study.checkpoint(winner)).params)


def test_plan_counts_every_training_of_an_on_policy_study_and_table1_says_so(tmp_path):
    c = replace(small(), table_models=("cnn", "manc"), sample_models=("cnn",),
                fractions=(0.75, 1.0), q_states=(3, 6), lrs=(1e-3, 3e-3), dagger_rounds=2)
    bc = replace(c, dagger_rounds=0)
    # on-policy, the seed-0 run at full data of each tuned pair is not its sweep's winner
    assert sum(plan(c, 1)["train"].values()) == sum(plan(bc, 1)["train"].values()) + 2
    assert plan(c, 1)["rollouts"] == plan(bc, 1)["rollouts"]
    log: list[str] = []
    study = study_of(c, tmp_path, agents=("replay",), log=log.append)
    results = study.run()
    trained = [line for line in log if line.startswith("train:") and " in " in line]
    assert len(trained) == study.n_trainings() == sum(plan(c, 1)["train"].values())
    assert len(study.evaluations.futures) == study.n_runs()
    models_dir = study.files.dir / "models"
    on = [p for p in models_dir.iterdir() if p.name.endswith("-dagger")]
    assert len(on) == 4 and all((p / "dagger").is_dir() for p in on)  # cnn ×2, manc ×2
    assert len(list(models_dir.iterdir())) == 4 + 2 * len(c.lrs)
    assert results["config"]["dagger_rounds"] == 2
    md = studies.table_markdown(results)
    assert ("1 epochs, trained on-policy: DAgger with the "
            "world's expert, 2 rounds, each after the first continuing 1 epoch (the "
            "learning-rate sweep by behaviour cloning), learning rate from") in md
    # behaviour cloning: the words of a results file written before the fields existed
    without = {k: v for k, v in results["config"].items() if k not in NEW_FIELDS}
    old = studies.table_markdown({**results, "config": without})
    assert "on-policy" not in old
    assert studies.table_markdown({**results, "config": asdict(bc)}) == old
