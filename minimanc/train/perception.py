"""Chapter 8 — the auxiliary perception loss of Algorithm 1: every image model's backbone
asked to hold what the expert perceives, with the leader's losses masked where there is none.

Behaviour cloning (Algorithm 1) supervises only the controls; a backbone trained that way
need not keep the leader's gap or its closing speed, the numbers the expert brakes on. The
auxiliary loss supervises them too, for every image model alike: a linear read-out of the
flattened backbone features (:func:`perception_outputs`; the flattening keeps *where* a
feature fires, which eq. 7's global average pooling discards) predicts :class:`PerceptionTargets`,
and :func:`minimanc.train.step.loss_fn` adds

.. math::

    \\lambda \\, \\frac{1}{N K} \\sum_{n, k} m_{nk} \\, \\ell_k(\\hat y_{nk}, y_{nk}),

with ``λ`` = :attr:`~minimanc.train.TrainConfig.perception_weight`, ``ℓ_k`` the squared
error of the standardised target (:func:`standardised_targets`) for a number and the
logistic loss for a presence flag (``logit``), and the mask ``m``: 0 where a target means
nothing — the gap and the closing speed where there is no leader, the yield distance where
there is no yield point. Without the mask the network is taught "gap = 60 m, closing speed
0" wherever no leader is found and, unsure which car leads, hedges towards 60 m
(``research/seeing_the_leader`` measures both). The targets of a generated dataset come from
:func:`minimanc.diagnose.perception_targets`; the caller passes them to
:func:`minimanc.train.fit` (``perception=``).

The read-out's parameters live under ``params["perception"]`` while training (drawn from
their own stream, so the model's own initialisation does not change) and are not part of the
controller :func:`~minimanc.train.fit` returns.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from minimanc import layers, models

__all__ = ["PerceptionTargets", "concat_targets", "init_perception_head", "load_targets",
           "masked_perception_loss", "perception_outputs", "perception_term", "save_targets",
           "standardised_targets"]

BATCH_KEYS = ("perception", "perception_mask", "perception_logit")
"""The batch entries of the auxiliary loss (not observations): standardised targets
``(L, b, K)``, their mask ``(L, b, K)`` and the presence flags ``(K,)``."""


@dataclass(frozen=True)
class PerceptionTargets:
    """What the expert perceives in every state of a dataset, and where each number counts.

    Attributes
    ----------
    names : tuple of str
        The ``K`` targets, in order.
    values : numpy.ndarray, shape (S, T, K)
        Their values in every state (finite; a masked value is never read).
    mask : numpy.ndarray of bool, shape (S, T, K)
        Where each target counts in the loss.
    logit : tuple of bool
        Per target: a presence flag in {0, 1} (logistic loss) rather than a number (squared
        error after standardisation).

    Raises
    ------
    ValueError
        On shapes that disagree, a non-finite value or a presence flag other than 0 or 1.
    """

    names: tuple[str, ...]
    values: np.ndarray
    mask: np.ndarray
    logit: tuple[bool, ...]

    def __post_init__(self) -> None:
        K = len(self.names)
        values, mask = np.asarray(self.values), np.asarray(self.mask)
        if K == 0 or values.ndim != 3 or values.shape[2] != K:
            raise ValueError(f"values must have shape (S, T, {K}) for names={self.names!r}, "
                             f"got {values.shape}")
        if mask.shape != values.shape or mask.dtype != bool:
            raise ValueError(f"mask must be bool of the values' shape {values.shape}, got "
                             f"{mask.dtype} {mask.shape}")
        if len(self.logit) != K:
            raise ValueError(f"logit must have one flag per name ({K}), got {len(self.logit)}")
        if not np.all(np.isfinite(values)):
            raise ValueError("values must be finite (a masked value too)")
        flags = values[..., np.asarray(self.logit, dtype=bool)]
        if not np.all((flags == 0.0) | (flags == 1.0)):
            raise ValueError("a presence target (logit=True) must be 0 or 1")

    def subset(self, scenes: Any) -> PerceptionTargets:
        """The targets of the scenes ``scenes`` (indices or a slice), in that order: those
        of :meth:`minimanc.world.Dataset.subset` with the same argument."""
        idx = scenes if isinstance(scenes, slice) else np.asarray(scenes, dtype=np.int64)
        return replace(self, values=np.asarray(self.values)[idx],
                       mask=np.asarray(self.mask)[idx])


def concat_targets(parts: Sequence[PerceptionTargets]) -> PerceptionTargets:
    """The targets of ``parts`` one scene block after the other (the targets of
    :func:`minimanc.dagger.concat` of their datasets); ``ValueError`` unless they all have
    the same names, presence flags and steps."""
    if len(parts) == 0:
        raise ValueError("parts must hold at least one PerceptionTargets, got 0")
    first = parts[0]
    for k, p in enumerate(parts[1:], start=1):
        if (p.names, p.logit) != (first.names, first.logit) or \
                np.shape(p.values)[1] != np.shape(first.values)[1]:
            raise ValueError(f"parts[{k}] has names {p.names}, flags {p.logit} and "
                             f"{np.shape(p.values)[1]} steps; parts[0] has {first.names}, "
                             f"{first.logit} and {np.shape(first.values)[1]}")
    if len(parts) == 1:
        return first
    return replace(first, values=np.concatenate([np.asarray(p.values) for p in parts]),
                   mask=np.concatenate([np.asarray(p.mask) for p in parts]))


def save_targets(targets: PerceptionTargets, path: str | Path) -> Path:
    """Write ``targets`` to the ``.npz`` file ``path`` (written beside it, then renamed: a
    killed write leaves no partial file)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.npz")
    np.savez(tmp, names=np.asarray(targets.names), values=np.asarray(targets.values),
             mask=np.asarray(targets.mask), logit=np.asarray(targets.logit, dtype=bool))
    os.replace(tmp, path)
    return path


