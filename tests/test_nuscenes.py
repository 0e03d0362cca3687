"""The nuScenes importer on the package's schema-exact sample
(:mod:`minimanc.world.nuscenes.sample`): the sample's schema, ego poses, controls, boxes, map
classes and the route against values computed here, skipped scenes, and one-line errors for
bad input."""

import json
import math
import re
import shutil
import tracemalloc
import zipfile
from collections import namedtuple

import numpy as np
import pytest

from minimanc import world
from minimanc.cli import main
from minimanc.world.lanes import class_grid
from minimanc.world.nuscenes import (
    MapExpansion,
    NuScenesError,
    Tables,
    import_nuscenes,
    importer,
    keyframe_poses,
)
from minimanc.world.nuscenes.mapexp import MARGIN
from minimanc.world.nuscenes.sample import CENTRE, LOCATION, VERSION, lane_token, write_sample

SCHEMA = {  # the devkit's schema.md, every field of every table
    "attribute": {"token", "name", "description"},
    "visibility": {"token", "level", "description"},
    "category": {"token", "name", "description"},
    "instance": {"token", "category_token", "nbr_annotations", "first_annotation_token",
                 "last_annotation_token"},
    "sensor": {"token", "channel", "modality"},
    "calibrated_sensor": {"token", "sensor_token", "translation", "rotation",
                          "camera_intrinsic"},
    "ego_pose": {"token", "translation", "rotation", "timestamp"},
    "log": {"token", "logfile", "vehicle", "date_captured", "location"},
    "scene": {"token", "name", "description", "log_token", "nbr_samples", "first_sample_token",
              "last_sample_token"},
    "sample": {"token", "timestamp", "scene_token", "next", "prev"},
    "sample_data": {"token", "sample_token", "ego_pose_token", "calibrated_sensor_token",
                    "filename", "fileformat", "width", "height", "timestamp", "is_key_frame",
                    "next", "prev"},
    "sample_annotation": {"token", "sample_token", "instance_token", "attribute_tokens",
                          "visibility_token", "translation", "size", "rotation",
                          "num_lidar_pts", "num_radar_pts", "next", "prev"},
    "map": {"token", "log_tokens", "category", "filename"},
}
EXPANSION_LAYERS = {"version", "canvas_edge", "polygon", "line", "node", "drivable_area",
                    "road_segment", "road_block", "lane", "ped_crossing", "walkway",
                    "stop_line", "carpark_area", "road_divider", "lane_divider",
                    "traffic_light", "lane_connector", "arcline_path_3", "connectivity"}


@pytest.fixture(scope="module")
def dataroot(tmp_path_factory):
    root = tmp_path_factory.mktemp("nuscenes")
    return root, write_sample(root)


def test_fixture_is_schema_exact(dataroot):
    root, truth = dataroot
    for table, fields in SCHEMA.items():
        rows = json.loads((root / VERSION / f"{table}.json").read_text())
        assert rows and all(set(r) == fields for r in rows), table
        tokens = [r["token"] for r in rows]
        assert len(set(tokens)) == len(tokens), table
    exp = json.loads((root / "maps" / "expansion" / f"{LOCATION}.json").read_text())
    assert set(exp) == EXPANSION_LAYERS
    nodes = {n["token"] for n in exp["node"]}
    for p in exp["polygon"]:
        assert set(p["exterior_node_tokens"]) <= nodes
    lanes = {r["token"] for r in exp["lane"] + exp["lane_connector"]}
    assert set(exp["arcline_path_3"]) == lanes == set(exp["connectivity"])
    # the chains the devkit follows: scene -> samples, instance -> annotations
    samples = {r["token"]: r for r in json.loads((root / VERSION / "sample.json").read_text())}
    for sc in json.loads((root / VERSION / "scene.json").read_text()):
        tok, n = sc["first_sample_token"], 0
        while tok:
            n, tok = n + 1, samples[tok]["next"]
        assert n == sc["nbr_samples"] == len(truth[sc["name"]]["stamps"])


