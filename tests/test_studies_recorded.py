"""``minimanc reproduce --data FILE``: the studies on an imported (recorded) nuScenes file
(:mod:`minimanc.studies.recorded`), on the package's schema-exact sample
(:mod:`minimanc.world.nuscenes.sample`)."""

import hashlib
import json
import shutil
from dataclasses import asdict, replace

import numpy as np
import pytest

from minimanc import models, world
from minimanc.cli import main
from minimanc.diagnose.bounds import BOUND_ROWS
from minimanc.studies import PRESETS, Study, StudyConfig, reproduce
from minimanc.studies.recorded import (
    BOUNDS_OMITTED,
    GENERATED,
    MODES_OMITTED,
    REACTIVE_REFUSAL,
    data_config,
    is_recorded,
)
from minimanc.train import TrainConfig
from minimanc.world.nuscenes.sample import write_sample

SMALL = replace(PRESETS["tiny"], table_models=("cnn", "manc"), ablation_models=("manc",),
                sample_models=("manc",), q_states=(3,), fractions=(1.0,))
"""The tiny preset with two Table I models and the smallest studies (seconds)."""


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """``minimanc data import-nuscenes`` of the fixture, five copies of each scene under
    trainval names: 5 ``train`` scenes (scene-0061's copies) and 5 ``val`` (scene-0103's)
    import, the others are skipped (39 keyframes, a gap, no lane)."""
    base = tmp_path_factory.mktemp("recorded")
    write_sample(base / "root", "v1.0-trainval", copies=5)
    path = base / "data" / "ns.npz"
    assert main(["data", "import-nuscenes", str(base / "root"), "--version", "v1.0-trainval",
                 "--out", str(path), "--size", "32", "--quiet"]) == 0
    return path


def _one_line_error(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def test_data_config_splits_the_recorded_file(recorded, tmp_path):
    meta = world.read_meta(recorded)
    splits = [t["split"] for t in meta["tags"]]
    assert splits == ["train"] * 5 + ["val"] * 5
    c = data_config(PRESETS["tiny"], recorded)
    # the last 5 % of train (at least one scene) tune; the val split validates; the file's BEV
    assert (c.n_train, c.n_tune, c.n_val, c.raster) == (4, 1, 5, world.RasterConfig(size=32))
    assert c.data_source == "nuscenes" and is_recorded(c)
    assert c.data_hash == world.file_content_hash(recorded)
    assert (c.training, c.lrs, c.table_models) == (PRESETS["tiny"].training, PRESETS["tiny"].lrs,
                                                     PRESETS["tiny"].table_models)
    train, tune, val = Study(c, tmp_path / "o", engine="numpy", workers=0,
                             agents=("replay",)).datasets()
    names = [t["scene"] for t in meta["tags"]]
    assert [t["scene"] for t in train.tags] == names[:4]
    assert [t["scene"] for t in tune.tags] == names[4:5]
    assert [t["scene"] for t in val.tags] == names[5:]
    assert {t["split"] for t in tune.tags} == {"train"}
    # the cache is named by the content, not the path; another file is another cache
    moved = tmp_path / "elsewhere.npz"
    shutil.copy(recorded, moved)
    assert data_config(PRESETS["tiny"], moved).fingerprint() == c.fingerprint()
    assert c.fingerprint() != PRESETS["tiny"].fingerprint()
    ds = world.load(recorded)
    other = ds.subset([0, 1, 2, 3, 5])
    world.save(other, tmp_path / "other.npz")
    assert data_config(PRESETS["tiny"], tmp_path / "other.npz").fingerprint() != c.fingerprint()


def test_generated_fingerprints_are_unchanged_by_the_data_fields():
    """Without a data file the cache name is the hash of the configuration without the
    data fields, as before the option existed (so a generated run reuses its cache)."""
    for c in PRESETS.values():
        c = replace(c, dagger_rounds=0, model=models.ModelConfig())
        d = asdict(c)
        for k in ("preset", "n_seeds", "explain_scenes", "data_file", "data_hash",
                  "data_source", "dagger_rounds", "round_epochs", "model"):
            d.pop(k)
        d["model_defaults"] = models.ModelConfig().to_dict()
        d["default_gains"] = list(models.DEFAULT_GAINS)
        old = hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]
        assert c.fingerprint() == old
    with pytest.raises(ValueError, match="given together"):
        StudyConfig(data_file="x.npz")


