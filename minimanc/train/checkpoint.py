"""Chapter 8 — checkpoints: parameters, optimiser state, the run's configuration and the
raster of its training data written atomically to one ``.npz`` (:func:`save_checkpoint`),
read back (:func:`load_checkpoint`, :func:`load_fit`), and the check that refuses unusable
parameters (:func:`bad_params`)."""

from __future__ import annotations

import json
import os
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from minimanc import models
from minimanc.train.config import PARAM_LIMIT, CheckpointError, FitResult, TrainConfig
from minimanc.train.trained import CHECKPOINT_DEFAULTS, accepts_fit
from minimanc.tree import from_flat_dict, to_flat_dict
from minimanc.tree import map as tree_map
from minimanc.world.datawriter import temp_file
from minimanc.world.raster import RasterConfig

__all__ = ["bad_params", "load_checkpoint", "load_fit", "restore_opt", "save_checkpoint",
           "to_numpy"]

CHECKPOINT_FORMAT = 2
"""The version of the checkpoint's metadata :func:`save_checkpoint` writes and
:func:`load_checkpoint` reads (2: the raster of the training data is recorded); a file of
another version is refused as unreadable."""


def to_numpy(tree: Any) -> Any:
    """A copy of ``tree`` with NumPy leaves (from engine arrays)."""
    return tree_map(np.array, tree)


def bad_params(params: Any, limit: float = PARAM_LIMIT) -> str | None:
    """Why ``params`` cannot be kept — a non-finite entry or one above ``limit`` in
    magnitude, naming the array — or ``None`` when they are fine."""
    worst, where = 0.0, ""
    for key, a in to_flat_dict(to_numpy(params)).items():
        a = np.asarray(a)
        if not np.issubdtype(a.dtype, np.floating) or a.size == 0:
            continue
        if not np.all(np.isfinite(a)):
            return f"non-finite value in {key!r}"
        m = float(np.max(np.abs(a)))
        if m > worst:
            worst, where = m, key
    if worst > limit:
        return f"max |param| = {worst:.3g} in {where!r} exceeds {limit:.0e}"
    return None


def _atomic_savez(path: Path, arrays: dict[str, np.ndarray]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = temp_file(path)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _meta(name: str, cfg: models.ModelConfig, tc: TrainConfig, epoch: int,
          history: list[float], val_history: list[float], steps: int,
          std: np.ndarray, raster: RasterConfig) -> np.ndarray:
    meta = {
        "format": CHECKPOINT_FORMAT,
        "name": name,
        "cfg": cfg.to_dict(),
        "raster": raster.as_meta(),
        "train_cfg": asdict(tc),
        "epoch": epoch,
        "history": history,
        "val_history": val_history,
        "steps": steps,
        "control_std": [float(x) for x in std],
    }
    return np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)


@accepts_fit(CHECKPOINT_DEFAULTS)
def save_checkpoint(path: str | Path, name: str | FitResult, params: dict,
                    cfg: models.ModelConfig, train_cfg: TrainConfig | None = None,
                    opt_state: Any = None, epoch: int = 0, history: Sequence[float] = (),
                    val_history: Sequence[float] = (), steps: int = 0,
                    std: Any = None, raster: RasterConfig | None = None) -> Path:
    """Write parameters (and optionally the optimiser state) atomically to ``path`` (.npz).

    ``save_checkpoint(path, fit)`` writes a :class:`FitResult` (its configurations, loss
    histories, steps, normalisation, raster, and ``epoch = len(fit.history)``), which
    :func:`load_fit` reads back; ``save_checkpoint(path, name, params, cfg, ...,
    raster=...)`` writes the parts. ``raster`` is the :class:`minimanc.world.RasterConfig`
    the training data was drawn with (:func:`minimanc.inputs.raster_of`): a closed loop
    draws the model's input with it.

    Refuses (``ValueError``) parameters that :func:`bad_params` rejects, a missing
    ``raster`` and one whose planes are not those the model reads
    (:func:`minimanc.models.check_input_shape`).
    """
    path = Path(path)
    bad = bad_params(params)
    if bad is not None:
        raise ValueError(f"params cannot be saved to {path}: {bad}")
    if not isinstance(raster, RasterConfig):
        raise ValueError(f"raster must be the world.RasterConfig the training data was drawn "
                         f"with (inputs.raster_of(train_ds)), got raster={raster!r}")
    models.check_input_shape(cfg, raster.input_shape, "raster")
    arrays = {f"params/{k}": v for k, v in to_flat_dict(to_numpy(params)).items()}
    if opt_state is not None:
        arrays.update({f"opt/{k}": v for k, v in to_flat_dict(to_numpy(opt_state)).items()})
    std = np.ones(2) if std is None else np.asarray(std, dtype=np.float64)
    arrays["meta"] = _meta(name, cfg, train_cfg or TrainConfig(), int(epoch), list(history),
                           list(val_history), int(steps), std, raster)
    _atomic_savez(path, arrays)
    return path


