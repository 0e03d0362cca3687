"""The nuScenes reader's parts: the official splits, arcline discretisation, polygon clipping,
quaternion yaw and bad input."""

import json
import math

import numpy as np
import pytest

from minimanc.world.nuscenes import (
    NuScenesError,
    Tables,
    clip_polygon,
    discretize_arcline,
    read_records,
    scene_split,
    simplify_polyline,
    split_lists,
    yaw_of,
)


def test_official_splits():
    s = split_lists()
    assert (len(s["train"]), len(s["val"]), len(s["mini_train"]), len(s["mini_val"])) == \
        (700, 150, 8, 2)
    assert not set(s["train"]) & set(s["val"])
    assert scene_split("v1.0-mini", "scene-0103") == "mini_val"
    assert scene_split("v1.0-mini", "scene-0001") is None


def test_arcline_left_quarter_circle():
    r = 10.0
    path = {"start_pose": [1.0, 2.0, 0.0], "shape": "LSL", "radius": r,
            "segment_length": [r * math.pi / 2, 0.0, 0.0]}
    p = discretize_arcline(path)
    assert np.allclose(p[-1], [1.0 + r, 2.0 + r, math.pi / 2], atol=1e-9)
    assert np.allclose(np.hypot(p[:, 0] - 1.0, p[:, 1] - 12.0), r)
    assert np.max(np.hypot(*np.diff(p[:, :2], axis=0).T)) <= 1.0


def test_arcline_straight_then_right():
    path = {"start_pose": [0.0, 0.0, 0.0], "shape": "RSR", "radius": 5.0,
            "segment_length": [0.0, 7.0, 5.0 * math.pi / 2]}
    p = discretize_arcline(path)
    assert np.allclose(p[-1], [12.0, -5.0, -math.pi / 2], atol=1e-9)


def test_clip_polygon():
    sq = np.array([[-1, -1], [3, -1], [3, 3], [-1, 3]], dtype=float)
    c = clip_polygon(sq, (0, 0, 2, 2))
    x, y = c[:, 0], c[:, 1]
    assert 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))) == pytest.approx(4.0)
    assert len(clip_polygon(sq, (10, 10, 12, 12))) == 0


def test_yaw_of():
    a = 0.7
    assert yaw_of([math.cos(a / 2), 0, 0, math.sin(a / 2)]) == pytest.approx(a)


def test_bad_dataroot(tmp_path):
    with pytest.raises(NuScenesError, match="version must be one of"):
        Tables(tmp_path, "v2.0")
    with pytest.raises(NuScenesError, match="no folder v1.0-mini"):
        Tables(tmp_path, "v1.0-mini")
    (tmp_path / "v1.0-mini").mkdir()
    with pytest.raises(NuScenesError, match="table 'scene'.*missing"):
        Tables(tmp_path, "v1.0-mini")
    (tmp_path / "v1.0-mini" / "scene.json").write_text("[{")
    with pytest.raises(NuScenesError, match="not valid JSON"):
        Tables(tmp_path, "v1.0-mini")
    (tmp_path / "v1.0-mini" / "scene.json").write_text(json.dumps([]))
    with pytest.raises(NuScenesError, match="table 'sample'.*missing"):
        Tables(tmp_path, "v1.0-mini")


def test_simplify_polyline():
    line = np.stack([np.linspace(0, 99, 100), 0.5 * np.linspace(0, 99, 100)], axis=1)
    assert np.array_equal(simplify_polyline(line), line[[0, -1]])
    a = np.linspace(0.0, np.pi / 2, 200)
    arc = np.stack([20 * np.cos(a), 20 * np.sin(a)], axis=1)
    kept = simplify_polyline(arc, 0.01)
    assert 2 < len(kept) < len(arc) and np.array_equal(kept[[0, -1]], arc[[0, -1]])
    # every point left out lies within 1 cm of the chord of the kept points around it
    for p in arc:
        d = [abs((b - a)[0] * (p - a)[1] - (b - a)[1] * (p - a)[0]) / np.linalg.norm(b - a)
             for a, b in zip(kept[:-1], kept[1:]) if np.dot(p - a, b - a) >= -1e-9
             and np.dot(p - b, a - b) >= -1e-9]
        assert min(d) <= 0.01 + 1e-12


def test_read_records(tmp_path):
    path = tmp_path / "t.json"
    rows = [{"token": f"t{i}", "k": i % 2 == 0, "v": [1.5, None]} for i in range(5)]
    path.write_text(json.dumps(rows, indent=1))
    assert read_records(path, "table") == rows
    assert read_records(path, "table", lambda r: r["k"]) == rows[::2]
    path.write_text(" [ ] \n")
    assert read_records(path, "table") == []
    for text, match in [("", "not valid JSON: Expecting value at line 1 column 1"),
                        ('[{"token": 1}', "not valid JSON: Expecting ',' delimiter"),
                        ('[{"token": 1},]', "Illegal trailing comma"),
                        ('[{"token": 1}] x', "Extra data at line 1 column 16"),
                        ('[{"token": 1}\n {"token": 2}]', "Expecting ',' delimiter at line 2"),
                        ('[{"tok', "not valid JSON"),
                        ('{"token": 1}', "must hold a list of records with a 'token'"),
                        ('[{"token": 1}, 3]', "must hold a list of records")]:
        path.write_text(text)
        with pytest.raises(NuScenesError, match=match):
            read_records(path, "table 'x':")
        try:  # the same verdict as the standard library's parser
            ok = isinstance(json.loads(text), list)
        except json.JSONDecodeError:
            ok = False
        assert not ok or "must hold" in match
    with pytest.raises(NuScenesError, match="is missing"):
        read_records(tmp_path / "none.json", "table")