def test_the_library_refuses_what_recorded_data_cannot_do(recorded, tmp_path):
    c = data_config(SMALL, recorded)
    with pytest.raises(ValueError, match="reactive protocol is not available on recorded"):
        Study(c, tmp_path / "o", engine="numpy", workers=0, agents=("replay", "reactive"))
    with pytest.raises(ValueError, match="dagger"):
        reproduce(c, tmp_path / "o", engine="numpy", workers=0, agents=("replay",),
                  dagger=True)
    with pytest.raises(ValueError, match="perception loss .* is not available on recorded"):
        Study(replace(c, training=replace(c.training, perception_weight=1.0)), tmp_path / "o",
              engine="numpy", workers=0, agents=("replay",))
    study = Study(c, tmp_path / "o", engine="numpy", workers=0, agents=("replay",))
    assert study.references.bound_rows == ()
    with pytest.raises(ValueError, match="modes come from re-driving"):
        study.human_modes()
    # the file changed after its configuration was made: refused, not silently used
    changed = tmp_path / "changed.npz"
    shutil.copy(recorded, changed)
    c2 = data_config(SMALL, changed)
    world.save(world.load(recorded).subset([0, 1, 2, 3, 4, 5]), changed)
    with pytest.raises(ValueError, match="changed since its study configuration"):
        Study(c2, tmp_path / "o2", engine="numpy", workers=0, agents=("replay",)).datasets()


