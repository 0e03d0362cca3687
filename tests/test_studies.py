"""Tests for minimanc.studies: findings from numbers, the markdown table, the CLI, and
``minimanc reproduce`` end to end on a tiny configuration."""

from __future__ import annotations

import json

import numpy as np
import pytest

from minimanc import metrics, studies
from minimanc.studies import jobs, report


def agg(**means):
    """An aggregate with the given means (std 0.1, 3 seeds)."""
    return {k: {"mean": v, "std": 0.1, "n": 3, "values": [v] * 3} for k, v in means.items()}


def row(ce, acc, ade, goal):
    return agg(close_encounters=ce, max_acceleration=acc, ade=ade, goal_distance=goal,
               collision_rate=0.0, off_road_rate=0.0)


def fake_results(manc_ade=1.0, q_ades=(3.0, 2.0, 1.5, 1.0)):
    human = row(2.0, 3.0, 0.0, 0.0)
    table = {
        "paper": {"human": human, "cnn": row(1.0, 5.0, 4.0, 9.0),
                  "cnn_lstm": row(5.0, 6.0, 3.0, 8.0), "rvs_g": row(9.0, 1.0, 2.0, 7.0),
                  "manc": row(2.5, 3.2, manc_ade, 3.0)},
        "parity": {"human": human, "cnn": row(1.0, 5.0, 1.5, 4.0),
                   "cnn_lstm": row(5.0, 6.0, 2.5, 5.0), "rvs_g": row(9.0, 1.0, 2.5, 6.0),
                   "manc": row(2.5, 3.2, manc_ade, 3.0)},
    }
    return {
        "config": {**studies.PRESETS["quick"].__dict__, "lrs": [1e-3, 3e-3], "n_seeds": 3},
        "engine": "jax",
        "close_gap_m": metrics.CLOSE_GAP,
        "table1": table,
        "sample_efficiency": {"setting": "paper", "fractions": [0.25, 1.0],
                              "models": {"cnn": [row(1, 1, 6.0, 1), row(1, 1, 4.0, 1)],
                                         "manc": [row(1, 1, 2.0, 1), row(1, 1, 1.0, 1)]}},
        "q_states": {"setting": "paper", "n_states": [3, 6, 9, 12],
                     "results": [row(1, 1, a, 1) for a in q_ades]},
        "ablation": {"setting": "paper", "models": {
            "manc": row(2.5, 3.2, manc_ade, 3.0), "vagn_only": row(1.0, 2.0, 5.0, 9.0),
            "dmp_only": row(4.0, 5.0, 1.2, 3.5)}},
        "param_counts": {"paper": {"cnn": 100_000, "cnn_lstm": 120_000, "rvs_g": 200_000,
                                   "manc": 20_000, "vagn_only": 25_000, "dmp_only": 19_000}},
        "lr": {"manc-paper": 1e-3},
        "references": {"dmp_prior": row(3.0, 2.0, 2.5, 6.0)},
    }


def by_id(found):
    return {f["id"]: f for f in found}


def test_findings_follow_the_numbers():
    f = by_id(studies.findings(fake_results()))
    assert f["manc_best_ade_paper"]["holds"] is True
    assert f["manc_best_goal_distance_paper"]["holds"] is True
    assert f["manc_best_ade_parity"]["holds"] is True
    assert f["manc_near_human_close_encounters_paper"]["holds"] is True
    assert f["manc_near_human_max_acceleration_paper"]["holds"] is True
    assert f["q_states_ade"]["holds"] is True and "monotone" in f["q_states_ade"]["detail"]
    assert f["ablation_dmp_only_aggressive"]["holds"] is True
    assert f["ablation_vagn_only_safer"]["holds"] is True
    assert f["ablation_vagn_only_worse_goal"]["holds"] is True
    assert f["sample_efficiency"]["holds"] is True
    assert f["param_counts"]["holds"] is True
    # parity lowers cnn's ADE but not rvs_g's: the claim does not hold, the text says why
    assert f["parity_helps_baselines"]["holds"] is False
    assert "rvs_g 2.00 → 2.50" in f["parity_helps_baselines"]["detail"]


