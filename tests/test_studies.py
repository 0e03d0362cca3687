"""Tests for minimanc.studies: the configuration and its fingerprint, the study's files and
cache recovery, the CLI, and ``minimanc reproduce`` end to end on a tiny configuration (the
findings and the table: tests/test_studies_report.py)."""

from __future__ import annotations

import json
from dataclasses import fields, replace

import numpy as np
import pytest

from minimanc import cli, diagnose, metrics, models, rollout, studies, train, viz, world
from minimanc.studies import jobs, report
from minimanc.studies.cache import StudyFiles
from minimanc.studies.evaluation import families_of
from minimanc.train import load_targets


def test_study_config_validation_and_fingerprint():
    base = studies.PRESETS["tiny"]
    assert base.fingerprint() == studies.StudyConfig(**{**base.__dict__}).fingerprint()
    assert replace(base, n_seeds=3).fingerprint() == base.fingerprint()
    assert replace(base, training=replace(base.training, epochs=2)).fingerprint() != \
        base.fingerprint()
    with pytest.raises(ValueError, match="n_val"):
        replace(base, n_val=0)
    with pytest.raises(ValueError, match="lrs"):
        replace(base, lrs=())
    with pytest.raises(ValueError, match="fractions"):
        replace(base, fractions=(0.0, 1.0))
    with pytest.raises(ValueError, match="table_models"):
        replace(base, table_models=("resnet",))
    with pytest.raises(ValueError, match="engine"):
        studies.Study(base, "/tmp/x", engine="torch")


def test_canonical_setting_shares_manc_runs():
    assert studies.canonical_setting("manc", "parity") == "paper"
    assert studies.canonical_setting("dmp_only", "parity") == "paper"
    assert studies.canonical_setting("cnn", "parity") == "parity"


def test_cli_registers_reproduce():
    parser = cli.build_parser()
    args = parser.parse_args(["reproduce", "--quick", "--engine", "numpy", "--out", "x",
                              "--seeds", "2"])
    assert args.quick and args.engine == "numpy" and args.seeds == 2 and args.out == "x"