def load_checkpoint(path: str | Path) -> dict:
    """Read a file written by :func:`save_checkpoint`: ``name, params, cfg, train_cfg, opt_state,
    epoch, history, val_history, steps, control_std, raster``.

    A file that cannot be read raises :class:`CheckpointError` naming it: truncated or
    corrupt, of another :data:`CHECKPOINT_FORMAT` (one written before the raster was
    recorded), or whose raster's planes are not those its model reads.
    """
    path = Path(path)
    if not path.exists():
        raise ValueError(f"no checkpoint at path={str(path)!r}")
    restart = ("delete it (or train without resume / --resume) to start again from epoch 0")
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(bytes(z["meta"]).decode())
            if meta["format"] != CHECKPOINT_FORMAT:
                raise ValueError(f"checkpoint format {meta['format']!r}, this version reads "
                                 f"{CHECKPOINT_FORMAT}")
            p = {k[len("params/"):]: z[k] for k in z.files if k.startswith("params/")}
            o = {k[len("opt/"):]: z[k] for k in z.files if k.startswith("opt/")}
        cfg_d = dict(meta["cfg"])
        cfg_d["channels"] = tuple(cfg_d["channels"])
        out = {
            "name": meta["name"],
            "params": from_flat_dict(p),
            "opt_state": from_flat_dict(o) if o else None,
            "cfg": models.ModelConfig(**cfg_d),
            "train_cfg": TrainConfig(**meta["train_cfg"]),
            "epoch": meta["epoch"],
            "history": list(meta["history"]),
            "val_history": list(meta["val_history"]),
            "steps": meta["steps"],
            "control_std": np.asarray(meta["control_std"]),
            "raster": RasterConfig(**meta["raster"]),
        }
        models.check_input_shape(out["cfg"], out["raster"].input_shape, "its raster")
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, KeyError, TypeError, ValueError,
            UnicodeDecodeError, AttributeError) as e:
        raise CheckpointError(f"{path}: unreadable checkpoint (truncated, corrupt or of "
                              f"another version: {type(e).__name__}: {e}); {restart}") from e
    bad = bad_params(out["params"])
    if bad is not None:
        raise CheckpointError(f"{path}: checkpoint holds unusable parameters ({bad}); {restart}")
    return out


def load_fit(path: str | Path) -> FitResult:
    """A :class:`FitResult` from a file written by :func:`save_checkpoint` or by :func:`fit`."""
    ck = load_checkpoint(path)
    return FitResult(name=ck["name"], params=ck["params"], history=ck["history"],
                     cfg=ck["cfg"], train_cfg=ck["train_cfg"], val_history=ck["val_history"],
                     steps=ck["steps"], control_std=ck["control_std"], raster=ck["raster"])


def restore_opt(template: Any, loaded: Any) -> Any:
    """Put loaded optimiser arrays into the structure of ``template`` (tuples, scalars)."""
    def restore(t: Any, x: Any) -> Any:
        if isinstance(t, int | np.integer) and not isinstance(t, bool):
            return int(np.asarray(x))
        return np.asarray(x).astype(np.asarray(t).dtype)

    return tree_map(restore, template, loaded)
