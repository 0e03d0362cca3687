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
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import tempfile
import time
import zipfile
import zlib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from minimanc.world.driver import MAX_ADOS, T_STEPS, check_scene, simulate_scene
from minimanc.world.geometry import DT, goal_in_ego_frame
from minimanc.world.maps import K_TARGETS, Map, build_map, lane_targets, random_recipe
from minimanc.world.raster import RasterConfig, rasterize_batch, rasterize_goal

FORMAT_VERSION = 1
"""Version of the generator and of the dataset layout, recorded as ``meta["version"]``."""
FILE_FORMAT_VERSION = 2
"""Version of the file format (2: sharded, metadata under the checksum); files of another
version are refused."""
MAX_ATTEMPTS = 25
"""Redraws allowed per scene before giving up."""
SHARD_BYTES = 64 * 2**20
"""Target uncompressed size of one shard (the memory :func:`generate_file` needs)."""

ARRAY_FIELDS = ("bev", "ego", "controls", "goal", "lane_target", "ado", "ado_valid", "goal_bev")
FLOAT_FIELDS = ("ego", "controls", "goal", "lane_target", "ado")
"""The float arrays, which must hold finite numbers only."""
META_KEYS = ("seed", "version", "dt", "raster", "recipes", "tags", "attempts", "scene_index")
"""Keys every dataset's ``meta`` holds (the per-scene ones hold one entry per scene)."""
PER_SCENE_KEYS = ("recipes", "tags", "attempts", "scene_index")

_FORMAT_NAME = "minimanc.world"
_NPY_MAGIC = b"\x93NUMPY"
_EXPECTED = ("expected a dataset archive (.npz) written by minimanc.world.save or "
             "`minimanc data generate`")


class DatasetFileError(ValueError):
    """A dataset file that cannot be used (not ours, truncated, corrupt, altered, wrong version)."""


class LazyMaps(Sequence):
    """A read-only list of maps built from their recipes on first access (then kept)."""

    def __init__(self, recipes: list[dict], built: dict[int, Map] | None = None) -> None:
        self._recipes = list(recipes)
        self._built: dict[int, Map] = dict(built or {})

    def __len__(self) -> int:
        return len(self._recipes)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        i = range(len(self))[i]  # bounds check and negative indices
        m = self._built.get(i)
        if m is None:
            m = self._built[i] = build_map(self._recipes[i])
        return m

    def __repr__(self) -> str:
        return f"LazyMaps({len(self)} maps, {len(self._built)} built)"


@dataclass
class Dataset:
    """S scenes of T steps. Arrays are NumPy; see the field comments for shapes.

    ``maps[i]`` is scene ``i``'s :class:`~minimanc.world.maps.Map` (with the
    ego's route; built from its recipe on first access, see :class:`LazyMaps`);
    ``meta`` holds ``seed``, ``version``, ``raster`` (the :class:`RasterConfig`
    as a dict), ``recipes``, ``tags`` (per scene: kind,
    has_junction, has_roundabout, has_cut_in, turn, style, ...), ``attempts``
    and ``scene_index`` (index of each scene in its generation run).
    """

    bev: np.ndarray  # uint8 (S, T, H, W, 3) raster at the logged ego pose, ados at step t
    ego: np.ndarray  # float32 (S, T, 3) logged ego pose [x, y, yaw], world frame
    controls: np.ndarray  # float32 (S, T, 2) [speed, yaw rate] applied from t to t+1
    goal: np.ndarray  # float32 (S, T, 3) final human pose in the ego frame at step t
    lane_target: np.ndarray  # float32 (S, T, K, 2) route points ahead every 4 m, ego frame
    ado: np.ndarray  # float32 (S, T, A, 5) [x, y, yaw, length, width], world frame
    ado_valid: np.ndarray  # bool (S, T, A)
    goal_bev: np.ndarray  # uint8 (S, H, W, 3) static raster seen from the goal (RvS-G)
    maps: Sequence[Map] = field(repr=False)
    meta: dict = field(repr=False)

    def __len__(self) -> int:
        return int(self.ego.shape[0])

    def __repr__(self) -> str:
        S, T = self.ego.shape[:2]
        return (f"Dataset(scenes={S}, steps={T}, raster={self.bev.shape[2:]}, "
                f"ados={self.ado.shape[2]}, seed={self.meta.get('seed')}, "
                f"version={self.meta.get('version')})")

    @property
    def n_steps(self) -> int:
        return int(self.ego.shape[1])

    @property
    def tags(self) -> list[dict]:
        return self.meta["tags"]

    @property
    def raster(self) -> RasterConfig:
        return RasterConfig(**self.meta["raster"])

    @property
    def dt(self) -> float:
        return float(self.meta.get("dt", DT))

    def subset(self, indices) -> Dataset:
        """The scenes ``indices`` (a slice, a list or an integer array)."""
        idx = np.arange(len(self))[indices]
        idx = np.atleast_1d(idx)
        meta = dict(self.meta)
        for key in ("recipes", "tags", "attempts", "scene_index"):
            meta[key] = [self.meta[key][i] for i in idx]
        arrays = {f: getattr(self, f)[idx] for f in ARRAY_FIELDS}
        return Dataset(**arrays, maps=[self.maps[i] for i in idx], meta=meta)

    def split(self, n_train: int = 650) -> tuple[Dataset, Dataset]:
        """First ``n_train`` scenes for training, the rest for validation."""
        if not (isinstance(n_train, int | np.integer) and 0 < n_train < len(self)):
            raise ValueError(f"n_train must be an integer in [1, {len(self) - 1}], "
                             f"got {n_train!r}")
        return self.subset(slice(0, n_train)), self.subset(slice(n_train, None))

    def content_hash(self) -> str:
        """SHA-256 of all arrays and the scene metadata (same seed -> same hash)."""
        h = hashlib.sha256()
        for name in ARRAY_FIELDS:
            a = np.ascontiguousarray(getattr(self, name))
            h.update(f"{name}:{a.dtype.str}:{a.shape}".encode())
            h.update(a.tobytes())
        for key in ("recipes", "tags"):
            h.update(json.dumps(self.meta[key], sort_keys=True).encode())
        return h.hexdigest()


