"""Chapter 7 — the dataset: generate, split, save and load nuScenes-style scenes.

``generate(n_scenes, seed)`` draws each scene ``i`` from its own random stream
``default_rng([seed, i, attempt])`` — a map, a human style, traffic — and
simulates 40 steps of 0.5 s. A scene in which the human would leave the
drivable area or touch an ado is drawn again (next ``attempt``), so the data
contain neither; the attempts are recorded in ``meta["attempts"]``. Because
each scene depends only on ``(seed, i)``, the result is the same whatever the
number of worker processes, and the first 650 scenes of an 850-scene set are
the 650-scene set.

**Files** (:data:`FILE_FORMAT_VERSION` 2) are zip archives that ``numpy.load`` also opens
(``.npz``, deflate-compressed). The scenes are stored in *shards* of
consecutive scenes, one member ``<array>-<k>.npy`` per array and shard, so
that :func:`generate_file` writes a dataset of any size while holding one
shard in memory. The member ``header.npy`` (JSON, written last) holds the
format version, the metadata (seed, ``dt``, raster config, map recipes, tags,
attempts, scene indices), the shape, dtype and SHA-256 of every shard's
arrays, and a SHA-256 of all of that. A file is written under a temporary
name in its directory and renamed (:func:`os.replace`) once complete, so a
partial dataset is never taken for a complete one; the temporary file is
removed on failure, and stale ones of the same target are removed by the
next write. :func:`load` rebuilds the maps from their recipes and refuses,
with a :class:`DatasetFileError` naming the file, any file that is not one
of ours, truncated, corrupt, altered (arrays *or* metadata), of another
version, missing a metadata key, or holding a non-finite number.

This module gathers the dataset's public names; each part lives in its own module:

* :mod:`~minimanc.world.fileformat` — the format: array fields, metadata
  (:func:`empty_meta`, :func:`append_scenes`, :func:`check_meta`), finite
  checks, member names and checksums;
* :mod:`~minimanc.world.scenes` — :class:`Dataset` in memory (:meth:`Dataset.build`,
  subset, split, content hash) and :class:`LazyMaps`;
* :mod:`~minimanc.world.datawriter` — :class:`DatasetWriter` and :func:`save`;
* :mod:`~minimanc.world.datareader` — :func:`load`, :func:`read_meta`,
  :func:`file_content_hash` (verifying every checksum);
* :mod:`~minimanc.world.generation` — :func:`draw_scene`, :func:`generate_scene`,
  :func:`generate`, :func:`generate_file`, :func:`generate_splits`, :func:`estimate`.
"""

from minimanc.world.datareader import file_content_hash, load, read_meta
from minimanc.world.datawriter import DatasetWriter, remove_temp_files, save, temp_files
from minimanc.world.fileformat import (
    ARRAY_FIELDS,
    FILE_FORMAT_VERSION,
    FLOAT_FIELDS,
    FORMAT_NAME,
    FORMAT_VERSION,
    HEADER_MEMBER,
    META_KEYS,
    PER_SCENE_KEYS,
    SHARD_BYTES,
    DatasetFileError,
    append_scenes,
    array_sha256,
    check_finite,
    check_meta,
    content_digest,
    describe_non_finite,
    empty_meta,
    first_non_finite,
    header_sha256,
    member_name,
)
from minimanc.world.generation import (
    MAX_ATTEMPTS,
    Estimate,
    default_shard_scenes,
    draw_scene,
    estimate,
    generate,
    generate_file,
    generate_scene,
    generate_splits,
    scene_nbytes,
)
from minimanc.world.scenes import Dataset, LazyMaps

__all__ = [
    "ARRAY_FIELDS", "FILE_FORMAT_VERSION", "FLOAT_FIELDS", "FORMAT_NAME", "FORMAT_VERSION",
    "HEADER_MEMBER", "MAX_ATTEMPTS", "META_KEYS", "PER_SCENE_KEYS", "SHARD_BYTES", "Dataset",
    "DatasetFileError", "DatasetWriter", "Estimate", "LazyMaps", "append_scenes", "array_sha256",
    "check_finite", "check_meta", "content_digest", "default_shard_scenes", "describe_non_finite",
    "draw_scene", "empty_meta", "estimate", "file_content_hash", "first_non_finite",
    "generate", "generate_file", "generate_scene", "generate_splits", "header_sha256", "load",
    "member_name", "read_meta", "remove_temp_files", "save", "scene_nbytes", "temp_files",
]
