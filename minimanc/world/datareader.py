"""Chapter 7 — reading and verifying dataset files: :func:`load`, :func:`read_meta`.

:func:`load` rebuilds the maps from their recipes (on first access) and
refuses, with a :class:`~minimanc.world.fileformat.DatasetFileError` naming
the file, any file that is not one of ours, truncated, corrupt, altered
(arrays *or* metadata: both are under the header's checksum), of another
version, missing a metadata key, or holding a non-finite number.
:func:`file_content_hash` hashes a file one shard at a time, as
:meth:`Dataset.content_hash` hashes a dataset in memory.
"""

from __future__ import annotations

import json
import os
import zipfile
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from minimanc.world.fileformat import (
    ARRAY_FIELDS,
    FILE_FORMAT_VERSION,
    FORMAT_NAME,
    HEADER_MEMBER,
    DatasetFileError,
    array_sha256,
    check_meta,
    check_raster_shapes,
    content_digest,
    describe_non_finite,
    first_non_finite,
    header_sha256,
    member_name,
)
from minimanc.world.roads import build_map
from minimanc.world.scenes import Dataset, LazyMaps

__all__ = ["file_content_hash", "load", "read_meta"]

_NPY_MAGIC = b"\x93NUMPY"
_EXPECTED = ("expected a dataset archive (.npz) written by minimanc.world.save or "
             "`minimanc data generate`")
_READ_ERRORS = (zipfile.BadZipFile, zlib.error, ValueError, OSError, EOFError, KeyError)


def _read_npy(zf: zipfile.ZipFile, member: str) -> np.ndarray:
    with zf.open(member) as fh:
        return np.lib.format.read_array(fh, allow_pickle=False)


