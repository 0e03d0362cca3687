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
With ``odometer=True`` it also reads the one number every vehicle has, its own speed (the
``motion`` input that MANC's DMP integrates from, eqs. 10–13), and perceives only the rest.
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

__all__ = ["ODOMETER", "PERCEIVE", "OraclePerceivingPolicy", "Perception", "PerceivingPolicy",
           "check_features", "fit_driver", "fit_perception", "read_dataset",
           "with_exact", "with_last_acceleration"]

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


ODOMETER: tuple[str, ...] = ("v", "a_prev")
"""What the ego's odometer gives exactly (its own speed, and the last acceleration as the
difference of two speeds) when a driver takes its speed from it instead of the raster."""


def check_features(names: Sequence[str]) -> tuple[str, ...]:
    """``names`` as a tuple if each is one of :data:`~minimanc.dagger.privileged.FEATURES`,
    else a ValueError naming the first that is not."""
    for n in names:
        if n not in P.FEATURES:
            raise ValueError(f"unknown feature {n!r}; the features are {P.FEATURES}")
    return tuple(names)


def with_exact(X: np.ndarray, exact: np.ndarray, names: Sequence[str] = ODOMETER
               ) -> np.ndarray:
    """Features ``X (N, len(FEATURES))`` with the columns ``names`` taken from ``exact``
    (same shape): what a driver reads when those come from the vehicle (:data:`ODOMETER`,
    the default) or, as a diagnostic, from the world's human's own perception."""
    X, exact = np.array(X, dtype=np.float64), np.asarray(exact, dtype=np.float64)
    if X.shape != exact.shape or X.ndim != 2 or X.shape[1] != len(P.FEATURES):
        raise ValueError(f"X and exact must both have shape (N, {len(P.FEATURES)}), got "
                         f"{X.shape} and {exact.shape}")
    cols = [P.FEATURES.index(f) for f in check_features(names)]
    X[:, cols] = exact[:, cols]
    return X


def fit_driver(perception: Perception, train_ds: Any, steps: int = 3000, seed: int = 0,
               read: np.ndarray | None = None, exact: Sequence[str] = ()) -> P.Privileged:
    """The privileged MLP trained on what ``perception`` reads in ``train_ds``'s logged
    states (``read``, from :func:`read_dataset` when not given), with the human's logged
    controls as labels; the features ``exact`` (e.g. :data:`ODOMETER`) are the logged ones
    (:func:`with_exact`) instead of read from the raster."""
    read = read_dataset(perception, train_ds) if read is None else read
    X_exact, Y = P.demonstrations(train_ds)
    X = with_exact(with_last_acceleration(read, perception.names), X_exact, exact)
    return P.fit_privileged(X, Y, steps=steps, seed=seed)


class PerceivingPolicy:
    """The modular learner as a closed-loop driver: each step, ``perception`` reads the
    rendered raster and ``driver`` (a :class:`~minimanc.dagger.privileged.Privileged`
    learner) turns what it read into ``[clip(v̂ + a Δt, 0, V_MAX), ω]``, ``v̂`` the perceived
    speed; with ``odometer=True`` ``v̂`` is the ego's own speed (the ``motion`` input, as
    MANC's DMP receives it) and only the rest is read from the raster. Its state is the
    last speed of each row."""

    model = None
    setting = "paper"

    def __init__(self, perception: Perception, driver: P.Privileged,
                 odometer: bool = False) -> None:
        self.perception, self.driver, self.odometer = perception, driver, bool(odometer)
        self.keys = ("bev", "motion") if self.odometer else ("bev",)
        self.refused = 0  # it is never refused: it needs no expert in the loop

    def initial_state(self, scenes: np.ndarray) -> None:
        return None

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        read = self.perception.read(obs["bev"])
        X = with_last_acceleration(read[:, None], self.perception.names)
        if self.odometer:
            X[:, P.FEATURES.index("v")] = np.asarray(obs["motion"], dtype=np.float64)[:, 0]
        v = X[:, P.FEATURES.index("v")]
        if state is not None:
            X[:, P.FEATURES.index("a_prev")] = (v - state) / DT
        a = P.predict(self.driver, X)
        u = np.stack([np.clip(v + a[:, 0] * DT, 0.0, P.V_MAX), a[:, 1]], axis=1)
        return u, v, {}


class OraclePerceivingPolicy(P.PrivilegedPolicy):
    """A diagnostic of the modular learner: its own speed and last acceleration
    (:data:`ODOMETER`) and the features ``exact`` from the world's human's own perception in
    the state the closed loop reached (as :class:`~minimanc.dagger.privileged.PrivilegedPolicy`
    reads them), every other feature read from the raster by ``perception``; ``driver``
    trained with the same split (:func:`fit_driver` with ``exact`` = :data:`ODOMETER` +
    ``exact``). Which perception errors cost the closed loop shows as the gain of making one
    group exact."""

    keys = ("bev", "motion")

    def __init__(self, perception: Perception, driver: P.Privileged, teacher: Any,
                 exact: Sequence[str]) -> None:
        super().__init__(driver, teacher)
        self.perception = perception
        self.exact = ODOMETER + tuple(f for f in check_features(exact) if f not in ODOMETER)

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        sits = self.situations(t)
        F = np.array([P.features(s, a) if s is not None else np.zeros(len(P.FEATURES))
                      for s, a in zip(sits, self.a_prev)])
        X = with_last_acceleration(self.perception.read(obs["bev"])[:, None],
                                   self.perception.names)
        X = with_exact(X, F, self.exact)
        a = P.predict(self.net, X)
        v = X[:, P.FEATURES.index("v")]
        u = np.stack([np.clip(v + a[:, 0] * DT, 0.0, P.V_MAX), a[:, 1]], axis=1)
        return self.finish(u, sits), state, {}
