"""Chapter 7 — generating the dataset: scenes drawn from a seed, in memory or streamed to disk.

``generate(n_scenes, seed)`` draws each scene ``i`` from its own random stream
``default_rng([seed, i, attempt])`` (:func:`draw_scene`) — a map, a human
style, traffic — and simulates 40 steps of 0.5 s. A scene in which the human
would leave the drivable area or touch an ado is drawn again (next
``attempt``), so the data contain neither; the attempts are recorded in
``meta["attempts"]``. Because each scene depends only on ``(seed, i)``, the
result is the same whatever the number of worker processes, and the first
650 scenes of an 850-scene set are the 650-scene set. :func:`generate_file`
streams any number of scenes to a file, one shard in memory at a time.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing as mp
import os
import sys
import time
import zlib
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from minimanc.checks import check_int
from minimanc.world.datareader import load
from minimanc.world.datawriter import DatasetWriter, save
from minimanc.world.driver import MAX_ADOS, T_STEPS, check_scene, simulate_scene
from minimanc.world.fileformat import (
    ARRAY_FIELDS,
    FILE_FORMAT_VERSION,
    FORMAT_VERSION,
    SHARD_BYTES,
    DatasetFileError,
    append_scenes,
    empty_meta,
)
from minimanc.world.geometry import goal_in_ego_frame
from minimanc.world.history import history_of
from minimanc.world.lanes import K_TARGETS, Map
from minimanc.world.maps import lane_targets, random_recipe
from minimanc.world.raster import RasterConfig, rasterize_batch, rasterize_goal
from minimanc.world.roads import build_map
from minimanc.world.scenes import Dataset

__all__ = [
    "MAX_ATTEMPTS", "POOL_DIED", "Estimate", "default_shard_scenes", "draw_scene", "estimate",
    "generate", "scene_stream",
    "generate_file", "generate_scene", "generate_splits", "scene_nbytes",
]

MAX_ATTEMPTS = 25
"""Redraws allowed per scene before giving up."""

POOL_DIED: dict[str, str] = {
    "spawn": ("minimanc.world: a worker process died; with JAX imported the workers are "
              "spawned and re-run the calling script: put the call under "
              "`if __name__ == \"__main__\":`, or pass workers=1"),
    "fork": ("minimanc.world: a worker process died while generating scenes (out of "
             "memory?); pass workers=1 to generate in this process"),
}
"""The one-line error of :func:`generate` (and :func:`generate_file`) when a worker process
dies, by the way the workers were started."""


def draw_scene(seed: int, index: int, attempt: int = 0
               ) -> tuple[np.random.Generator, dict, Map]:
    """The start of attempt ``attempt`` of scene ``index`` of run ``seed``.

    Returns ``(rng, recipe, map)``: the scene's random stream
    ``default_rng([seed, index, attempt])`` just after the map was drawn from
    it, the map's recipe and the map. ``simulate_scene(map, rng, ...)`` then
    simulates exactly what :func:`generate_scene` stored; a stored scene's
    attempt is ``meta["attempts"][i] - 1`` and its index
    ``meta["scene_index"][i]``.
    """
    rng, recipe = scene_stream(seed, index, attempt)
    return rng, recipe, build_map(recipe)


def scene_stream(seed: int, index: int, attempt: int = 0
                 ) -> tuple[np.random.Generator, dict]:
    """:func:`draw_scene` without building the map: ``(rng, recipe)``."""
    seed = check_int("seed", seed, 0)
    index = check_int("index", index, 0)
    attempt = check_int("attempt", attempt, 0)
    rng = np.random.default_rng([seed, index, attempt])
    return rng, random_recipe(rng)


def generate_scene(seed: int, index: int, cfg: RasterConfig, k_targets: int = K_TARGETS,
                   max_ados: int = MAX_ADOS) -> dict:
    """Generate scene ``index`` of run ``seed``: arrays for one scene plus recipe and tags."""
    for attempt in range(MAX_ATTEMPTS):
        rng, recipe, m = draw_scene(seed, index, attempt)
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
    ado64 = ado32.astype(np.float64)
    past = history_of(ego, ado64, log.ado_valid, cfg.history) if cfg.history else None
    bev = rasterize_batch(m, ego, ado64, log.ado_valid, cfg, history=past)
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
    check_int("n_scenes", n_scenes, 1)
    check_int("seed", seed, 0)
    check_int("k_targets", k_targets, 1)
    check_int("max_ados", max_ados, 1)
    cfg = raster or RasterConfig()
    if not isinstance(cfg, RasterConfig):
        raise ValueError(f"raster must be a RasterConfig, got {raster!r}")
    return cfg


def _check_workers(workers: Any, n_scenes: int) -> int:
    if workers is None:
        workers = 2 if (n_scenes >= 64 and (os.cpu_count() or 1) >= 2) else 1
    return check_int("workers", workers, 1)


def scene_nbytes(raster: RasterConfig | None = None, k_targets: int = K_TARGETS,
                 max_ados: int = MAX_ADOS, steps: int = T_STEPS) -> int:
    """Uncompressed bytes of one scene's arrays (the memory a scene takes in a shard)."""
    cfg = raster or RasterConfig()
    px = int(np.prod(cfg.shape))
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
    # fork is cheap and works from unguarded scripts; once JAX is loaded (its threads
    # make fork unsafe) use fresh "spawn" processes, which notebooks support
    method = "spawn" if "jax" in sys.modules else "fork"
    try:
        with ProcessPoolExecutor(max_workers=workers,
                                 mp_context=mp.get_context(method)) as ex:
            for chunk in chunks:
                shard = []
                size = max(1, min(8, len(chunk) // (2 * workers)))
                for out in ex.map(_scene_worker, chunk, chunksize=size):
                    shard.append(out)
                    bar.update(1)
                yield shard
    except BrokenProcessPool as exc:
        raise RuntimeError(POOL_DIED[method]) from exc
    except RuntimeError as exc:
        # a spawned worker that re-runs an unguarded script reaches this call again, and
        # multiprocessing refuses to start processes while the worker is starting
        if "bootstrapping phase" in str(exc):
            raise RuntimeError(POOL_DIED["spawn"]) from None
        raise


def _append_meta(meta: dict, scenes: list[dict], start: int) -> None:
    append_scenes(meta, [sc["recipe"] for sc in scenes], [sc["tags"] for sc in scenes],
                  [sc["attempts"] for sc in scenes], range(start, start + len(scenes)))


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
    the ``if __name__ == "__main__":`` guard, and without it the call stops with
    the one-line error :data:`POOL_DIED` saying so);
    ``cache`` — ``True`` (directory ``$MINIMANC_CACHE`` or
    ``~/.cache/minimanc``) or a directory — reuses a saved result of the same
    arguments and version, and saves new results there. The whole dataset is
    held in memory: for more scenes than fit, use :func:`generate_file`.
    """
    cfg = _check_generate_args(n_scenes, seed, raster, k_targets, max_ados)
    key = {"n_scenes": int(n_scenes), "seed": int(seed), "raster": cfg.as_meta(),
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
    bar = tqdm(total=n_scenes, desc="world scenes", disable=not progress, leave=False)
    scenes: list[dict] = []
    try:
        for shard in _scene_shards(int(seed), int(n_scenes), cfg, k_targets, max_ados, workers,
                                   int(n_scenes), bar):
            scenes.extend(shard)
    finally:
        bar.close()
    meta = empty_meta(seed, cfg)
    _append_meta(meta, scenes, 0)
    ds = Dataset.build(scenes, meta, maps=[sc.get("map") for sc in scenes])
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
    shard_scenes = check_int("shard_scenes", shard_scenes, 1)
    meta = empty_meta(seed, cfg)
    bar = tqdm(total=n_scenes, desc="world scenes", disable=not progress, leave=False)
    try:
        with DatasetWriter(path) as writer:
            for shard in _scene_shards(int(seed), int(n_scenes), cfg, k_targets, max_ados,
                                       workers, shard_scenes, bar):
                start = len(meta["recipes"])
                writer.add({f: np.stack([sc[f] for sc in shard]) for f in ARRAY_FIELDS})
                _append_meta(meta, shard, start)
                del shard
            out = writer.finish(meta)
    finally:
        bar.close()
    return out


def generate_splits(n_train: int = 650, n_val: int = 200, seed: int = 0,
                    **kwargs) -> tuple[Dataset, Dataset]:
    """``generate(n_train + n_val, seed, ...).split(n_train)`` (the paper's 650 / 200)."""
    n_train = check_int("n_train", n_train, 1)
    n_val = check_int("n_val", n_val, 1)
    return generate(n_train + n_val, seed=seed, **kwargs).split(n_train)
