"""Chapter 7 — the generated dataset: determinism, consistency, safety, statistics, the
builder and draw_scene, and the arguments generate refuses."""

import numpy as np
import pytest
from world_dataset_helpers import N, generate_test_dataset

from minimanc import world
from minimanc.world import fileformat, generation


@pytest.fixture(scope="module")
def ds():
    return generate_test_dataset()


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

