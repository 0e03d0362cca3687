"""Chapter 7 — reading nuScenes' JSON tables (the devkit's ``schema.md``) with the standard library.

:class:`Tables` loads the tables of one version under ``DATAROOT/<version>/`` and indexes
them by token; :func:`keyframe_poses` gives the ego's pose at a scene's keyframes (the
``ego_pose`` of each keyframe's ``LIDAR_TOP`` ``sample_data``, as the devkit's
``NuScenes.get('ego_pose', sd['ego_pose_token'])``), and :func:`yaw_of` the heading of a
nuScenes quaternion ``[w, x, y, z]``. Every failure is a :class:`NuScenesError` of one line
naming the file and what is wrong.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from minimanc.world.nuscenes.splits import VERSIONS

__all__ = ["TABLES", "NuScenesError", "Tables", "keyframe_poses", "read_json", "yaw_of"]

TABLES: tuple[str, ...] = ("scene", "sample", "sample_data", "ego_pose", "sample_annotation",
                           "instance", "category", "log", "map", "calibrated_sensor", "sensor")
"""The tables the importer reads (``DATAROOT/<version>/<table>.json``)."""


class NuScenesError(ValueError):
    """A nuScenes DATAROOT that cannot be imported (one line: the file and what is wrong)."""


def read_json(path: Path, what: str) -> object:
    """``json.load`` of ``path``, or a :class:`NuScenesError` naming it (missing or corrupt)."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise NuScenesError(f"{what} {path} is missing") from None
    except OSError as e:
        raise NuScenesError(f"cannot read {what} {path}: {e.strerror or e}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise NuScenesError(f"{what} {path} is not valid JSON: {e.msg} at line {e.lineno} "
                            f"column {e.colno}") from None


def yaw_of(q) -> float:
    """Heading (rad) of the rotation quaternion ``q = [w, x, y, z]`` (nuScenes' order)."""
    w, x, y, z = (float(v) for v in q)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


class Tables:
    """The JSON tables of ``DATAROOT/<version>/``, each a list of records, indexed by token."""

    def __init__(self, dataroot: str | Path, version: str) -> None:
        root = Path(dataroot)
        if version not in VERSIONS:
            raise NuScenesError(f"version must be one of {', '.join(VERSIONS)}, got {version!r}")
        if not root.is_dir():
            raise NuScenesError(f"DATAROOT {root} is not a directory")
        folder = root / version
        if not folder.is_dir():
            found = sorted(p.name for p in root.iterdir() if p.is_dir() and p.name[:2] == "v1")
            hint = f" (it holds {', '.join(found)})" if found else ""
            raise NuScenesError(f"DATAROOT {root} has no folder {version}/ of JSON tables{hint}")
        self.root, self.version = root, version
        self.rows: dict[str, list[dict]] = {}
        for name in TABLES:
            rows = read_json(folder / f"{name}.json", f"table {name!r}:")
            if not isinstance(rows, list) or not all(isinstance(r, dict) and "token" in r
                                                     for r in rows):
                raise NuScenesError(f"table {name!r}: {folder / (name + '.json')} must hold a "
                                    "list of records with a 'token'")
            self.rows[name] = rows
        self.by_token = {name: {r["token"]: r for r in rows} for name, rows in self.rows.items()}
        self.annotations_of_sample: dict[str, list[dict]] = {}
        for ann in self.rows["sample_annotation"]:
            self.annotations_of_sample.setdefault(ann["sample_token"], []).append(ann)
        channel = {cs["token"]: self.get("sensor", cs["sensor_token"])["channel"]
                   for cs in self.rows["calibrated_sensor"]}
        self.lidar_of_sample: dict[str, dict] = {}
        for sd in self.rows["sample_data"]:
            if sd.get("is_key_frame") and channel.get(sd["calibrated_sensor_token"]) == "LIDAR_TOP":
                self.lidar_of_sample[sd["sample_token"]] = sd
        self.map_of_log = {lt: m for m in self.rows["map"] for lt in m.get("log_tokens", [])}

    def get(self, table: str, token: str) -> dict:
        """The record ``token`` of ``table`` (a :class:`NuScenesError` if there is none)."""
        try:
            return self.by_token[table][token]
        except KeyError:
            raise NuScenesError(f"table {table!r} of {self.root / self.version} has no record "
                                f"{token!r}") from None

    def scene_by_name(self) -> dict[str, dict]:
        return {s["name"]: s for s in self.rows["scene"]}

    def samples(self, scene: dict) -> list[dict]:
        """The scene's keyframes in order (following ``next`` from ``first_sample_token``)."""
        out, token = [], scene["first_sample_token"]
        while token:
            s = self.get("sample", token)
            out.append(s)
            if len(out) > 10_000:
                raise NuScenesError(f"scene {scene['name']}: its samples form a cycle")
            token = s.get("next", "")
        return out

    def location(self, scene: dict) -> str:
        return str(self.get("log", scene["log_token"])["location"])


def keyframe_poses(tables: Tables, samples: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    """``(poses (N, 3) [x, y, yaw], timestamps (N,) in s)`` of the ego at the keyframes."""
    poses, stamps = [], []
    for s in samples:
        sd = tables.lidar_of_sample.get(s["token"])
        if sd is None:
            raise NuScenesError(f"sample {s['token']} has no LIDAR_TOP keyframe in "
                                "sample_data.json (the ego pose is read from it)")
        ep = tables.get("ego_pose", sd["ego_pose_token"])
        t = ep["translation"]
        poses.append((float(t[0]), float(t[1]), yaw_of(ep["rotation"])))
        stamps.append(float(s["timestamp"]) * 1e-6)
    return np.asarray(poses, dtype=np.float64), np.asarray(stamps, dtype=np.float64)
