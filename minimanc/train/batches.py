"""Chapter 8 — the samples of Algorithm 1: training subsets, the loss normalisation, each
model's window length (its :class:`~minimanc.models.ModelSpec` names the
:class:`~minimanc.train.TrainConfig` field), the windows of an epoch and their observations."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from minimanc import inputs, models
from minimanc.train.config import TrainConfig
from minimanc.world.encodings import unpack

__all__ = ["batches", "control_std", "dataset_shape", "initial_q", "make_batch", "subset_scenes",
           "unpack_batch", "window_len"]


def dataset_shape(ds: Any) -> tuple[int, int]:
    """``(S, T)``: scenes and steps of a dataset (from its ego poses ``(S, T, 3)``)."""
    ego = np.asarray(ds.ego) if not hasattr(ds.ego, "shape") else ds.ego
    if len(ego.shape) != 3:
        raise ValueError(f"dataset ego poses must have shape (S, T, 3), got {ego.shape}")
    return int(ego.shape[0]), int(ego.shape[1])


def subset_scenes(n_scenes: int, subset: float, seed: int) -> np.ndarray:
    """Scene indices of a training subset: the first ``⌈subset·S⌉`` of a seeded permutation.

    Nested: for one seed, the 25 % subset is contained in the 50 % one.
    """
    if not 0.0 < subset <= 1.0:
        raise ValueError(f"subset must be in (0, 1], got subset={subset!r}")
    n = max(1, int(math.ceil(subset * n_scenes - 1e-9)))
    perm = np.random.default_rng([int(seed), 7]).permutation(n_scenes)
    return np.sort(perm[:n])


def control_std(ds: Any, scenes: Any = None) -> np.ndarray:
    """Standard deviation of ``[speed, yaw rate]`` over the given scenes (all by default)."""
    c = np.asarray(ds.controls, dtype=np.float64)
    if scenes is not None:
        c = c[np.asarray(scenes)]
    sd = c.reshape(-1, 2).std(axis=0)
    return np.where(sd > 1e-6, sd, 1.0)


def window_len(name: str, tc: TrainConfig) -> int:
    """Training window of model ``name``: the field of ``tc`` its spec's ``window`` names
    (``seq_len`` for the LSTM models, ``dmp_seq_len`` for the DMP models, ``q_seq_len``
    for vAGN-only), or 1."""
    field = models.spec(name).window
    return 1 if field is None else int(getattr(tc, field))


def batches(name: str, ds: Any, scenes: np.ndarray, tc: TrainConfig, epoch: int
            ) -> list[tuple[np.ndarray, np.ndarray]]:
    """The minibatches of one epoch: a list of ``(scene_idx, t_idx)`` arrays of shape ``(L, b)``.

    ``L`` is the window length (1 for feed-forward models); windows tile each
    scene from a random offset, and ``b = max(1, batch_size // L)`` windows
    form a batch. Only full batches are kept (a constant shape for ``jit``)
    unless there are fewer samples than one batch.
    """
    S, T = dataset_shape(ds)
    L = min(window_len(name, tc), T)
    rng = np.random.default_rng([int(tc.seed), int(epoch)])
    starts_s, starts_t = [], []
    for s in scenes:
        off = int(rng.integers(0, L)) if L > 1 else 0
        ts = np.arange(off, T - L + 1, L)
        if ts.size == 0:
            ts = np.array([0])
        starts_s.append(np.full(ts.size, s))
        starts_t.append(ts)
    ss = np.concatenate(starts_s)
    tt = np.concatenate(starts_t)
    order = rng.permutation(ss.size)
    ss, tt = ss[order], tt[order]
    b = max(1, tc.batch_size // L)
    b = min(b, ss.size)
    n_batches = ss.size // b
    out = []
    for i in range(n_batches):
        s_b = ss[i * b:(i + 1) * b]
        t_b = tt[i * b:(i + 1) * b]
        out.append((np.broadcast_to(s_b, (L, b)).copy(), t_b[None, :] + np.arange(L)[:, None]))
    return out


def make_batch(name: str, ds: Any, s_idx: np.ndarray, t_idx: np.ndarray,
                cfg: models.ModelConfig, dtype: Any) -> dict:
    """Observations ``(L, b, ...)`` and controls ``(L, b, 2)`` for index arrays ``(L, b)``;
    for a DMP model on a dataset with driven scenes (:func:`minimanc.inputs.driven_rows`)
    also ``driven (b,)`` bool, the windows whose ``motion`` is the applied control at
    every step (:func:`minimanc.train.step.loss_fn`).

    The numbers are in ``dtype``; a ``"channels"`` raster's ``bev`` (and ``goal_bev``) stay
    the stored uint8 bytes (:func:`minimanc.inputs.from_dataset` with ``packed``), which
    :func:`unpack_batch` turns into the float planes inside the compiled step: unpacking
    there instead of on the host (``benchmarks/bench_raster_training.py``) spares the
    host's unpacking, its float copies and a float32 transfer 24 times larger (12 planes in
    2 bytes), and gives the model the same numbers."""
    L, b = s_idx.shape
    obs = inputs.from_dataset(ds, s_idx.reshape(-1), t_idx.reshape(-1), cfg.setting,
                               model=models.get(name), packed=True)
    batch = {k: v.reshape((L, b) + v.shape[1:]) for k, v in obs.items()}
    batch = {k: v if v.dtype == np.uint8 else v.astype(dtype) for k, v in batch.items()}
    y = np.asarray(ds.controls)[s_idx, t_idx]
    batch["controls"] = y.astype(dtype)
    if models.spec(name).dmp:
        rows = inputs.driven_rows(ds)
        if rows.any():
            batch["driven"] = rows[s_idx[0]]
    return batch


def unpack_batch(batch: dict, cfg: models.ModelConfig) -> dict:
    """``batch`` with each packed raster of :func:`make_batch` (a uint8 ``bev`` or
    ``goal_bev``) replaced by its float planes (:func:`minimanc.world.encodings.unpack`,
    ``cfg.bev_shape[2]`` of them) in the dtype of ``batch["controls"]``; other entries as
    they are. Called at the top of Algorithm 1's loss (:func:`minimanc.train.step.loss_fn`),
    so inside the jitted step."""
    out = dict(batch)
    for key in ("bev", "goal_bev"):
        v = out.get(key)
        if v is not None and v.dtype == np.uint8:
            out[key] = unpack(v, cfg.bev_shape[2], dtype=batch["controls"].dtype)
    return out


def initial_q(name: str, b: int, cfg: models.ModelConfig, tc: TrainConfig,
              rng: np.random.Generator, dtype: Any) -> np.ndarray | None:
    """Algorithm 1's q' for a minibatch of ``b`` samples (uniform or random, ``tc.q_init``);
    ``None`` for models without a vAGN."""
    if models.spec(name).family != "vagn":
        return None
    st = models.initial_state(name, b, cfg, xp=np, rng=rng, mode=tc.q_init, dtype=dtype)
    return np.asarray(st["q"])