@pytest.mark.whole_run
def test_reproduce_data_on_an_imported_file(recorded, tmp_path, capsys, monkeypatch):
    """The issue's end to end run: import, then ``reproduce --preset tiny --data FILE``."""
    monkeypatch.setitem(PRESETS, "tiny", SMALL)
    out = tmp_path / "out"
    assert main(["reproduce", "--preset", "tiny", "--data", str(recorded), "--engine", "numpy",
                 "--workers", "0", "--no-progress", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    refusal = f"minimanc reproduce: {REACTIVE_REFUSAL}; running agents replay only\n"
    assert printed.count(refusal) == 1 and printed.index(refusal) == 0
    assert "4 training, 1 tuning, 5 validation scenes, 32×32 RGB raster (the paper's form)" \
        in printed
    md = (out / "table1.md").read_text()
    assert ("4 training, 1 tuning and 5 validation scenes, 32×32 RGB raster (the paper's "
            "form), 1 epochs, learning rate") in md
    assert BOUNDS_OMITTED in md and MODES_OMITTED in md
    assert "recorded (nuscenes): the first 4 scenes of its training split train" in md
    assert "| Expert" not in md and "| Style floor" not in md
    assert "agents `reactive`" not in md and "## Table I — setting `paper`, agents `replay`" in md
    assert "| Human | " in md and "| MANC | " in md and "| CNN | " in md
    assert md.index(BOUNDS_OMITTED) < md.index("## Table I")
    res = json.loads((out / "results.json").read_text())
    assert res["agents"] == ["replay"] and list(res["table1"]) == ["replay"]
    for table in res["table1"]["replay"].values():
        assert not set(BOUND_ROWS) & set(table) and {"human", "cnn", "manc"} <= set(table)
        assert np.isfinite(table["manc"]["ade"]["mean"])
    assert res["n_scenes"] == {"train": 4, "tune": 1, "val": 5}
    assert res["config"]["data_hash"] == world.file_content_hash(recorded)
    assert res["modes"]["models"] == {}
    c = data_config(SMALL, recorded)
    assert (out / "cache" / f"{c.fingerprint()}-numpy" / "models").is_dir()
    assert sorted(p.name for p in recorded.parent.iterdir()) == ["ns.npz"]  # nothing beside it
    assert not list((out / "figures").glob("q_modes_*"))
    assert (out / "figures" / "trajectories.png").exists()
    # --agents reactive alone: the same refusal, the run goes on under replay (from the cache)
    models_before = sorted(p.name for p in (out / "cache").rglob("*.npz"))
    assert main(["reproduce", "--preset", "tiny", "--data", str(recorded), "--engine", "numpy",
                 "--workers", "0", "--no-progress", "--out", str(out),
                 "--agents", "reactive"]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith(refusal) and "agents replay, output" in printed
    assert sorted(p.name for p in (out / "cache").rglob("*.npz")) == models_before


def test_reproduce_data_bad_input_is_one_line_exit_2(recorded, tmp_path, capsys):
    base = ["reproduce", "--preset", "tiny", "--engine", "numpy", "--workers", "0",
            "--no-progress", "--out", str(tmp_path / "out"), "--data"]
    text = tmp_path / "notes.txt"
    text.write_text("not a dataset\n")
    assert "not a readable minimanc world file" in _one_line_error(capsys, [*base, str(text)])
    line = _one_line_error(capsys, [*base, str(tmp_path / "missing.npz")])
    assert "no such dataset file" in line
    gen = tmp_path / "gen.npz"
    world.save(world.generate(3, seed=0, raster=world.RasterConfig(size=32)), gen)
    line = _one_line_error(capsys, [*base, str(gen)])
    assert line.startswith("minimanc reproduce: error: --data ") and \
        "generated file of 3 scenes, 32×32 RGB raster (the paper's form), does not fit preset " \
        "'tiny' (7 scenes" in line and "`minimanc data generate --scenes 7 --size 32`" in line
    ds = world.load(recorded)
    nosplit = ds.subset(slice(None))
    nosplit.meta["tags"] = [{k: v for k, v in t.items() if k != "split"} for t in ds.tags]
    world.save(nosplit, tmp_path / "nosplit.npz")
    line = _one_line_error(capsys, [*base, str(tmp_path / "nosplit.npz")])
    assert "10 of 10 recorded scenes name no split (tags['split']" in line
    mixed = ds.subset([5, 0, 1, 2, 3, 4])  # a val scene first: not the importer's order
    world.save(mixed, tmp_path / "mixed.npz")
    line = _one_line_error(capsys, [*base, str(tmp_path / "mixed.npz")])
    assert "not the train split then the val split" in line
    world.save(ds.subset([0, 1, 5]), tmp_path / "few.npz")
    assert "need at least 3" in _one_line_error(capsys, [*base, str(tmp_path / "few.npz")])
    line = _one_line_error(capsys, [*base, str(recorded), "--dagger"])
    assert "--dagger needs the world's expert" in line
    assert not (tmp_path / "out").exists()


def test_a_generated_file_that_fits_the_preset_keeps_the_bounds(tmp_path):
    small = StudyConfig(n_train=2, n_tune=1, n_val=1, raster=world.RasterConfig(size=32),
                        training=TrainConfig(epochs=1))
    path = tmp_path / "gen.npz"
    world.save(world.generate(5, seed=3, raster=world.RasterConfig(size=32)), path)
    c = data_config(small, path)
    assert c.data_source == GENERATED and not is_recorded(c) and c.data_seed == 3
    study = Study(c, tmp_path / "o", engine="numpy", workers=0)
    assert study.references.bound_rows == BOUND_ROWS and study.agents == ("replay", "reactive")
    train, tune, val = study.datasets()
    assert (len(train), len(tune), len(val)) == (2, 1, 1)  # the first 4 of the 5 scenes
    assert study.files.derived_path("-val-modes.npy").parent == tmp_path / "o" / "data"


def test_a_generated_file_must_be_drawn_with_the_configurations_raster(tmp_path):
    rgb = world.RasterConfig(size=32)
    channels = world.RasterConfig(size=32, encoding="channels", route=True, history=2)
    small = StudyConfig(n_train=2, n_tune=1, n_val=1, raster=rgb, training=TrainConfig(epochs=1))
    path = tmp_path / "channels.npz"
    world.save(world.generate(4, seed=3, raster=channels, workers=1), path)
    with pytest.raises(ValueError) as err:
        data_config(small, path)
    assert ("a generated file of 4 scenes, 32×32 binary channels (route, vehicles at t, t−1, "
            "t−2), does not fit preset 'custom' (4 scenes") in str(err.value)
    assert "32×32 RGB raster (the paper's form)); generate it with `minimanc data generate " \
        "--scenes 4 --size 32` or choose the preset" in str(err.value)
    c = data_config(replace(small, raster=channels), path)
    assert c.raster == channels and c.data_source == GENERATED
    assert Study(c, tmp_path / "o", engine="numpy", workers=0).datasets()[0].raster == channels
    world.save(world.generate(4, seed=3, raster=rgb, workers=1), tmp_path / "rgb.npz")
    with pytest.raises(ValueError) as err:
        data_config(replace(small, raster=channels), tmp_path / "rgb.npz")
    assert ("generate it with `minimanc.world.generate_file(FILE, 4, raster=minimanc.world."
            "RasterConfig(size=32, history=2, encoding='channels', route=True))`") in str(err.value)
