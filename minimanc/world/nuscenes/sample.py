"""Chapter 7 — a nuScenes sample to try the importer without a download: a tiny made-up
DATAROOT in the exact nuScenes schema, not real data.

:func:`write_sample` writes ``DATAROOT/v1.0-mini/*.json`` (all thirteen tables of the
devkit's ``schema.md``, every field) and ``DATAROOT/maps/expansion/boston-seaport.json``
(the map expansion v1.3: every layer the devkit's ``NuScenesMap`` loads, geometry as
``node``/``line``/``polygon`` tokens, ``arcline_path_3`` centrelines and ``connectivity``),
and the other three locations' expansions with every layer empty. Every record, scene and
map element is invented (only the scene *names* are those of the official splits, so that
the split lists apply); the importer reads it exactly as it reads the real download
(:func:`minimanc.world.nuscenes.import_nuscenes`), and so does the devkit. The tests check
the importer against it and against the devkit on it.

The map is a T junction at ``CENTRE`` in right-hand traffic: a north-south road with one
lane per direction (lanes at ``x = cx +- 1.75``), a west arm, six lane connectors (straight
on, left and right turns), a drivable area (the roads, plus a plaza with a hole), a walkway
along the east side of the south arm overlapping the road's edge by 0.6 m (and one 500 m
away, outside every scene's map), and a pedestrian crossing over the north arm.

Scenes (names of the official ``mini`` splits):

* ``scene-0061`` (mini_train): 42 keyframes (a 1.0 s gap before the last, which is not
  used), the ego drives north and turns left onto the
  west arm; a car leads it, a car comes the other way (keyframes 2-20 only), a bicycle is
  parked at the kerb, a pedestrian walks on the walkway, a barrier stands at the corner;
* ``scene-0103`` (mini_val): exactly 40 keyframes, the ego waits 2 s, then drives straight
  on behind a car; a pedestrian stands on the crossing;
* ``scene-0553`` (mini_train): 39 keyframes (too short);
* ``scene-0655`` (mini_train): 41 keyframes with a 1.0 s gap after keyframe 20;
* ``scene-0757`` (mini_train): 41 keyframes in the plaza, far from every lane.

The ``map`` table's semantic-prior mask is a blank 16 x 16 PNG (the devkit opens it).
Each keyframe has a ``LIDAR_TOP`` keyframe ``sample_data`` (whose ``ego_pose`` is the
truth), a ``CAM_FRONT`` keyframe 50 ms earlier and a ``LIDAR_TOP`` sweep (not a keyframe)
250 ms later, each with its own ``ego_pose``, so that reading the wrong one is detected.
Ego rotations carry a small roll and pitch. The truth (poses, stamps, boxes) is returned.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
from PIL import Image

from minimanc.checks import check_int
from minimanc.world.nuscenes.splits import split_lists

__all__ = ["CATEGORIES", "CENTRE", "LOCATION", "OTHER_LOCATIONS", "SAMPLE_VERSIONS", "SIZES",
           "SUCCESSORS", "VERSION", "Path2D", "lane_token", "quat", "token", "write_sample"]

CENTRE = (600.0, 1200.0)
VERSION = "v1.0-mini"
SAMPLE_VERSIONS = (VERSION, "v1.0-trainval")
LOCATION = "boston-seaport"
OTHER_LOCATIONS = ("singapore-onenorth", "singapore-hollandvillage", "singapore-queenstown")
BASE_US = 1533151603547590


def token(*parts: object) -> str:
    """The sample's tokens: the MD5 hex digest of the parts joined by ``/`` (stable)."""
    return hashlib.md5("/".join(map(str, parts)).encode()).hexdigest()


