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
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np

from minimanc.world.nuscenes.splits import VERSIONS

__all__ = ["LOAD_ORDER", "TABLES", "NuScenesError", "Tables", "keyframe_poses", "read_json",
           "read_records", "read_text", "yaw_of"]

TABLES: tuple[str, ...] = ("scene", "sample", "sample_data", "ego_pose", "sample_annotation",
                           "instance", "category", "log", "map", "calibrated_sensor", "sensor")
"""The tables the importer reads (``DATAROOT/<version>/<table>.json``)."""
LOAD_ORDER: tuple[str, ...] = ("scene", "sample", "sensor", "calibrated_sensor", "sample_data",
                               "ego_pose", "sample_annotation", "instance", "category", "log",
                               "map")
"""The order they are read in: the LIDAR_TOP sensors before ``sample_data`` (of which only
their keyframes are kept), before ``ego_pose`` (only those keyframes' poses)."""


class NuScenesError(ValueError):
    """A nuScenes DATAROOT that cannot be imported (one line: the file and what is wrong)."""


def read_text(path: Path, what: str) -> str:
    """The text of ``path``, or a :class:`NuScenesError` naming ``what`` (missing, unreadable)."""
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise NuScenesError(f"{what} {path} is missing") from None
    except OSError as e:
        raise NuScenesError(f"cannot read {what} {path}: {e.strerror or e}") from None


def read_json(path: Path, what: str) -> object:
    """``json.load`` of ``path``, or a :class:`NuScenesError` naming it (missing or corrupt)."""
    text = read_text(path, what)
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise NuScenesError(f"{what} {path} is not valid JSON: {e.msg} at line {e.lineno} "
                            f"column {e.colno}") from None


_SPACE = re.compile(r"[ \t\n\r]*")


def read_records(path: Path, what: str, keep: Callable[[dict], bool] | None = None
                 ) -> list[dict]:
    """The records of the JSON table ``path`` (a list of objects with a ``"token"``) that
    ``keep`` accepts (default: all), decoded one record at a time, so that the records
    left out of a large table (trainval's sweeps) are never all in memory at once.

    Raises :class:`NuScenesError` (one line, naming ``what`` and ``path``) if the file is
    missing, is not valid JSON or is not such a list.
    """
    text = read_text(path, what)

    def invalid(msg: str, pos: int) -> NuScenesError:
        line = text.count("\n", 0, pos) + 1
        return NuScenesError(f"{what} {path} is not valid JSON: {msg} at line {line} column "
                             f"{pos - text.rfind(chr(10), 0, pos)}")

    not_records = NuScenesError(f"{what} {path} must hold a list of records with a 'token'")
    decoder = json.JSONDecoder()
    i = _SPACE.match(text).end()
    if i == len(text):
        raise invalid("Expecting value", i)
    if text[i] != "[":
        raise not_records
    i = _SPACE.match(text, i + 1).end()
    out: list[dict] = []
    while i < len(text) and text[i] != "]":
        try:
            rec, i = decoder.raw_decode(text, i)
        except json.JSONDecodeError as e:
            raise invalid(e.msg, e.pos) from None
        if not isinstance(rec, dict) or "token" not in rec:
            raise not_records
        if keep is None or keep(rec):
            out.append(rec)
        i = _SPACE.match(text, i).end()
        if i < len(text) and text[i] == ",":
            i = _SPACE.match(text, i + 1).end()
            if i < len(text) and text[i] == "]":
                raise invalid("Illegal trailing comma before end of array", i)
        elif i < len(text) and text[i] != "]":
            raise invalid("Expecting ',' delimiter", i)
    if i >= len(text):
        raise invalid("Expecting ',' delimiter" if out else "Expecting value", i)
    if _SPACE.match(text, i + 1).end() != len(text):
        raise invalid("Extra data", _SPACE.match(text, i + 1).end())
    return out


def yaw_of(q) -> float:
    """Heading (rad) of the rotation quaternion ``q = [w, x, y, z]`` (nuScenes' order)."""
    w, x, y, z = (float(v) for v in q)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


class Tables:
    """The JSON tables of ``DATAROOT/<version>/``, each a list of records, indexed by token.

    Of ``sample_data`` only the ``LIDAR_TOP`` keyframes are kept, and of ``ego_pose`` only
    their poses (trainval's tables hold 2.6 million of each, nearly all sweeps): the rest
    is decoded one record at a time and dropped (:func:`read_records`)."""

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
        self.by_token: dict[str, dict[str, dict]] = {}
        lidar: set[str] = set()
        poses: set[str] = set()
        keep = {"sample_data": lambda r: bool(r.get("is_key_frame"))
                and r.get("calibrated_sensor_token") in lidar,
                "ego_pose": lambda r: r["token"] in poses}
        for name in sorted(TABLES, key=LOAD_ORDER.index):
            self.rows[name] = read_records(folder / f"{name}.json", f"table {name!r}:",
                                           keep.get(name))
            self.by_token[name] = {r["token"]: r for r in self.rows[name]}
            if name == "calibrated_sensor":
                lidar = {cs["token"] for cs in self.rows[name]
                         if self.get("sensor", cs["sensor_token"]).get("channel") == "LIDAR_TOP"}
            elif name == "sample_data":
                poses = {sd["ego_pose_token"] for sd in self.rows[name]}
        self.annotations_of_sample: dict[str, list[dict]] = {}
        for ann in self.rows["sample_annotation"]:
            self.annotations_of_sample.setdefault(ann["sample_token"], []).append(ann)
        self.lidar_of_sample = {sd["sample_token"]: sd for sd in self.rows["sample_data"]}
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