@pytest.mark.whole_run
def test_reproduce_tiny_writes_everything(tmp_path, capsys):
    out = tmp_path / "run"
    code = cli.main(["reproduce", "--preset", "tiny", "--engine", "numpy", "--out", str(out),
                     "--workers", "0", "--no-progress"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "table1.md" in printed and "results.json" in printed
    res = json.loads((out / "results.json").read_text())
    assert res["provenance"]["command"] == ("minimanc reproduce --preset tiny --engine numpy "
                                            f"--out {out} --workers 0 --no-progress")
    assert res["provenance"]["packages"]["numpy"] and res["wall_time_s"] > 0
    table = (out / "table1.md").read_text()
    assert table.rstrip().splitlines()[-1].startswith("- wall time: ")
    assert "- command: `minimanc reproduce --preset tiny" in table
    assert "| Model | ADE ÷ floor | along-track ÷ floor |" in table
    assert "| Model | front | stopped ado | lateral | rear | stopped ego | at fault |" in table
    assert "agents replay and reactive" in printed and "agents `reactive`" in printed
    assert res["agents"] == ["replay", "reactive"] and set(res["table1"]) == set(res["agents"])
    for agents, t1 in res["table1"].items():
        assert set(t1) == {"paper", "parity"}
        assert set(t1["paper"]) == {"human", "dmp_prior", "expert", "style_floor",
                                    "privileged", "cnn", "cnn_lstm", "rvs_g", "manc"}
        # the bounds: the world's driver asked closed loop is the log; the median-style
        # driver is not, and collides no more than the human
        assert t1["paper"]["expert"]["ade"]["mean"] < 1e-3
        assert t1["paper"]["expert"]["at_fault_collision_rate"]["mean"] == 0.0
        assert t1["paper"]["style_floor"]["ade"]["mean"] > 0.0
        # the privileged learner: one run per training seed, trained on the training split
        priv = t1["paper"]["privileged"]
        assert priv["ade"]["n"] == res["config"]["n_seeds"] and priv["ade"]["mean"] > 0.0
        # the human's log touches nothing it is at fault for
        assert t1["paper"]["human"]["contacts_at_fault"]["mean"] == 0.0
        human = t1["paper"]["human"]
        # the log itself, or its controls integrated again among reactive ados (float32 log)
        assert human["ade"]["mean"] < 1e-4 and human["along_track"]["mean"] < 1e-4
        assert human["at_fault_collision_rate"]["mean"] == 0.0
        assert t1["paper"]["dmp_prior"]["ade"]["mean"] > 0.0
        # MANC sees the same in both settings: the same run, the same numbers
        assert t1["paper"]["manc"] == t1["parity"]["manc"]
        for m, row_ in t1["paper"].items():
            assert set(jobs.STUDY_METRICS) <= set(row_), (agents, m)
            # the split is a rotation of the displacement: each part is at most the ADE
            assert row_["along_track"]["mean"] <= row_["ade"]["mean"] + 1e-9
            assert row_["cross_track"]["mean"] <= row_["ade"]["mean"] + 1e-9
        fams = res["families"][agents]["paper"]
        assert set(fams) == set(t1["paper"])
        assert all(set(f) <= set(jobs.SCENE_FAMILIES) and f for f in fams.values())
    assert res["table1"]["replay"]["paper"]["human"]["ade"]["mean"] == 0.0
    assert [len(v) for v in res["sample_efficiency"]["models"].values()] == [2] * 4
    assert res["q_states"]["n_states"] == [3, 6]
    assert set(res["ablation"]["models"]) == {"manc", "vagn_only", "dmp_only"}
    assert res["ablation"]["agents"] == "replay"
    assert set(res["modes"]["models"]) == {"manc", "vagn_only"}
    assert sum(res["modes"]["mode_counts"].values()) == 2 * 40  # 2 validation scenes, 40 steps
    for f in res["findings"]:
        assert f["holds"] in (True, False, None) and f["detail"]
    ids = {f["id"] for f in res["findings"]}
    assert {"vagn_modes_manc", "vagn_modes_vagn_only", "reactive_human_no_at_fault"} <= ids
    md = (out / "table1.md").read_text()
    assert "Table I" in md and "MANC" in md and "Per scenario family" in md
    figs = {p.name for p in (out / "figures").iterdir()}
    for name in ("table1_replay.png", "table1_reactive.png", "families_replay.png",
                 "families_reactive.png", "speeds_replay.png", "sample_efficiency.png",
                 "param_counts.png", "q_states.png",
                 "ablation.png", "trajectories.png", "rollout.gif"):
        assert name in figs, name
    assert any(n.startswith("explain_scene") for n in figs)
    assert any(n.startswith("saliency_scene") for n in figs)
    assert any(n.startswith("q_modes_scene") for n in figs)
    # a re-run reuses every cached model and rollout
    mtimes = {p: p.stat().st_mtime for p in (out / "cache").rglob("*.npz")}
    assert mtimes
    res2 = studies.reproduce(studies.PRESETS["tiny"], out, engine="numpy", workers=0,
                             progress=False, figures=False)
    assert {p: p.stat().st_mtime for p in (out / "cache").rglob("*.npz")} == mtimes
    study = studies.Study(studies.PRESETS["tiny"], out, engine="numpy", workers=0,
                          progress=False)
    study.run()
    assert len(study.evaluations.futures) == study.n_runs()  # the progress bar's total is exact
    assert np.isclose(res2["table1"]["reactive"]["paper"]["cnn"]["ade"]["mean"],
                      res["table1"]["reactive"]["paper"]["cnn"]["ade"]["mean"])
    assert res2["modes"] == res["modes"]  # the mode labels and the MI come from the cache


def test_study_agents_choose_the_protocols_and_their_files(tmp_path):
    tiny = studies.PRESETS["tiny"]
    both = studies.Study(tiny, tmp_path, engine="numpy", workers=0)
    replay = studies.Study(tiny, tmp_path, engine="numpy", workers=0, agents=("replay",))
    assert both.agents == ("replay", "reactive") and both.primary == "replay"
    run = _tiny_run(both)
    files = both.files
    assert files.rollout_paths(run, "val", "replay") != files.rollout_paths(run, "val", "reactive")
    # two protocols: Table I's validation runs once more each, nothing else changes
    c = tiny
    n_table = len({(m, studies.canonical_setting(m, s)) for s in c.settings
                   for m in c.table_models}) * c.n_seeds
    assert both.n_runs() == replay.n_runs() + n_table
    for bad in ("reactive", (), ("replay", "replay"), ("replay", "ideal")):
        with pytest.raises(ValueError, match="agents"):
            studies.Study(tiny, tmp_path, engine="numpy", agents=bad)


def test_cli_agents_option():
    parser = cli.build_parser()
    assert parser.parse_args(["reproduce"]).agents == "both"
    assert parser.parse_args(["reproduce", "--agents", "reactive"]).agents == "reactive"
    with pytest.raises(SystemExit):
        parser.parse_args(["reproduce", "--agents", "ideal"])


def test_new_plots_refuse_bad_input():
    with pytest.raises(ValueError, match="q must have shape"):
        viz.explain.plot_q_modes(np.zeros((5, 3)), np.zeros(4, int))
    with pytest.raises(ValueError, match="families"):
        viz.study.plot_families({})
    with pytest.raises(ValueError, match="metrics"):
        viz.study.plot_families({"manc": {}}, metrics=("speed",))


def test_scene_families_follow_the_tags():
    tags = [{"kind": "straight", "has_cut_in": False}, {"kind": "curved", "has_cut_in": True},
            {"kind": "intersection", "has_cut_in": True}, {"kind": "roundabout",
                                                           "has_cut_in": False}]

    class DS:
        ego = np.zeros((4, 2, 3))

    DS.tags = tags
    fam = jobs.scene_families(DS)
    assert list(fam) == list(jobs.SCENE_FAMILIES)
    assert fam["free"].tolist() == [True, False, False, False]
    assert fam["junction"].tolist() == [False, False, True, False]
    assert fam["roundabout"].tolist() == [False, False, False, True]
    assert fam["cut_in"].tolist() == [False, True, True, False]
    DS.tags = None
    with pytest.raises(ValueError, match="tag"):
        jobs.scene_families(DS)


def test_score_splits_the_error_and_scores_each_family_on_its_scenes():
    ds = world.generate(6, seed=11, raster=world.RasterConfig(size=32), workers=1)
    traj = rollout.fixed_gains(ds)
    res = jobs.score(traj, ds)
    assert set(jobs.STUDY_METRICS) <= set(res)
    # per scene, then averaged: the numbers of metrics.evaluate, under either protocol
    for t in (traj, rollout.fixed_gains(ds, agents="reactive")):
        got, want = jobs.score(t, ds), metrics.evaluate(t, ds)
        assert all(np.isclose(got[k], want[k], rtol=1e-12, atol=1e-12) for k in want), want
    along, cross = metrics.along_cross_track(traj.ego, ds.ego)
    assert np.isclose(res["along_track"], np.abs(along).mean())
    assert np.isclose(res["cross_track"], np.abs(cross).mean())
    fam = jobs.scene_families(ds)
    for name, f in res["families"].items():
        idx = np.flatnonzero(fam[name])
        assert f["n_scenes"] == idx.size > 0
        one = metrics.evaluate(traj.subset(idx), ds.subset(idx))
        for k, v in one.items():
            assert np.isclose(f[k], v), (name, k)
    absent = [n for n in jobs.SCENE_FAMILIES if not fam[n].any()]
    assert all(n not in res["families"] for n in absent)


def test_run_files_are_distinct_per_lr_seed_and_split(tmp_path):
    study = studies.Study(studies.PRESETS["tiny"], tmp_path, engine="numpy", workers=0)
    runs = [studies.Run("cnn", "paper", 6, 1.0, s, lr) for s in (0, 1) for lr in (1e-3, 3e-3)]
    paths = {p for r in runs for split in ("tune", "val")
             for p in study.files.rollout_paths(r, split)}
    assert len(paths) == 2 * len(runs) * 2
    assert len({study.checkpoint(r) for r in runs}) == len(runs)
    assert all(p.name.endswith((".npz", ".json")) and "lr0.001" in p.name or "lr0.003" in p.name
               for p in paths)


def test_a_closed_loop_that_blows_up_scores_inf(tmp_path, monkeypatch):
    # train.save_checkpoint/load refuse non-finite parameters; let them through to the closed loop
    monkeypatch.setattr(train.checkpoint, "bad_params", lambda *a, **k: None)

    ds = world.generate(2, seed=5, raster=world.RasterConfig(size=32), workers=1)
    data = world.save(ds, tmp_path / "d.npz")
    cfg = models.ModelConfig(input_shape=(32, 32, 3))
    params = models.init("cnn", np.random.default_rng(0), cfg)
    params["out"]["b"] = params["out"]["b"] * np.nan
    ck = train.save_checkpoint(tmp_path / "ck.npz", "cnn", params, cfg, raster=ds.raster)
    job = {"data": str(data), "lo": 0, "hi": 2, "checkpoint": str(ck), "engine": "numpy",
           "rollout": str(tmp_path / "r.npz"), "metrics": str(tmp_path / "m.json")}
    res = jobs.evaluate_job(job)
    assert res["ade"] == float("inf") and "finite" in res["error"]
    agg = metrics.aggregate([res])
    assert "error" not in agg and agg["ade"]["mean"] == float("inf")
    assert "diverged" in report.cell(agg, "ade", 1)
    # every metric of the study is there (aggregate keeps only the keys of every seed)
    assert set(agg) == set(jobs.STUDY_METRICS)
    assert set(res["families"]) == set(jobs.SCENE_FAMILIES)
    assert set(families_of([res])["free"]) == set(jobs.STUDY_METRICS)


# --------------------------------------------------------------------------- cache recovery


def _tiny_run(study):
    c = study.config
    return studies.Run("cnn", "paper", c.n_states, 1.0, 0, float(c.lrs[0]))


def test_a_broken_checkpoint_in_the_cache_is_retrained(tmp_path, capsys):
    tiny = studies.PRESETS["tiny"]
    study = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    run = _tiny_run(study)
    path = study.fit(run)
    good = train.load_checkpoint(path)
    raw = path.read_bytes()
    for broken in (raw[: len(raw) // 2], b""):
        path.write_bytes(broken)
        (path.parent / f"{path.name}.x1y2.tmp").write_bytes(b"")  # a killed save's leftover
        again = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
        assert again.fit(run) == path
        err = capsys.readouterr().err
        assert "discarding the unreadable cache entry" in err and path.name in err
        ck = train.load_checkpoint(path)  # retrained: readable and complete
        assert ck["epoch"] == tiny.training.epochs and ck["history"] == good["history"]
        assert sorted(p.name for p in path.parent.iterdir()) == [path.name]


def test_a_broken_data_file_in_the_cache_is_regenerated(tmp_path, capsys):
    tiny = studies.PRESETS["tiny"]
    study = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    train_ds, _, _ = study.datasets()
    raw = study.files.data_path.read_bytes()
    study.files.data_path.write_bytes(raw[:1000])
    again = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    train2, _, _ = again.datasets()
    assert "discarding the unreadable cache entry" in capsys.readouterr().err
    assert train2.content_hash() == train_ds.content_hash()
    assert study.files.data_path.read_bytes() == raw


def test_the_reference_rows_are_driven_once_and_read_back(tmp_path, capsys, monkeypatch):
    """A study that resumes reads the rows without training from its cache; a broken file
    is driven again."""
    from minimanc import rollout

    tiny = studies.PRESETS["tiny"]
    study = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)

    def same(a, b):  # compared as JSON text, where NaN equals NaN
        return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)

    first = study.references.score("human", "replay")
    path = study.files.reference_path("human-val-replay")
    assert same(json.loads(path.read_text()), first)

    def no_drive(*args, **kwargs):
        raise AssertionError("driven again")

    monkeypatch.setattr(rollout, "human", no_drive)
    again = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    assert same(again.references.score("human", "replay"), first)
    monkeypatch.undo()
    path.write_text("[1, 2")  # cut short
    third = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    assert same(third.references.score("human", "replay"), first)
    assert "discarding the unreadable cache entry" in capsys.readouterr().err
    assert same(json.loads(path.read_text()), first)


def test_a_broken_metrics_file_is_recomputed(tmp_path, capsys):
    tiny = studies.PRESETS["tiny"]
    study = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    run = _tiny_run(study)
    first = study.result(run)
    _, met = study.files.rollout_paths(run, "val")
    met.write_text('{"ade": 1.')  # cut short
    again = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    assert again.result(run) == first
    assert "discarding the unreadable cache entry" in capsys.readouterr().err
    assert json.loads(met.read_text()) == first
    assert not list(met.parent.glob("*.tmp"))


@pytest.mark.parametrize("args,expected", [
    (["--seeds", "0"], "--seeds must be an integer >= 1, got --seeds=0"),
    (["--workers", "-1"], "--workers must be an integer >= 0, got --workers=-1"),
])
def test_reproduce_bad_arguments_are_one_line_exit_2(tmp_path, capsys, args, expected):
    code = cli.main(["reproduce", "--preset", "tiny", "--out", str(tmp_path / "r"), *args])
    err = capsys.readouterr().err
    assert code == 2 and err.strip() == f"minimanc reproduce: error: {expected}", err
    assert not (tmp_path / "r").exists()


def test_reproduce_unwritable_out_is_one_line_exit_2(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code = cli.main(["reproduce", "--preset", "tiny", "--out", str(blocker / "sub")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and "cannot create the directory" in err


# --------------------------------------------------------------------------- the training config


def _changed(field, value):
    """A valid TrainConfig value different from ``value``."""
    if isinstance(value, bool):
        return not value
    if field == "q_init":
        return "random" if value == "uniform" else "uniform"
    if field == "dtype":
        return "float64" if value == "float32" else "float32"
    if value is None:
        return 3
    if isinstance(value, int):
        return value + 1
    return value * 0.5 if value else 0.25


def test_study_config_holds_a_train_config_and_every_training_field_changes_the_fingerprint():
    base = studies.PRESETS["tiny"]
    assert isinstance(base.training, train.TrainConfig)
    seen = set()
    for f in fields(train.TrainConfig):
        tc = replace(base.training, **{f.name: _changed(f.name, getattr(base.training, f.name))})
        other = replace(base, training=tc)
        assert other.training == tc
        assert other.fingerprint() != base.fingerprint(), f.name
        seen.add(other.fingerprint())
    assert len(seen) == len(fields(train.TrainConfig))
    # one spelling per setting: the training fields are the TrainConfig's, not the study's
    with pytest.raises(TypeError, match="epochs"):
        studies.StudyConfig(epochs=2)
    assert not hasattr(base, "epochs")
    with pytest.raises(ValueError, match="dmp_seq_len"):
        studies.StudyConfig(training=train.TrainConfig(dmp_seq_len=0))
    with pytest.raises(ValueError, match="training"):
        studies.StudyConfig(training={"epochs": 2})


def test_presets_keep_their_training_values():
    want = {
        "tiny": train.TrainConfig(epochs=1, batch_size=16, max_steps_per_epoch=2, seq_len=4),
        "quick": train.TrainConfig(epochs=3, batch_size=64),
        "full": train.TrainConfig(epochs=4, batch_size=64),
        "paper": train.TrainConfig(epochs=6, batch_size=64),
    }
    for name, tc in want.items():
        assert studies.PRESETS[name].training == tc, name


def test_a_run_trains_with_the_studys_train_config(tmp_path):
    tiny = studies.PRESETS["tiny"]
    c = replace(tiny, training=replace(tiny.training, dmp_seq_len=6, q_seq_len=2))
    study = studies.Study(c, tmp_path, engine="numpy", workers=0, progress=False)
    run = studies.Run("manc", "paper", c.n_states, 0.5, 1, 2e-3)
    tc = study.train_config(run)
    assert (tc.dmp_seq_len, tc.q_seq_len, tc.lr, tc.seed, tc.subset, tc.epochs) == \
        (6, 2, 2e-3, 1, 0.5, 1)


@pytest.mark.whole_run
def test_reproduce_with_dagger_adds_the_table_and_the_figures(tmp_path, capsys, monkeypatch):
    # the tiny preset's Table I of CNN and MANC in one setting (the models DAgger compares),
    # without its other studies: what --dagger adds, at a third of the trainings
    small = replace(studies.PRESETS["tiny"], table_models=("cnn", "manc"), ablation_models=(),
                    sample_models=(), settings=("paper",))
    monkeypatch.setitem(studies.PRESETS, "tiny", small)
    out = tmp_path / "run"
    code = cli.main(["reproduce", "--preset", "tiny", "--engine", "numpy", "--out", str(out),
                     "--workers", "0", "--no-progress", "--agents", "replay", "--dagger"])
    assert code == 0
    res = json.loads((out / "results.json").read_text())
    dg = res["dagger"]
    assert dg["agents"] == "replay" and dg["rounds"] == 3 and set(dg["models"]) == {"manc", "cnn"}
    for m in dg["models"].values():
        assert len(m["by_round"]) == 4
        # DAgger's last round is the table's DAgger row; both methods see the same labels
        assert m["dagger"] == m["by_round"][-1]
        assert np.isfinite(m["bc"]["ade"]["mean"]) and np.isfinite(m["dagger"]["ade"]["mean"])
    table = (out / "table1.md").read_text()
    assert "## BC against DAgger at equal labels (agents `replay`)" in table
    assert f"{dg['labelled']} expert-labelled samples for both methods" in table
    assert (out / "figures" / "dagger_ade.png").exists()
    # the studies of no models have no figure (and the others theirs)
    figs = {p.name for p in (out / "figures").iterdir()}
    assert "ablation.png" not in figs and "sample_efficiency.png" not in figs
    assert {"q_states.png", "param_counts.png", "table1_replay.png"} <= figs
    # a rerun loads every round from the checkpoints: the same numbers
    assert cli.main(["reproduce", "--preset", "tiny", "--engine", "numpy", "--out", str(out),
                     "--workers", "0", "--no-progress", "--agents", "replay", "--dagger"]) == 0
    assert json.loads((out / "results.json").read_text())["dagger"] == dg


# --------------------------------------------------------------------------- the raster


CHANNELS = dict(size=32, encoding="channels", route=True, history=2)
"""The learner's raster at the tiny preset's size."""


def test_the_raster_names_the_cache_the_data_file_and_the_text():
    tiny = studies.PRESETS["tiny"]
    assert tiny.raster == world.RasterConfig(size=32)
    assert all(studies.PRESETS[p].raster == studies.config.LEARNER_RASTER
               for p in ("quick", "full", "paper"))
    learner = replace(tiny, raster=world.RasterConfig(**CHANNELS))
    assert learner.fingerprint() != tiny.fingerprint()
    assert replace(tiny, raster=world.RasterConfig(size=32)).fingerprint() == tiny.fingerprint()
    paths = {c.raster: StudyFiles(c, "out", "numpy", print).data_path for c in (tiny, learner)}
    assert paths[tiny.raster].name == "world-7x0-32px.npz"
    assert paths[learner.raster].name.startswith("world-7x0-32x32-channels-")
    assert studies.raster_text(tiny.raster) == "32×32 RGB raster (the paper's form)"
    assert studies.raster_text(learner.raster) == \
        "32×32 binary channels (route, vehicles at t, t−1, t−2)"
    corridor = world.RasterConfig.from_extent(60.0, 25.0, 50 / 64, encoding="channels",
                                              route=True, history=2)
    assert studies.raster_text(corridor) == \
        "90×64 binary channels (route, vehicles at t, t−1, t−2), 60 m ahead"
    for bad in (32, {"size": 32}, None):
        with pytest.raises(ValueError, match="raster must be a minimanc.world.RasterConfig"):
            replace(tiny, raster=bad)
    with pytest.raises(TypeError, match="image_size"):
        studies.StudyConfig(image_size=32)


def test_the_learners_raster_with_the_perception_loss_trains_and_drives_every_table_model(
        tmp_path, capsys):
    """The tiny preset on the binary channels with λ = 1: every Table I model trains with the
    auxiliary loss on the targets of the training scenes as the raster shows them, and
    drives its validation scenes closed loop; behaviour cloning against DAgger learns it too."""
    tiny = studies.PRESETS["tiny"]
    raster = world.RasterConfig(**CHANNELS)
    c = replace(tiny, raster=raster, settings=("paper",),
                training=replace(tiny.training, perception_weight=1.0))
    study = studies.Study(c, tmp_path, engine="numpy", workers=0, progress=False,
                          agents=("replay",))
    train_ds, _, val = study.datasets()
    assert train_ds.raster == raster and val.raster == raster
    table = study.table1()["replay"]["paper"]
    for m in c.table_models:
        run = study.runs(m)[0]
        ck = train.load_checkpoint(study.checkpoint(run))
        assert ck["cfg"].input_shape == (32, 32, 12), m
        assert ck["train_cfg"].perception_weight == 1.0 and "perception" in ck["params"], m
        assert np.isfinite(table[m]["ade"]["mean"]), m
    targets = load_targets(study.files.perception_path())
    want = diagnose.perception_targets(train_ds, view=raster)
    assert targets.names == want.names and np.array_equal(targets.mask, want.mask)
    assert np.allclose(targets.values, want.values)
    assert study.param_counts()["paper"]["cnn"] > 0
    # the targets are derived data: a broken file is computed again
    path = study.files.perception_path()
    path.write_bytes(path.read_bytes()[:100])
    assert study.files.perception_targets() == path
    assert "discarding the unreadable cache entry" in capsys.readouterr().err
    assert np.array_equal(load_targets(path).values, targets.values)
    # behaviour cloning against DAgger with the loss: both learn it, DAgger also on the
    # states it collects
    res = studies.dagger_study.run_dagger(study, models=("cnn",), rounds=1)
    assert np.isfinite(res["models"]["cnn"]["dagger"]["ade"]["mean"])
    base = study.files.dir / "dagger" / "cnn-s0"
    for where in (base / "bc" / "bc", base / "dagger" / "round_000",
                  base / "dagger" / "round_001"):
        assert "perception" in train.load_checkpoint(where / "checkpoint.npz")["params"]
    collected = load_targets(base / "dagger" / "round_001" / "perception.npz")
    assert collected.names == want.names and collected.values.shape[1] == train_ds.n_steps
