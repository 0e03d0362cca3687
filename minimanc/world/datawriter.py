"""Chapter 7 — writing dataset files: :class:`DatasetWriter` (shard by shard) and :func:`save`.

The file format is :mod:`minimanc.world.fileformat`'s: one member per array
and shard, then the JSON header (written last) with every shard's shape,
dtype and SHA-256, the metadata and a SHA-256 of all of that. A file is
written under a temporary name in its directory and renamed
(:func:`os.replace`) once complete, so a partial dataset is never taken for a
complete one; the temporary file is removed on failure, and stale ones of
the same target are removed by the next write (:func:`remove_temp_files`). A temporary
name carries its writer's process id (:func:`temp_prefix`), so that a write never removes
the file another live process on the same machine is still writing (two jobs that fill one
cache entry at once).
"""

from __future__ import annotations

import json
import os
import tempfile
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from minimanc.checks import check_int
from minimanc.world.fileformat import (
    ARRAY_FIELDS,
    FILE_FORMAT_VERSION,
    FORMAT_NAME,
    HEADER_MEMBER,
    SHARD_BYTES,
    array_sha256,
    check_arrays_finite,
    check_meta,
    header_sha256,
    member_name,
)
from minimanc.world.scenes import Dataset

__all__ = ["DatasetWriter", "remove_temp_files", "save", "temp_files", "temp_prefix"]


def temp_files(path: str | os.PathLike) -> list[Path]:
    """Temporary files that writing ``path`` may have left (``<name>.*.tmp``, ``<name>.tmp``)."""
    path = Path(path)
    if not path.parent.is_dir():
        return []
    found = set(path.parent.glob(f"{path.name}.*.tmp"))
    old = path.with_name(path.name + ".tmp")
    if old.exists():
        found.add(old)
    return sorted(p for p in found if p.is_file())


def temp_prefix(path: str | os.PathLike) -> str:
    """The prefix of this process's temporary names for ``path``:
    ``<name>.pid<process id>.`` (:func:`tempfile.mkstemp` adds a random part)."""
    return f"{Path(path).name}.pid{os.getpid()}."


def temp_file(path: str | os.PathLike) -> tuple[int, str]:
    """A new temporary file beside ``path`` (named by :func:`temp_prefix`), open for writing:
    ``(descriptor, name)``. Its mode is that of a file :func:`open` creates (``0o666`` less
    the umask), not :func:`tempfile.mkstemp`'s private ``0o600``, so the file it is renamed to
    can be read as any other the user writes."""
    fd, tmp = tempfile.mkstemp(prefix=temp_prefix(path), suffix=".tmp", dir=Path(path).parent)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    return fd, tmp


