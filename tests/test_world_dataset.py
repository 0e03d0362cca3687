"""Chapter 7 — the generated dataset: determinism, consistency, safety, statistics, files."""

import base64
import hashlib
import importlib
import json
import os
import zipfile
from pathlib import Path

import numpy as np
import pytest

from minimanc import world
from minimanc.world import datareader, datawriter, fileformat, generation, scenes

N = 40


@pytest.fixture(scope="module")
def ds():
    return world.generate(N, seed=5, workers=1)


def test_shapes_and_dtypes(ds):
    S, T = N, world.T_STEPS
    A = ds.ado.shape[2]
    assert ds.bev.shape == (S, T, 64, 64, 3) and ds.bev.dtype == np.uint8
    assert ds.ego.shape == (S, T, 3) and ds.ego.dtype == np.float32
    assert ds.controls.shape == (S, T, 2) and ds.controls.dtype == np.float32
    assert ds.goal.shape == (S, T, 3) and ds.goal.dtype == np.float32
    assert ds.lane_target.shape == (S, T, world.K_TARGETS, 2)
    assert ds.ado.shape == (S, T, A, 5) and ds.ado_valid.shape == (S, T, A)
    assert ds.goal_bev.shape == (S, 64, 64, 3)
    assert len(ds.maps) == S and len(ds.tags) == S
    assert ds.meta["seed"] == 5 and ds.meta["version"] == world.FORMAT_VERSION
    # padded ado rows are zero
    assert np.all(ds.ado[~ds.ado_valid] == 0)


def test_same_seed_same_hash_and_prefix_property(ds):
    small = world.generate(5, seed=5, workers=1)
    assert small.content_hash() == ds.subset(slice(0, 5)).content_hash()
    other = world.generate(5, seed=6, workers=1)
    assert other.content_hash() != small.content_hash()


def test_worker_processes_do_not_change_the_data(ds):
    two = world.generate(4, seed=5, workers=2)
    assert two.content_hash() == ds.subset(slice(0, 4)).content_hash()


def test_logged_controls_reproduce_the_logged_trajectory(ds):
    ego = ds.ego.astype(np.float64)
    ctl = ds.controls.astype(np.float64)
    one = world.unicycle_step(ego[:, :-1], ctl[:, :-1], world.DT)
    err = np.abs(one[..., :2] - ego[:, 1:, :2]).max()
    assert err < 1e-3, err
    dyaw = np.abs(world.wrap_angle(one[..., 2] - ego[:, 1:, 2])).max()
    assert dyaw < 1e-4
    # open-loop integration from the first pose stays on the log for all 40 steps
    pose = ego[:, 0]
    for t in range(world.T_STEPS - 1):
        pose = world.unicycle_step(pose, ctl[:, t], world.DT)
    assert np.abs(pose[:, :2] - ego[:, -1, :2]).max() < 0.02


def test_goal_and_lane_target_are_consistent(ds):
    ego = ds.ego.astype(np.float64)
    final = np.broadcast_to(ego[:, -1:], ego.shape)
    np.testing.assert_allclose(ds.goal, world.goal_in_ego_frame(final, ego), atol=1e-3)
    np.testing.assert_allclose(ds.goal[:, -1], 0.0, atol=1e-5)
    for i in (0, 7, 19):
        for t in (0, 13, 39):
            lt = world.lane_targets(ds.maps[i], ego[i, t])
            np.testing.assert_allclose(ds.lane_target[i, t], lt, atol=1e-4)
    # targets start ~4 m ahead (the human keeps close to the centreline)
    assert np.all(np.abs(ds.lane_target[:, :, 0, 0] - 4.0) < 1.2)


def test_stored_rasters_are_re_rendered_exactly(ds):
    """The closed loop re-renders from stored poses: it must see what the data show."""
    cfg = ds.raster
    for i in (0, 11, 23):
        for t in (0, 20, 39):
            img = world.rasterize(ds.maps[i], ds.ego[i, t].astype(np.float64),
                                  ds.ado[i, t].astype(np.float64), ds.ado_valid[i, t], cfg)
            np.testing.assert_array_equal(img, ds.bev[i, t])
        goal_img = world.rasterize_goal(ds.maps[i], ds.ego[i, -1].astype(np.float64), cfg)
        np.testing.assert_array_equal(goal_img, ds.goal_bev[i])


def _sampled_overlap(a, b, n=15):
    """Independent collision oracle: points sampled inside box a tested against box b."""
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, n), np.linspace(-0.5, 0.5, n))
    c, s = np.cos(a[2]), np.sin(a[2])
    px = a[0] + c * u.ravel() * a[3] - s * v.ravel() * a[4]
    py = a[1] + s * u.ravel() * a[3] + c * v.ravel() * a[4]
    cb, sb = np.cos(b[2]), np.sin(b[2])
    du, dv = px - b[0], py - b[1]
    uu = cb * du + sb * dv
    vv = -sb * du + cb * dv
    return bool(np.any((np.abs(uu) <= b[3] / 2) & (np.abs(vv) <= b[4] / 2)))


