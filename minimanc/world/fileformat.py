"""Chapter 7 — the dataset format: arrays, metadata, checksums (what every writer follows).

A dataset holds the arrays :data:`ARRAY_FIELDS` (one row per scene) and a
``meta`` dict with the keys :data:`META_KEYS`; :func:`empty_meta` and
:func:`append_scenes` build it, :func:`check_meta` verifies it, and
:func:`check_arrays_finite` refuses a non-finite number naming its array, scene and
step. The file (:data:`FILE_FORMAT_VERSION` 2, a zip archive that
``numpy.load`` also opens) stores each shard ``k`` of each array as the member
:func:`member_name` ``"<array>-<k:05d>.npy"`` and a JSON header ``header.npy``
with the SHA-256 of every shard's array (:func:`array_sha256`) and of the
header itself (:func:`header_sha256`). :func:`content_digest` is the content
hash of a dataset, in memory or on disk. The writer is
:mod:`minimanc.world.datawriter`, the reader :mod:`minimanc.world.datareader`.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from minimanc.world.geometry import DT
from minimanc.world.raster import RasterConfig

__all__ = [
    "ARRAY_FIELDS", "FILE_FORMAT_VERSION", "FLOAT_FIELDS", "FORMAT_NAME", "FORMAT_VERSION",
    "HEADER_MEMBER", "META_KEYS", "PER_SCENE_KEYS", "SHARD_BYTES", "DatasetFileError",
    "append_scenes", "array_sha256", "check_arrays_finite", "check_meta", "check_raster_shapes",
    "content_digest",
    "describe_non_finite", "empty_meta", "first_non_finite", "header_sha256", "member_name",
]

FORMAT_VERSION = 1
"""Version of the generator and of the dataset layout, recorded as ``meta["version"]``."""
FILE_FORMAT_VERSION = 2
"""Version of the file format (2: sharded, metadata under the checksum); files of another
version are refused."""
SHARD_BYTES = 64 * 2**20
"""Target uncompressed size of one shard (the memory :func:`generate_file` needs)."""
FORMAT_NAME = "minimanc.world"
"""The header's ``"format"`` entry, which marks a file as one of ours."""
HEADER_MEMBER = "header.npy"
"""The archive member holding the JSON header (written last)."""

ARRAY_FIELDS = ("bev", "ego", "controls", "goal", "lane_target", "ado", "ado_valid", "goal_bev")
"""The arrays of a dataset, in the order they are written and hashed."""
FLOAT_FIELDS = ("ego", "controls", "goal", "lane_target", "ado")
"""The float arrays, which must hold finite numbers only."""
META_KEYS = ("seed", "version", "dt", "raster", "recipes", "tags", "attempts", "scene_index")
"""Keys every dataset's ``meta`` holds (the per-scene ones hold one entry per scene)."""
PER_SCENE_KEYS = ("recipes", "tags", "attempts", "scene_index")
"""The keys of ``meta`` that hold one entry per scene."""


class DatasetFileError(ValueError):
    """A dataset file that cannot be used (not ours, truncated, corrupt, altered, wrong version)."""


# --------------------------------------------------------------------------- finite numbers


def first_non_finite(arrays: Any, fields: Sequence[str] = FLOAT_FIELDS
                     ) -> tuple[str, tuple[int, ...], float] | None:
    """The first non-finite number of ``arrays`` (a :class:`Dataset` or a dict of arrays).

    Returns ``(field, index, value)`` — ``index`` starts with the scene and the
    step — or ``None`` when every float array is finite. Fields that are
    missing are skipped.
    """
    for name in fields:
        a = arrays.get(name) if isinstance(arrays, dict) else getattr(arrays, name, None)
        if a is None:
            continue
        a = np.asarray(a)
        if not np.issubdtype(a.dtype, np.floating):
            continue
        bad = ~np.isfinite(a)
        if bad.any():
            idx = tuple(int(i) for i in np.argwhere(bad)[0])
            return name, idx, float(a[idx])
    return None


def describe_non_finite(found: tuple[str, tuple[int, ...], float], scene_offset: int = 0) -> str:
    """``"controls[scene 1, step 5, 0] = nan"`` for a result of :func:`first_non_finite`."""
    name, idx, value = found
    where = [f"scene {idx[0] + scene_offset}"] if idx else []
    if len(idx) > 1:
        where.append(f"step {idx[1]}")
    where += [str(i) for i in idx[2:]]
    return f"{name}[{', '.join(where)}] = {value}"


def check_arrays_finite(arrays: Any, what: str = "dataset", scene_offset: int = 0) -> None:
    """Raise ``ValueError`` naming the array, scene and step of the first non-finite number.

    ``scene_offset`` is added to the scene shown (the first scene of a shard).
    """
    found = first_non_finite(arrays)
    if found is not None:
        raise ValueError(f"{what} holds a non-finite number: "
                         f"{describe_non_finite(found, scene_offset)}; "
                         "every float array must be finite")


# --------------------------------------------------------------------------- metadata


