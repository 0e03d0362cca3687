"""Chapter 7 — the dataset on disk: save and load, corrupt, partial, altered and
non-finite files refused by name, shards, streaming generation and temporary files."""

import json
import os
import zipfile
from pathlib import Path

import numpy as np
import pytest
from world_dataset_helpers import generate_test_dataset

from minimanc import world
from minimanc.world import datawriter, fileformat, generation, scenes


@pytest.fixture(scope="module")
def ds():
    return generate_test_dataset()


def test_save_load_round_trip(ds, tmp_path):
    small = ds.subset(slice(0, 3))
    path = world.save(small, tmp_path / "w.npz")
    back = world.load(path)
    assert back.content_hash() == small.content_hash()
    np.testing.assert_array_equal(back.maps[1].route_points, small.maps[1].route_points)


def test_corrupt_truncated_and_wrong_version_files(ds, tmp_path, monkeypatch):
    small = ds.subset(slice(0, 2))
    good = world.save(small, tmp_path / "good.npz")
    raw = good.read_bytes()
    # truncated
    trunc = tmp_path / "trunc.npz"
    trunc.write_bytes(raw[: len(raw) // 2])
    with pytest.raises(world.DatasetFileError, match="trunc.npz"):
        world.load(trunc)
    # corrupted bytes inside the compressed arrays
    for frac in (0.2, 0.5, 0.8):
        bad = bytearray(raw)
        k = int(len(raw) * frac)
        bad[k:k + 16] = bytes(16)
        path = tmp_path / f"corrupt{int(frac * 10)}.npz"
        path.write_bytes(bytes(bad))
        with pytest.raises(world.DatasetFileError, match=path.name):
            world.load(path)
    # not a dataset at all
    junk = tmp_path / "junk.npz"
    junk.write_text("hello")
    with pytest.raises(world.DatasetFileError, match="junk.npz"):
        world.load(junk)
    other = tmp_path / "other.npz"
    np.savez(other, x=np.zeros(3))
    with pytest.raises(world.DatasetFileError, match="other.npz"):
        world.load(other)
    # a valid archive whose array was altered after the checksum was written
    altered = tmp_path / "altered.npz"
    with zipfile.ZipFile(good) as zin, zipfile.ZipFile(altered, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "controls-00000.npy":
                data = data[:-4] + b"\x00\x00\x80\x3f"
            zout.writestr(item, data)
    with pytest.raises(world.DatasetFileError, match="checksum"):
        world.load(altered)
    # wrong version
    monkeypatch.setattr(datawriter, "FILE_FORMAT_VERSION", 999)
    old = world.save(small, tmp_path / "v999.npz")
    monkeypatch.undo()
    with pytest.raises(world.DatasetFileError, match="v999.npz.*version 999"):
        world.load(old)
    header = json.loads(bytes(np.load(old)["header"]).decode())
    assert header["version"] == 999
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        world.load(tmp_path / "missing.npz")



# --------------------------------------------------------------------------- file format v2


def _rewrite(src: Path, dst: Path, edit) -> Path:
    """Copy the archive ``src`` to ``dst``, passing each member through ``edit(name, bytes)``."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = edit(item.filename, zin.read(item.filename))
            if data is not None:
                zout.writestr(item, data)
    return dst


def _edit_header(src: Path, dst: Path, change) -> Path:
    """Rewrite ``src``'s JSON header through ``change(header)`` (checksum left as it was)."""
    def edit(name, data):
        if name != "header.npy":
            return data
        import io

        header = json.loads(bytes(np.load(io.BytesIO(data))).decode())
        change(header)
        buf = io.BytesIO()
        np.save(buf, np.frombuffer(json.dumps(header).encode(), dtype=np.uint8))
        return buf.getvalue()
    return _rewrite(src, dst, edit)


@pytest.mark.parametrize("change", [
    lambda h: h["meta"].update(seed=h["meta"]["seed"] + 1),
    lambda h: h["meta"].update(dt=0.25),
    lambda h: h["meta"]["tags"][0].update(has_cut_in=not h["meta"]["tags"][0]["has_cut_in"]),
    lambda h: h["meta"]["raster"].update(size=32),
    lambda h: h["meta"].update(version=h["meta"]["version"] + 1),
    lambda h: h["shards"][0]["arrays"]["controls"].update(sha256="0" * 64),
], ids=["seed", "dt", "tags", "raster.size", "meta.version", "array sha"])
def test_altered_metadata_is_refused(ds, tmp_path, change):
    good = world.save(ds.subset(slice(0, 2)), tmp_path / "good.npz")
    bad = _edit_header(good, tmp_path / "edited.npz", change)
    with pytest.raises(world.DatasetFileError, match=r"edited\.npz.*header checksum"):
        world.load(bad)
    # the unedited copy (same writer, same rewrite path) still loads
    same = _edit_header(good, tmp_path / "same.npz", lambda h: None)
    assert world.load(same).content_hash() == ds.subset(slice(0, 2)).content_hash()


def test_missing_meta_key_names_the_file_and_the_key(ds, tmp_path, monkeypatch):
    small = ds.subset(slice(0, 2))
    # a header whose checksum is right but whose meta lacks "tags" (an older writer's bug)
    good = world.save(small, tmp_path / "good.npz")

    def drop(h):
        del h["meta"]["tags"]
        h["sha256"] = fileformat.header_sha256(h)
    bad = _edit_header(good, tmp_path / "notags.npz", drop)
    with pytest.raises(world.DatasetFileError, match=r"notags\.npz.*'tags' missing"):
        world.load(bad)
    # and save refuses to write such a dataset in the first place
    meta = dict(small.meta)
    del meta["raster"]
    with pytest.raises(ValueError, match="'raster' missing"):
        world.save(scenes.Dataset(**{f: getattr(small, f) for f in fileformat.ARRAY_FIELDS},
                                 maps=small.maps, meta=meta), tmp_path / "x.npz")
    assert not list(tmp_path.glob("x.npz*"))


def test_npy_and_directory_paths_say_what_was_expected(ds, tmp_path):
    npy = tmp_path / "controls.npy"
    np.save(npy, ds.controls)
    with pytest.raises(world.DatasetFileError, match=r"controls\.npy.*\.npy file.*expected a "
                                                     r"dataset archive \(\.npz\)"):
        world.load(npy)
    with pytest.raises(world.DatasetFileError, match="is a directory; expected"):
        world.load(tmp_path)
    # save() to an existing directory: a clear error, and no "<dir>.tmp" left beside it
    d2 = tmp_path / "d2"
    d2.mkdir()
    with pytest.raises(ValueError, match=r"d2.*is a directory.*world\.npz"):
        world.save(ds.subset(slice(0, 1)), d2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["controls.npy", "d2"]


@pytest.mark.parametrize("field,idx", [("controls", (1, 5, 0)), ("ego", (0, 39, 2)),
                                       ("lane_target", (1, 0, 3, 1))])
def test_non_finite_data_is_refused_naming_scene_and_step(ds, tmp_path, monkeypatch, field, idx):
    small = ds.subset(slice(0, 2))
    getattr(small, field)[idx] = np.nan
    with pytest.raises(ValueError, match=rf"{field}\[scene {idx[0]}, step {idx[1]}.*= nan"):
        world.save(small, tmp_path / "nan.npz")
    assert not list(tmp_path.iterdir())  # nothing written
    # a file holding one (written before this check existed) is refused at load
    monkeypatch.setattr(datawriter, "check_arrays_finite", lambda *a, **k: None)
    path = world.save(small, tmp_path / "nan.npz", shard_scenes=1)
    monkeypatch.undo()
    with pytest.raises(world.DatasetFileError,
                       match=rf"nan\.npz.*{field}\[scene {idx[0]}, step {idx[1]}"):
        world.load(path)


def test_shards_round_trip_for_every_shard_size(ds, tmp_path):
    small = ds.subset(slice(0, 5))
    for k in (1, 2, 5, 7):
        path = world.save(small, tmp_path / f"s{k}.npz", shard_scenes=k)
        header = json.loads(bytes(np.load(path)["header"]).decode())
        assert [s["stop"] - s["start"] for s in header["shards"]] == \
            [min(k, 5 - a) for a in range(0, 5, k)]
        back = world.load(path)
        assert back.content_hash() == small.content_hash()
        assert world.file_content_hash(path) == small.content_hash()
        assert world.read_meta(path)["tags"] == small.tags


def test_generate_file_streams_shards_and_matches_generate(ds, tmp_path, monkeypatch):
    added = []
    real_add = datawriter.DatasetWriter.add
    monkeypatch.setattr(datawriter.DatasetWriter, "add",
                        lambda self, arrays: (added.append(len(arrays["ego"])),
                                              real_add(self, arrays))[1])
    path = world.generate_file(tmp_path / "w.npz", 5, seed=5, workers=1, shard_scenes=2)
    assert added == [2, 2, 1]  # never more than one shard handed to the writer at a time
    assert world.file_content_hash(path) == ds.subset(slice(0, 5)).content_hash()
    assert world.load(path).meta["scene_index"] == [0, 1, 2, 3, 4]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.npz"]


def test_generate_file_failure_leaves_nothing_and_stale_temps_are_cleaned(tmp_path, monkeypatch):
    target = tmp_path / "w.npz"
    stale = [tmp_path / "w.npz.abc123.tmp", tmp_path / "w.npz.tmp"]
    for p in stale:
        p.write_bytes(b"partial")
    other = tmp_path / "other.npz.x.tmp"  # another file's temp: not ours to remove
    other.write_bytes(b"")
    real = generation.generate_scene

    def boom(seed, index, *a, **k):
        if index == 3:
            raise RuntimeError("simulated crash in scene 3")
        return real(seed, index, *a, **k)
    monkeypatch.setattr(generation, "generate_scene", boom)
    with pytest.raises(RuntimeError, match="scene 3"):
        world.generate_file(target, 5, seed=1, workers=1, shard_scenes=2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.npz.x.tmp"]


def test_a_partial_file_is_never_a_dataset(ds, tmp_path):
    path = world.save(ds.subset(slice(0, 3)), tmp_path / "w.npz", shard_scenes=1)
    raw = path.read_bytes()
    for cut in (len(raw) - 10, len(raw) * 3 // 4, 100):
        part = tmp_path / f"part{cut}.npz"
        part.write_bytes(raw[:cut])
        with pytest.raises(world.DatasetFileError, match=part.name):
            world.load(part)
    # a shard member deleted from an otherwise valid archive
    gone = _rewrite(path, tmp_path / "gone.npz",
                    lambda n, d: None if n == "bev-00001.npy" else d)
    with pytest.raises(world.DatasetFileError, match="'bev' of shard 1 is missing"):
        world.load(gone)


def test_estimate_scales_with_the_scene_count():
    e = world.estimate(100_000, seed=0, workers=2)
    assert e.n_scenes == 100_000 and e.workers == 2
    # compressed rasters: far below the 0.54 MB a 64 px scene takes in memory
    assert 5e3 < e.bytes_per_scene < generation.scene_nbytes()
    assert e.disk_bytes == pytest.approx(100_000 * e.bytes_per_scene)
    assert e.seconds == pytest.approx(50_000 * e.seconds_per_scene)
    assert "GB on disk" in str(e)
    with pytest.raises(ValueError, match="n_scenes"):
        world.estimate(0)



def test_a_write_keeps_the_temp_file_of_a_live_writer(tmp_path):
    # Two jobs filling one cache entry at once: the second writer must not remove the
    # first's temporary file, only those whose writer is gone.
    target = tmp_path / "w.npz"
    dead = tmp_path / f"w.npz.pid{2 ** 22 + 7}.abc.tmp"  # above Linux's largest pid
    dead.write_bytes(b"partial")
    first = datawriter.DatasetWriter(target)
    try:
        (ours,) = datawriter.temp_files(target)
        assert ours.name.startswith(f"w.npz.pid{os.getpid()}.")
        old = tmp_path / "w.npz.tmp"  # a writer before names carried a pid
        dead.write_bytes(b"partial")
        old.write_bytes(b"partial")
        assert datawriter.remove_temp_files(target) == [dead, old]
        assert datawriter.temp_files(target) == [ours]
    finally:
        first.abort()
    assert datawriter.temp_files(target) == []



@pytest.mark.skipif(os.name != "posix", reason="file modes are POSIX's")
def test_written_files_have_the_mode_of_any_file_the_user_writes(ds, tmp_path):
    """The atomic writers (the dataset, a checkpoint, the studies' JSON and Markdown) give the
    file the umask's mode, not the private mode of a temporary file."""
    from minimanc import models, train
    from minimanc.studies.provenance import write_text

    old = os.umask(0o027)
    try:
        paths = [world.save(ds.subset(slice(0, 1)), tmp_path / "w.npz"),
                 write_text(tmp_path / "table1.md", "# results\n"),
                 train.save_checkpoint(tmp_path / "checkpoint.npz", "cnn", {"w": np.ones(2)},
                                       models.ModelConfig(), raster=ds.raster)]
    finally:
        os.umask(old)
    assert {oct(Path(p).stat().st_mode & 0o777) for p in paths} == {oct(0o640)}