def test_fixture_tables_read_and_route_through_the_junction(dataroot):
    """The stage-1 readers on the fixture: LIDAR_TOP keyframe poses, and the left turn's
    route (connectors converge at the junction's exit: the lane driven is kept)."""
    root, truth = dataroot
    tables = Tables(root, VERSION)
    m = MapExpansion(root, LOCATION)
    expect = {"scene-0061": ["lane_s_in", "conn_s_w", "lane_w_out"],
              "scene-0103": ["lane_s_in", "conn_s_n", "lane_n_out"]}
    for name, lanes in expect.items():
        poses, _ = keyframe_poses(tables, tables.samples(tables.scene_by_name()[name]))
        assert np.allclose(poses, truth[name]["poses"], atol=1e-9)
        recipe = m.local_recipe(poses[:41])
        assert [recipe["lanes"][i]["token"] for i in recipe["route"]] == \
            [lane_token(k) for k in lanes]


# --------------------------------------------------------------------------- the import


@pytest.fixture(scope="module")
def imported(dataroot, tmp_path_factory):
    root, truth = dataroot
    path = tmp_path_factory.mktemp("out") / "nuscenes.npz"
    report = import_nuscenes(root, VERSION, path)
    return truth, report, world.load(path)


def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def test_scenes_splits_and_skipped(imported):
    truth, report, ds = imported
    assert report.imported == ("scene-0061", "scene-0103")  # mini_train first, then mini_val
    assert [t["split"] for t in ds.tags] == ["mini_train", "mini_val"]
    assert [t["scene_token"] for t in ds.tags] == [truth[n]["token"] for n in report.imported]
    assert dict(report.skipped) == {
        "scene-0553": "39 keyframes, fewer than the 40 a scene needs",
        "scene-0655": "a gap of 1.00 s between keyframes 20 and 21 (allowed 0.3-0.7 s)",
        "scene-0757": "the ego drives on no lane of boston-seaport (within 5.0 m, heading "
                      "within 90 degrees)"}
    assert np.diff(truth["scene-0061"]["stamps"])[40] == pytest.approx(1.0)  # not used
    assert ds.meta["nuscenes"]["skipped"] == [{"scene": n, "reason": r}
                                              for n, r in report.skipped]
    assert ds.meta["nuscenes"]["splits"] == {"mini_train": 1, "mini_val": 1}
    assert ds.ego.shape == (2, 40, 3) and ds.controls.shape == (2, 40, 2)
    assert ds.dt == 0.5


def test_ego_poses_are_the_lidar_keyframes(imported):
    truth, _, ds = imported
    for i, name in enumerate(("scene-0061", "scene-0103")):
        want = truth[name]["poses"][:40]
        assert np.abs(ds.ego[i, :, :2] - want[:, :2]).max() < 1e-3
        assert np.abs(wrap(ds.ego[i, :, 2] - want[:, 2])).max() < 1e-5


def _expected_controls(p):
    """Finite differences at dt = 0.5 s, the displacement projected on the heading."""
    dx, dy = np.diff(p[:, 0]), np.diff(p[:, 1])
    v = (dx * np.cos(p[:-1, 2]) + dy * np.sin(p[:-1, 2])) / 0.5
    w = wrap(np.diff(p[:, 2])) / 0.5
    return np.stack([v, w], axis=1)


def test_controls_by_finite_differences(imported):
    truth, _, ds = imported
    a = _expected_controls(truth["scene-0061"]["poses"][:41])  # 42 keyframes: the first 41
    assert np.abs(ds.controls[0] - a).max() < 2e-3
    assert ds.controls[0, :, 1].sum() * 0.5 == pytest.approx(math.pi / 2, abs=0.05)  # a left turn
    b = _expected_controls(truth["scene-0103"]["poses"])  # exactly 40: the last one held
    assert np.abs(ds.controls[1, :39] - b).max() < 2e-3
    assert np.array_equal(ds.controls[1, 39], ds.controls[1, 38])
    assert np.all(ds.controls[1, :3, 0] == 0.0)  # it waits 2 s
    assert ds.tags[1]["stopped_steps"] == 4 and ds.tags[0]["turn"] == "left"