class _Archive:
    """An open dataset file whose header has been verified."""

    def __init__(self, path: str | os.PathLike) -> None:
        path = Path(path)
        self.path = path
        if not path.exists():
            raise FileNotFoundError(f"{path}: no such dataset file")
        if path.is_dir():
            raise DatasetFileError(f"{path}: is a directory; {_EXPECTED}")
        with open(path, "rb") as fh:
            magic = fh.read(len(_NPY_MAGIC))
        if magic == _NPY_MAGIC:
            raise DatasetFileError(f"{path}: is a single NumPy array (.npy file); {_EXPECTED}")
        try:
            self.zf = zipfile.ZipFile(path)
        except (zipfile.BadZipFile, OSError, EOFError, ValueError) as e:
            raise DatasetFileError(f"{path}: not a readable minimanc world file "
                                   f"(truncated or corrupt?): {e}; {_EXPECTED}") from e
        try:
            self.header = self._read_header()
        except BaseException:
            self.zf.close()
            raise

    def _read_header(self) -> dict:
        path = self.path
        if HEADER_MEMBER not in self.zf.namelist():
            raise DatasetFileError(f"{path}: no header — not a minimanc world file; {_EXPECTED}")
        try:
            raw = _read_npy(self.zf, HEADER_MEMBER)
            header = json.loads(bytes(raw).decode())
        except (*_READ_ERRORS, UnicodeDecodeError) as e:
            raise DatasetFileError(f"{path}: corrupt header: {e}") from e
        if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
            raise DatasetFileError(f"{path}: not a minimanc world file; {_EXPECTED}")
        if header.get("version") != FILE_FORMAT_VERSION:
            raise DatasetFileError(f"{path}: file format version {header.get('version')!r}, "
                                   f"this minimanc reads version {FILE_FORMAT_VERSION}; "
                                   "regenerate it with `minimanc data generate`")
        if header.get("sha256") != header_sha256(header):
            raise DatasetFileError(f"{path}: header checksum mismatch — the metadata or the "
                                   "array checksums were altered after the file was written")
        shards, n = header.get("shards"), header.get("n_scenes")
        if (not isinstance(shards, list) or not isinstance(n, int)
                or sum(s["stop"] - s["start"] for s in shards) != n):
            raise DatasetFileError(f"{path}: header lists no consistent shards")
        check_meta(header.get("meta"), n, str(path), DatasetFileError)
        if shards:  # the rasters are what the metadata's raster config stores
            try:
                arrays = shards[0]["arrays"]
                bev, goal_bev = arrays["bev"]["shape"], arrays["goal_bev"]["shape"]
            except (KeyError, TypeError) as e:
                raise DatasetFileError(f"{path}: header lists no raster arrays") from e
            check_raster_shapes(header["meta"], bev, goal_bev, str(path), DatasetFileError)
        return header

    @property
    def n_scenes(self) -> int:
        return int(self.header["n_scenes"])

    @property
    def n_shards(self) -> int:
        return len(self.header["shards"])

    def shape(self, name: str) -> tuple[int, ...]:
        first = self.header["shards"][0]["arrays"][name]
        return (self.n_scenes, *first["shape"][1:])

    def dtype(self, name: str) -> np.dtype:
        return np.dtype(self.header["shards"][0]["arrays"][name]["dtype"])

    def shard_array(self, name: str, k: int) -> np.ndarray:
        """Array ``name`` of shard ``k``, checked against the header."""
        path, shard = self.path, self.header["shards"][k]
        info = shard["arrays"].get(name)
        member = member_name(name, k)
        if info is None or member not in self.zf.namelist():
            raise DatasetFileError(f"{path}: array {name!r} of shard {k} is missing")
        try:
            a = _read_npy(self.zf, member)
        except _READ_ERRORS as e:
            raise DatasetFileError(f"{path}: array {name!r} of shard {k} is corrupt: {e}") from e
        n = shard["stop"] - shard["start"]
        if (list(a.shape) != info["shape"] or a.dtype.str != info["dtype"] or a.shape[0] != n
                or list(a.shape[1:]) != list(self.shape(name)[1:])):
            raise DatasetFileError(f"{path}: array {name!r} of shard {k} has an unexpected "
                                   "shape/dtype")
        if array_sha256(a) != info["sha256"]:
            raise DatasetFileError(f"{path}: checksum mismatch in array {name!r} (shard {k})")
        found = first_non_finite({name: a})
        if found is not None:
            raise DatasetFileError(f"{path}: non-finite number in "
                                   f"{describe_non_finite(found, shard['start'])}")
        return a

    def array(self, name: str) -> np.ndarray:
        out = np.empty(self.shape(name), self.dtype(name))
        for k, shard in enumerate(self.header["shards"]):
            out[shard["start"]:shard["stop"]] = self.shard_array(name, k)
        return out

    def close(self) -> None:
        self.zf.close()

    def __enter__(self) -> _Archive:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def read_meta(path: str | os.PathLike) -> dict:
    """The verified metadata of a dataset file, without reading its arrays."""
    with _Archive(path) as ar:
        return ar.header["meta"]


def load(path: str | os.PathLike) -> Dataset:
    """Read a file written by :func:`~minimanc.world.datawriter.save` or
    :func:`~minimanc.world.generation.generate_file`, verifying it (see the module doc)."""
    with _Archive(path) as ar:
        arrays = {name: ar.array(name) for name in ARRAY_FIELDS}
        meta = ar.header["meta"]
    recipes = meta["recipes"]
    try:  # maps are built on first use; check one now so a bad file fails here
        build_map(recipes[0]) if recipes else None
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise DatasetFileError(f"{path}: invalid map recipes: {e}") from e
    return Dataset(**arrays, maps=LazyMaps(recipes), meta=meta)


def file_content_hash(path: str | os.PathLike,
                      on_progress: Callable[[int], None] | None = None) -> str:
    """``load(path).content_hash()``, reading one shard of one array at a time.

    ``on_progress(k)`` is called after each shard read (for progress bars).
    """
    with _Archive(path) as ar:

        def shards(name: str) -> Iterator[np.ndarray]:
            for k in range(ar.n_shards):
                yield ar.shard_array(name, k)
                if on_progress is not None:
                    on_progress(k)

        return content_digest(((name, ar.dtype(name), ar.shape(name), shards(name))
                               for name in ARRAY_FIELDS), ar.header["meta"])