def quat(yaw: float, pitch: float = 0.0, roll: float = 0.0) -> list[float]:
    """``[w, x, y, z]`` of ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy]


# --------------------------------------------------------------------------- paths


class Path2D:
    """A dense polyline with exact headings, posed at arc length ``s`` by interpolation."""

    def __init__(self, pieces: list[tuple]) -> None:
        pts, hds = [], []
        for p in pieces:
            if p[0] == "line":
                _, (x0, y0), h, length = p
                u = np.linspace(0.0, length, int(length / 0.05) + 1)
                pts.append(np.stack([x0 + u * math.cos(h), y0 + u * math.sin(h)], 1))
                hds.append(np.full(len(u), h))
            else:  # ("arc", centre, radius, angle0, angle1): counter-clockwise if a1 > a0
                _, (cx, cy), r, a0, a1 = p
                a = np.linspace(a0, a1, int(abs(a1 - a0) * r / 0.05) + 1)
                pts.append(np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], 1))
                hds.append(a + (math.pi / 2 if a1 > a0 else -math.pi / 2))
        self.p = np.concatenate(pts)
        self.h = np.unwrap(np.concatenate(hds))
        self.s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(self.p, axis=0).T))])

    def pose(self, s: float) -> tuple[float, float, float]:
        x = float(np.interp(s, self.s, self.p[:, 0]))
        y = float(np.interp(s, self.s, self.p[:, 1]))
        h = float(np.interp(s, self.s, self.h))
        return x, y, math.remainder(h, 2 * math.pi)


def left_turn_path(off: float) -> Path2D:
    """North on the south arm, left onto the west arm, ``off`` metres right of the lanes."""
    cx, cy = CENTRE
    r = 11.75 + off
    return Path2D([("line", (cx + 1.75 + off, cy - 80.0), math.pi / 2, 70.0),
                   ("arc", (cx - 10.0, cy - 10.0), r, 0.0, math.pi / 2),
                   ("line", (cx - 10.0, cy - 10.0 + r), math.pi, 110.0)])


def straight_path(off: float, y0: float = -70.0) -> Path2D:
    cx, cy = CENTRE
    return Path2D([("line", (cx + 1.75 + off, cy + y0), math.pi / 2, 200.0)])


def southbound_path() -> Path2D:
    cx, cy = CENTRE
    return Path2D([("line", (cx - 1.75, cy + 40.0), -math.pi / 2, 200.0)])


# --------------------------------------------------------------------------- scenes

CATEGORIES = ("vehicle.car", "vehicle.bicycle", "vehicle.truck", "human.pedestrian.adult",
              "movable_object.barrier")
SIZES = {"vehicle.car": (1.9, 4.5, 1.6), "vehicle.bicycle": (0.6, 1.8, 1.2),
         "human.pedestrian.adult": (0.7, 0.7, 1.75), "movable_object.barrier": (2.5, 0.5, 1.0)}


def _stamps(n: int, gap_after: int | None = None) -> np.ndarray:
    dts = 0.5 + 0.02 * np.sin(np.arange(n - 1))  # keyframes about 2 Hz, as recorded
    if gap_after is not None:
        dts[gap_after] = 1.0
    return np.concatenate([[0.0], np.cumsum(dts)])


def _scene_specs() -> list[dict]:
    cx, cy = CENTRE
    a_path, a_t = left_turn_path(0.3), _stamps(42, gap_after=40)  # after the 41 used
    a_s = lambda t: 6.0 * t + 3.0 * math.sin(0.3 * t)  # noqa: E731  speed 6 +- 0.9 m/s
    lead = left_turn_path(0.0)
    south = southbound_path()

    b_t = _stamps(40)

    def b_s(t: float) -> float:  # waits 2 s, accelerates at 1.5 m/s^2 to 8 m/s
        u = max(t - 2.0, 0.0)
        ramp = 8.0 / 1.5
        return 0.75 * u * u if u < ramp else 0.75 * ramp * ramp + 8.0 * (u - ramp)

    b_path = straight_path(0.3)
    car_b = straight_path(0.0)
    const = lambda t: 5.0 * t  # noqa: E731
    return [
        {"name": "scene-0061", "log": 0, "t": a_t, "path": a_path, "s": a_s, "agents": [
            {"label": "car_lead", "category": "vehicle.car", "frames": range(42),
             "pose": lambda t: lead.pose(a_s(t) + 15.0)},
            {"label": "car_oncoming", "category": "vehicle.car", "frames": range(2, 21),
             "pose": lambda t: south.pose(7.0 * (t - a_t[2]))},
            {"label": "bike", "category": "vehicle.bicycle", "frames": range(42),
             "pose": lambda t: (cx + 3.5, cy - 30.0, math.pi / 2)},
            {"label": "ped", "category": "human.pedestrian.adult", "frames": range(42),
             "pose": lambda t: (cx + 5.5, cy - 60.0 + 1.2 * t, math.pi / 2)},
            {"label": "barrier", "category": "movable_object.barrier", "frames": range(42),
             "pose": lambda t: (cx + 3.3, cy - 5.0, 0.0)}]},
        {"name": "scene-0103", "log": 0, "t": b_t, "path": b_path, "s": b_s, "agents": [
            {"label": "car_b", "category": "vehicle.car", "frames": range(40),
             "pose": lambda t: car_b.pose(b_s(t) + 20.0)},
            {"label": "ped_b", "category": "human.pedestrian.adult", "frames": range(11),
             "pose": lambda t: (cx - 3.0, cy + 14.5, 0.0)}]},
        {"name": "scene-0553", "log": 1, "t": _stamps(39), "path": straight_path(0.0),
         "s": const, "agents": []},
        {"name": "scene-0655", "log": 1, "t": _stamps(41, gap_after=20),
         "path": straight_path(0.0), "s": const, "agents": []},
        {"name": "scene-0757", "log": 1, "t": _stamps(41), "s": lambda t: 1.0 * t,
         "path": Path2D([("line", (cx + 25.0, cy - 50.0), 0.0, 100.0)]), "agents": []},
    ]


# --------------------------------------------------------------------------- the tables


def _specs(version: str, copies: int) -> list[dict]:
    """The four scenes (``v1.0-mini``), or ``copies`` of each under the names of the
    ``v1.0-trainval`` splits (scene-0103's copies in ``val``, the others in ``train``)."""
    specs = _scene_specs()
    if version == VERSION:
        return specs
    lists = split_lists()
    train, val = iter(lists["train"]), iter(lists["val"])
    return [{**sp, "name": next(val if sp["name"] == "scene-0103" else train)}
            for _ in range(copies) for sp in specs]


def _tables(version: str, copies: int) -> tuple[dict[str, list[dict]], dict]:
    T: dict[str, list[dict]] = {k: [] for k in (
        "attribute", "calibrated_sensor", "category", "ego_pose", "instance", "log", "map",
        "sample", "sample_annotation", "sample_data", "scene", "sensor", "visibility")}
    for name in ("vehicle.moving", "vehicle.parked", "cycle.without_rider",
                 "pedestrian.moving"):
        T["attribute"].append({"token": token("attribute", name), "name": name,
                               "description": name.replace(".", " ")})
    for i, level in enumerate(("v0-40", "v40-60", "v60-80", "v80-100"), start=1):
        T["visibility"].append({"token": str(i), "level": level,
                                "description": f"visibility of whole object is {level}"})
    for name in CATEGORIES:
        T["category"].append({"token": token("category", name), "name": name,
                              "description": name.replace(".", " ")})
    sensors = {"LIDAR_TOP": "lidar", "CAM_FRONT": "camera"}
    for ch, modality in sensors.items():
        T["sensor"].append({"token": token("sensor", ch), "channel": ch, "modality": modality})
    for lg in range(2):
        T["log"].append({"token": token("log", lg),
                         "logfile": f"n008-2018-08-0{lg + 1}-15-16-36-0400",
                         "vehicle": "n008", "date_captured": f"2018-08-0{lg + 1}",
                         "location": LOCATION})
        for ch in sensors:
            T["calibrated_sensor"].append({
                "token": token("calibrated_sensor", lg, ch), "sensor_token": token("sensor", ch),
                "translation": [0.94, 0.0, 1.84] if ch == "LIDAR_TOP" else [1.7, 0.0, 1.5],
                "rotation": quat(-math.pi / 2) if ch == "LIDAR_TOP" else
                [0.5, -0.5, 0.5, -0.5],
                "camera_intrinsic": [] if ch == "LIDAR_TOP" else
                [[1266.4, 0.0, 816.3], [0.0, 1266.4, 491.5], [0.0, 0.0, 1.0]]})
    T["map"].append({"token": token("map", LOCATION), "log_tokens": [token("log", 0),
                                                                     token("log", 1)],
                     "category": "semantic_prior",
                     "filename": f"maps/{token('map png', LOCATION)}.png"})
    truth: dict = {}
    for si, spec in enumerate(_specs(version, copies)):
        name, stamps = spec["name"], spec["t"] + 40.0 * si
        n = len(stamps)
        us = [BASE_US + int(round(t * 1e6)) for t in stamps]
        log_tok = token("log", spec["log"])
        sample_toks = [token(name, "sample", k) for k in range(n)]
        scene_tok = token(name, "scene")
        T["scene"].append({"token": scene_tok, "log_token": log_tok, "nbr_samples": n,
                           "first_sample_token": sample_toks[0],
                           "last_sample_token": sample_toks[-1], "name": name,
                           "description": f"fixture scene {name}"})
        t0 = stamps[0]
        poses = np.array([spec["path"].pose(spec["s"](t - t0)) for t in stamps])
        chains: dict[str, list[dict]] = {"LIDAR_TOP": [], "CAM_FRONT": []}
        for k in range(n):
            T["sample"].append({"token": sample_toks[k], "timestamp": us[k],
                                "scene_token": scene_tok,
                                "next": sample_toks[k + 1] if k + 1 < n else "",
                                "prev": sample_toks[k - 1] if k else ""})
            frames = [("LIDAR_TOP", True, 0.0), ("CAM_FRONT", True, -0.05)]
            if k + 1 < n:
                frames.append(("LIDAR_TOP", False, 0.25))
            for ch, key, dt in frames:
                t = stamps[k] + dt
                x, y, h = spec["path"].pose(max(spec["s"](t - t0), 0.0))
                t_us = us[k] + int(round(dt * 1e6))
                ep = token(name, "ego_pose", ch, k, key)
                T["ego_pose"].append({"token": ep, "timestamp": t_us,
                                      "rotation": quat(h, 0.02 * math.cos(k), 0.01 * math.sin(k)),
                                      "translation": [x, y, 0.0]})
                sd = {"token": token(name, "sample_data", ch, k, key),
                      "sample_token": sample_toks[k if key else k + 1], "ego_pose_token": ep,
                      "calibrated_sensor_token": token("calibrated_sensor", spec["log"], ch),
                      "timestamp": t_us, "fileformat": "pcd" if ch == "LIDAR_TOP" else "jpg",
                      "is_key_frame": key, "height": 0 if ch == "LIDAR_TOP" else 900,
                      "width": 0 if ch == "LIDAR_TOP" else 1600,
                      "filename": (f"{'samples' if key else 'sweeps'}/{ch}/n008__{ch}__{t_us}"
                                   + (".pcd.bin" if ch == "LIDAR_TOP" else ".jpg")),
                      "prev": "", "next": ""}
                chains[ch].append(sd)
        for chain in chains.values():
            chain.sort(key=lambda r: r["timestamp"])
            for a, b in zip(chain[:-1], chain[1:]):
                a["next"], b["prev"] = b["token"], a["token"]
            T["sample_data"] += chain
        agents = []
        for ag in spec["agents"]:
            inst = token(name, "instance", ag["label"])
            w, ln, ht = SIZES[ag["category"]]
            frames = list(ag["frames"])
            ann_toks = [token(name, "ann", ag["label"], k) for k in frames]
            boxes = {}
            for j, k in enumerate(frames):
                x, y, h = ag["pose"](stamps[k] - t0)
                boxes[k] = (x, y, h, ln, w)
                T["sample_annotation"].append({
                    "token": ann_toks[j], "sample_token": sample_toks[k], "instance_token": inst,
                    "visibility_token": "4", "attribute_tokens": [],
                    "translation": [x, y, ht / 2], "size": [w, ln, ht], "rotation": quat(h),
                    "prev": ann_toks[j - 1] if j else "",
                    "next": ann_toks[j + 1] if j + 1 < len(frames) else "",
                    "num_lidar_pts": 40, "num_radar_pts": 2})
            T["instance"].append({"token": inst,
                                  "category_token": token("category", ag["category"]),
                                  "nbr_annotations": len(frames),
                                  "first_annotation_token": ann_toks[0],
                                  "last_annotation_token": ann_toks[-1]})
            agents.append({"label": ag["label"], "category": ag["category"],
                           "instance_token": inst, "boxes": boxes})
        truth[name] = {"poses": poses, "stamps": stamps, "agents": agents, "token": scene_tok}
    return T, truth


# --------------------------------------------------------------------------- map expansion


class _Expansion:
    def __init__(self) -> None:
        self.layers: dict = {k: [] for k in (
            "polygon", "line", "node", "drivable_area", "road_segment", "road_block", "lane",
            "ped_crossing", "walkway", "stop_line", "carpark_area", "road_divider",
            "lane_divider", "traffic_light", "lane_connector")}
        self.layers["arcline_path_3"] = {}
        self.layers["connectivity"] = {}

    def node(self, x: float, y: float) -> str:
        t = token("node", len(self.layers["node"]))
        self.layers["node"].append({"token": t, "x": float(x), "y": float(y)})
        return t

    def polygon(self, ring, holes=()) -> str:
        t = token("polygon", len(self.layers["polygon"]))
        self.layers["polygon"].append({
            "token": t, "exterior_node_tokens": [self.node(*p) for p in ring],
            "holes": [{"node_tokens": [self.node(*p) for p in h]} for h in holes]})
        return t

    def line(self, pts) -> str:
        t = token("line", len(self.layers["line"]))
        self.layers["line"].append({"token": t, "node_tokens": [self.node(*p) for p in pts]})
        return t


def _arc_points(start, h: float, sign: int, r: float, length: float, n: int = 8):
    """Points of a straight (``sign`` 0) or an arc of ``length`` from pose ``start, h``."""
    out = []
    for u in np.linspace(0.0, length, n):
        if sign == 0:
            out.append((start[0] + u * math.cos(h), start[1] + u * math.sin(h)))
        else:
            k = sign / r
            out.append((start[0] + (math.sin(h + k * u) - math.sin(h)) / k,
                        start[1] - (math.cos(h + k * u) - math.cos(h)) / k))
    return out


# lane label: (start xy relative to the centre, heading, turn sign, radius, length, pieces)
def _lane_specs() -> dict[str, tuple]:
    q = math.pi / 2
    return {
        "lane_s_in": ((1.75, -120.0), q, 0, 999.0, 110.0, (60.0, 50.0)),
        "lane_s_out": ((-1.75, -10.0), -q, 0, 999.0, 110.0, (110.0,)),
        "lane_n_in": ((-1.75, 120.0), -q, 0, 999.0, 110.0, (110.0,)),
        "lane_n_out": ((1.75, 10.0), q, 0, 999.0, 110.0, (110.0,)),
        "lane_w_in": ((-120.0, -1.75), 0.0, 0, 999.0, 110.0, (110.0,)),
        "lane_w_out": ((-10.0, 1.75), math.pi, 0, 999.0, 110.0, (110.0,)),
        "conn_s_n": ((1.75, -10.0), q, 0, 999.0, 20.0, (20.0,)),
        "conn_s_w": ((1.75, -10.0), q, 1, 11.75, 11.75 * q, (11.75 * q,)),
        "conn_n_s": ((-1.75, 10.0), -q, 0, 999.0, 20.0, (20.0,)),
        "conn_n_w": ((-1.75, 10.0), -q, -1, 8.25, 8.25 * q, (8.25 * q,)),
        "conn_w_s": ((-10.0, -1.75), 0.0, -1, 8.25, 8.25 * q, (8.25 * q,)),
        "conn_w_n": ((-10.0, -1.75), 0.0, 1, 11.75, 11.75 * q, (11.75 * q,)),
    }


SUCCESSORS = {"lane_s_in": ["conn_s_n", "conn_s_w"], "lane_n_in": ["conn_n_s", "conn_n_w"],
              "lane_w_in": ["conn_w_s", "conn_w_n"], "conn_s_n": ["lane_n_out"],
              "conn_s_w": ["lane_w_out"], "conn_n_s": ["lane_s_out"],
              "conn_n_w": ["lane_w_out"], "conn_w_s": ["lane_s_out"],
              "conn_w_n": ["lane_n_out"]}


def lane_token(label: str) -> str:
    """The token of the lane or connector ``label`` (e.g. ``"lane_s_in"``)."""
    return token("lane", label)


def _expansion() -> dict:
    cx, cy = CENTRE
    ex = _Expansion()
    L = ex.layers
    for label, (rel, h, sign, r, length, pieces) in _lane_specs().items():
        start = (cx + rel[0], cy + rel[1])
        centre = _arc_points(start, h, sign, r, length)
        nrm = [(-math.sin(h + (sign / r) * u), math.cos(h + (sign / r) * u))
               for u in np.linspace(0.0, length, len(centre))]
        left = [(p[0] + 1.75 * n[0], p[1] + 1.75 * n[1]) for p, n in zip(centre, nrm)]
        right = [(p[0] - 1.75 * n[0], p[1] - 1.75 * n[1]) for p, n in zip(centre, nrm)]
        poly = ex.polygon(right + left[::-1])
        tok = lane_token(label)
        if label.startswith("lane"):
            L["lane"].append({"token": tok, "polygon_token": poly, "lane_type": "CAR",
                              "from_edge_line_token": ex.line([right[0], left[0]]),
                              "to_edge_line_token": ex.line([right[-1], left[-1]]),
                              "left_lane_divider_segments": [],
                              "right_lane_divider_segments": []})
        else:
            L["lane_connector"].append({"token": tok, "polygon_token": poly})
        paths, x, y, hh = [], start[0], start[1], h
        for piece in pieces:
            end = _arc_points((x, y), hh, sign, r, piece, 2)[-1]
            he = hh + (sign / r) * piece if sign else hh
            seg = [piece, 0.0, 0.0] if sign else [0.0, piece, 0.0]
            shape = "RSR" if sign < 0 else "LSL"
            paths.append({"start_pose": [x, y, math.remainder(hh, 2 * math.pi)],
                          "end_pose": [end[0], end[1], math.remainder(he, 2 * math.pi)],
                          "shape": shape, "radius": r, "segment_length": seg})
            x, y, hh = end[0], end[1], he
        L["arcline_path_3"][tok] = paths
    for label in _lane_specs():
        L["connectivity"][lane_token(label)] = {
            "incoming": [lane_token(a) for a, outs in SUCCESSORS.items() if label in outs],
            "outgoing": [lane_token(b) for b in SUCCESSORS.get(label, [])]}
    hw = 3.6
    road = [(cx + hw, cy - 120), (cx + hw, cy + 120), (cx - hw, cy + 120), (cx - hw, cy + 12),
            (cx - 12, cy + 12), (cx - 12, cy + hw), (cx - 120, cy + hw), (cx - 120, cy - hw),
            (cx - 12, cy - hw), (cx - 12, cy - 12), (cx - hw, cy - 12), (cx - hw, cy - 120)]
    plaza = [(cx + 20, cy - 60), (cx + 60, cy - 60), (cx + 60, cy - 20), (cx + 20, cy - 20)]
    hole = [(cx + 35, cy - 45), (cx + 45, cy - 45), (cx + 45, cy - 35), (cx + 35, cy - 35)]
    da = token("drivable_area", 0)
    L["drivable_area"].append({"token": da, "polygon_tokens": [ex.polygon(road),
                                                               ex.polygon(plaza, [hole])]})
    junction = token("road_segment", "junction")
    box = [(cx - 12, cy - 12), (cx + hw, cy - 12), (cx + hw, cy + 12), (cx - 12, cy + 12)]
    L["road_segment"].append({"token": junction, "is_intersection": True,
                              "drivable_area_token": da, "polygon_token": ex.polygon(box)})
    L["walkway"].append({"token": token("walkway", 0), "polygon_token": ex.polygon(
        [(cx + 3.0, cy - 120), (cx + 7.0, cy - 120), (cx + 7.0, cy - 12), (cx + 3.0, cy - 12)])})
    L["walkway"].append({"token": token("walkway", 1), "polygon_token": ex.polygon(  # far away
        [(cx + 500, cy - 20), (cx + 510, cy - 20), (cx + 510, cy + 20), (cx + 500, cy + 20)])})
    zebra = [(cx - hw, cy + 13), (cx + hw, cy + 13), (cx + hw, cy + 16), (cx - hw, cy + 16)]
    L["ped_crossing"].append({"token": token("ped_crossing", 0), "road_segment_token": junction,
                              "polygon_token": ex.polygon(zebra)})
    return {"version": "1.3", "canvas_edge": [2979.5, 2118.1], **L}


# --------------------------------------------------------------------------- writing


def write_sample(dataroot: str | Path, version: str = VERSION, copies: int = 1) -> dict:
    """Write the sample DATAROOT under ``dataroot``; returns the truth of every scene, by name.

    ``version="v1.0-trainval"`` writes ``copies`` of every scene under names of the
    trainval splits instead (scene-0103's copies in ``val``, the others in ``train``; enough
    scenes for ``minimanc reproduce --data``, and for measuring the import's speed).

    ``truth[name]`` holds ``poses (N, 3)`` (the LIDAR_TOP keyframes' ego ``[x, y, yaw]``),
    ``stamps (N,)`` (s), ``token`` and ``agents``: per agent its ``label``, ``category``,
    ``instance_token`` and ``boxes {keyframe: (x, y, yaw, length, width)}``.
    """
    if version not in SAMPLE_VERSIONS:
        raise ValueError(f"the sample has versions {', '.join(SAMPLE_VERSIONS)}; got "
                         f"version={version!r}")
    copies = check_int("copies", copies, 1)
    if version == VERSION and copies != 1:
        raise ValueError(f"the {VERSION} sample holds its scenes once (the mini split names "
                         f"them); copies={copies} needs version='v1.0-trainval'")
    root = Path(dataroot)
    tables, truth = _tables(version, copies)
    folder = root / version
    folder.mkdir(parents=True, exist_ok=True)
    for name, rows in tables.items():
        (folder / f"{name}.json").write_text(json.dumps(rows, indent=0))
    maps = root / "maps" / "expansion"
    maps.mkdir(parents=True, exist_ok=True)
    (maps / f"{LOCATION}.json").write_text(json.dumps(_expansion()))
    for other in OTHER_LOCATIONS:  # the download holds all four (empty here)
        empty = {k: ([] if isinstance(v, list) else {}) for k, v in _Expansion().layers.items()}
        (maps / f"{other}.json").write_text(json.dumps({"version": "1.3",
                                                        "canvas_edge": [2000.0, 2000.0],
                                                        **empty}))
    for rec in tables["map"]:  # the semantic prior mask the devkit opens (not read by us)
        Image.fromarray(np.zeros((16, 16), dtype=np.uint8)).save(root / rec["filename"])
    return truth