def empty_meta(seed: int, cfg: RasterConfig) -> dict:
    """The metadata of a dataset with no scenes yet (keys :data:`META_KEYS`, in order):
    every dataset writer of the package starts from it, so the format lives here."""
    return {"seed": int(seed), "version": FORMAT_VERSION, "dt": DT, "raster": cfg.as_meta(),
            "recipes": [], "tags": [], "attempts": [], "scene_index": []}


def append_scenes(meta: dict, recipes: Sequence[dict], tags: Sequence[dict],
                  attempts: Sequence[int], scene_index: Sequence[int]) -> None:
    """Add the per-scene metadata (:data:`PER_SCENE_KEYS`) of some scenes to ``meta``."""
    lists = {"recipes": list(recipes), "tags": list(tags),
             "attempts": [int(a) for a in attempts], "scene_index": [int(i) for i in scene_index]}
    if len({len(v) for v in lists.values()}) != 1:
        raise ValueError("recipes, tags, attempts and scene_index must have one entry per scene, "
                         f"got {', '.join(f'{k}: {len(v)}' for k, v in lists.items())}")
    for key in PER_SCENE_KEYS:
        meta[key].extend(lists[key])


def check_meta(meta: Any, n: int, where: str, err: type[Exception] = ValueError) -> None:
    """Raise ``err`` (prefixed by ``where``) unless ``meta`` is the metadata of ``n`` scenes.

    It must be a dict holding :data:`META_KEYS`, one entry per scene in each
    of :data:`PER_SCENE_KEYS`, a :class:`RasterConfig` as a dict in
    ``"raster"`` and a positive finite ``"dt"``.
    """
    if not isinstance(meta, dict):
        raise err(f"{where}: metadata must be a dict, got {type(meta).__name__}")
    missing = [k for k in META_KEYS if k not in meta]
    if missing:
        raise err(f"{where}: metadata key(s) {', '.join(map(repr, missing))} missing "
                  f"(a dataset's meta holds {', '.join(META_KEYS)})")
    for k in PER_SCENE_KEYS:
        if not isinstance(meta[k], list) or len(meta[k]) != n:
            got = len(meta[k]) if isinstance(meta[k], list) else type(meta[k]).__name__
            raise err(f"{where}: metadata {k!r} must be a list of one entry per scene "
                      f"({n}), got {got}")
    if not isinstance(meta["raster"], dict):
        raise err(f"{where}: metadata 'raster' must be a dict, got {meta['raster']!r}")
    try:
        RasterConfig(**meta["raster"])
    except (TypeError, ValueError) as e:
        raise err(f"{where}: metadata 'raster' is not a raster config: {e}") from e
    dt = meta["dt"]
    if not (isinstance(dt, int | float) and not isinstance(dt, bool) and math.isfinite(dt)
            and dt > 0):
        raise err(f"{where}: metadata 'dt' must be a positive number, got {dt!r}")


def check_raster_shapes(meta: dict, bev: tuple[int, ...], goal_bev: tuple[int, ...],
                        where: str, err: type[Exception] = ValueError) -> None:
    """Raise ``err`` (prefixed by ``where``) unless the rasters' shapes ``bev (S, T, ...)``
    and ``goal_bev (S, ...)`` are what the metadata's raster config stores per frame
    (:attr:`RasterConfig.shape`: an RGB image, or the packed channels)."""
    cfg = RasterConfig(**meta["raster"])
    for name, shape, lead in (("bev", tuple(bev), 2), ("goal_bev", tuple(goal_bev), 1)):
        if shape[lead:] != cfg.shape:
            raise err(f"{where}: {name} frames have shape {shape[lead:]}, but the raster "
                      f"config ({cfg.encoding}, {cfg.size}x{cfg.width}) stores {cfg.shape}")


# --------------------------------------------------------------------------- checksums


def member_name(name: str, shard: int) -> str:
    """The archive member of array ``name`` in shard ``shard``: ``"ego-00003.npy"``."""
    return f"{name}-{shard:05d}.npy"


def array_sha256(a: np.ndarray) -> str:
    """SHA-256 (hex) of an array's C-order bytes, as recorded per shard in the header."""
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def header_sha256(header: dict) -> str:
    """SHA-256 of the header without its ``"sha256"`` entry (JSON, keys sorted)."""
    body = {k: v for k, v in header.items() if k != "sha256"}
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


def content_digest(arrays: Iterable[tuple[str, np.dtype, tuple[int, ...], Iterable[np.ndarray]]],
                   meta: dict) -> str:
    """The content hash of a dataset: SHA-256 of its arrays and scene metadata.

    ``arrays`` yields ``(name, dtype, shape, chunks)`` for each of
    :data:`ARRAY_FIELDS` in order, ``chunks`` the array's consecutive scene
    blocks (the whole array, or its shards); the hash covers each array's
    name, dtype, shape and bytes, then ``meta["recipes"]`` and ``meta["tags"]``
    — so a dataset and the file it was saved to hash alike.
    """
    h = hashlib.sha256()
    for name, dtype, shape, chunks in arrays:
        h.update(f"{name}:{np.dtype(dtype).str}:{tuple(shape)}".encode())
        for chunk in chunks:
            h.update(np.ascontiguousarray(chunk).tobytes())
    for key in ("recipes", "tags"):
        h.update(json.dumps(meta[key], sort_keys=True).encode())
    return h.hexdigest()