# --------------------------------------------------------------------------- checks


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


def check_finite(arrays: Any, what: str = "dataset") -> None:
    """Raise ``ValueError`` naming the array, scene and step of the first non-finite number."""
    found = first_non_finite(arrays)
    if found is not None:
        raise ValueError(f"{what} holds a non-finite number: {describe_non_finite(found)}; "
                         "every float array must be finite")


# --------------------------------------------------------------------------- generation


def generate_scene(seed: int, index: int, cfg: RasterConfig, k_targets: int = K_TARGETS,
                   max_ados: int = MAX_ADOS) -> dict:
    """Generate scene ``index`` of run ``seed``: arrays for one scene plus recipe and tags."""
    for attempt in range(MAX_ATTEMPTS):
        rng = np.random.default_rng([int(seed), int(index), attempt])
        recipe = random_recipe(rng)
        m = build_map(recipe)
        log = simulate_scene(m, rng, T=T_STEPS, max_ados=max_ados)
        off_road, collision = check_scene(m, log)
        if not (off_road or collision):
            break
    else:
        raise RuntimeError(f"scene {index} of seed {seed}: no valid scene in {MAX_ATTEMPTS} "
                           "attempts")
    # everything derived from the float32 values that are stored, so that re-rendering
    # from the stored poses (as the closed loop does) reproduces the stored rasters exactly
    ego32 = log.ego.astype(np.float32)
    ado32 = np.where(log.ado_valid[..., None], log.ado, 0.0).astype(np.float32)
    ego = ego32.astype(np.float64)
    bev = rasterize_batch(m, ego, ado32.astype(np.float64), log.ado_valid, cfg)
    goal = goal_in_ego_frame(np.broadcast_to(ego[-1], ego.shape), ego)
    lt = lane_targets(m, ego, k_targets)
    return {
        "bev": bev,
        "ego": ego32,
        "controls": log.controls.astype(np.float32),
        "goal": goal.astype(np.float32),
        "lane_target": lt.astype(np.float32),
        "ado": ado32,
        "ado_valid": log.ado_valid.copy(),
        "goal_bev": rasterize_goal(m, ego[-1], cfg),
        "recipe": recipe,
        "tags": log.tags,
        "attempts": attempt + 1,
        "map": m,
    }


def _scene_worker(args: tuple) -> dict:
    out = generate_scene(*args)
    out.pop("map")  # rebuilt from the recipe in the parent (cheaper than pickling)
    return out


