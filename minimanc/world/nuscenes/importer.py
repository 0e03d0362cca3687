"""Chapter 7 — importing real nuScenes scenes into the world's dataset file.

:func:`import_nuscenes` reads a version's JSON tables (:class:`~minimanc.world.nuscenes.Tables`)
and the map expansion (:class:`~minimanc.world.nuscenes.MapExpansion`) and streams the scenes
through the package's one dataset writer (:class:`minimanc.world.DatasetWriter`: same format,
checksums and shards as ``world.generate_file``; one shard of scenes' arrays in memory at a
time, so they do not grow with the number of scenes — only the small per-scene metadata the
header keeps (recipe, tags) does; the tables are read once, :class:`Tables` keeping of the
sweeps only the ``LIDAR_TOP`` keyframes and their ego poses).
The paper trains on nuScenes' 20 s scenes at 2 Hz; a scene becomes the world's 40 steps of
``dt = 0.5`` s (``world.DT``) as follows.

* **Ego.** The pose at each keyframe is the ``ego_pose`` of the keyframe's ``LIDAR_TOP``
  ``sample_data`` (:func:`~minimanc.world.nuscenes.keyframe_poses`): ``[x, y, yaw]`` in the
  map's global frame, ``yaw`` the heading of its quaternion (roll, pitch and height dropped).
  nuScenes' ego frame has its origin at the middle of the rear axle, the point a unicycle
  moves (no sideways slip), so the controls below describe the log well; the world centres
  the ego's box on the pose, so on imported scenes that box sits about a wheelbase's half
  behind the car's true footprint (collision and off-road checks, not the pose errors).
  The controls ``[speed, yaw rate]`` are finite differences at the dataset's ``dt``
  (:func:`minimanc.world.controls_from_poses`: the displacement projected on the heading over
  ``dt``, the wrapped heading change over ``dt``; the unicycle of the paper's environment).
* **Length.** A scene of 41 or more keyframes keeps its first 41 poses: 40 steps and the pose
  after the last control. A scene of exactly 40 keyframes keeps them all; its 39 differences
  are the first 39 controls and the last is held. A scene of fewer than 40 keyframes, or with
  a gap between two of the keyframes used outside :data:`MIN_GAP`–:data:`MAX_GAP` s (a
  dropped keyframe), is skipped and reported (:attr:`ImportReport.skipped`), as is a scene in
  which the ego drives on no lane of the map (a car park).
* **Ados.** Every ``vehicle.*`` annotation (cars, trucks, buses, trailers, construction
  vehicles, emergency vehicles, and also bicycles and motorcycles, ridden or not) is an ado
  box ``[x, y, yaw, length, width]`` (the annotation's centre and heading; its ``size`` is
  ``[width, length, height]``) at the keyframes it is annotated at (``ado_valid``). Each
  instance keeps one slot for the whole scene, slots in order of first appearance (then
  token); if a scene holds more vehicles than ``max_ados`` slots, the ones that come closest
  to the ego are kept and the rest counted in ``tags["n_vehicles_dropped"]``. Pedestrians
  (``human.pedestrian.*``) are counted (``tags["n_pedestrians"]``), not imported: the world's
  raster and collision checks know vehicles only. Other categories are ignored.
* **Map and route.** :meth:`MapExpansion.local_recipe` cuts the map around the ego's track
  into an explicit recipe: lane centrelines (discretised arclines, whose directions give the
  raster's hue), drivable area with its holes, walkways (drawn where nothing drivable is:
  walkways under drivable), pedestrian crossings, and the route — the lanes the logged ego
  drove made connected through the lane graph (:func:`~minimanc.world.nuscenes.route_of`),
  so the lane target is defined exactly as on the world.
* **Splits.** Scenes of the version's training split come first, then the validation split
  (:data:`~minimanc.world.nuscenes.SPLITS_OF_VERSION`, the devkit's official lists), each in
  the order of ``scene.json``; ``tags["split"]`` names each scene's split and
  ``meta["nuscenes"]`` records the version, the counts per split and the skipped scenes.
  ``meta["scene_index"]`` is each scene's row in ``scene.json`` and ``meta["attempts"]`` is
  0: no draw of the world's generator, so what re-simulates a generated scene from its seed
  (the reactive ados, the style floor) refuses a recorded one instead of drawing another.

Every failure is a one-line :class:`~minimanc.world.nuscenes.NuScenesError`, and a failed
import leaves no file (the writer's temporary file is removed).
"""

from __future__ import annotations