def _vehicles(agents):
    cars = [a for a in agents if a["category"].startswith("vehicle.")]
    return sorted(cars, key=lambda a: (min(a["boxes"]), a["instance_token"]))


def test_vehicle_boxes_fill_the_ado_slots(imported):
    truth, _, ds = imported
    for i, name in enumerate(("scene-0061", "scene-0103")):
        agents = truth[name]["agents"]
        cars = _vehicles(agents)
        assert ds.tags[i]["n_vehicles"] == len(cars) == ds.tags[i]["n_ados"]
        assert ds.tags[i]["n_pedestrians"] == sum(a["category"].startswith("human.")
                                                  for a in agents) == 1
        assert not ds.ado_valid[i, :, len(cars):].any()  # pedestrians, barriers: not ados
        for slot, car in enumerate(cars):
            frames = [k for k in range(40) if k in car["boxes"]]
            assert list(np.flatnonzero(ds.ado_valid[i, :, slot])) == frames
            want = np.array([car["boxes"][k] for k in frames])
            got = ds.ado[i, frames, slot]
            assert np.abs(got[:, [0, 1, 3, 4]] - want[:, [0, 1, 3, 4]]).max() < 1e-3
            assert np.abs(wrap(got[:, 2] - want[:, 2])).max() < 1e-5
    labels = [c["label"] for c in _vehicles(truth["scene-0061"]["agents"])]
    assert sorted(labels) == ["bike", "car_lead", "car_oncoming"]  # the bicycle is an ado


def test_too_many_vehicles_keep_the_nearest(dataroot, tmp_path):
    root, truth = dataroot
    import_nuscenes(root, VERSION, tmp_path / "one.npz", scenes=["scene-0061"], max_ados=1)
    ds = world.load(tmp_path / "one.npz")
    ego = truth["scene-0061"]["poses"][:40]
    cars = _vehicles(truth["scene-0061"]["agents"])
    near = [min(math.hypot(b[0] - ego[k, 0], b[1] - ego[k, 1]) for k, b in c["boxes"].items()
                if k < 40) for c in cars]
    best = cars[int(np.argmin(near))]
    assert best["label"] == "bike"  # parked at the kerb the ego passes
    k = min(best["boxes"])
    assert np.allclose(ds.ado[0, k, 0, :2], best["boxes"][k][:2], atol=1e-3)
    assert ds.tags[0]["n_vehicles_dropped"] == 2 and ds.ado.shape[2] == 1


def test_map_classes_lanes_and_route(imported):
    truth, _, ds = imported
    cx, cy = CENTRE
    m = ds.maps[0]
    grid, origin, res = class_grid(m, 0.25)

    def cls(x, y):
        return int(grid[int((y - origin[1]) / res), int((x - origin[0]) / res)])

    assert cls(cx + 1.75, cy - 50) == 1  # road
    assert cls(cx + 3.3, cy - 50) == 1  # walkway under the drivable area
    assert cls(cx + 5.5, cy - 50) == 3  # walkway
    assert cls(cx + 10.0, cy - 50) == 0
    assert cls(cx + 25.0, cy - 25) == 1  # plaza
    assert cls(cx + 40.0, cy - 40) == 0  # its hole
    assert cls(cx + 0.0, cy + 14.5) == 2  # crossing
    assert len(m.recipe["walkway_polygons"]) == 1  # the far one is left out
    top = max(np.asarray(p)[:, 1].max() for p in m.recipe["polygons"])
    assert top == pytest.approx(truth["scene-0061"]["poses"][:41, 1].max() + MARGIN, abs=0.01)
    lanes = {ln["token"]: ln for ln in m.recipe["lanes"]}
    turn = np.asarray(lanes[lane_token("conn_s_w")]["points"])
    assert np.abs(np.hypot(turn[:, 0] - (cx - 10), turn[:, 1] - (cy - 10)) - 11.75).max() < 0.02
    assert lanes[lane_token("conn_s_w")]["kind"] == "connector"
    west = m.lanes[list(lanes).index(lane_token("lane_w_out"))]
    assert np.allclose(np.cos(west.heads), -1.0, atol=1e-6)  # the raster's hue: westbound
    for i, route in enumerate((["lane_s_in", "conn_s_w", "lane_w_out"],
                               ["lane_s_in", "conn_s_n", "lane_n_out"])):
        rec = ds.maps[i].recipe
        assert [rec["lanes"][j]["token"] for j in rec["route"]] == [lane_token(k) for k in route]
        assert ds.tags[i]["has_junction"] and ds.tags[i]["kind"] == "intersection"


