"""The modular learner: a perception learned from the raster, feeding the
privileged learner (the two halves of Chen et al. 2019's *Learning by Cheating*, the second
one trained on what the first perceives).

An end-to-end controller (CNN → head, or MANC's CNN → predicates → vAGN → FC → DMP) learns
what to perceive only through Algorithm 1's control loss. The modular learner separates
the two questions the end-to-end one leaves tangled: *can* the raster be read for the
numbers the world's human drives on, and does a controller that reads those numbers drive?

**Perception.** :func:`fit_perception` trains the CNN backbone of :mod:`minimanc.models`
(its convolutions of the raster, flattened) with a read-out to the standardised
:data:`PERCEIVE` features of :mod:`minimanc.diagnose.privileged` in every logged state, on
the perception loss alone: a linear read-out, or, with ``hidden`` units, one hidden layer,
which with ``route=True`` also reads the lane targets (the route ahead that MANC's DMP
gets). :meth:`Perception.read` returns the features in their units. (Until the switch was
deleted, the linear read-out was trained by :func:`minimanc.train.fit` with the control loss
and an auxiliary perception loss at a weight that made the control loss negligible: see
``REPORT.md``.)

**Driving.** :func:`fit_driver` trains the privileged MLP
(:func:`minimanc.diagnose.privileged.fit_privileged`) on the features the perception *reads* in
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
from rounds import Round
from tqdm import tqdm

from minimanc import engine, inputs, models, optim, rollout, train
from minimanc.checks import check_int
from minimanc.dagger.teachers import WorldTeacher
from minimanc.diagnose import policies
from minimanc.diagnose import privileged as P
from minimanc.layers import dense, flatten, init_dense
from minimanc.models.backbone import backbone
from minimanc.world.geometry import DT

PERCEIVE: tuple[str, ...] = tuple(f for f in P.FEATURES if f != "a_prev")
"""What the perception reads: every privileged feature but the last acceleration (a
difference of perceived speeds)."""


@dataclass
class Perception:
    """A trained perception: the CNN's ``params`` (its backbone is used), the ``readout``
    (dense layers with ReLUs between them: one layer is a linear read-out) of the features
    ``names`` standardised by ``mean`` and ``std``, and ``cfg``. With ``route=True`` the
    read-out also takes the ``lane_target`` input (the route ahead, which MANC's DMP gets
    in the paper setting) next to the flattened image features."""

    params: dict
    readout: list[dict]
    mean: np.ndarray
    std: np.ndarray
    cfg: models.ModelConfig
    names: tuple[str, ...] = PERCEIVE
    route: bool = False

    def __post_init__(self) -> None:
        self._eng = engine("jax")
        self._read = self._eng.jit(self.forward)

    @property
    def keys(self) -> tuple[str, ...]:
        """The observation keys it reads."""
        return ("bev", "lane_target") if self.route else ("bev",)

    def forward(self, params: dict, readout: list[dict], bev: Any, lane: Any = None) -> Any:
        """The standardised features read from ``bev (B, H, W, 3)`` (and, with
        :attr:`route`, ``lane (B, K, 2)``), on the JAX engine."""
        xp = self._eng.xp
        h = flatten(backbone(params["backbone"], bev, self.cfg, self._eng), xp)
        if self.route:
            h = xp.concatenate([h, xp.reshape(lane / inputs.LANE_SCALE, (h.shape[0], -1))],
                               axis=1)
        for layer in readout[:-1]:
            h = self._eng.nn.relu(dense(layer, h, xp))
        return dense(readout[-1], h, xp)

    def read(self, bev: Any, lane_target: Any = None) -> np.ndarray:
        """The features :attr:`names` ``(B, K)`` float64 read from rasters ``bev (B, H, W, 3)``
        scaled to ``[0, 1]`` (as :func:`minimanc.inputs.from_dataset` gives them) and, with
        :attr:`route`, the lane targets ``(B, K_TARGETS, 2)``."""
        bev = np.asarray(bev, dtype=np.float32)
        if bev.ndim != 4 or bev.shape[1:] != self.cfg.bev_shape:
            raise ValueError(f"bev must have shape (B, {', '.join(map(str, self.cfg.bev_shape))}),"
                             f" got {bev.shape}")
        lane = None
        if self.route:
            if lane_target is None:
                raise ValueError("this perception reads the route: pass lane_target "
                                 "(B, K, 2)")
            lane = np.asarray(lane_target, dtype=np.float32)
            if lane.ndim != 3 or lane.shape[0] != len(bev) or lane.shape[2] != 2:
                raise ValueError(f"lane_target must have shape ({len(bev)}, K, 2), got "
                                 f"{lane.shape}")
        z = np.asarray(self._read(self.params, self.readout, bev, lane), dtype=np.float64)
        return z * self.std + self.mean


def fit_perception(train_ds: Any, targets: np.ndarray | None = None, epochs: int = 6,
                   lr: float = 1e-3, seed: int = 0, cfg: models.ModelConfig | None = None,
                   progress: bool = False, hidden: int = 0, route: bool = False,
                   batch: int = 64) -> Perception:
    """Train a :class:`Perception` on every logged state of ``train_ds``; ``targets``
    ``(S, T, K)`` are its :data:`PERCEIVE` features
    (:func:`minimanc.diagnose.privileged.perceived`, computed when not given).

    The CNN backbone of :mod:`minimanc.models` and a read-out of its flattened features
    (linear with ``hidden = 0``, else with one hidden ReLU layer of ``hidden`` units; with
    ``route`` it also reads the lane targets) are trained on the perception loss alone: the
    mean squared error of the standardised features, Adam at ``lr``, minibatches of
    ``batch`` states, ``epochs`` passes (:func:`fit_reader`)."""
    y = P.perceived(train_ds, PERCEIVE) if targets is None else np.asarray(targets, float)
    if y.ndim != 3 or y.shape[2] != len(PERCEIVE):
        raise ValueError(f"targets must have shape (S, T, {len(PERCEIVE)}), got {y.shape}")
    cfg = train.config_for_data(cfg or models.ModelConfig(setting="paper"), train_ds, "train_ds")
    return fit_reader(train_ds, y, cfg, epochs, lr, seed, hidden, route, batch, progress)


def observe_states(ds: Any, s: np.ndarray, t: np.ndarray, route: bool
                   ) -> tuple[np.ndarray, np.ndarray | None]:
    """The rasters ``(B, H, W, 3)`` float32 of the logged states ``(s[b], t[b])`` of ``ds``
    and, with ``route``, their lane targets ``(B, K, 2)`` (else ``None``)."""
    spec = models.get("manc" if route else "cnn")  # MANC sees the lane targets in "paper"
    obs = inputs.from_dataset(ds, s, t, "paper", spec)
    lane = np.asarray(obs["lane_target"], dtype=np.float32) if route else None
    return np.asarray(obs["bev"], dtype=np.float32), lane


def fit_reader(train_ds: Any, y: np.ndarray, cfg: models.ModelConfig, epochs: int, lr: float,
               seed: int, hidden: int, route: bool, batch: int, progress: bool = False
               ) -> Perception:
    """The :class:`Perception` of :func:`fit_perception` (arguments as there; ``y`` the
    ``(S, T, K)`` targets)."""
    hidden = check_int("hidden", hidden, 0)
    epochs, batch = check_int("epochs", epochs, 1), check_int("batch", batch, 1)
    rng = np.random.default_rng(seed)
    S, T = y.shape[:2]
    s, t = np.divmod(np.arange(S * T), T)
    parts = [observe_states(train_ds, s[i:i + 500], t[i:i + 500], route)
             for i in range(0, S * T, 500)]
    bev = np.concatenate([b for b, _ in parts])
    lane = np.concatenate([c for _, c in parts]) if route else None
    del parts
    mean, std = y.reshape(-1, y.shape[2]).mean(0), y.reshape(-1, y.shape[2]).std(0) + 1e-6
    z = ((y.reshape(-1, y.shape[2]) - mean) / std).astype(np.float32)
    params = {"backbone": models.init("cnn", rng, cfg, dtype=np.float32)["backbone"]}
    probe = Perception(params, [], mean, std, cfg, route=route)
    n_in = int(np.prod(backbone(params["backbone"], bev[:1], cfg, probe._eng).shape[1:]))
    n_in += lane.shape[1] * 2 if route else 0
    sizes = [n_in, hidden, len(PERCEIVE)] if hidden else [n_in, len(PERCEIVE)]
    readout = [init_dense(rng, a, b, np.float32) for a, b in zip(sizes[:-1], sizes[1:])]
    xp = probe._eng.xp

    def loss(p: dict, bev_b: Any, lane_b: Any, z_b: Any) -> Any:
        miss = probe.forward(p["net"], p["readout"], bev_b, lane_b) - z_b
        return xp.mean(miss * miss)

    grad = probe._eng.value_and_grad(loss)

    def step(p: dict, state: dict, bev_b: Any, lane_b: Any, z_b: Any) -> tuple:
        value, g = grad(p, bev_b, lane_b, z_b)
        p, state = optim.adam_update(g, state, p, lr=lr)
        return p, state, value

    step = probe._eng.jit(step)
    p = {"net": params, "readout": readout}
    state = optim.adam_init(p)
    n = len(z)
    for _ in tqdm(range(epochs), desc="perception", disable=not progress):
        order = rng.permutation(n)
        for i in range(0, n - batch + 1, batch):
            idx = np.sort(order[i:i + batch])
            p, state, _ = step(p, state, bev[idx], None if lane is None else lane[idx], z[idx])
    net = {"backbone": {"convs": [{k: np.asarray(v) for k, v in c.items()}
                                  for c in p["net"]["backbone"]["convs"]]}}
    out = [{k: np.asarray(v) for k, v in layer.items()} for layer in p["readout"]]
    return Perception(net, out, mean, std, cfg, route=route)


def read_dataset(perception: Perception, ds: Any, batch: int = 500) -> np.ndarray:
    """What ``perception`` reads in every logged state of ``ds``: ``(S, T, K)``."""
    S, T = np.asarray(ds.ego).shape[:2]
    s, t = np.divmod(np.arange(S * T), T)
    out = [perception.read(*observe_states(ds, s[i:i + batch], t[i:i + batch],
                                           perception.route))
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
    """``names`` as a tuple if each is one of :data:`~minimanc.diagnose.privileged.FEATURES`,
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
    rendered raster and ``driver`` (a :class:`~minimanc.diagnose.privileged.Privileged`
    learner) turns what it read into ``[clip(v̂ + a Δt, 0, V_MAX), ω]``, ``v̂`` the perceived
    speed; with ``odometer=True`` ``v̂`` is the ego's own speed (the ``motion`` input, as
    MANC's DMP receives it) and only the rest is read from the raster. Its state is the
    last speed of each row."""

    model = None
    setting = "paper"

    def __init__(self, perception: Perception, driver: P.Privileged,
                 odometer: bool = False) -> None:
        self.perception, self.driver, self.odometer = perception, driver, bool(odometer)
        self.keys = perception.keys + (("motion",) if self.odometer else ())
        self.refused = 0  # it is never refused: it needs no expert in the loop

    def initial_state(self, scenes: np.ndarray) -> None:
        return None

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        read = self.perception.read(obs["bev"], obs.get("lane_target"))
        X = with_last_acceleration(read[:, None], self.perception.names)
        if self.odometer:
            X[:, P.FEATURES.index("v")] = np.asarray(obs["motion"], dtype=np.float64)[:, 0]
        v = X[:, P.FEATURES.index("v")]
        if state is not None:
            X[:, P.FEATURES.index("a_prev")] = (v - state) / DT
        a = P.predict(self.driver, X)
        u = np.stack([np.clip(v + a[:, 0] * DT, 0.0, P.V_MAX), a[:, 1]], axis=1)
        return u, v, {}


class OraclePerceivingPolicy(policies.PrivilegedPolicy):
    """A diagnostic of the modular learner: its own speed and last acceleration
    (:data:`ODOMETER`) and the features ``exact`` from the world's human's own perception in
    the state the closed loop reached (as :class:`~minimanc.diagnose.policies.PrivilegedPolicy`
    reads them), every other feature read from the raster by ``perception``; ``driver``
    trained with the same split (:func:`fit_driver` with ``exact`` = :data:`ODOMETER` +
    ``exact``). Which perception errors cost the closed loop shows as the gain of making one
    group exact. With no ``exact`` it is the odometer driver asked in the simulator's state,
    and ``record=True`` keeps what it read in every state reached with the expert's label
    there (``visited()``), for :func:`dagger_driver`."""

    def __init__(self, perception: Perception, driver: P.Privileged, teacher: Any,
                 exact: Sequence[str] = (), record: bool = False) -> None:
        super().__init__(driver, teacher, record=record)
        self.perception = perception
        self.keys = perception.keys + ("motion",)
        self.exact = ODOMETER + tuple(f for f in check_features(exact) if f not in ODOMETER)

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        sits = self.situations(t)
        F = np.array([P.features(s, a) if s is not None else np.zeros(len(P.FEATURES))
                      for s, a in zip(sits, self.a_prev)])
        X = with_last_acceleration(
            self.perception.read(obs["bev"], obs.get("lane_target"))[:, None],
            self.perception.names)
        u, state = self.act(with_exact(X, F, self.exact), sits, state=state)
        return u, state, {}


def dagger_driver(perception: Perception, train_ds: Any, val_ds: Any, rounds: int,
                  per_round: int, agents: str = "reactive", seed: int = 0, steps: int = 3000,
                  read: np.ndarray | None = None, progress: bool = False) -> list[Round]:
    """DAgger for the modular learner's driver (its perception fixed): round 0 is
    :func:`fit_driver` with the odometer; each further round drives ``per_round`` training
    scenes (a seeded order, cycling) with the current driver under ``agents``, keeps what the
    perception read in every state reached with the world's human's label there, aggregates
    and retrains from the previous weights (as
    :func:`rounds.dagger_rounds` does for the privileged learner).
    Every round is driven on ``val_ds`` under ``agents``; ``read`` is what ``perception``
    reads in ``train_ds``'s logged states (:func:`read_dataset`, computed when not given)."""
    rounds = check_int("rounds", rounds, 0)
    per_round = check_int("per_round", per_round, 1)
    teacher, vteacher = WorldTeacher(train_ds, agents=agents), WorldTeacher(val_ds,
                                                                            agents=agents)
    read = read_dataset(perception, train_ds) if read is None else read
    exact, Y = P.demonstrations(train_ds, expert=teacher.expert)
    X = with_exact(with_last_acceleration(read, perception.names), exact)
    model = P.fit_privileged(X, Y, steps=steps, seed=seed)

    def score(m: P.Privileged) -> dict[str, float]:
        return policies.evaluate_policy(OraclePerceivingPolicy(perception, m, vteacher), val_ds,
                                 agents=agents)

    out = [Round(len(X), score(model))]
    order = np.random.default_rng(seed).permutation(len(np.asarray(train_ds.ego)))
    for r in range(rounds):
        pick = order[(np.arange(per_round) + r * per_round) % len(order)]
        policy = OraclePerceivingPolicy(perception, model, teacher, record=True)
        rollout.simulate(policy, train_ds, scenes=np.sort(pick), agents=agents,
                         progress=progress, desc=f"DAgger round {r + 1}")
        Xn, Yn = policy.visited()
        X, Y = np.concatenate([X, Xn]), np.concatenate([Y, Yn])
        model = P.fit_privileged(X, Y, steps=steps, seed=seed + r + 1, init=model)
        out.append(Round(len(X), score(model)))
    return out
