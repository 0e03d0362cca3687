"""The seed-0 draw re-rendered in any raster: the rasteriser of ``minimanc.world`` run on the
stored poses and boxes (as the closed loop renders), cached per raster config.

A raster is stored as the package stores it (``RasterConfig.shape``: RGB, or channels
bit-packed) in ``DATA_DIR/rasters/<config digest>/scenes_<a>-<b>.npy``, one file per block
of :data:`leader_data.BLOCK` scenes (a killed run resumes at the first missing block).
"""

from __future__ import annotations

import hashlib
import json
import os

import leader_data as L
import numpy as np

from minimanc.world import RasterConfig, rasterize_batch
from minimanc.world.history import history_of


def digest(cfg: RasterConfig) -> str:
    """A short name of ``cfg`` (SHA-256 of its metadata)."""
    return hashlib.sha256(json.dumps(cfg.as_meta(), sort_keys=True).encode()).hexdigest()[:12]


def _render_block(ds, scenes: range, cfg: RasterConfig) -> np.ndarray:
    out = []
    for s in scenes:
        ego = np.asarray(ds.ego[s], dtype=np.float64)
        ado = np.asarray(ds.ado[s], dtype=np.float64)
        valid = np.asarray(ds.ado_valid[s])
        past = history_of(ego, ado, valid, cfg.history) if cfg.history else None
        out.append(rasterize_batch(ds.maps[s], ego, ado, valid, cfg, history=past))
    return np.stack(out)


def frames(cfg: RasterConfig, scenes: range, ds=None, progress: bool = True) -> np.ndarray:
    """Stored rasters ``(len(scenes), T, *cfg.shape)`` uint8 of the draw's ``scenes`` (a range
    aligned to blocks of ``L.BLOCK``), rendered once and cached."""
    if scenes.start % L.BLOCK or scenes.stop % L.BLOCK:
        raise ValueError(f"scenes must be whole blocks of {L.BLOCK}, got {scenes}")
    root = L.DATA_DIR / "rasters" / digest(cfg)
    root.mkdir(parents=True, exist_ok=True)
    (root / "config.json").write_text(json.dumps(cfg.as_meta(), sort_keys=True))
    parts = []
    for a in range(scenes.start, scenes.stop, L.BLOCK):
        path = root / f"scenes_{a:04d}-{a + L.BLOCK - 1:04d}.npy"
        if not path.exists():
            ds = L.world() if ds is None else ds
            if progress:
                print(f"render {digest(cfg)} scenes {a}-{a + L.BLOCK - 1}", flush=True)
            block = _render_block(ds, range(a, a + L.BLOCK), cfg)
            tmp = path.with_suffix(".tmp.npy")
            np.save(tmp, block)
            os.replace(tmp, path)
        parts.append(np.load(path, mmap_mode="r"))
    return np.concatenate(parts)