def test_lane_target_and_goal(imported):
    truth, _, ds = imported
    # scene-0103 drives north 0.3 m right of the lane centre: the targets are 0.3 m left
    want = np.stack([4.0 * np.arange(1, 11), np.full(10, 0.3)], axis=1)
    assert np.abs(ds.lane_target[1] - want[None]).max() < 0.02
    p = truth["scene-0103"]["poses"]
    assert np.allclose(ds.goal[1, :, 0], p[39, 1] - p[:40, 1], atol=2e-3)
    assert np.allclose(ds.goal[1, :, 1:], 0.0, atol=2e-3)


def test_shards_stream_the_same_dataset(dataroot, tmp_path):
    root, _ = dataroot
    one = import_nuscenes(root, VERSION, tmp_path / "a.npz", shard_scenes=1).path
    two = import_nuscenes(root, VERSION, tmp_path / "b.npz").path
    with zipfile.ZipFile(one) as z:
        assert {"ego-00000.npy", "ego-00001.npy"} <= set(z.namelist())
    assert world.file_content_hash(one) == world.file_content_hash(two)


# --------------------------------------------------------------------------- bad input


def _edit(root, table, fn):
    path = root / VERSION / f"{table}.json"
    path.write_text(json.dumps(fn(json.loads(path.read_text()))))


@pytest.mark.parametrize("case, match", [
    ("corrupt", r"table 'sample_annotation':.*sample_annotation\.json is not valid JSON"),
    ("no_expansion", r"map expansion .*boston-seaport\.json is missing: download"),
    ("no_ego_pose", r"table 'ego_pose' of .* has no record"),
    ("no_category", r"table 'category' of .* has no record"),
    ("not_in_split", r"scene 'scene-0001' is not in the v1\.0-mini splits"),
    ("not_in_tables", r"scene 'scene-0796' is not in .*scene\.json"),
    ("all_skipped", r"no scene could be imported: scene-0553: 39 keyframes"),
    ("no_tables", r"has no folder v1\.0-trainval/"),
])
def test_bad_input_one_line_error_and_no_file(tmp_path, case, match):
    root = tmp_path / "root"
    write_sample(root)
    version, scenes = VERSION, None
    if case == "corrupt":
        path = root / VERSION / "sample_annotation.json"
        path.write_text(path.read_text()[:-40])
    elif case == "no_expansion":
        (root / "maps" / "expansion" / f"{LOCATION}.json").unlink()
    elif case == "no_ego_pose":
        _edit(root, "ego_pose", lambda rows: rows[5:])
    elif case == "no_category":
        _edit(root, "category", lambda rows: [r for r in rows if r["name"] != "vehicle.bicycle"])
    elif case == "not_in_split":
        scenes = ["scene-0001"]
    elif case == "not_in_tables":
        scenes = ["scene-0796"]
    elif case == "all_skipped":
        scenes = ["scene-0553"]
    else:
        version = "v1.0-trainval"
    out = tmp_path / "out"
    with pytest.raises(NuScenesError, match=match) as err:
        import_nuscenes(root, version, out / "ns.npz", scenes=scenes)
    assert "\n" not in str(err.value)
    assert not out.exists() or list(out.iterdir()) == []


