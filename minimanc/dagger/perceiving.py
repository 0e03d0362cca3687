"""Chapter 11 — the modular learner: a perception learned from the raster, feeding the
privileged learner (the two halves of Chen et al. 2019's *Learning by Cheating*, the second
one trained on what the first perceives).

An end-to-end controller (CNN → head, or MANC's CNN → predicates → vAGN → FC → DMP) learns
what to perceive only through Algorithm 1's control loss. The modular learner separates
the two questions the end-to-end one leaves tangled: *can* the raster be read for the
numbers the world's human drives on, and does a controller that reads those numbers drive?

**Perception.** :func:`fit_perception` trains the CNN backbone of :mod:`minimanc.models`
(its convolutions of the raster, flattened) with a linear read-out to the standardised
:data:`PERCEIVE` features of :mod:`minimanc.dagger.privileged` in every logged state
(:func:`minimanc.train.fit`'s auxiliary perception loss at a weight that makes the control
loss negligible). :meth:`Perception.read` returns the features in their units.

**Driving.** :func:`fit_driver` trains the privileged MLP
(:func:`minimanc.dagger.privileged.fit_privileged`) on the features the perception *reads* in
the training states (not the exact ones, so that it learns to drive on its own perception's
errors), with the last acceleration taken from the perceived speeds. :class:`PerceivingPolicy`
drives it closed loop on the rendered raster alone: it reads no number from the simulator.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from minimanc import engine, inputs, models, train
from minimanc.dagger import privileged as P
from minimanc.layers import dense, flatten
from minimanc.models.backbone import backbone
from minimanc.world.geometry import DT

__all__ = ["PERCEIVE", "Perception", "PerceivingPolicy", "fit_driver", "fit_perception",
           "read_dataset", "with_last_acceleration"]

PERCEIVE: tuple[str, ...] = tuple(f for f in P.FEATURES if f != "a_prev")
"""What the perception reads: every privileged feature but the last acceleration (a
difference of perceived speeds)."""


@dataclass
class Perception:
    """A trained perception: the CNN's ``params`` (its backbone is used), the linear
    ``readout`` of the features ``names`` standardised by ``mean`` and ``std``, and ``cfg``."""

    params: dict
    readout: dict
    mean: np.ndarray
    std: np.ndarray
    cfg: models.ModelConfig
    names: tuple[str, ...] = PERCEIVE

    def __post_init__(self) -> None:
        self._eng = engine("jax")

        def read(params: dict, readout: dict, bev: Any) -> Any:
            f = backbone(params["backbone"], bev, self.cfg, self._eng)
            return dense(readout, flatten(f, self._eng.xp), self._eng.xp)

        self._read = self._eng.jit(read)

    def read(self, bev: Any) -> np.ndarray:
        """The features :attr:`names` ``(B, K)`` float64 read from rasters ``bev (B, H, W, 3)``
        scaled to ``[0, 1]`` (as :func:`minimanc.inputs.from_dataset` gives them)."""
        bev = np.asarray(bev, dtype=np.float32)
        if bev.ndim != 4 or bev.shape[1:] != (self.cfg.image_size, self.cfg.image_size, 3):
            raise ValueError(f"bev must have shape (B, {self.cfg.image_size}, "
                             f"{self.cfg.image_size}, 3), got {bev.shape}")
        z = np.asarray(self._read(self.params, self.readout, bev), dtype=np.float64)
        return z * self.std + self.mean


def fit_perception(train_ds: Any, targets: np.ndarray | None = None, epochs: int = 6,
                   lr: float = 1e-3, seed: int = 0, weight: float = 100.0,
                   cfg: models.ModelConfig | None = None, progress: bool = False) -> Perception:
    """Train a :class:`Perception` on every logged state of ``train_ds``; ``targets``
    ``(S, T, K)`` are its :data:`PERCEIVE` features
    (:func:`minimanc.dagger.privileged.perceived`, computed when not given)."""
    y = P.perceived(train_ds, PERCEIVE) if targets is None else np.asarray(targets, float)
    if y.ndim != 3 or y.shape[2] != len(PERCEIVE):
        raise ValueError(f"targets must have shape (S, T, {len(PERCEIVE)}), got {y.shape}")
    cfg = cfg or models.ModelConfig(setting="paper")
    tc = train.TrainConfig(epochs=epochs, lr=lr, seed=seed, perception_weight=weight)
    res = train.fit("cnn", train_ds, cfg, tc, progress=progress, perception=y)
    mean, std = train.perception_moments(y, train.subset_scenes(len(y), tc.subset, tc.seed))
    return Perception(res.params, res.readout, mean, std, cfg)


def read_dataset(perception: Perception, ds: Any, batch: int = 500) -> np.ndarray:
    """What ``perception`` reads in every logged state of ``ds``: ``(S, T, K)``."""
    S, T = np.asarray(ds.ego).shape[:2]
    s, t = np.divmod(np.arange(S * T), T)
    out = [perception.read(inputs.from_dataset(ds, s[i:i + batch], t[i:i + batch],
                                               "paper", models.get("cnn"))["bev"])
           for i in range(0, S * T, batch)]
    return np.concatenate(out).reshape(S, T, len(perception.names))


def with_last_acceleration(read: np.ndarray, names: Sequence[str] = PERCEIVE) -> np.ndarray:
    """Features read over whole scenes ``(S, T, K)`` → the privileged learner's inputs
    ``(S·T, len(FEATURES))``, its last acceleration the difference of the perceived speeds
    (0 at each scene's first step)."""
    read = np.asarray(read, dtype=np.float64)
    S, T, _ = read.shape
    X = np.zeros((S, T, len(P.FEATURES)))
    for k, name in enumerate(names):
        X[..., P.FEATURES.index(name)] = read[..., k]
    v = X[..., P.FEATURES.index("v")]
    X[:, 1:, P.FEATURES.index("a_prev")] = np.diff(v, axis=1) / DT
    return X.reshape(S * T, -1)


def fit_driver(perception: Perception, train_ds: Any, steps: int = 3000, seed: int = 0,
               read: np.ndarray | None = None) -> P.Privileged:
    """The privileged MLP trained on what ``perception`` reads in ``train_ds``'s logged
    states (``read``, from :func:`read_dataset` when not given), with the human's logged
    controls as labels."""
    read = read_dataset(perception, train_ds) if read is None else read
    _, Y = P.demonstrations(train_ds)
    return P.fit_privileged(with_last_acceleration(read, perception.names), Y, steps=steps,
                            seed=seed)


class PerceivingPolicy:
    """The modular learner as a closed-loop driver: each step, ``perception`` reads the
    rendered raster and ``driver`` (a :class:`~minimanc.dagger.privileged.Privileged`
    learner) turns what it read into ``[clip(v̂ + a Δt, 0, V_MAX), ω]``, ``v̂`` the perceived
    speed. Its state is the last perceived speed of each row."""

    model = None
    setting = "paper"
    keys = ("bev",)

    def __init__(self, perception: Perception, driver: P.Privileged) -> None:
        self.perception, self.driver = perception, driver
        self.refused = 0  # it is never refused: it needs no expert in the loop

    def initial_state(self, scenes: np.ndarray) -> None:
        return None

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        read = self.perception.read(obs["bev"])
        X = with_last_acceleration(read[:, None], self.perception.names)
        v = X[:, P.FEATURES.index("v")]
        if state is not None:
            X[:, P.FEATURES.index("a_prev")] = (v - state) / DT
        a = P.predict(self.driver, X)
        u = np.stack([np.clip(v + a[:, 0] * DT, 0.0, P.V_MAX), a[:, 1]], axis=1)
        return u, v, {}
