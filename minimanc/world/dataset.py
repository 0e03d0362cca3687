"""Chapter 7 — the dataset: generate, split, save and load nuScenes-style scenes.

``generate(n_scenes, seed)`` draws each scene ``i`` from its own random stream
``default_rng([seed, i, attempt])`` — a map, a human style, traffic — and
simulates 40 steps of 0.5 s. A scene in which the human would leave the
drivable area or touch an ado is drawn again (next ``attempt``), so the data
contain neither; the attempts are recorded in ``meta["attempts"]``. Because
each scene depends only on ``(seed, i)``, the result is the same whatever the
number of worker processes, and the first 650 scenes of an 850-scene set are
the 650-scene set.

Files are ``.npz`` archives (zip, deflate-compressed) with a JSON header that
holds the format version, the metadata (map recipes, tags, raster config) and
a SHA-256 checksum of every array. :func:`load` rebuilds the maps from their
recipes and refuses, with a :class:`DatasetFileError` naming the file, any
archive that is not one of ours, truncated, corrupt, altered or of another
version.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from minimanc.world.driver import MAX_ADOS, T_STEPS, check_scene, simulate_scene
from minimanc.world.geometry import DT, goal_in_ego_frame
from minimanc.world.maps import K_TARGETS, Map, build_map, lane_targets, random_recipe
from minimanc.world.raster import RasterConfig, rasterize_batch, rasterize_goal

FORMAT_VERSION = 1
"""Version of the generator and file format; files of another version are refused."""
MAX_ATTEMPTS = 25
"""Redraws allowed per scene before giving up."""

ARRAY_FIELDS = ("bev", "ego", "controls", "goal", "lane_target", "ado", "ado_valid", "goal_bev")


class DatasetFileError(ValueError):
    """A dataset file that cannot be used (not ours, truncated, corrupt, wrong version)."""


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
        if not (isinstance(n_train, (int, np.integer)) and 0 < n_train < len(self)):
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
    return root / f"world_v{FORMAT_VERSION}_{key['n_scenes']}x{key['seed']}_{digest}.npz"


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
    arguments and version, and saves new results there.
    """
    if not (isinstance(n_scenes, (int, np.integer)) and n_scenes >= 1):
        raise ValueError(f"n_scenes must be a positive integer, got {n_scenes!r}")
    if not (isinstance(seed, (int, np.integer)) and seed >= 0):
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if not (isinstance(k_targets, (int, np.integer)) and k_targets >= 1):
        raise ValueError(f"k_targets must be a positive integer, got {k_targets!r}")
    if not (isinstance(max_ados, (int, np.integer)) and max_ados >= 1):
        raise ValueError(f"max_ados must be a positive integer, got {max_ados!r}")
    cfg = raster or RasterConfig()
    if not isinstance(cfg, RasterConfig):
        raise ValueError(f"raster must be a RasterConfig, got {raster!r}")
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
    if workers is None:
        workers = 2 if (n_scenes >= 64 and (os.cpu_count() or 1) >= 2) else 1
    if not (isinstance(workers, (int, np.integer)) and workers >= 1):
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    from tqdm import tqdm

    jobs = [(int(seed), i, cfg, int(k_targets), int(max_ados)) for i in range(n_scenes)]
    bar = tqdm(total=n_scenes, desc="world scenes", disable=not progress, leave=False)
    scenes: list[dict] = []
    try:
        if workers == 1:
            for job in jobs:
                scenes.append(_scene_worker(job))
                bar.update(1)
        else:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            # fork is cheap and works from unguarded scripts; once JAX is loaded (its threads
            # make fork unsafe) use fresh "spawn" processes, which notebooks support
            ctx = mp.get_context("spawn" if "jax" in sys.modules else "fork")
            with ProcessPoolExecutor(max_workers=int(workers), mp_context=ctx) as ex:
                for out in ex.map(_scene_worker, jobs, chunksize=8):
                    scenes.append(out)
                    bar.update(1)
    finally:
        bar.close()
    ds = _assemble(scenes, seed, cfg)
    if cache_path is not None:
        save(ds, cache_path)
    return ds


def generate_splits(n_train: int = 650, n_val: int = 200, seed: int = 0,
                    **kwargs) -> tuple[Dataset, Dataset]:
    """``generate(n_train + n_val, seed, ...).split(n_train)`` (the paper's 650 / 200)."""
    if not (isinstance(n_train, (int, np.integer)) and n_train >= 1):
        raise ValueError(f"n_train must be a positive integer, got {n_train!r}")
    if not (isinstance(n_val, (int, np.integer)) and n_val >= 1):
        raise ValueError(f"n_val must be a positive integer, got {n_val!r}")
    return generate(n_train + n_val, seed=seed, **kwargs).split(n_train)