def test_the_human_never_leaves_the_road_nor_collides(ds):
    off, hits, near = 0, 0, 0
    for i in range(N):
        m = ds.maps[i]
        boxes = np.concatenate([ds.ego[i].astype(np.float64),
                                np.tile([world.EGO_LENGTH, world.EGO_WIDTH], (40, 1))], 1)
        off += int(not m.is_drivable(world.box_corners(boxes)).all())
        for t in range(world.T_STEPS):
            for a in ds.ado[i, t][ds.ado_valid[i, t]].astype(np.float64):
                d = np.hypot(*(a[:2] - boxes[t, :2]))
                if d < 8.0:
                    near += 1
                    hits += _sampled_overlap(boxes[t], a) or _sampled_overlap(a, boxes[t])
    assert off / N == 0.0
    assert hits == 0
    assert near > 0  # interactions happen: ados do come within 8 m of the human


def test_scene_statistics(ds):
    v = ds.controls[..., 0]
    w = ds.controls[..., 1]
    assert 3.0 < v.mean() < 12.0 and v.min() >= 0.0 and v.max() <= 22.0
    assert (v < 0.3).mean() > 0.0  # somebody stops (yielding, queues)
    assert v.std() > 2.0  # not a constant speed
    assert np.abs(w).max() <= 1.2 and (np.abs(w) > 0.2).mean() > 0.02  # real turning
    acc = np.diff(v, axis=1) / world.DT
    assert np.abs(acc).max() <= 8.0 + 1e-3
    tags = ds.tags
    share = {k: np.mean([t[k] for t in tags]) for k in ("has_junction", "has_roundabout",
                                                          "has_cut_in")}
    assert share["has_junction"] > 0.15 and share["has_roundabout"] > 0.15
    assert share["has_cut_in"] > 0.0
    assert any(t["yield_steps"] > 0 for t in tags)
    assert any(t["follow_steps"] > 0 for t in tags)
    styles = np.array([t["style"]["v0"] for t in tags])
    assert styles.std() > 1.0  # styles vary across scenes
    assert ds.ado_valid.sum(axis=2).mean() > 5  # traffic is present


def test_split_and_subset(ds):
    tr, va = ds.split(n_train=30)
    assert len(tr) == 30 and len(va) == 10
    np.testing.assert_array_equal(va.ego, ds.ego[30:])
    assert va.maps[0] is ds.maps[30] and va.tags[0] == ds.tags[30]
    for bad in (0, N, 2.5):
        with pytest.raises(ValueError, match="n_train"):
            ds.split(n_train=bad)


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


def test_cache_reuses_generated_output(tmp_path):
    a = world.generate(2, seed=11, workers=1, cache=tmp_path)
    files = list(tmp_path.glob("*.npz"))
    assert len(files) == 1
    b = world.generate(2, seed=11, workers=1, cache=tmp_path)
    assert a.content_hash() == b.content_hash()
    # a broken cache entry is regenerated, not trusted
    files[0].write_bytes(b"broken")
    c = world.generate(2, seed=11, workers=1, cache=tmp_path)
    assert c.content_hash() == a.content_hash()


def test_generate_rejects_bad_arguments():
    for kw, name in [({"n_scenes": 0}, "n_scenes"), ({"seed": -1}, "seed"),
                     ({"raster": "big"}, "raster"), ({"workers": 0}, "workers"),
                     ({"k_targets": 0}, "k_targets")]:
        with pytest.raises(ValueError, match=name):
            world.generate(**{"n_scenes": 1, **kw})


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


# ------------------------------------------------------------------------ the builder, draw_scene


def test_build_is_what_generate_assembles_and_save_round_trips(ds, tmp_path):
    cfg = ds.raster
    scenes = [generation.generate_scene(5, i, cfg) for i in range(3)]
    meta = fileformat.empty_meta(5, cfg)
    fileformat.append_scenes(meta, [s["recipe"] for s in scenes], [s["tags"] for s in scenes],
                        [s["attempts"] for s in scenes], range(3))
    built = world.Dataset.build(scenes, meta, maps=[s["map"] for s in scenes])
    assert built.content_hash() == ds.subset(slice(0, 3)).content_hash()
    assert built.maps[2] is scenes[2]["map"]  # maps given are kept, not rebuilt
    path = world.save(built, tmp_path / "b.npz", shard_scenes=2)
    assert world.file_content_hash(path) == built.content_hash()