def _cache_file(cache: bool | str | os.PathLike, key: dict) -> Path:
    if cache is True:
        root = Path(os.environ.get("MINIMANC_CACHE", Path.home() / ".cache" / "minimanc"))
    else:
        root = Path(cache)
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]
    return root / (f"world_v{FORMAT_VERSION}.{FILE_FORMAT_VERSION}_{key['n_scenes']}x"
                   f"{key['seed']}_{digest}.npz")


def _check_generate_args(n_scenes: Any, seed: Any, raster: Any, k_targets: Any,
                         max_ados: Any) -> RasterConfig:
    if not (isinstance(n_scenes, int | np.integer) and n_scenes >= 1):
        raise ValueError(f"n_scenes must be a positive integer, got {n_scenes!r}")
    if not (isinstance(seed, int | np.integer) and seed >= 0):
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if not (isinstance(k_targets, int | np.integer) and k_targets >= 1):
        raise ValueError(f"k_targets must be a positive integer, got {k_targets!r}")
    if not (isinstance(max_ados, int | np.integer) and max_ados >= 1):
        raise ValueError(f"max_ados must be a positive integer, got {max_ados!r}")
    cfg = raster or RasterConfig()
    if not isinstance(cfg, RasterConfig):
        raise ValueError(f"raster must be a RasterConfig, got {raster!r}")
    return cfg


def _check_workers(workers: Any, n_scenes: int) -> int:
    if workers is None:
        workers = 2 if (n_scenes >= 64 and (os.cpu_count() or 1) >= 2) else 1
    if not (isinstance(workers, int | np.integer) and workers >= 1):
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    return int(workers)


def scene_nbytes(raster: RasterConfig | None = None, k_targets: int = K_TARGETS,
                 max_ados: int = MAX_ADOS, steps: int = T_STEPS) -> int:
    """Uncompressed bytes of one scene's arrays (the memory a scene takes in a shard)."""
    cfg = raster or RasterConfig()
    px = cfg.size * cfg.size * 3
    per_step = px + 4 * (3 + 2 + 3 + 2 * k_targets + 5 * max_ados) + max_ados
    return int(steps * per_step + px)