import json
import math
import os
import time
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from minimanc.checks import check_int
from minimanc.world.datawriter import DatasetWriter
from minimanc.world.driver import MAX_ADOS, T_STEPS
from minimanc.world.fileformat import ARRAY_FIELDS, append_scenes, empty_meta
from minimanc.world.generation import Estimate, default_shard_scenes
from minimanc.world.geometry import DT, controls_from_poses, goal_in_ego_frame, wrap_angle
from minimanc.world.history import history_of
from minimanc.world.lanes import K_TARGETS
from minimanc.world.maps import lane_targets
from minimanc.world.nuscenes.mapexp import MapExpansion
from minimanc.world.nuscenes.splits import SPLITS_OF_VERSION, VERSIONS, split_lists
from minimanc.world.nuscenes.tables import NuScenesError, Tables, keyframe_poses, yaw_of
from minimanc.world.raster import RasterConfig, rasterize_batch, rasterize_goal
from minimanc.world.roads import build_map

__all__ = ["MAX_GAP", "MIN_GAP", "ImportEstimate", "ImportReport", "SceneSkipped", "ego_track",
           "estimate_import", "import_nuscenes", "import_scene", "select_scenes", "skip_reason",
           "vehicle_boxes"]

MIN_GAP = 0.3
"""Shortest time between two keyframes a scene may hold (s)."""
MAX_GAP = 0.7
"""Longest time between two keyframes a scene may hold (s); a longer one is a dropped frame."""
VEHICLE_PREFIX = "vehicle."
"""Category prefix of the annotations imported as ados."""
PEDESTRIAN = "human.pedestrian."
"""Category prefix of the annotations counted as pedestrians."""


@dataclass(frozen=True)
class ImportEstimate(Estimate):
    """What :func:`estimate_import` predicts: a world :class:`~minimanc.world.Estimate`
    measured on the first scene that imports (``scene``), for every scene selected."""

    scene: str = ""

    def __str__(self) -> str:
        return (f"about {_human(self.disk_bytes, 'B')} on disk and {self.seconds:.0f} s "
                f"({_human(self.bytes_per_scene, 'B')} and {self.seconds_per_scene:.2f} s per "
                f"scene, measured on {self.scene}; fewer if some scenes are skipped)")


def _human(n: float, unit: str) -> str:
    for prefix in ("", "k", "M", "G", "T"):
        if n < 1000 or prefix == "T":
            return f"{n:.0f} {prefix}{unit}" if not prefix else f"{n:.1f} {prefix}{unit}"
        n /= 1000
    raise AssertionError("unreachable")


class SceneSkipped(Exception):
    """A scene that does not make 40 steps (too short, a gap, no lane); its reason."""


@dataclass(frozen=True)
class ImportReport:
    """What :func:`import_nuscenes` did: the file, the scenes imported and those skipped."""

    path: Path
    imported: tuple[str, ...]
    skipped: tuple[tuple[str, str], ...]  # (scene name, reason)
    seconds: float

    def __str__(self) -> str:
        lines = [f"imported {len(self.imported)} scene(s) in {self.seconds:.1f} s -> {self.path}"]
        lines += [f"  skipped {name}: {why}" for name, why in self.skipped]
        return "\n".join(lines)


def select_scenes(tables: Tables, names: Sequence[str] | None = None) -> list[tuple[dict, str]]:
    """``[(scene record, split name)]`` to import: the training split's, then the validation's.

    ``names`` (default: every scene of ``scene.json`` in the version's splits) must each be
    a scene of the version's splits and of ``scene.json``; they are imported in split order.
    Scenes of ``scene.json`` in neither split are left out.

    Raises :class:`NuScenesError` naming the first scene that is not.
    """
    splits = SPLITS_OF_VERSION[tables.version]
    lists = split_lists()
    by_name = tables.scene_by_name()
    if names is not None:
        for n in names:
            if not any(n in lists[s] for s in splits):
                raise NuScenesError(f"scene {n!r} is not in the {tables.version} splits "
                                    f"({', '.join(splits)}) of the devkit")
            if n not in by_name:
                raise NuScenesError(f"scene {n!r} is not in {tables.root / tables.version}/"
                                    "scene.json")
    wanted = set(by_name) if names is None else set(names)
    out = []
    for split in splits:
        members = set(lists[split])
        out += [(sc, split) for sc in tables.rows["scene"]
                if sc["name"] in members and sc["name"] in wanted]
    return out