def test_build_refuses_what_would_make_a_bad_dataset(ds):
    cfg = ds.raster
    one = {f: getattr(ds, f)[0] for f in fileformat.ARRAY_FIELDS}
    meta = fileformat.empty_meta(0, cfg)
    fileformat.append_scenes(meta, ds.meta["recipes"][:1], ds.tags[:1], [1], [0])
    assert len(world.Dataset.build([one], meta)) == 1
    with pytest.raises(ValueError, match="at least one scene"):
        world.Dataset.build([], meta)
    with pytest.raises(ValueError, match=r"missing \['goal_bev'\]"):
        world.Dataset.build([{k: v for k, v in one.items() if k != "goal_bev"}], meta)
    with pytest.raises(ValueError, match=r"'recipes' must be a list of one entry per scene \(2\)"):
        world.Dataset.build([one, one], meta)
    bad = dict(one, controls=one["controls"].copy())
    bad["controls"][7, 1] = np.inf
    with pytest.raises(ValueError, match=r"^demo holds a non-finite number: controls\[scene 0, "
                                         r"step 7, 1\] = inf"):
        world.Dataset.build([bad], meta, what="demo")


def test_draw_scene_restarts_the_stream_that_generated_a_stored_scene():
    ds2 = world.generate(2, seed=2, workers=1)
    assert ds2.meta["attempts"][0] == 2  # scene 0 of seed 2 was redrawn once
    for i in range(2):
        attempt = ds2.meta["attempts"][i] - 1
        rng, recipe, m = world.draw_scene(2, ds2.meta["scene_index"][i], attempt)
        assert recipe == ds2.meta["recipes"][i]
        log = world.simulate_scene(m, rng, T=world.T_STEPS, max_ados=world.MAX_ADOS)
        np.testing.assert_array_equal(log.ego.astype(np.float32), ds2.ego[i])
        np.testing.assert_array_equal(log.controls.astype(np.float32), ds2.controls[i])
        np.testing.assert_array_equal(log.ado_valid, ds2.ado_valid[i])
    for kw, name in [({"seed": -1}, "seed"), ({"index": 1.0}, "index"), ({"attempt": True},
                                                                         "attempt")]:
        with pytest.raises(ValueError, match=rf"^{name} must be an integer >= 0, got {name}="):
            world.draw_scene(**{"seed": 0, "index": 0, **kw})


@pytest.mark.parametrize("call, name", [
    (lambda ds: world.generate(True), "n_scenes"),
    (lambda ds: world.generate(1, seed=True), "seed"),
    (lambda ds: world.generate(1, max_ados=2.0), "max_ados"),
    (lambda ds: world.generate_splits(2.0, 1), "n_train"),
    (lambda ds: ds.split(True), "n_train"),
    (lambda ds: world.save(ds.subset(slice(0, 1)), "/nonexistent/x.npz", shard_scenes=True),
     "shard_scenes"),
    (lambda ds: world.lane_targets(ds.maps[0], ds.ego[0, 0].astype(np.float64), k=2.5), "k"),
    (lambda ds: world.RasterConfig(size=True), "size"),
])
def test_integer_arguments_refuse_bools_and_floats(ds, call, name):
    """A bool or a float is not silently taken for an integer (True was 1, 2.5 was 2)."""
    with pytest.raises(ValueError, match=rf"^{name} must be an integer "):
        call(ds)


# --------------------------------------------------------------------------- file format v2, pinned
# A two-scene dataset whose arrays are small exact integers (identical on every machine), saved
# with shard_scenes=1. OLD_FILE_V2 is that file as written by the writer before the dataset module
# was split into fileformat / scenes / datawriter / datareader / generation: it must keep loading,
# and today's writer must produce the same header (same members, meta, checksums).

RECIPE = {
    "arms": [
        {"angle": -0.11603336747315302, "lanes": 2,
         "pieces": [[30.0, 0.0], [27.855, 0.0], [33.31, 0.0]]},
        {"angle": 1.645981184202962, "lanes": 1,
         "pieces": [[30.0, 0.0], [71.024, 0.0], [35.282, -0.010683], [80.011, 0.0],
                    [57.613, 0.0], [59.536, 0.0]]},
        {"angle": 3.2406539921364463, "lanes": 2,
         "pieces": [[30.0, 0.0], [80.289, 0.0], [43.245, 0.0]]},
        {"angle": 4.737981566568813, "lanes": 1,
         "pieces": [[30.0, 0.0], [69.655, 0.0], [14.68, -0.009914]]},
    ],
    "ego": {"arm_in": 2, "arm_out": 1, "lane_pick": 0.9340435159562497,
            "start_dist": 107.53413360282693},
    "kind": "intersection", "rotation": -1.4464727375963786,
}
TINY_CONTENT_HASH = "0e52b347e7a49e1bde104b80d4fdcf392cd6bd181e868e1bdda3ac7f94024e3c"
TINY_HEADER_SHA = "5f0597cca1a115a7f88caa959ea19c61f3c8a3280f61aaa91ced045ec1d48f91"
FIELDS_V2 = ("bev", "ego", "controls", "goal", "lane_target", "ado", "ado_valid", "goal_bev")
META_V2 = ("seed", "version", "dt", "raster", "recipes", "tags", "attempts", "scene_index")