def _assemble(scenes: list[dict], seed: int, cfg: RasterConfig) -> Dataset:
    arrays = {f: np.stack([sc[f] for sc in scenes]) for f in ARRAY_FIELDS}
    recipes = [sc["recipe"] for sc in scenes]
    meta = {
        "seed": int(seed),
        "version": FORMAT_VERSION,
        "dt": DT,
        "raster": asdict(cfg),
        "recipes": recipes,
        "tags": [sc["tags"] for sc in scenes],
        "attempts": [int(sc["attempts"]) for sc in scenes],
        "scene_index": list(range(len(scenes))),
    }
    built = {i: sc["map"] for i, sc in enumerate(scenes) if "map" in sc}
    return Dataset(**arrays, maps=LazyMaps(recipes, built), meta=meta)


# --------------------------------------------------------------------------- files


def _sha(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def save(ds: Dataset, path: str | os.PathLike) -> Path:
    """Write ``ds`` to ``path`` (``.npz``, compressed, with checksums); returns the path."""
    if not isinstance(ds, Dataset):
        raise ValueError(f"ds must be a Dataset, got {type(ds).__name__}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = {
        "format": "minimanc.world",
        "version": FORMAT_VERSION,
        "meta": ds.meta,
        "arrays": {f: {"sha256": _sha(getattr(ds, f)), "shape": list(getattr(ds, f).shape),
                       "dtype": getattr(ds, f).dtype.str} for f in ARRAY_FIELDS},
    }
    hdr = np.frombuffer(json.dumps(header, sort_keys=True).encode(), dtype=np.uint8)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        np.savez_compressed(fh, header=hdr, **{f: getattr(ds, f) for f in ARRAY_FIELDS})
    os.replace(tmp, path)
    return path


def load(path: str | os.PathLike) -> Dataset:
    """Read a file written by :func:`save`; see the module doc for the checks."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such dataset file")
    try:
        archive = np.load(path, allow_pickle=False)
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as e:
        raise DatasetFileError(f"{path}: not a readable minimanc world file "
                               f"(truncated or corrupt?): {e}") from e
    with archive:
        try:
            header = json.loads(bytes(archive["header"]).decode())
        except KeyError as e:
            raise DatasetFileError(f"{path}: no header — not a minimanc world file") from e
        except (zipfile.BadZipFile, zlib.error, ValueError, OSError, EOFError,
                UnicodeDecodeError) as e:
            raise DatasetFileError(f"{path}: corrupt header: {e}") from e
        if not isinstance(header, dict) or header.get("format") != "minimanc.world":
            raise DatasetFileError(f"{path}: not a minimanc world file")
        if header.get("version") != FORMAT_VERSION:
            raise DatasetFileError(f"{path}: file format version {header.get('version')!r}, "
                                   f"this minimanc reads version {FORMAT_VERSION}; regenerate "
                                   "it with `minimanc data generate`")
        arrays = {}
        for name in ARRAY_FIELDS:
            info = header["arrays"].get(name)
            try:
                a = archive[name]
            except KeyError as e:
                raise DatasetFileError(f"{path}: array {name!r} is missing") from e
            except (zipfile.BadZipFile, zlib.error, ValueError, OSError, EOFError) as e:
                raise DatasetFileError(f"{path}: array {name!r} is corrupt: {e}") from e
            if info is None or list(a.shape) != info["shape"] or a.dtype.str != info["dtype"]:
                raise DatasetFileError(f"{path}: array {name!r} has an unexpected shape/dtype")
            if _sha(a) != info["sha256"]:
                raise DatasetFileError(f"{path}: checksum mismatch in array {name!r}")
            arrays[name] = a
    meta = header["meta"]
    recipes = meta.get("recipes")
    if not isinstance(recipes, list) or len(recipes) != arrays["ego"].shape[0]:
        raise DatasetFileError(f"{path}: map recipes missing or not one per scene")
    try:  # maps are built on first use; check one now so a bad file fails here
        build_map(recipes[0]) if recipes else None
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise DatasetFileError(f"{path}: invalid map recipes: {e}") from e
    return Dataset(**arrays, maps=LazyMaps(recipes), meta=meta)