def skip_reason(stamps: np.ndarray, steps: int = T_STEPS) -> str | None:
    """Why keyframes at times ``stamps (N,)`` (s) cannot make ``steps`` steps, or ``None``.

    Fewer than ``steps`` keyframes, or a gap outside [:data:`MIN_GAP`, :data:`MAX_GAP`]
    between two of the first ``steps + 1`` keyframes.
    """
    n = len(stamps)
    if n < steps:
        return f"{n} keyframes, fewer than the {steps} a scene needs"
    gaps = np.diff(np.asarray(stamps[:steps + 1], dtype=np.float64))
    bad = np.flatnonzero((gaps < MIN_GAP) | (gaps > MAX_GAP))
    if len(bad):
        k = int(bad[0])
        return (f"a gap of {gaps[k]:.2f} s between keyframes {k} and {k + 1} (allowed "
                f"{MIN_GAP}-{MAX_GAP} s)")
    return None


def ego_track(poses: np.ndarray, dt: float = DT, steps: int = T_STEPS
              ) -> tuple[np.ndarray, np.ndarray]:
    """``(ego (steps, 3), controls (steps, 2))`` from keyframe poses ``(N >= steps, 3)``.

    With ``N > steps`` the first ``steps + 1`` poses give ``steps`` controls by finite
    differences at ``dt`` (:func:`~minimanc.world.controls_from_poses`); with ``N == steps``
    the last of the ``steps - 1`` differences is held.
    """
    p = np.asarray(poses, dtype=np.float64)
    if len(p) > steps:
        return p[:steps].copy(), controls_from_poses(p[:steps + 1], dt)
    c = controls_from_poses(p[:steps], dt)
    return p[:steps].copy(), np.concatenate([c, c[-1:]], axis=0)


def vehicle_boxes(tables: Tables, samples: Sequence[dict], ego: np.ndarray,
                  max_ados: int = MAX_ADOS) -> tuple[np.ndarray, np.ndarray, dict]:
    """Ado boxes of the ``vehicle.*`` annotations at ``samples`` (see the module doc).

    Returns ``(ado (T, A, 5), ado_valid (T, A), counts)`` with ``A = max_ados`` and
    ``counts`` holding ``n_vehicles``, ``n_ados``, ``n_vehicles_dropped`` and
    ``n_pedestrians`` (instances seen at these keyframes).
    """
    T = len(samples)
    boxes: dict[str, dict[int, tuple]] = {}
    pedestrians: set[str] = set()
    category: dict[str, str] = {}
    for t, s in enumerate(samples):
        for ann in tables.annotations_of_sample.get(s["token"], []):
            inst = ann["instance_token"]
            if inst not in category:
                rec = tables.get("instance", inst)
                category[inst] = str(tables.get("category", rec["category_token"])["name"])
            name = category[inst]
            if name.startswith(PEDESTRIAN):
                pedestrians.add(inst)
            elif name.startswith(VEHICLE_PREFIX):
                (x, y, _), (w, ln, _) = ann["translation"], ann["size"]
                boxes.setdefault(inst, {})[t] = (float(x), float(y), yaw_of(ann["rotation"]),
                                                 float(ln), float(w))
    near = {i: min(math.hypot(b[0] - ego[t, 0], b[1] - ego[t, 1]) for t, b in bx.items())
            for i, bx in boxes.items()}
    kept = sorted(boxes, key=lambda i: (near[i], i))[:max_ados]
    slots = sorted(kept, key=lambda i: (min(boxes[i]), i))
    ado = np.zeros((T, max_ados, 5))
    valid = np.zeros((T, max_ados), dtype=bool)
    for a, inst in enumerate(slots):
        for t, b in boxes[inst].items():
            ado[t, a] = b
            valid[t, a] = True
    if not np.all(np.isfinite(ado)):
        raise NuScenesError(f"sample_annotation: a vehicle box at sample "
                            f"{samples[int(np.argwhere(~np.isfinite(ado))[0, 0])]['token']} "
                            "is not finite")
    counts = {"n_vehicles": len(boxes), "n_ados": len(slots),
              "n_vehicles_dropped": len(boxes) - len(slots), "n_pedestrians": len(pedestrians)}
    return ado, valid, counts


def _turn(ego: np.ndarray, junction: bool) -> str:
    turned = float(np.sum(wrap_angle(np.diff(ego[:, 2]))))
    if turned > math.pi / 4:
        return "left"
    if turned < -math.pi / 4:
        return "right"
    return "straight" if junction else "road"