def default_shard_scenes(raster: RasterConfig | None = None, k_targets: int = K_TARGETS,
                         max_ados: int = MAX_ADOS) -> int:
    """Scenes per shard: as many as fit in :data:`SHARD_BYTES` (at least one)."""
    return max(1, SHARD_BYTES // scene_nbytes(raster, k_targets, max_ados))


def _scene_shards(seed: int, n_scenes: int, cfg: RasterConfig, k_targets: int, max_ados: int,
                  workers: int, shard_scenes: int, bar: Any) -> Iterator[list[dict]]:
    """Scenes ``0 .. n_scenes-1`` in lists of ``shard_scenes`` (one list in memory at a time)."""
    jobs = [(int(seed), i, cfg, int(k_targets), int(max_ados)) for i in range(n_scenes)]
    chunks = [jobs[a:a + shard_scenes] for a in range(0, n_scenes, shard_scenes)]
    if workers == 1:
        for chunk in chunks:
            shard = []
            for job in chunk:
                shard.append(_scene_worker(job))
                bar.update(1)
            yield shard
        return
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    # fork is cheap and works from unguarded scripts; once JAX is loaded (its threads
    # make fork unsafe) use fresh "spawn" processes, which notebooks support
    ctx = mp.get_context("spawn" if "jax" in sys.modules else "fork")
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as ex:
        for chunk in chunks:
            shard = []
            size = max(1, min(8, len(chunk) // (2 * workers)))
            for out in ex.map(_scene_worker, chunk, chunksize=size):
                shard.append(out)
                bar.update(1)
            yield shard


def generate(
    n_scenes: int = 850,
    seed: int = 0,
    raster: RasterConfig | None = None,
    progress: bool = False,
    workers: int | None = None,
    cache: bool | str | os.PathLike | None = None,
    k_targets: int = K_TARGETS,
    max_ados: int = MAX_ADOS,
) -> Dataset:
    """Generate ``n_scenes`` scenes from ``seed`` (deterministic; see the module doc).

    ``raster`` sets the BEV geometry (default :class:`RasterConfig`);
    ``progress`` shows a tqdm bar; ``workers`` processes share the work
    (default: 2 when there are at least 64 scenes and 2 CPUs, else 1; they
    are forked, or spawned if JAX is already imported — scripts then need
    the ``if __name__ == "__main__":`` guard);
    ``cache`` — ``True`` (directory ``$MINIMANC_CACHE`` or
    ``~/.cache/minimanc``) or a directory — reuses a saved result of the same
    arguments and version, and saves new results there. The whole dataset is
    held in memory: for more scenes than fit, use :func:`generate_file`.
    """
    cfg = _check_generate_args(n_scenes, seed, raster, k_targets, max_ados)
    key = {"n_scenes": int(n_scenes), "seed": int(seed), "raster": asdict(cfg),
           "k_targets": int(k_targets), "max_ados": int(max_ados), "version": FORMAT_VERSION}
    cache_path = None
    if cache:
        cache_path = _cache_file(cache, key)
        if cache_path.exists():
            try:
                return load(cache_path)
            except DatasetFileError:
                pass  # regenerate and overwrite a broken cache entry
    workers = _check_workers(workers, int(n_scenes))
    from tqdm import tqdm

    bar = tqdm(total=n_scenes, desc="world scenes", disable=not progress, leave=False)
    scenes: list[dict] = []
    try:
        for shard in _scene_shards(int(seed), int(n_scenes), cfg, k_targets, max_ados, workers,
                                   int(n_scenes), bar):
            scenes.extend(shard)
    finally:
        bar.close()
    ds = _assemble(scenes, seed, cfg)
    if cache_path is not None:
        save(ds, cache_path)
    return ds


@dataclass(frozen=True)
class Estimate:
    """What :func:`estimate` predicts for a :func:`generate_file` run."""

    n_scenes: int
    bytes_per_scene: float  # compressed, measured on scene 0
    seconds_per_scene: float  # one process, measured on scene 0
    workers: int

    @property
    def disk_bytes(self) -> float:
        return self.bytes_per_scene * self.n_scenes

    @property
    def seconds(self) -> float:
        return self.seconds_per_scene * self.n_scenes / self.workers

    def __str__(self) -> str:
        return (f"about {_human_bytes(self.disk_bytes)} on disk and "
                f"{_human_seconds(self.seconds)} with {self.workers} process(es) "
                f"({_human_bytes(self.bytes_per_scene)} and {self.seconds_per_scene:.2f} s "
                "per scene, measured on scene 0)")


def _human_bytes(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    raise AssertionError("unreachable")


def _human_seconds(s: float) -> str:
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


def estimate(n_scenes: int, seed: int = 0, raster: RasterConfig | None = None,
             workers: int | None = None, k_targets: int = K_TARGETS,
             max_ados: int = MAX_ADOS) -> Estimate:
    """Disk size and time of ``generate_file(n_scenes, ...)``, from generating scene 0.

    The compressed size is that of scene 0's arrays deflated as in the file,
    plus its metadata; the time is scene 0's, divided among ``workers``.
    """
    cfg = _check_generate_args(n_scenes, seed, raster, k_targets, max_ados)
    workers = _check_workers(workers, int(n_scenes))
    t0 = time.perf_counter()
    sc = _scene_worker((int(seed), 0, cfg, int(k_targets), int(max_ados)))
    seconds = time.perf_counter() - t0
    nbytes = sum(len(zlib.compress(np.ascontiguousarray(sc[f]).tobytes(), 6))
                 for f in ARRAY_FIELDS)
    nbytes += len(json.dumps({"recipe": sc["recipe"], "tags": sc["tags"]}))
    return Estimate(int(n_scenes), float(nbytes), float(seconds), workers)


def generate_file(
    path: str | os.PathLike,
    n_scenes: int = 850,
    seed: int = 0,
    raster: RasterConfig | None = None,
    progress: bool = False,
    workers: int | None = None,
    k_targets: int = K_TARGETS,
    max_ados: int = MAX_ADOS,
    shard_scenes: int | None = None,
) -> Path:
    """Generate ``n_scenes`` scenes (as :func:`generate`) straight into the file ``path``.

    Scenes are written in shards of ``shard_scenes`` (default
    :func:`default_shard_scenes`, about :data:`SHARD_BYTES` each), so memory
    stays that of one shard whatever ``n_scenes``. ``load(path)`` gives what
    ``generate(n_scenes, seed, ...)`` gives. The file appears only once
    complete; on failure nothing is left behind.
    """
    cfg = _check_generate_args(n_scenes, seed, raster, k_targets, max_ados)
    workers = _check_workers(workers, int(n_scenes))
    if shard_scenes is None:
        shard_scenes = default_shard_scenes(cfg, k_targets, max_ados)
    if not (isinstance(shard_scenes, int | np.integer) and shard_scenes >= 1):
        raise ValueError(f"shard_scenes must be a positive integer, got {shard_scenes!r}")
    from tqdm import tqdm

    meta = empty_meta(seed, cfg)
    bar = tqdm(total=n_scenes, desc="world scenes", disable=not progress, leave=False)
    try:
        with DatasetWriter(path) as writer:
            for shard in _scene_shards(int(seed), int(n_scenes), cfg, k_targets, max_ados,
                                       workers, int(shard_scenes), bar):
                start = len(meta["recipes"])
                writer.add({f: np.stack([sc[f] for sc in shard]) for f in ARRAY_FIELDS})
                _extend_meta(meta, shard, start)
                del shard
            out = writer.finish(meta)
    finally:
        bar.close()
    return out


def generate_splits(n_train: int = 650, n_val: int = 200, seed: int = 0,
                    **kwargs) -> tuple[Dataset, Dataset]:
    """``generate(n_train + n_val, seed, ...).split(n_train)`` (the paper's 650 / 200)."""
    if not (isinstance(n_train, int | np.integer) and n_train >= 1):
        raise ValueError(f"n_train must be a positive integer, got {n_train!r}")
    if not (isinstance(n_val, int | np.integer) and n_val >= 1):
        raise ValueError(f"n_val must be a positive integer, got {n_val!r}")
    return generate(n_train + n_val, seed=seed, **kwargs).split(n_train)


def empty_meta(seed: int, cfg: RasterConfig) -> dict:
    """The metadata of a dataset with no scenes yet (keys :data:`META_KEYS`, in order):
    every dataset writer of the package starts from it, so the format lives here."""
    return {"seed": int(seed), "version": FORMAT_VERSION, "dt": DT, "raster": asdict(cfg),
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


def _extend_meta(meta: dict, scenes: list[dict], start: int) -> None:
    append_scenes(meta, [sc["recipe"] for sc in scenes], [sc["tags"] for sc in scenes],
                  [sc["attempts"] for sc in scenes], range(start, start + len(scenes)))


def _assemble(scenes: list[dict], seed: int, cfg: RasterConfig) -> Dataset:
    arrays = {f: np.stack([sc[f] for sc in scenes]) for f in ARRAY_FIELDS}
    meta = empty_meta(seed, cfg)
    _extend_meta(meta, scenes, 0)
    built = {i: sc["map"] for i, sc in enumerate(scenes) if "map" in sc}
    return Dataset(**arrays, maps=LazyMaps(meta["recipes"], built), meta=meta)


# --------------------------------------------------------------------------- files


def _sha(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def _header_sha(header: dict) -> str:
    body = {k: v for k, v in header.items() if k != "sha256"}
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


def _member(name: str, shard: int) -> str:
    return f"{name}-{shard:05d}.npy"


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


def remove_temp_files(path: str | os.PathLike) -> list[Path]:
    """Remove what :func:`temp_files` lists (left by a killed writer); returns them."""
    gone = []
    for p in temp_files(path):
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
        fd, tmp = tempfile.mkstemp(prefix=self.path.name + ".", suffix=".tmp",
                                   dir=self.path.parent)
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
        found = first_non_finite(arrays)
        if found is not None:
            raise ValueError(f"dataset holds a non-finite number: "
                             f"{describe_non_finite(found, self._n)}; every float array "
                             "must be finite")
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
            with self._zip.open(_member(f, k), "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, a, allow_pickle=False)
            info[f] = {"sha256": _sha(a), "shape": list(a.shape), "dtype": a.dtype.str}
        n = next(iter(s))
        self._shards.append({"start": self._n, "stop": self._n + n, "arrays": info})
        self._n += n

    def finish(self, meta: dict) -> Path:
        """Write the header (``meta`` and the checksums) and move the file into place."""
        _check_meta(meta, self._n, str(self.path), ValueError)
        header = {"format": _FORMAT_NAME, "version": FILE_FORMAT_VERSION, "n_scenes": self._n,
                  "shards": self._shards, "meta": meta}
        header = json.loads(json.dumps(header))  # the checksum covers what load will read
        header["sha256"] = _header_sha(header)
        hdr = np.frombuffer(json.dumps(header, sort_keys=True).encode(), dtype=np.uint8)
        with self._zip.open("header.npy", "w", force_zip64=True) as fh:
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
    """Write ``ds`` to the file ``path`` (see the module doc for the format); returns the path.

    ``shard_scenes`` scenes go in each shard (default :func:`default_shard_scenes`).
    Raises ``ValueError`` if ``path`` is a directory or ``ds`` holds a
    non-finite number or lacks a metadata key.
    """
    if not isinstance(ds, Dataset):
        raise ValueError(f"ds must be a Dataset, got {type(ds).__name__}")
    path = Path(path)
    _check_target(path)
    check_finite(ds)
    _check_meta(ds.meta, len(ds), str(path), ValueError)
    if shard_scenes is None:
        shard_scenes = max(1, SHARD_BYTES // max(1, sum(
            getattr(ds, f)[:1].nbytes for f in ARRAY_FIELDS)))
    if not (isinstance(shard_scenes, int | np.integer) and shard_scenes >= 1):
        raise ValueError(f"shard_scenes must be a positive integer, got {shard_scenes!r}")
    with DatasetWriter(path) as writer:
        for a in range(0, len(ds), int(shard_scenes)):
            writer.add({f: getattr(ds, f)[a:a + shard_scenes] for f in ARRAY_FIELDS})
        return writer.finish(ds.meta)


def _check_meta(meta: Any, n: int, where: str, err: type[Exception]) -> None:
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


def _read_npy(zf: zipfile.ZipFile, member: str) -> np.ndarray:
    with zf.open(member) as fh:
        return np.lib.format.read_array(fh, allow_pickle=False)


_READ_ERRORS = (zipfile.BadZipFile, zlib.error, ValueError, OSError, EOFError, KeyError)


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
        if "header.npy" not in self.zf.namelist():
            raise DatasetFileError(f"{path}: no header — not a minimanc world file; {_EXPECTED}")
        try:
            raw = _read_npy(self.zf, "header.npy")
            header = json.loads(bytes(raw).decode())
        except (*_READ_ERRORS, UnicodeDecodeError) as e:
            raise DatasetFileError(f"{path}: corrupt header: {e}") from e
        if not isinstance(header, dict) or header.get("format") != _FORMAT_NAME:
            raise DatasetFileError(f"{path}: not a minimanc world file; {_EXPECTED}")
        if header.get("version") != FILE_FORMAT_VERSION:
            raise DatasetFileError(f"{path}: file format version {header.get('version')!r}, "
                                   f"this minimanc reads version {FILE_FORMAT_VERSION}; "
                                   "regenerate "
                                   "it with `minimanc data generate`")
        if header.get("sha256") != _header_sha(header):
            raise DatasetFileError(f"{path}: header checksum mismatch — the metadata or the "
                                   "array checksums were altered after the file was written")
        shards, n = header.get("shards"), header.get("n_scenes")
        if (not isinstance(shards, list) or not isinstance(n, int)
                or sum(s["stop"] - s["start"] for s in shards) != n):
            raise DatasetFileError(f"{path}: header lists no consistent shards")
        _check_meta(header.get("meta"), n, str(path), DatasetFileError)
        return header

    @property
    def n_scenes(self) -> int:
        return int(self.header["n_scenes"])

    def shape(self, name: str) -> tuple[int, ...]:
        first = self.header["shards"][0]["arrays"][name]
        return (self.n_scenes, *first["shape"][1:])

    def dtype(self, name: str) -> np.dtype:
        return np.dtype(self.header["shards"][0]["arrays"][name]["dtype"])

    def shard_array(self, name: str, k: int) -> np.ndarray:
        """Array ``name`` of shard ``k``, checked against the header."""
        path, shard = self.path, self.header["shards"][k]
        info = shard["arrays"].get(name)
        member = _member(name, k)
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
        if _sha(a) != info["sha256"]:
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
    """Read a file written by :func:`save` or :func:`generate_file`; see the module doc."""
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
        h = hashlib.sha256()
        for name in ARRAY_FIELDS:
            h.update(f"{name}:{ar.dtype(name).str}:{ar.shape(name)}".encode())
            for k in range(len(ar.header["shards"])):
                h.update(ar.shard_array(name, k).tobytes())
                if on_progress is not None:
                    on_progress(k)
        meta = ar.header["meta"]
    for key in ("recipes", "tags"):
        h.update(json.dumps(meta[key], sort_keys=True).encode())
    return h.hexdigest()
