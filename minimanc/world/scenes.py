"""Chapter 7 — the :class:`Dataset` in memory: S scenes of T steps, their maps and metadata.

:meth:`Dataset.build` is the one place a dataset is assembled from per-scene
arrays (the world's generator and the highway-env demonstrations both use it),
:func:`minimanc.world.save` writes it (:mod:`minimanc.world.datawriter`), and
:meth:`Dataset.subset` / :meth:`Dataset.split` select scenes (the paper's
650 / 200 split). Maps are rebuilt from their recipes on first access
(:class:`LazyMaps`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from minimanc.checks import check_int
from minimanc.world.fileformat import (
    ARRAY_FIELDS,
    PER_SCENE_KEYS,
    check_arrays_finite,
    check_meta,
    check_raster_shapes,
    content_digest,
)
from minimanc.world.geometry import DT
from minimanc.world.lanes import Map
from minimanc.world.raster import RasterConfig
from minimanc.world.roads import build_map

__all__ = ["Dataset", "LazyMaps"]


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

    ``maps[i]`` is scene ``i``'s :class:`~minimanc.world.lanes.Map` (with the
    ego's route; built from its recipe on first access, see :class:`LazyMaps`);
    ``meta`` holds ``seed``, ``version``, ``raster`` (the :class:`RasterConfig`
    as a dict), ``recipes``, ``tags`` (per scene: kind,
    has_junction, has_roundabout, has_cut_in, turn, style, ...), ``attempts``
    and ``scene_index`` (index of each scene in its generation run).
    """

    bev: np.ndarray  # uint8 (S, T, *raster.shape) raster at the logged ego pose, ados at t
    ego: np.ndarray  # float32 (S, T, 3) logged ego pose [x, y, yaw], world frame
    controls: np.ndarray  # float32 (S, T, 2) [speed, yaw rate] applied from t to t+1
    goal: np.ndarray  # float32 (S, T, 3) final human pose in the ego frame at step t
    lane_target: np.ndarray  # float32 (S, T, K, 2) route points ahead every 4 m, ego frame
    ado: np.ndarray  # float32 (S, T, A, 5) [x, y, yaw, length, width], world frame
    ado_valid: np.ndarray  # bool (S, T, A)
    goal_bev: np.ndarray  # uint8 (S, *raster.shape) static raster seen from the goal (RvS-G)
    maps: Sequence[Map] = field(repr=False)
    meta: dict = field(repr=False)

    @classmethod
    def build(cls, scenes: Sequence[Mapping[str, np.ndarray]], meta: dict,
              maps: Sequence[Map | None] | None = None, what: str = "dataset") -> Dataset:
        """The dataset of ``scenes`` (each a mapping holding :data:`ARRAY_FIELDS`) and ``meta``.

        Each scene's arrays are stacked along a new scene axis. ``meta`` must
        describe as many scenes (:func:`~minimanc.world.fileformat.check_meta`,
        start from :func:`~minimanc.world.fileformat.empty_meta`); the float
        arrays must be finite (``ValueError`` naming ``what``, the array, scene
        and step otherwise). ``maps[i]`` is scene ``i``'s map if already built
        (``None`` or missing: built from ``meta["recipes"][i]`` on first access).
        """
        if len(scenes) == 0:
            raise ValueError(f"scenes must hold at least one scene, got 0 ({what})")
        missing = sorted({f for sc in scenes for f in ARRAY_FIELDS if f not in sc})
        if missing:
            raise ValueError(f"every scene must hold the arrays {ARRAY_FIELDS}; "
                             f"missing {missing} ({what})")
        arrays = {f: np.stack([np.asarray(sc[f]) for sc in scenes]) for f in ARRAY_FIELDS}
        check_arrays_finite(arrays, what)
        check_meta(meta, len(scenes), what)
        check_raster_shapes(meta, arrays["bev"].shape, arrays["goal_bev"].shape, what)
        built = {i: m for i, m in enumerate(maps or ()) if m is not None}
        return cls(**arrays, maps=LazyMaps(meta["recipes"], built), meta=meta)

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
        for key in PER_SCENE_KEYS:
            meta[key] = [self.meta[key][i] for i in idx]
        arrays = {f: getattr(self, f)[idx] for f in ARRAY_FIELDS}
        return Dataset(**arrays, maps=[self.maps[i] for i in idx], meta=meta)

    def split(self, n_train: int = 650) -> tuple[Dataset, Dataset]:
        """First ``n_train`` scenes for training, the rest for validation."""
        if len(self) < 2:
            raise ValueError(f"a dataset of {len(self)} scene cannot be split; it needs >= 2")
        n_train = check_int("n_train", n_train, 1, len(self) - 1)
        return self.subset(slice(0, n_train)), self.subset(slice(n_train, None))

    def content_hash(self) -> str:
        """SHA-256 of all arrays and the scene metadata (same seed -> same hash)."""
        arrays = [getattr(self, name) for name in ARRAY_FIELDS]
        return content_digest(((name, a.dtype, a.shape, [a])
                               for name, a in zip(ARRAY_FIELDS, arrays, strict=True)), self.meta)