def import_scene(tables: Tables, expansions: dict[str, MapExpansion], scene: dict, split: str,
                 cfg: RasterConfig, k_targets: int = K_TARGETS, max_ados: int = MAX_ADOS
                 ) -> dict:
    """One scene's arrays (:data:`~minimanc.world.fileformat.ARRAY_FIELDS`), recipe and tags.

    ``expansions`` caches the map expansion of each location (filled as needed).

    Raises :class:`SceneSkipped` (with the reason) for a scene that does not make 40 steps,
    and :class:`NuScenesError` for tables that cannot be read.
    """
    name = scene["name"]
    samples = tables.samples(scene)
    poses, stamps = keyframe_poses(tables, samples)
    reason = skip_reason(stamps)
    if reason is not None:
        raise SceneSkipped(reason)
    if not np.all(np.isfinite(poses)):
        raise NuScenesError(f"scene {name}: an ego_pose of its keyframes is not finite")
    location = tables.location(scene)
    if location not in expansions:
        expansions[location] = MapExpansion(tables.root, location)
    try:
        recipe = expansions[location].local_recipe(poses[:T_STEPS + 1])
    except NuScenesError as e:
        raise SceneSkipped(str(e)) from None
    ego, controls = ego_track(poses)
    ado, valid, counts = vehicle_boxes(tables, samples[:T_STEPS], ego, max_ados)
    m = build_map(recipe)
    # as world.generate_scene: everything derived from the float32 values that are stored
    ego32 = ego.astype(np.float32)
    ado32 = np.where(valid[..., None], ado, 0.0).astype(np.float32)
    ego64, ado64 = ego32.astype(np.float64), ado32.astype(np.float64)
    past = history_of(ego64, ado64, valid, cfg.history) if cfg.history else None
    tags = {"kind": m.kind, "source": "nuscenes", "version": tables.version, "scene": name,
            "scene_token": scene["token"], "split": split, "location": location,
            "description": str(scene.get("description", "")), "keyframes": len(samples),
            "timestamp": int(samples[0]["timestamp"]), "has_junction": bool(m.has_junction),
            "has_roundabout": False, "has_cut_in": False,
            "turn": _turn(ego, bool(m.has_junction)),
            "stopped_steps": int(np.sum(controls[:, 0] < 0.3)), **counts}
    return {
        "bev": rasterize_batch(m, ego64, ado64, valid, cfg, history=past),
        "ego": ego32,
        "controls": controls.astype(np.float32),
        "goal": goal_in_ego_frame(np.broadcast_to(ego64[-1], ego64.shape),
                                  ego64).astype(np.float32),
        "lane_target": lane_targets(m, ego64, k_targets).astype(np.float32),
        "ado": ado32,
        "ado_valid": valid,
        "goal_bev": rasterize_goal(m, ego64[-1], cfg),
        "recipe": recipe,
        "tags": tags,
    }


def _scene_index(tables: Tables) -> dict[str, int]:
    return {sc["token"]: i for i, sc in enumerate(tables.rows["scene"])}


def _tables(dataroot: str | os.PathLike, version: str, tables: Tables | None) -> Tables:
    if tables is None:
        return Tables(dataroot, version)
    if tables.version != version or Path(tables.root) != Path(dataroot):
        raise ValueError(f"tables are those of {tables.root} {tables.version}, not of "
                         f"{dataroot} {version}")
    return tables


def estimate_import(dataroot: str | os.PathLike, version: str,
                    scenes: Sequence[str] | None = None, raster: RasterConfig | None = None,
                    k_targets: int = K_TARGETS, max_ados: int = MAX_ADOS,
                    tables: Tables | None = None,
                    expansions: dict[str, MapExpansion] | None = None) -> ImportEstimate:
    """Disk size and time of :func:`import_nuscenes`, from importing the first scene that
    imports (compressed as in the file, with its metadata); ``tables`` are the
    :class:`Tables` of ``dataroot`` and ``version`` if already read, ``expansions`` a cache
    of the map expansion of each location (filled as needed; pass the same to
    :func:`import_nuscenes` to read each file once).

    Raises :class:`NuScenesError` if no scene imports (the reasons of the first few).
    """
    tables = _tables(dataroot, version, tables)
    cfg = raster or RasterConfig()
    chosen = select_scenes(tables, scenes)
    expansions = {} if expansions is None else expansions
    reasons = []
    for sc, split in chosen:
        t0 = time.perf_counter()
        try:
            out = import_scene(tables, expansions, sc, split, cfg, k_targets, max_ados)
        except SceneSkipped as e:
            reasons.append(f"{sc['name']}: {e}")
            continue
        seconds = time.perf_counter() - t0
        nbytes = sum(len(zlib.compress(np.ascontiguousarray(out[f]).tobytes(), 6))
                     for f in ARRAY_FIELDS)
        nbytes += len(json.dumps({"recipe": out["recipe"], "tags": out["tags"]}))
        return ImportEstimate(len(chosen), float(nbytes), float(seconds), 1, sc["name"])
    raise NuScenesError(_none_imported(chosen, reasons))