def test_findings_report_failures_with_numbers():
    f = by_id(studies.findings(fake_results(manc_ade=2.9, q_ades=(1.0, 2.0, 1.5, 3.0))))
    ade = f["manc_best_ade_paper"]
    assert ade["holds"] is False and "manc 2.90" in ade["detail"] and "best is rvs_g" in ade[
        "detail"]
    assert f["q_states_ade"]["holds"] is False
    assert "not monotone" in f["q_states_ade"]["detail"]
    # parity: cnn 1.50 beats manc 2.90
    assert f["manc_best_ade_parity"]["holds"] is False
    assert "best is cnn" in f["manc_best_ade_parity"]["detail"]


def test_findings_compare_manc_with_its_fixed_gain_prior():
    f = by_id(studies.findings(fake_results(manc_ade=1.0)))["learning_beats_prior"]
    assert f["holds"] is True and "MANC 1.00" in f["detail"] and "fixed gains 2.50" in f["detail"]
    f = by_id(studies.findings(fake_results(manc_ade=2.9)))["learning_beats_prior"]
    assert f["holds"] is False
    res = fake_results()
    del res["references"]
    assert "learning_beats_prior" not in by_id(studies.findings(res))


def test_findings_mention_seed_noise():
    res = fake_results(manc_ade=1.95)  # rvs_g 2.00: difference 0.05 < 0.1 + 0.1
    d = by_id(studies.findings(res))["manc_best_ade_paper"]["detail"]
    assert "within the seed spread" in d


def test_table_markdown_contains_every_section():
    res = fake_results()
    res["findings"] = studies.findings(res)
    md = studies.table_markdown(res)
    for text in ("setting `paper`", "setting `parity`", "| MANC | 2.50 ± 0.10",
                 "| Human | 2.00 |", "Sample efficiency", "q-states", "Self-ablation",
                 "Parameters", "holds", "does NOT hold", "| 20,000 |",
                 "| DMP at fixed gains | 3.00 | 2.00 | 2.50 |"):
        assert text in md, text


def test_study_config_validation_and_fingerprint():
    base = studies.PRESETS["tiny"]
    assert base.fingerprint() == studies.StudyConfig(**{**base.__dict__}).fingerprint()
    from dataclasses import replace

    assert replace(base, n_seeds=3).fingerprint() == base.fingerprint()
    assert replace(base, epochs=2).fingerprint() != base.fingerprint()
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
    from minimanc import cli

    parser = cli.build_parser()
    args = parser.parse_args(["reproduce", "--quick", "--engine", "numpy", "--out", "x",
                              "--seeds", "2"])
    assert args.quick and args.engine == "numpy" and args.seeds == 2 and args.out == "x"