def _tiny() -> world.Dataset:
    S, T, H, A, K = 2, 3, 8, 2, 2

    def n(shape, dtype, k):
        return (np.arange(int(np.prod(shape))) * k % 251).astype(dtype).reshape(shape)
    arrays = {
        "bev": n((S, T, H, H, 3), np.uint8, 7), "ego": n((S, T, 3), np.float32, 0.5),
        "controls": n((S, T, 2), np.float32, 0.25), "goal": n((S, T, 3), np.float32, -1.5),
        "lane_target": n((S, T, K, 2), np.float32, 4.0), "ado": n((S, T, A, 5), np.float32, 0.125),
        "ado_valid": n((S, T, A), np.int64, 1) % 2 == 0, "goal_bev": n((S, H, H, 3), np.uint8, 3),
    }
    meta = {"seed": 7, "version": 1, "dt": 0.5, "raster": {
        "draw_crossings": True, "draw_lanes": True, "draw_walkways": True, "ego_length": 4.727,
        "ego_width": 1.907, "lane_width_m": 0.5, "metres_ahead": 40.0, "metres_behind": 10.0,
        "metres_side": 25.0, "size": 8}, "recipes": [RECIPE, RECIPE],
        "tags": [{"kind": "a"}, {"kind": "b"}], "attempts": [1, 2], "scene_index": [0, 1]}
    return world.Dataset(**arrays, maps=[], meta=meta)


def _header(path: Path) -> dict:
    return json.loads(bytes(np.load(path)["header"]).decode())


def test_the_format_constants_are_those_of_version_2():
    assert fileformat.ARRAY_FIELDS == FIELDS_V2 and fileformat.META_KEYS == META_V2
    assert (world.FILE_FORMAT_VERSION, world.FORMAT_VERSION) == (2, 1)
    assert list(fileformat.empty_meta(7, world.RasterConfig(size=8))) == list(META_V2)


def test_a_file_written_before_the_split_still_loads(tmp_path):
    path = tmp_path / "old.npz"
    path.write_bytes(base64.b64decode(OLD_FILE_V2))
    tiny, back = _tiny(), world.load(path)
    assert back.content_hash() == tiny.content_hash() == TINY_CONTENT_HASH
    assert world.file_content_hash(path) == TINY_CONTENT_HASH
    for f in FIELDS_V2:
        np.testing.assert_array_equal(getattr(back, f), getattr(tiny, f))
        assert getattr(back, f).dtype == getattr(tiny, f).dtype
    assert back.meta == tiny.meta == world.read_meta(path)
    assert back.maps[1].kind == "intersection"


def test_the_writer_keeps_the_v2_layout_and_header(tmp_path):
    path = world.save(_tiny(), tmp_path / "tiny.npz", shard_scenes=1)
    with zipfile.ZipFile(path) as z:
        names = z.namelist()
    assert names == [f"{f}-{k:05d}.npy" for k in range(2) for f in FIELDS_V2] + ["header.npy"]
    header = _header(path)
    assert sorted(header) == ["format", "meta", "n_scenes", "sha256", "shards", "version"]
    assert (header["format"], header["version"], header["n_scenes"]) == ("minimanc.world", 2, 2)
    assert sorted(header["meta"]) == sorted(META_V2)
    assert [(s["start"], s["stop"]) for s in header["shards"]] == [(0, 1), (1, 2)]
    assert header["shards"][1]["arrays"]["ado_valid"] == {
        "dtype": "|b1", "shape": [1, 3, 2],
        "sha256": hashlib.sha256(_tiny().ado_valid[1:].tobytes()).hexdigest()}
    assert header["sha256"] == TINY_HEADER_SHA
    old = tmp_path / "old.npz"
    old.write_bytes(base64.b64decode(OLD_FILE_V2))
    assert header == _header(old)


def test_every_public_name_of_the_dataset_lives_in_one_module():
    names = [
        "ARRAY_FIELDS", "Dataset", "DatasetFileError", "DatasetWriter", "Estimate",
        "FILE_FORMAT_VERSION", "FLOAT_FIELDS", "FORMAT_VERSION", "LazyMaps", "MAX_ATTEMPTS",
        "META_KEYS", "PER_SCENE_KEYS", "SHARD_BYTES", "append_scenes", "check_arrays_finite",
        "default_shard_scenes", "describe_non_finite", "empty_meta", "estimate",
        "file_content_hash", "first_non_finite", "generate", "generate_file", "generate_scene",
        "generate_splits", "load", "read_meta", "remove_temp_files", "save", "scene_nbytes",
        "temp_files",
    ]
    modules = (fileformat, scenes, datawriter, datareader, generation)
    homes = {n: [m.__name__ for m in modules if n in m.__all__] for n in names}
    assert {n: h for n, h in homes.items() if len(h) != 1} == {}
    for n in ("Dataset", "DatasetWriter", "load", "save", "generate", "generate_file"):
        assert getattr(world, n) is getattr(importlib.import_module(homes[n][0]), n)