def _none_imported(chosen: list, reasons: list[str]) -> str:
    if not chosen:
        return "no scene to import (none of scene.json is in the version's splits)"
    more = f" (and {len(reasons) - 3} more)" if len(reasons) > 3 else ""
    return f"no scene could be imported: {'; '.join(reasons[:3])}{more}"


def import_nuscenes(dataroot: str | os.PathLike, version: str, path: str | os.PathLike,
                    scenes: Sequence[str] | None = None, raster: RasterConfig | None = None,
                    progress: bool = False, k_targets: int = K_TARGETS,
                    max_ados: int = MAX_ADOS, shard_scenes: int | None = None,
                    tables: Tables | None = None,
                    expansions: dict[str, MapExpansion] | None = None) -> ImportReport:
    """Import the scenes of ``DATAROOT/<version>`` into the dataset file ``path``.

    ``scenes`` names the scenes (default: all of the version's splits; see
    :func:`select_scenes`), ``raster`` the BEV geometry (default :class:`RasterConfig`),
    ``progress`` shows a tqdm bar; ``shard_scenes`` scenes go in each shard (default
    :func:`~minimanc.world.default_shard_scenes`); ``tables`` are the :class:`Tables` of
    ``dataroot`` and ``version`` if already read and ``expansions`` a cache of the map
    expansions (as in :func:`estimate_import`). ``world.load(path)`` reads the result.
    Returns the :class:`ImportReport` (scenes imported and skipped, with reasons).

    Raises :class:`NuScenesError` (one line) for an unknown version, a DATAROOT without the
    version's tables, a corrupt or inconsistent table, a missing map expansion, a scene
    not in the splits, or when no scene imports; nothing is written then.
    """
    if version not in VERSIONS:
        raise NuScenesError(f"version must be one of {', '.join(VERSIONS)}, got {version!r}")
    k_targets = check_int("k_targets", k_targets, 1)
    max_ados = check_int("max_ados", max_ados, 1)
    cfg = raster or RasterConfig()
    if not isinstance(cfg, RasterConfig):
        raise ValueError(f"raster must be a RasterConfig, got {raster!r}")
    if shard_scenes is None:
        shard_scenes = default_shard_scenes(cfg, k_targets, max_ados)
    shard_scenes = check_int("shard_scenes", shard_scenes, 1)
    t0 = time.perf_counter()
    tables = _tables(dataroot, version, tables)
    chosen = select_scenes(tables, scenes)
    index = _scene_index(tables)
    meta = empty_meta(0, cfg)
    expansions = {} if expansions is None else expansions
    imported: list[str] = []
    skipped: list[tuple[str, str]] = []
    per_split = dict.fromkeys(SPLITS_OF_VERSION[version], 0)
    bar = tqdm(total=len(chosen), desc="nuScenes scenes", disable=not progress, leave=False)
    try:
        with DatasetWriter(path) as writer:
            shard: list[dict] = []

            def flush() -> None:
                writer.add({f: np.stack([sc[f] for sc in shard]) for f in ARRAY_FIELDS})
                append_scenes(meta, [sc["recipe"] for sc in shard], [sc["tags"] for sc in shard],
                              [0] * len(shard), [sc["index"] for sc in shard])
                shard.clear()

            for sc, split in chosen:
                try:
                    out = import_scene(tables, expansions, sc, split, cfg, k_targets, max_ados)
                except SceneSkipped as e:
                    skipped.append((sc["name"], str(e)))
                else:
                    out["index"] = index[sc["token"]]
                    shard.append(out)
                    imported.append(sc["name"])
                    per_split[split] += 1
                    if len(shard) >= shard_scenes:
                        flush()
                bar.update(1)
            if shard:
                flush()
            if not imported:
                raise NuScenesError(_none_imported(chosen, [f"{n}: {r}" for n, r in skipped]))
            meta["source"] = "nuscenes"
            meta["nuscenes"] = {"version": version, "splits": per_split,
                                "skipped": [{"scene": n, "reason": r} for n, r in skipped]}
            out_path = writer.finish(meta)
    finally:
        bar.close()
    return ImportReport(out_path, tuple(imported), tuple(skipped), time.perf_counter() - t0)