def _writer_alive(tmp: Path, target: Path) -> bool:
    """Whether the process named in ``tmp`` (a :func:`temp_prefix` name) is running."""
    rest = tmp.name[len(target.name) + 1:]
    head = rest.split(".", 1)[0]
    if not (head.startswith("pid") and head[3:].isdigit()):
        return False  # an unnamed writer's leftover
    try:
        os.kill(int(head[3:]), 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, another user's
        return True
    return True


def remove_temp_files(path: str | os.PathLike) -> list[Path]:
    """Remove what :func:`temp_files` lists, left by a killed writer (a file whose writing
    process is still running is kept); returns the removed files."""
    gone = []
    for p in temp_files(path):
        if _writer_alive(p, Path(path)):
            continue
        try:
            p.unlink()
            gone.append(p)
        except FileNotFoundError:
            pass
    return gone


def _check_target(path: Path) -> None:
    if path.is_dir():
        raise ValueError(f"path={str(path)!r} is a directory; give a file name such as "
                         f"{str(path / 'world.npz')!r}")


class DatasetWriter:
    """Write a dataset file shard by shard: ``add(arrays)`` per shard, then ``finish(meta)``.

    Used as a context manager, an exception (or a missing ``finish``) removes
    the temporary file, and the target is not created. Each shard's arrays
    must have the same trailing shapes and dtypes; they are checked finite.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        _check_target(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        remove_temp_files(self.path)
        fd, tmp = temp_file(self.path)
        self._tmp = Path(tmp)
        self._fh = os.fdopen(fd, "wb")
        self._zip = zipfile.ZipFile(self._fh, "w", compression=zipfile.ZIP_DEFLATED,
                                    allowZip64=True)
        self._shards: list[dict] = []
        self._n = 0
        self._done = False

    @property
    def n_scenes(self) -> int:
        return self._n

    def add(self, arrays: dict[str, np.ndarray]) -> None:
        """Append one shard: ``arrays[f]`` for every ``f`` in :data:`ARRAY_FIELDS`."""
        missing = [f for f in ARRAY_FIELDS if f not in arrays]
        if missing:
            raise ValueError(f"arrays is missing {missing}")
        arrays = {f: np.ascontiguousarray(arrays[f]) for f in ARRAY_FIELDS}
        s = {int(a.shape[0]) if a.ndim else -1 for a in arrays.values()}
        if len(s) != 1 or s == {-1} or s == {0}:
            raise ValueError("every array of a shard must hold the same number (>= 1) of "
                             f"scenes, got { {f: a.shape for f, a in arrays.items()} }")
        check_arrays_finite(arrays, "dataset", scene_offset=self._n)
        if self._shards:
            first = self._shards[0]["arrays"]
            for f, a in arrays.items():
                if list(a.shape[1:]) != first[f]["shape"][1:] or a.dtype.str != first[f]["dtype"]:
                    raise ValueError(f"array {f!r} of shard {len(self._shards)} has shape "
                                     f"{a.shape} {a.dtype}, earlier shards "
                                     f"{first[f]['shape']} {first[f]['dtype']}")
        k = len(self._shards)
        info = {}
        for f, a in arrays.items():
            with self._zip.open(member_name(f, k), "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, a, allow_pickle=False)
            info[f] = {"sha256": array_sha256(a), "shape": list(a.shape), "dtype": a.dtype.str}
        n = next(iter(s))
        self._shards.append({"start": self._n, "stop": self._n + n, "arrays": info})
        self._n += n

    def finish(self, meta: dict) -> Path:
        """Write the header (``meta`` and the checksums) and move the file into place."""
        check_meta(meta, self._n, str(self.path), ValueError)
        header = {"format": FORMAT_NAME, "version": FILE_FORMAT_VERSION, "n_scenes": self._n,
                  "shards": self._shards, "meta": meta}
        header = json.loads(json.dumps(header))  # the checksum covers what load will read
        header["sha256"] = header_sha256(header)
        hdr = np.frombuffer(json.dumps(header, sort_keys=True).encode(), dtype=np.uint8)
        with self._zip.open(HEADER_MEMBER, "w", force_zip64=True) as fh:
            np.lib.format.write_array(fh, hdr, allow_pickle=False)
        self._zip.close()
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self._fh.close()
        os.replace(self._tmp, self.path)
        self._done = True
        return self.path

    def abort(self) -> None:
        """Drop the temporary file (nothing is written to ``path``)."""
        if self._done:
            return
        self._done = True
        try:
            self._zip.close()
        except Exception:  # noqa: BLE001 - the file is deleted anyway
            pass
        self._fh.close()
        try:
            self._tmp.unlink()
        except FileNotFoundError:
            pass

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.abort()


def save(ds: Dataset, path: str | os.PathLike, shard_scenes: int | None = None) -> Path:
    """Write ``ds`` to the file ``path`` (format: :mod:`minimanc.world.fileformat`).

    ``shard_scenes`` scenes go in each shard (default: as many as fit in
    :data:`~minimanc.world.fileformat.SHARD_BYTES`). Returns the path.
    Raises ``ValueError`` if ``path`` is a directory or ``ds`` holds a
    non-finite number or lacks a metadata key.
    """
    if not isinstance(ds, Dataset):
        raise ValueError(f"ds must be a Dataset, got {type(ds).__name__}")
    path = Path(path)
    _check_target(path)
    check_arrays_finite(ds)
    check_meta(ds.meta, len(ds), str(path), ValueError)
    if shard_scenes is None:
        shard_scenes = max(1, SHARD_BYTES // max(1, sum(
            getattr(ds, f)[:1].nbytes for f in ARRAY_FIELDS)))
    shard_scenes = check_int("shard_scenes", shard_scenes, 1)
    with DatasetWriter(path) as writer:
        for a in range(0, len(ds), shard_scenes):
            writer.add({f: getattr(ds, f)[a:a + shard_scenes] for f in ARRAY_FIELDS})
        return writer.finish(ds.meta)