OLD_FILE_V2 = (  # base64 of tiny.npz as the pre-split writer wrote it
    "UEsDBC0AAAAIAAAAIQAVirhY//////////8NABQAYmV2LTAwMDAwLm5weQEAEADAAgAAAAAAAFkBAAAAAAAAm+wX6hsQ"
    "ychQxlCtnpJanFykbqWgXlNqqK6joJ6WX1RSlJgXn1+UkgoSd0vMKU4FihdnJBakAvkahjoKxjoKFmBkrKmjUKtAKuBi"
    "YOcTlVHWMrSwd/MNiU7KLCiva+2ZPGvhivXb9h45fenmg+fvvjJy8IvJqmgbWTq4+4XGJGcVVtS39U6ZvWjlhu37jp65"
    "fOvhi/ffmDgFxOVUdYytHD38w2JTsosqG9r7ps5ZvGrjjv3Hzl65/ejlh+/MXIIS8mq6JtZOngHhcak5xVWNHf3T5i5Z"
    "vWnngePnrt55/OrjDxZuIUkFdT1TG2evwIj4tNyS6qbOCdPnLV2zedfBE+ev3X3y+tNPVh5hKUUNfTNbF++gyIT0vNKa"
    "5q6JM+YvW7tl96GTF67fe/rm8y82XhFpJU0DcztXn+CoxIz8stqW7kkzFyxft3XP4VMXb9x/9vbLqNep4HUAUEsDBC0A"
    "AAAIAAAAIQBpXiaF//////////8NABQAZWdvLTAwMDAwLm5weQEAEACkAAAAAAAAAGAAAAAAAAAAm+wX6hsQychQxlCt"
    "npJanFykbqWgbpNmoq6joJ6WX1RSlJgXn1+UkgoSd0vMKU4FihdnJBakAvkahjoKxkCkqaNQq0Ae4GKAAHsGhgYgPgDE"
    "DA4MDApA7ADECUDc4AAAUEsDBC0AAAAIAAAAIQB0ncn5//////////8SABQAY29udHJvbHMtMDAwMDAubnB5AQAQAJgA"
    "AAAAAAAAWQAAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBuk2airqOgnpZfVFKUmBefX5SSChJ3S8wpTgWKF2ckFqQC"
    "+RqGOgrGOgpGmjoKtQrkAS4GMGiwAxL2DAwOQNwAxAvsAVBLAwQtAAAACAAAACEASjLArP//////////DgAUAGdvYWwt"
    "MDAwMDAubnB5AQAQAKQAAAAAAAAAYgAAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBuk2airqOgnpZfVFKUmBefX5SS"
    "ChJ3S8wpTgWKF2ckFqQC+RqGOgrGQKSpo1CrQB7gYgCBhkpnBoYKZ4aGMiBdCqSLgXQRkC4A0vnOAFBLAwQtAAAACAAA"
    "ACEAAH5mhf//////////FQAUAGxhbmVfdGFyZ2V0LTAwMDAwLm5weQEAEACwAAAAAAAAAGwAAAAAAAAAm+wX6hsQychQ"
    "xlCtnpJanFykbqWgbpNmoq6joJ6WX1RSlJgXn1+UkgoSd0vMKU4FihdnJBakAvkahjoKxjoKRkCkqaNQq0AG4GIAgwYH"
    "IOHIwOAAxA1AvACIDwDxAyBmcGJgEABiBSA2cAIAUEsDBC0AAAAIAAAAIQD4SruN//////////8NABQAYWRvLTAwMDAw"
    "Lm5weQEAEAD4AAAAAAAAAJkAAAAAAAAAnci9CcJQGEbhz06sLC2/7ka4hb8gIppKbJQ0glYmmIQUYiQRGxEyguACjuAI"
    "GcERHMERPOIGvvAU77ktlnNvXZGTnE0Y5dvMDNWM4p6xauI0O2bBfpNmYfTt02CXR/Q8CQ4R32lb7VrtWO03rV70j9Xk"
    "t7FIgRIyEVG48FHgijseKPHEC2+IK1JFHQ0oHLQwgIsZPKzgI3E/UEsDBC0AAAAIAAAAIQAJ+0SF//////////8TABQA"
    "YWRvX3ZhbGlkLTAwMDAwLm5weQEAEACGAAAAAAAAAE0AAAAAAAAAm+wX6hsQychQxlCtnpJanFykbqWgXpNkqK6joJ6W"
    "X1RSlJgXn1+UkgoSd0vMKU4FihdnJBakAvkahjoKxjoKRpo6CrUK5AEuRgYQBABQSwMELQAAAAgAAAAhAB9DMTX/////"
    "/////xIAFABnb2FsX2Jldi0wMDAwMC5ucHkBABAAQAEAAAAAAAASAQAAAAAAAJvsF+obEMnIUMZQrZ6SWpxcpG6loF5T"
    "aqiuo6Cell9UUpSYF59flJIKEndLzClOBYoXZyQWpAL5GoY6ChZgZKypo1CrQAbgYmBm4+ThFxKVkJZTVFHX0jUwNrO0"
    "sXdy9fD2CwwJj4pNSE7LzMkvKq2ormtsae/qnTB52sw58xctXbF63cYt23ftPXD42Mkz5y9dvXH73sMnz1+9/fD5209G"
    "FnYuXgFhMUkZeSVVDW09QxNzK1sHZzdPH/+g0IjouMSU9KzcguKyypr6ptaO7r6JU6bPmrtg8bKVa9Zv2rpj976DR46f"
    "Onvh8rWbd+4/evri9buPX77/YmLl4OYTFBGXklVQVtPU0TcytbC2c3RxBwBQSwMELQAAAAgAAAAhALfZ/37/////////"
    "/w0AFABiZXYtMDAwMDEubnB5AQAQAMACAAAAAAAAWQEAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBeU2qorqOgnpZf"
    "VFKUmBefX5SSChJ3S8wpTgWKF2ckFqQC+RqGOgrGOgoWYGSsqaNQq0Aq4BIQl1PVMbZy9PAPi03JLqpsaO+bOmfxqo07"
    "9h87e+X2o5cfvjNzCUrIq+maWDt5BoTHpeYUVzV29E+bu2T1pp0Hjp+7eufxq48/WLiFJBXU9UxtnL0CI+LTckuqmzon"
    "TJ+3dM3mXQdPnL9298nrTz9ZeYSlFDX0zWxdvIMiE9LzSmuauybOmL9s7Zbdh05euH7v6ZvPv9h4RaSVNA3M7Vx9gqMS"
    "M/LLalu6J81csHzd1j2HT128cf/Z2y8M7HyiMspahhb2br4h0UmZBeV1rT2TZy1csX7b3iOnL9188PzdV0YOfjFZFW0j"
    "Swd3v9CY5KzCivq23imzF63csH3f0TOXbz188f4bE+eo16ngdQBQSwMELQAAAAgAAAAhAFOnRxr//////////w0AFABl"
    "Z28tMDAwMDEubnB5AQAQAKQAAAAAAAAAZAAAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBuk2airqOgnpZfVFKUmBef"
    "X5SSChJ3S8wpTgWKF2ckFqQC+RqGOgrGQKSpo1CrQB7gYmCY4MDAsACINwDxASC+AMQPgPgDEDM4MjBwOAIAUEsDBC0A"
    "AAAIAAAAIQDP59FU//////////8SABQAY29udHJvbHMtMDAwMDEubnB5AQAQAJgAAAAAAAAAXQAAAAAAAACb7BfqGxDJ"
    "yFDGUK2eklqcXKRupaBuk2airqOgnpZfVFKUmBefX5SSChJ3S8wpTgWKF2ckFqQC+RqGOgrGOgpGmjoKtQrkAS4GhgP2"
    "DAwPgJjBgYFBAIgVgNjAAQBQSwMELQAAAAgAAAAhAGBBr27//////////w4AFABnb2FsLTAwMDAxLm5weQEAEACkAAAA"
    "AAAAAGMAAAAAAAAAm+wX6hsQychQxlCtnpJanFykbqWgbpNmoq6joJ6WX1RSlJgXn1+UkgoSd0vMKU4FihdnJBakAvka"
    "hjoKxkCkqaNQq0Ae4GJoyHVmYMhxZmjIAtKZQDodSKcB6RQgnQykE50BUEsDBC0AAAAIAAAAIQBLnhmd//////////8V"
    "ABQAbGFuZV90YXJnZXQtMDAwMDEubnB5AQAQALAAAAAAAAAAbAAAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBuk2ai"
    "rqOgnpZfVFKUmBefX5SSChJ3S8wpTgWKF2ckFqQC+RqGOgrGOgpGQKSpo1CrQAbgYmBwcGJgCADiBCAuAOIGIO4A4glA"
    "PAOIFwDxCiDeAMQ7nABQSwMELQAAAAgAAAAhAErv89r//////////w0AFABhZG8tMDAwMDEubnB5AQAQAPgAAAAAAAAA"
    "nQAAAAAAAACb7BfqGxDJyFDGUK2eklqcXKRupaBuk2airqOgnpZfVFKUmBefX5SSChJ3S8wpTgWKF2ckFqQC+RqGOgrG"
    "OgpGOgqmmjoKtQpkAC4GhgIHBoYKIG4A4hYg7gDiHiCeAMRTgHgGEM8B4gVAvASIVwDxGiDeAMRbgHgHEO8B4gNAfASI"
    "TwDxGSC+AMRXgPgGEN8B4gdA/ASIXwDxGwcAUEsDBC0AAAAIAAAAIQAJ+0SF//////////8TABQAYWRvX3ZhbGlkLTAw"
    "MDAxLm5weQEAEACGAAAAAAAAAE0AAAAAAAAAm+wX6hsQychQxlCtnpJanFykbqWgXpNkqK6joJ6WX1RSlJgXn1+UkgoS"
    "d0vMKU4FihdnJBakAvkahjoKxjoKRpo6CrUK5AEuRgYQBABQSwMELQAAAAgAAAAhACk4r0X//////////xIAFABnb2Fs"
    "X2Jldi0wMDAwMS5ucHkBABAAQAEAAAAAAAASAQAAAAAAAJvsF+obEMnIUMZQrZ6SWpxcpG6loF5Taqiuo6Cell9UUpSY"
    "F59flJIKEndLzClOBYoXZyQWpAL5GoY6ChZgZKypo1CrQAbg8vINCA6LjIlPSs3IzissKa+qbWhu6+zpnzR1xux5C5cs"
    "X7V2w+ZtO/fsP3T0xOlzF69cv3X3weNnL9+8//T1BwMzGycPv5CohLScooq6lq6BsZmljb2Tq4e3X2BIeFRsQnJaZk5+"
    "UWlFdV1jS3tX74TJ02bOmb9o6YrV6zZu2b5r74HDx06eOX/p6o3b9x4+ef7q7YfP334ysrBz8QoIi0nKyCupamjrGZqY"
    "W9k6OLt5+vgHhUZExyWmpGflFhSXVdbUN7V2dPdNBABQSwMELQAAAAgAAAAhADP/Vrz//////////woAFABoZWFkZXIu"
    "bnB5AQAQAJsPAAAAAAAAaQUAAAAAAADtVl2PW7cRTV/zKxZ62RTYChwOh+QEfe5bg77kITAMYUgO14K10uLq2pvU8a/I"
    "H87waj/srWK7aftQIAutQI545xzOHB7eX777/u//+OFPX7396t1l02OdLr+9uPz5DVxeXVz2wzRPst8cpqYj/jfZHdXi"
    "x1dyqzb/BnNMV3++unh/8Xv/vn63MpQbmVffXqxutvvtjezr+u4w7drqyiI6i/3ybiXzrDe389EmL+Dqwr+0H9t4yK3J"
    "hpMcZ52WlW2Su02dDsfjdn891s/TGx2rR3wne30eu5Pd6zv56YOwXh82O91fz68sFtbJp/vg3bYtMVizG7GR7hTc3Dxy"
    "Mc6THjfySqWN593aPUWLvtruRxg+Ch+3TS3oaQket/8cs/x+7Ezr9nbh/MKqMN08jPbXu7HmL24NEB0ixhQSAqHz98TG"
    "yjG+3Wo9JXiBC6h9Wfle+LTORI9TxDXCafbSgJ8gYB0DcQbIwTvP8cP88In8CdbOh6f8tPbZnjXGDlzMOIJ5TOBxDaV1"
    "BHya8pownuOEax9cJGT2gDGEiF+4aQP0mR+nYSSicwjWdky2a4qRYs6AX7jryOv4QVUhrGM+bdoxQzCUlycxnWQ93Wy2"
    "+3vOY3J4M98DLNq63dbXi7AYgwtIQEzRBx7iO84yzZu2PS5PuGS1CmA6cFbmyDjE8/qktdV2b6fjqHXeHvbjWE2HWZax"
    "CQjWVr5gGsdEHDHleKrDH1L7Q2r/e6kNhseqhm/P649jk7ZBWMKqI+PAn+X6XowPMLJaSvgwLasl01uDPmHB4LTfLKkf"
    "GmXXlqc4llN3xKlWAQEgST3nKsLEKsA1QseaBX12PYLYD1C1uUBaoYXcGVanbFN79OXpdIHYsJ3K3eafbkdzV3/tYfUR"
    "eC6uchR13rvIvpTcelTXNXXMtQA1DKlxtfpzdSFTF0kpc0OuVjp3n23JPu5Ck4vtjoamBvrmrey27WMOPxf4mENtrhgD"
    "aI6zQztwJQmEEjlE22Lxuec2OLmSEkt16KR1hdqqa6pRznFYCBR9+wz6zTPo4DRmS4U95MwxMSYtHrU3J0Gll2TAyiwe"
    "A5NQ6R4KVqOUFONZ6Lx8cCFQD/t5OuyOn2lCAc+utoAqNavvEqTlFqhxT2xyiLmbBIxJrtGnikiUMoQUsPfWUX+zAA/H"
    "7beha2yUu1idRal3Cto1alDNXEILseSuoRIWSFRIou+pJSEUKz6iOwd92vr1QXafw1YNkexQSwA7uqUzt4oJJLlgteBE"
    "ktlKYA7Shdlqbt2JrmFTa0PgT2JvPt98sKoGB74G4+A6uVLtMNiFUgYPK72rkJPW4ByUgLXUxtTNd0vL1qn4HP/Dzi8u"
    "ZkZ1rfNnqgCRXBLDtaQpUKSmkR1bF5wf8iZnrkYqKN5Rzi4K94imfKrkNcD5E2j9f//glcNIl/Hh9t6M/k2TEKq5eXTm"
    "lLpYlX3MF7xdQAh2ZCqwyw5ijMUoIpVQJTIX41lscFaf/0cmUVuMqna7KIpd4R5MjtRjDD2ZDriTqcQssReVBJ2dM+Oo"
    "LVeuJmRu5zzyd5iE5GKagCiuyrj9HUUuZsLkQmvorRPqzTpa6KCQ2LqTQXyycyudasL/wCRMhy7nbm9DEFtfzEiJAnKR"
    "rGaGtSS2FxYTSUmBAzSKQMMpocUa5Fztv9gkuPtWmjPvtSvKUma01wG7IWvRTlxiSZkaWAVSZUraixkFgThzrkzVf9qg"
    "vsAksBQxG1TrKUEyNXew7jcEj3ZqtUSCYPsn0yaX7ERiD4Xs+mSrvfn0f8ck0nCdnM0DmJO1GREgmD9UZHKSoiu9ETvo"
    "pdfxLy1VzcZUuhGXf7GqsyYBTybhn73B+Pe/AlBLAQItAy0AAAAIAAAAIQAVirhYWQEAAMACAAANAAAAAAAAAAAAAACA"
    "AQAAAABiZXYtMDAwMDAubnB5UEsBAi0DLQAAAAgAAAAhAGleJoVgAAAApAAAAA0AAAAAAAAAAAAAAIABmAEAAGVnby0w"
    "MDAwMC5ucHlQSwECLQMtAAAACAAAACEAdJ3J+VkAAACYAAAAEgAAAAAAAAAAAAAAgAE3AgAAY29udHJvbHMtMDAwMDAu"
    "bnB5UEsBAi0DLQAAAAgAAAAhAEoywKxiAAAApAAAAA4AAAAAAAAAAAAAAIAB1AIAAGdvYWwtMDAwMDAubnB5UEsBAi0D"
    "LQAAAAgAAAAhAAB+ZoVsAAAAsAAAABUAAAAAAAAAAAAAAIABdgMAAGxhbmVfdGFyZ2V0LTAwMDAwLm5weVBLAQItAy0A"
    "AAAIAAAAIQD4SruNmQAAAPgAAAANAAAAAAAAAAAAAACAASkEAABhZG8tMDAwMDAubnB5UEsBAi0DLQAAAAgAAAAhAAn7"
    "RIVNAAAAhgAAABMAAAAAAAAAAAAAAIABAQUAAGFkb192YWxpZC0wMDAwMC5ucHlQSwECLQMtAAAACAAAACEAH0MxNRIB"
    "AABAAQAAEgAAAAAAAAAAAAAAgAGTBQAAZ29hbF9iZXYtMDAwMDAubnB5UEsBAi0DLQAAAAgAAAAhALfZ/35ZAQAAwAIA"
    "AA0AAAAAAAAAAAAAAIAB6QYAAGJldi0wMDAwMS5ucHlQSwECLQMtAAAACAAAACEAU6dHGmQAAACkAAAADQAAAAAAAAAA"
    "AAAAgAGBCAAAZWdvLTAwMDAxLm5weVBLAQItAy0AAAAIAAAAIQDP59FUXQAAAJgAAAASAAAAAAAAAAAAAACAASQJAABj"
    "b250cm9scy0wMDAwMS5ucHlQSwECLQMtAAAACAAAACEAYEGvbmMAAACkAAAADgAAAAAAAAAAAAAAgAHFCQAAZ29hbC0w"
    "MDAwMS5ucHlQSwECLQMtAAAACAAAACEAS54ZnWwAAACwAAAAFQAAAAAAAAAAAAAAgAFoCgAAbGFuZV90YXJnZXQtMDAw"
    "MDEubnB5UEsBAi0DLQAAAAgAAAAhAErv89qdAAAA+AAAAA0AAAAAAAAAAAAAAIABGwsAAGFkby0wMDAwMS5ucHlQSwEC"
    "LQMtAAAACAAAACEACftEhU0AAACGAAAAEwAAAAAAAAAAAAAAgAH3CwAAYWRvX3ZhbGlkLTAwMDAxLm5weVBLAQItAy0A"
    "AAAIAAAAIQApOK9FEgEAAEABAAASAAAAAAAAAAAAAACAAYkMAABnb2FsX2Jldi0wMDAwMS5ucHlQSwECLQMtAAAACAAA"
    "ACEAM/9WvGkFAACbDwAACgAAAAAAAAAAAAAAgAHfDQAAaGVhZGVyLm5weVBLBQYAAAAAEQARABoEAACEEwAAAAA="
)



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