# --------------------------------------------------------------------------- the command


def test_cli_import_nuscenes(dataroot, tmp_path, capsys, monkeypatch):
    root, _ = dataroot
    out = tmp_path / "d" / "ns.npz"
    reads = []

    class Counted(MapExpansion):
        def __init__(self, *a):
            reads.append(a)
            super().__init__(*a)

    monkeypatch.setattr(importer, "MapExpansion", Counted)
    assert main(["data", "import-nuscenes", str(root), "--version", VERSION, "--out", str(out),
                 "--quiet"]) == 0
    cap = capsys.readouterr()
    assert "estimate for 5 scenes: about " in cap.err  # before knowing three are skipped
    assert "measured on scene-0061" in cap.err
    assert "imported 2 scene(s)" in cap.out and "skipped scene-0553: 39 keyframes" in cap.out
    ds = world.load(out)
    assert ds.tags[0]["scene"] == "scene-0061" and "content hash" in cap.out
    assert len(reads) == 1  # the estimate's map expansion is reused by the import
    assert main(["data", "import-nuscenes", str(root), "--version", VERSION, "--out", str(out),
                 "--quiet", "--scenes", "scene-0103"]) == 0
    assert [t["scene"] for t in world.load(out).tags] == ["scene-0103"]
    show = tmp_path / "show"  # chapter 7's gallery, animation and map plot of an imported file
    assert main(["data", "show", "--data", str(out), "--out", str(show)]) == 0
    assert sorted(p.name for p in show.iterdir()) == ["gallery.png", "scene.gif",
                                                     "scene_map.png"]
    assert sorted(p.name for p in out.parent.iterdir()) == ["ns.npz"]  # no temporary left