def load_targets(path: str | Path) -> PerceptionTargets:
    """The :class:`PerceptionTargets` :func:`save_targets` wrote to ``path``; ``ValueError``
    (or ``OSError``) when the file is not such targets."""
    try:
        with np.load(path, allow_pickle=False) as f:
            return PerceptionTargets(tuple(str(n) for n in f["names"]), f["values"],
                                     f["mask"], tuple(bool(b) for b in f["logit"]))
    except (KeyError, EOFError, zipfile.BadZipFile) as exc:  # a key missing, a truncated file
        raise ValueError(f"{path}: not perception targets ({exc})") from exc


def standardised_targets(targets: PerceptionTargets, scenes: Any) -> np.ndarray:
    """The targets as the loss reads them: each number ``(y − mean) / std`` with its mean and
    standard deviation over the states of ``scenes`` where it counts (its mask); presence
    flags unchanged.

    Parameters
    ----------
    targets : PerceptionTargets
    scenes : array_like of int
        The training scenes (e.g. the run's subset).

    Returns
    -------
    numpy.ndarray, shape (S, T, K), float64

    Raises
    ------
    ValueError
        If a number's mask is empty on ``scenes`` (nothing to standardise it by).
    """
    y = np.asarray(targets.values, dtype=np.float64)
    K = y.shape[2]
    seen = y[np.asarray(scenes)].reshape(-1, K)
    m = np.asarray(targets.mask)[np.asarray(scenes)].reshape(-1, K)
    out = y.copy()
    for k in range(K):
        if targets.logit[k]:
            continue
        if not m[:, k].any():
            raise ValueError(f"target {targets.names[k]!r} counts in no state of the training "
                             "scenes: nothing to standardise it by")
        v = seen[m[:, k], k]
        out[..., k] = (y[..., k] - v.mean()) / max(float(v.std()), 1e-6)
    return out


def init_perception_head(rng: np.random.Generator, cfg: models.ModelConfig, k: int) -> dict:
    """The read-out of the auxiliary loss: a dense layer from the flattened backbone features
    (:func:`minimanc.models.zoo.flat_size`) to ``k`` targets
    (:func:`minimanc.layers.init_dense`)."""
    return layers.init_dense(rng, models.zoo.flat_size(cfg), k)


def perception_outputs(params: dict, bev: Any, cfg: models.ModelConfig, eng: Any) -> Any:
    """The read-out's predictions ``(B, K)`` for rasters ``bev (B, H, W, 3)``: the model's
    backbone (:func:`minimanc.models.backbone`), flattened, through ``params["perception"]``
    (:func:`minimanc.layers.dense`). Standardised numbers and presence logits."""
    xp = eng.xp
    dtype = params["backbone"]["convs"][0]["w"].dtype
    f = models.backbone(params["backbone"], xp.asarray(bev, dtype=dtype), cfg, eng)
    return layers.dense(params["perception"], layers.flatten(f, xp), xp)


def masked_perception_loss(out: Any, z: Any, mask: Any, logit: Any, xp: Any = np) -> Any:
    """``(1/(N K)) Σ m · ℓ(out, z)``: the squared error of a number, the logistic loss
    ``log(1 + exp(−(2z − 1)·out))`` of a presence flag, each counted where ``mask`` is 1.

    Parameters
    ----------
    out : array, shape (N, K)
        Predictions (standardised numbers, presence logits).
    z : array, shape (N, K)
        Targets (:func:`standardised_targets`; flags 0 or 1).
    mask : array, shape (N, K)
        1 where a target counts, 0 where it does not (its value is then never read, nor its
        gradient).
    logit : array, shape (K,)
        1 for a presence flag, 0 for a number.
    xp : module
        Array namespace.

    Returns
    -------
    scalar
    """
    s = (2.0 * z - 1.0) * out
    # log(1 + e^{-s}) written so that it never overflows
    bce = xp.maximum(-s, 0.0) + xp.log(1.0 + xp.exp(-xp.abs(s)))
    err = out - z
    per = logit * bce + (1.0 - logit) * err * err
    return xp.sum(per * mask) / (out.shape[0] * out.shape[1])


def perception_term(params: dict, batch: dict, cfg: models.ModelConfig, eng: Any) -> Any:
    """The unweighted auxiliary loss of a training batch: :func:`masked_perception_loss` of
    :func:`perception_outputs` on ``batch["bev"] (L, b, H, W, 3)`` against
    ``batch["perception"]``, ``batch["perception_mask"]`` and ``batch["perception_logit"]``.

    Raises
    ------
    ValueError
        If the batch lacks those entries or the parameters lack ``"perception"`` (train with
        :func:`minimanc.train.fit`'s ``perception=``).
    """
    if any(k not in batch for k in BATCH_KEYS) or "perception" not in params:
        raise ValueError("perception_weight > 0 needs perception targets in the batch and the "
                         "read-out in the parameters: train with minimanc.train.fit(..., "
                         "perception=minimanc.diagnose.perception_targets(ds))")
    xp = eng.xp
    bev = batch["bev"]
    n = bev.shape[0] * bev.shape[1]
    out = perception_outputs(params, xp.reshape(bev, (n,) + tuple(bev.shape[2:])), cfg, eng)
    K = out.shape[1]
    z = xp.reshape(batch["perception"], (n, K))
    m = xp.reshape(batch["perception_mask"], (n, K))
    return masked_perception_loss(out, z, m, batch["perception_logit"], xp)