def test_reproduce_tiny_writes_everything(tmp_path, capsys):
    from minimanc import cli

    out = tmp_path / "run"
    code = cli.main(["reproduce", "--preset", "tiny", "--engine", "numpy", "--out", str(out),
                     "--workers", "0", "--no-progress"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "table1.md" in printed and "results.json" in printed
    res = json.loads((out / "results.json").read_text())
    assert set(res["table1"]) == {"paper", "parity"}
    assert set(res["table1"]["paper"]) == {"human", "cnn", "cnn_lstm", "rvs_g", "manc"}
    assert res["table1"]["paper"]["human"]["ade"]["mean"] == 0.0
    # MANC sees the same in both settings: the same run, the same numbers
    assert res["table1"]["paper"]["manc"] == res["table1"]["parity"]["manc"]
    assert [len(v) for v in res["sample_efficiency"]["models"].values()] == [2] * 4
    assert res["q_states"]["n_states"] == [3, 6]
    assert set(res["ablation"]["models"]) == {"manc", "vagn_only", "dmp_only"}
    assert res["references"]["dmp_prior"]["ade"]["mean"] > 0.0
    for f in res["findings"]:
        assert f["holds"] in (True, False, None) and f["detail"]
    md = (out / "table1.md").read_text()
    assert "Table I" in md and "MANC" in md
    figs = {p.name for p in (out / "figures").iterdir()}
    for name in ("table1.png", "sample_efficiency.png", "param_counts.png", "q_states.png",
                 "ablation.png", "trajectories.png", "rollout.gif"):
        assert name in figs, name
    assert any(n.startswith("explain_scene") for n in figs)
    assert any(n.startswith("saliency_scene") for n in figs)
    # a re-run reuses every cached model and rollout
    mtimes = {p: p.stat().st_mtime for p in (out / "cache").rglob("*.npz")}
    assert mtimes
    res2 = studies.reproduce(studies.PRESETS["tiny"], out, engine="numpy", workers=0,
                             progress=False, figures=False)
    assert {p: p.stat().st_mtime for p in (out / "cache").rglob("*.npz")} == mtimes
    study = studies.Study(studies.PRESETS["tiny"], out, engine="numpy", workers=0,
                          progress=False)
    study.run()
    assert len(study._futures) == study.n_runs()  # the progress bar's total is exact
    assert np.isclose(res2["table1"]["paper"]["cnn"]["ade"]["mean"],
                      res["table1"]["paper"]["cnn"]["ade"]["mean"])


def test_run_files_are_distinct_per_lr_seed_and_split(tmp_path):
    study = studies.Study(studies.PRESETS["tiny"], tmp_path, engine="numpy", workers=0)
    runs = [studies.Run("cnn", "paper", 6, 1.0, s, lr) for s in (0, 1) for lr in (1e-3, 3e-3)]
    paths = {p for r in runs for split in ("tune", "val") for p in study._paths(r, split)}
    assert len(paths) == 2 * len(runs) * 2
    assert len({study.checkpoint(r) for r in runs}) == len(runs)
    assert all(p.name.endswith((".npz", ".json")) and "lr0.001" in p.name or "lr0.003" in p.name
               for p in paths)


def test_a_closed_loop_that_blows_up_scores_inf(tmp_path, monkeypatch):
    from minimanc import models, train, world

    # train.save/load refuse non-finite parameters; let them through to reach the closed loop
    monkeypatch.setattr(train.checkpoint, "bad_params", lambda *a, **k: None)

    ds = world.generate(2, seed=5, raster=world.RasterConfig(size=32), workers=1)
    data = world.save(ds, tmp_path / "d.npz")
    cfg = models.ModelConfig(image_size=32)
    params = models.init("cnn", np.random.default_rng(0), cfg)
    params["out"]["b"] = params["out"]["b"] * np.nan
    ck = train.save(tmp_path / "ck.npz", "cnn", params, cfg)
    job = {"data": str(data), "lo": 0, "hi": 2, "checkpoint": str(ck), "engine": "numpy",
           "rollout": str(tmp_path / "r.npz"), "metrics": str(tmp_path / "m.json")}
    res = jobs.evaluate_job(job)
    assert res["ade"] == float("inf") and "finite" in res["error"]
    agg = metrics.aggregate([res])
    assert "error" not in agg and agg["ade"]["mean"] == float("inf")
    assert "diverged" in report.cell(agg, "ade", 1)


# --------------------------------------------------------------------------- cache recovery


def _tiny_run(study):
    c = study.config
    return studies.Run("cnn", "paper", c.n_states, 1.0, 0, float(c.lrs[0]))


def test_a_broken_checkpoint_in_the_cache_is_retrained(tmp_path, capsys):
    from minimanc import train

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
        assert ck["epoch"] == tiny.epochs and ck["history"] == good["history"]
        assert sorted(p.name for p in path.parent.iterdir()) == [path.name]


def test_a_broken_data_file_in_the_cache_is_regenerated(tmp_path, capsys):
    tiny = studies.PRESETS["tiny"]
    study = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    train_ds, _, _ = study.datasets()
    raw = study.data_path.read_bytes()
    study.data_path.write_bytes(raw[:1000])
    again = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    train2, _, _ = again.datasets()
    assert "discarding the unreadable cache entry" in capsys.readouterr().err
    assert train2.content_hash() == train_ds.content_hash()
    assert study.data_path.read_bytes() == raw


def test_a_broken_metrics_file_is_recomputed(tmp_path, capsys):
    tiny = studies.PRESETS["tiny"]
    study = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    run = _tiny_run(study)
    first = study.result(run)
    _, met = study._paths(run, "val")
    met.write_text('{"ade": 1.')  # cut short
    again = studies.Study(tiny, tmp_path, engine="numpy", workers=0, progress=False)
    assert again.result(run) == first
    assert "discarding the unreadable cache entry" in capsys.readouterr().err
    assert json.loads(met.read_text()) == first
    assert not list(met.parent.glob("*.tmp"))


@pytest.mark.parametrize("args,expected", [
    (["--seeds", "0"], "--seeds must be an integer >= 1, got 0"),
    (["--workers", "-1"], "--workers must be an integer >= 0, got -1"),
])
def test_reproduce_bad_arguments_are_one_line_exit_2(tmp_path, capsys, args, expected):
    from minimanc import cli

    code = cli.main(["reproduce", "--preset", "tiny", "--out", str(tmp_path / "r"), *args])
    err = capsys.readouterr().err
    assert code == 2 and err.strip() == f"minimanc reproduce: error: {expected}", err
    assert not (tmp_path / "r").exists()


def test_reproduce_unwritable_out_is_one_line_exit_2(tmp_path, capsys):
    from minimanc import cli

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
    from dataclasses import fields, replace

    from minimanc import train

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
    # the old keyword style still works, for every field a study used to copy and dmp_seq_len
    c = studies.StudyConfig(epochs=2, batch_size=8, seq_len=3, dmp_seq_len=5,
                            max_steps_per_epoch=4)
    assert (c.epochs, c.batch_size, c.seq_len, c.dmp_seq_len, c.max_steps_per_epoch) == \
        (2, 8, 3, 5, 4)
    assert c.training == train.TrainConfig(epochs=2, batch_size=8, seq_len=3, dmp_seq_len=5,
                                           max_steps_per_epoch=4)
    assert replace(c, dmp_seq_len=6).training.dmp_seq_len == 6
    with pytest.raises(ValueError, match="dmp_seq_len"):
        studies.StudyConfig(dmp_seq_len=0)
    with pytest.raises(TypeError, match="training"):
        studies.StudyConfig(training={"epochs": 2})
    with pytest.raises(TypeError, match="unknown"):
        studies.StudyConfig(epoch=2)


def test_presets_keep_their_training_values():
    from minimanc import train

    want = {
        "tiny": train.TrainConfig(epochs=1, batch_size=16, max_steps_per_epoch=2, seq_len=4),
        "quick": train.TrainConfig(epochs=3, batch_size=64),
        "full": train.TrainConfig(epochs=4, batch_size=64),
        "paper": train.TrainConfig(epochs=6, batch_size=64),
    }
    for name, tc in want.items():
        assert studies.PRESETS[name].training == tc, name


def test_a_run_trains_with_the_studys_train_config(tmp_path):
    from dataclasses import replace

    c = replace(studies.PRESETS["tiny"], dmp_seq_len=6, q_seq_len=2)
    study = studies.Study(c, tmp_path, engine="numpy", workers=0, progress=False)
    run = studies.Run("manc", "paper", c.n_states, 0.5, 1, 2e-3)
    tc = study.train_config(run)
    assert (tc.dmp_seq_len, tc.q_seq_len, tc.lr, tc.seed, tc.subset, tc.epochs) == \
        (6, 2, 2e-3, 1, 0.5, 1)