def _one_line_error(capsys, argv):
    code = main(argv)
    err = [ln for ln in capsys.readouterr().err.splitlines() if not ln.startswith("estimate")]
    assert code == 2 and len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def test_cli_bad_input_is_one_line_exit_2(dataroot, tmp_path, capsys, monkeypatch):
    root, _ = dataroot
    out = tmp_path / "o" / "ns.npz"
    base = ["data", "import-nuscenes", str(root), "--out", str(out), "--quiet"]
    line = _one_line_error(capsys, [*base, "--version", "v2.0"])
    assert line == ("minimanc data: error: --version must be one of v1.0-mini, v1.0-trainval, "
                    "got 'v2.0'")
    line = _one_line_error(capsys, [*base, "--version", VERSION, "--scenes", "scene-0001"])
    assert "scene 'scene-0001' is not in the v1.0-mini splits" in line
    line = _one_line_error(capsys, ["data", "import-nuscenes", str(tmp_path / "none"),
                                    "--version", VERSION, "--out", str(out), "--quiet"])
    assert "is not a directory" in line
    Usage = namedtuple("Usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda p: Usage(10**9, 10**9 - 10**3, 10**3))
    line = _one_line_error(capsys, [*base, "--version", VERSION])
    assert "not enough free disk space" in line
    assert not out.exists() and (not out.parent.exists() or list(out.parent.iterdir()) == [])


def test_streaming_memory_does_not_grow_with_the_scenes(tmp_path):
    """Twice 8 copies of the scenes in trainval's splits: shards of 2 scenes, training
    split first; the memory the import allocates on top of its (read) tables stays put."""
    peaks = {}
    for copies in (2, 8):
        root = tmp_path / f"copies{copies}"
        write_sample(root, "v1.0-trainval", copies)
        tables = Tables(root, "v1.0-trainval")
        tracemalloc.start()
        report = import_nuscenes(root, "v1.0-trainval", root / "o.npz", shard_scenes=2,
                                 raster=world.RasterConfig(size=32), tables=tables)
        peaks[copies] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert len(report.imported) == 2 * copies and len(report.skipped) == 3 * copies
        ds = world.load(report.path)
        assert [t["split"] for t in ds.tags] == ["train"] * copies + ["val"] * copies
        with zipfile.ZipFile(report.path) as z:
            assert sum(n.startswith("bev-") for n in z.namelist()) == copies  # 2 per shard
    assert peaks[8] < 1.2 * peaks[2], peaks


def test_the_replay_protocol_runs_on_imported_scenes(imported):
    """The closed loop and the metrics of chapter 8 on an imported file: the logged human
    replayed is on the road, collision-free and on its route; a policy drives it."""
    from minimanc import metrics, models, rollout

    _, _, ds = imported
    human = metrics.evaluate(rollout.human(ds, agents="replay"), ds)
    assert human["ade"] == 0.0 and human["off_road_rate"] == 0.0
    assert human["collision_rate"] == 0.0 and human["route_progress"] == pytest.approx(1.0)
    prior = rollout.fixed_gains(ds, cfg=models.ModelConfig(n_states=4, input_shape=(64, 64, 3)),
                                agents="replay")
    assert np.asarray(prior.ego).shape == ds.ego.shape and np.all(np.isfinite(prior.ego))
    assert np.isfinite(metrics.evaluate(prior, ds)["ade"])


def test_simulators_of_generated_scenes_refuse_recorded_ones(imported):
    """The reactive ados, the style floor and the expert re-draw a generated scene from its
    seed; an imported scene (attempts 0: no draw) is refused, never swapped for a generated
    one (the bounds say why: the dataset is recorded)."""
    from minimanc import rollout
    from minimanc.diagnose import bounds

    _, _, ds = imported
    assert ds.meta["attempts"] == [0, 0] and ds.meta["source"] == "nuscenes"
    with pytest.raises(ValueError, match="attempt"):
        rollout.human(ds, agents="reactive")
    with pytest.raises(ValueError, match=r"style floor re-drives .* recorded \(nuscenes\)"):
        bounds.floor_rollout(ds, bounds.median_style(50))
    with pytest.raises(ValueError, match=r"expert re-drives .* recorded \(nuscenes\)"):
        bounds.expert_rollout(ds, agents="replay")
    with pytest.raises(ValueError, match=r"demonstrations re-drives .* recorded \(nuscenes\)"):
        bounds.privileged_learner(ds)


def test_train_and_drive_on_imported_scenes(dataroot, tmp_path):
    """Behaviour cloning (chapter 8) on an imported file, then the trained MANC driving its
    scenes in closed loop under the replay protocol."""
    from minimanc import metrics, models, rollout, train

    root, _ = dataroot
    import_nuscenes(root, VERSION, tmp_path / "ns.npz", raster=world.RasterConfig(size=32))
    ds = world.load(tmp_path / "ns.npz")
    cfg = models.ModelConfig(input_shape=(32, 32, 3), channels=(4, 8), n_predicates=4, n_states=3,
                             hidden=8)
    tc = train.TrainConfig(epochs=1, batch_size=2, seq_len=4, dmp_seq_len=4, dtype="float64",
                           max_steps_per_epoch=2)
    fit = train.fit("manc", ds, cfg, tc, engine="numpy", progress=False)
    assert fit.steps == 2 and np.isfinite(fit.history).all()
    policy = rollout.ModelPolicy("manc", fit.params, cfg, "numpy")
    traj = rollout.simulate(policy, ds, progress=False, agents="replay")
    assert np.asarray(traj.ego).shape == ds.ego.shape and np.all(np.isfinite(traj.ego))
    assert np.isfinite(metrics.evaluate(traj, ds)["ade"])


@pytest.mark.parametrize("kwargs, message", [
    ({"version": "v1.0-test"}, "the sample has versions v1.0-mini, v1.0-trainval; got "
                               "version='v1.0-test'"),
    ({"copies": 2}, "copies=2 needs version='v1.0-trainval'"),
    ({"version": "v1.0-trainval", "copies": 0}, "copies"),
])
def test_write_sample_refuses_bad_arguments(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=re.escape(message)) as err:
        write_sample(tmp_path / "root", **kwargs)
    assert "\n" not in str(err.value)
    assert not (tmp_path / "root").exists()
