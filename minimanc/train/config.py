"""Chapter 8 — the training hyper-parameters of Algorithm 1 (:class:`TrainConfig`), what
:func:`~minimanc.train.fit` returns (:class:`FitResult`) and how training fails
(:class:`TrainingDiverged`, :class:`CheckpointError`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from minimanc import models
from minimanc.checks import check_int
from minimanc.world.raster import RasterConfig

__all__ = ["CHECKPOINT_NAME", "DTYPES", "PARAM_LIMIT", "CheckpointError", "FitResult",
           "TrainConfig", "TrainingDiverged"]

CHECKPOINT_NAME = "checkpoint.npz"
"""File name of the checkpoint inside ``checkpoint_dir``."""

DTYPES: dict = {"float32": np.float32, "float64": np.float64}
"""The training dtypes :attr:`TrainConfig.dtype` may name."""


PARAM_LIMIT = 1e6
"""Largest parameter magnitude :func:`fit` accepts (trained weights stay far below it)."""


class TrainingDiverged(RuntimeError):
    """Raised when the training loss or the parameters become non-finite or explode."""


class CheckpointError(ValueError):
    """A checkpoint file that cannot be used (truncated, corrupt, not a checkpoint)."""


@dataclass(frozen=True)
class TrainConfig:
    """Training hyper-parameters (Algorithm 1).

    ``epochs``, ``batch_size`` (samples per step; a window of ``L`` steps
    counts ``L`` samples), ``lr`` (Adam), ``seed``, ``subset`` of the
    training scenes, ``seq_len`` (LSTM window length), ``dmp_seq_len``
    (window length of the DMP models, MANC and DMP-only; default 40 = a whole
    20-s scene, longer is clipped to the scene) with
    ``motion_feedback`` (inside a window the DMP starts each step from its own
    previous output, as in closed loop), ``q_init`` ("uniform"/"random",
    Algorithm 1's q' at the start of each window), ``q_seq_len`` (window
    length of vAGN-only; 1 = Algorithm 1), ``normalize`` the MSE per control, ``dtype``
    ("float32"/"float64"), ``zeta_weight`` of the auxiliary
    :func:`minimanc.dmp.zeta_penalty` (DMP models), ``max_steps_per_epoch``
    (``None`` = all; for quick runs), ``grad_clip`` (global gradient-norm
    clip, ``None`` = off), ``perception_weight`` (λ of the masked auxiliary perception loss
    of :mod:`minimanc.train.perception`, for every image model alike; > 0 needs the targets
    of :func:`minimanc.train.fit`'s ``perception``). Its default 0 is Algorithm 1 alone:
    the loss becomes a default only once the closed loop measures that it helps.
    """

    epochs: int = 6
    batch_size: int = 64
    lr: float = 3e-3
    seed: int = 0
    subset: float = 1.0
    seq_len: int = 8
    dmp_seq_len: int = 40
    motion_feedback: bool = True
    q_init: str = "uniform"
    q_seq_len: int = 1
    normalize: bool = True
    dtype: str = "float32"
    zeta_weight: float = 0.0
    max_steps_per_epoch: int | None = None
    grad_clip: float | None = 5.0
    perception_weight: float = 0.0

    def __post_init__(self) -> None:
        for name in ("epochs", "batch_size", "seq_len", "dmp_seq_len", "q_seq_len"):
            check_int(name, getattr(self, name), 1)
        check_int("seed", self.seed, 0)
        if not (isinstance(self.lr, int | float) and math.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr must be a positive finite number, got lr={self.lr!r}")
        if not (isinstance(self.subset, int | float) and 0.0 < self.subset <= 1.0):
            raise ValueError(f"subset must be in (0, 1], got subset={self.subset!r}")
        if self.q_init not in ("uniform", "random"):
            raise ValueError(f"q_init must be 'uniform' or 'random', got q_init={self.q_init!r}")
        if self.dtype not in DTYPES:
            raise ValueError(f"dtype must be one of {tuple(DTYPES)}, got dtype={self.dtype!r}")
        if not (math.isfinite(self.zeta_weight) and self.zeta_weight >= 0):
            raise ValueError(f"zeta_weight must be >= 0, got zeta_weight={self.zeta_weight!r}")
        if self.max_steps_per_epoch is not None:
            check_int("max_steps_per_epoch", self.max_steps_per_epoch, 1)
        c = self.grad_clip
        if c is not None and not (isinstance(c, int | float) and math.isfinite(c) and c > 0):
            raise ValueError(f"grad_clip must be None or > 0, got grad_clip={c!r}")
        w = self.perception_weight
        if isinstance(w, bool) or not (isinstance(w, int | float) and math.isfinite(w)
                                       and w >= 0):
            raise ValueError(f"perception_weight must be a finite number >= 0, got "
                             f"perception_weight={w!r}")


@dataclass
class FitResult:
    """What :func:`fit` returns.

    ``params`` (NumPy pytree), ``history`` (mean training loss per epoch),
    ``val_history`` (open-loop validation loss per epoch, if ``val_ds``),
    ``name``, ``cfg``, ``train_cfg``, ``steps`` (optimiser steps),
    ``seconds`` (wall time of this call), ``control_std`` (the
    normalisation used), ``raster`` (the :class:`minimanc.world.RasterConfig` the training
    data was drawn with, which a closed loop draws the model's input with; ``None`` for a
    result built by hand).
    """

    name: str
    params: dict
    history: list[float]
    cfg: models.ModelConfig
    train_cfg: TrainConfig
    val_history: list[float] = field(default_factory=list)
    steps: int = 0
    seconds: float = 0.0
    control_std: np.ndarray = field(default_factory=lambda: np.ones(2))
    raster: RasterConfig | None = None
