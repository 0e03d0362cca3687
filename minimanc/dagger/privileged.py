"""Chapter 11 — the learners that read the world's own numbers: the expert as a policy, and
a behaviour-cloned MLP given exactly what the expert perceives (a *privileged* learner).

Behaviour cloning can fail for two reasons: the learning (Algorithm 1, the closed loop,
the labels) or the information (what the learner sees). A learner given the expert's own
inputs separates them (the "privileged agent" of Chen et al. 2019, *Learning by
Cheating*): if it drives like the expert, learning works and what the image-based models
lack is information.

**Perception.** :meth:`minimanc.dagger.expert.HumanExpert.situation` puts the ego at the
simulator's pose and speed among the step's ados and returns what the world's human
perceives there. :func:`features` turns it into :data:`FEATURES`, grouped as
:data:`FEATURE_GROUPS`:

* ``speed``: the ego's speed ``v``;
* ``history``: its last acceleration ``(v_t − v_{t−1})/Δt`` (0 at the first step), the
  only memory it is given (the human's reaction delay and jerk bound make its next
  acceleration depend on its last ones);
* ``leader``: the gap to the vehicle ahead in its corridor (clipped at :data:`FAR`),
  the speed difference ``v_lead − v`` and whether there is a leader;
* ``stop``: the distance to the point where it must yield at a junction (clipped) and
  whether there is one;
* ``curve``: the braking bound of the curves ahead (``a_curve``, clipped);
* ``lane``: the signed lateral offset from its path, the heading error, and the
  lateral position of the path :data:`AHEAD` metres ahead in the ego frame.

It does not see the scene's hidden style (desired speed, headway, reaction delay) nor
the driver's memory of its last commands, so it is bounded by the style floor, not by
the expert.

**Model.** An MLP (tanh hidden layers, :func:`minimanc.layers.dense`) on standardised
features predicts the acceleration ``a = (v_{t+1} − v_t)/Δt`` and the yaw rate ``ω``;
the control applied is ``[clip(v + a Δt, 0, V_MAX), ω]``. With ``head="dmp"`` the MLP
predicts MANC's four gain logits instead, and the control is one step of MANC's DMP head
(:func:`minimanc.models.dmp_head`, eqs. 10–11) from the ego's motion towards its lane
target (:func:`head_inputs`), clipped the same way: MANC's head given the expert's
perception, the bound of what MANC's perception and automaton can reach through it.
With ``head="vagn"`` the MLP's outputs are MANC's predicates (sigmoid, eq. 7 on the
expert's perception instead of the image), and the rest is MANC: vAGN (eqs. 8–9) carries
``q`` from step to step, ``FC(q)`` gives the gain logits (eq. 11) and the DMP head the
control; trained on whole scenes from the uniform ``q``. It separates what the automaton
and its linear read-out cost from what the visual perception costs. ``head="vagn_predicates"``
lets the gains read the predicates beside ``q`` (``FC(q ⊕ p)``, the DMP-only path added to
MANC's).
:func:`fit_privileged` trains it by Algorithm 1 (minibatches, mean squared error on both
outputs each divided by its standard deviation over the demonstrations, Adam) with
:mod:`minimanc.autodiff`.
``drop`` removes feature groups (the ablation: a group dropped is not an input).

**A perception that errs.** :func:`blur` adds independent Gaussian errors ``N(0, σ_f²)`` to
chosen features (distances then clipped at ``FAR``): a learner trained on blurred
demonstrations and driven by :class:`PrivilegedPolicy` with the same ``noise`` shows how
exact a perception has to be for the privileged learner to stay safe, the yardstick for an
image model's perception (what a linear probe of its features recovers, and how well).

**Policies.** :class:`ExpertPolicy` (the world's human asked in every reached state)
and :class:`PrivilegedPolicy` read the simulator they drive in through ``bind(sim)``
(:func:`minimanc.rollout.driver.drive`), so they run in the same closed loop as every
model. A state the expert cannot be asked in (off the drivable area, far from its
route) is driven with the last applied controls and counted as ``refused``.
:class:`PrivilegedPolicy` can record every state it visits with the expert's label
there, which is one DAgger round (:func:`dagger_rounds`; β_0 = 1, then β_i = 0:
after the demonstrations, the learner drives).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from minimanc import inputs, layers, metrics, optim, rollout, vagn
from minimanc.autodiff import numpy as anp
from minimanc.autodiff import value_and_grad
from minimanc.checks import check_int
from minimanc.dagger.expert import HumanExpert, Situation
from minimanc.dagger.teachers import WorldTeacher
from minimanc.engine import engine_of
from minimanc.metrics.trajectory import along_cross_track
from minimanc.models import DEFAULT_GAINS, ModelConfig, dmp_head, gain_logits, spec
from minimanc.models.zoo import gains_layer
from minimanc.world.geometry import DT, wrap_angle
from minimanc.world.traffic import B_MAX

__all__ = [
    "AHEAD", "FAR", "FEATURES", "FEATURE_GROUPS", "HEADS", "V_MAX", "ExpertPolicy",
    "Privileged", "PrivilegedPolicy", "Round", "advance", "blur", "dagger_rounds",
    "demonstrations", "evaluate_policy", "features", "fit_privileged", "head_inputs", "kept",
    "perceived", "predict", "predict_scenes",
]

FAR: float = 60.0
"""Distances (m) to a leader or a stop point are clipped here; beyond, nothing binds."""
AHEAD: tuple[float, ...] = (5.0, 10.0, 20.0)
"""Arc lengths ahead (m) at which the path's lateral position in the ego frame is read."""
V_MAX: float = 22.0
"""The largest speed (m/s) a control may ask for (the world's human's bound)."""

FEATURE_GROUPS: dict[str, tuple[str, ...]] = {
    "speed": ("v",),
    "history": ("a_prev",),
    "leader": ("gap", "dv", "has_leader"),
    "stop": ("stop", "has_stop"),
    "curve": ("a_curve",),
    "lane": ("lateral", "heading") + tuple(f"ahead_{int(d)}" for d in AHEAD),
}
"""The expert's perception, by group (what the ablation drops one at a time)."""
FEATURES: tuple[str, ...] = tuple(f for g in FEATURE_GROUPS.values() for f in g)
"""Every feature, in the order of :func:`features`' vector."""
HEADS: tuple[str, ...] = ("acceleration", "dmp", "vagn", "vagn_predicates")
"""What the MLP predicts: the acceleration and yaw rate, the gain logits of MANC's DMP head,
or MANC's predicates (vAGN, ``FC(q)`` and the DMP head follow; ``"vagn_predicates"``: the
gains read the predicates beside ``q``, ``FC(q ⊕ p)``)."""


def features(sit: Situation, a_prev: float = 0.0) -> np.ndarray:
    """The vector :data:`FEATURES` (float64) of what the human perceives in ``sit``, with
    ``a_prev`` the ego's last acceleration."""
    ego, path, per, pose = sit.ego, sit.path, sit.perceived, sit.pose
    v = float(ego.v)
    lead = math.isfinite(per["gap"])
    stop = math.isfinite(per["stop"])
    (px, py), h = path.pose(float(ego.s))
    dx, dy = pose[0] - px, pose[1] - py
    lateral = -math.sin(h) * dx + math.cos(h) * dy
    c, s = math.cos(pose[2]), math.sin(pose[2])
    ahead = []
    for d in AHEAD:
        (qx, qy), _ = path.pose(float(ego.s) + d)
        ahead.append(-s * (qx - pose[0]) + c * (qy - pose[1]))
    return np.array([
        v, float(a_prev),
        min(per["gap"], FAR) if lead else FAR, (per["v_lead"] - v) if lead else 0.0,
        float(lead),
        min(per["stop"], FAR) if stop else FAR, float(stop),
        min(max(per["a_curve"], -B_MAX), 4.0),
        lateral, float(wrap_angle(pose[2] - h)), *ahead,
    ])


def blur(X: np.ndarray, noise: Mapping[str, float], rng: np.random.Generator) -> np.ndarray:
    """``X (N, F)`` of :data:`FEATURES` with ``N(0, σ²)`` added to each feature named in
    ``noise`` (name → σ, in the feature's unit; σ = 0 leaves it exact), distances (``gap``,
    ``stop``) then clipped at ``FAR`` and the speed ``v`` at 0; a copy (``X`` is not
    changed)."""
    X = np.array(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != len(FEATURES):
        raise ValueError(f"X must have shape (N, {len(FEATURES)}), got {X.shape}")
    for name, sigma in noise.items():
        if name not in FEATURES:
            raise ValueError(f"unknown feature {name!r} in noise; expected some of {FEATURES}")
        if not (math.isfinite(sigma) and sigma >= 0):
            raise ValueError(f"noise[{name!r}] must be a finite number >= 0, got {sigma!r}")
        if sigma == 0:
            continue
        i = FEATURES.index(name)
        X[:, i] += rng.normal(0.0, sigma, size=len(X))
        if name in ("gap", "stop"):
            X[:, i] = np.minimum(X[:, i], FAR)
        elif name == "v":
            X[:, i] = np.maximum(X[:, i], 0.0)
    return X


def perceived(ds: Any, names: Sequence[str] = FEATURES, expert: HumanExpert | None = None
              ) -> np.ndarray:
    """What the human perceives in every logged state of ``ds``: the :data:`FEATURES`
    ``names`` as ``(S, T, K)`` (the targets of the auxiliary perception loss of
    :func:`minimanc.train.fit`)."""
    bad = [n for n in names if n not in FEATURES]
    if bad or not names:
        raise ValueError(f"names must be some of {FEATURES}; got {list(names)!r}")
    X, _ = demonstrations(ds, expert=expert)
    S, T = np.asarray(ds.ego).shape[:2]
    return X[:, [FEATURES.index(n) for n in names]].reshape(S, T, len(names))


def demonstrations(ds: Any, scenes: Iterable[int] | None = None,
                   expert: HumanExpert | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Features ``X (N, F)`` of every logged state of ``scenes`` (default: all) of ``ds`` and
    the human's logged controls there ``Y (N, 2)`` as ``[acceleration, yaw rate]``."""
    expert = HumanExpert(ds) if expert is None else expert
    ctrl = np.asarray(ds.controls, dtype=np.float64)  # a demonstration: what was applied
    pose = np.asarray(ds.ego, dtype=np.float64)
    X, Y = [], []
    for s in range(len(pose)) if scenes is None else scenes:
        steps = expert.steps(int(s))
        for t, step in enumerate(steps):
            a_prev = (step.speed - steps[t - 1].speed) / DT if t else 0.0
            X.append(features(expert.situation(int(s), t, pose[s, t], step.speed), a_prev))
            Y.append([(ctrl[s, t, 0] - step.speed) / DT, ctrl[s, t, 1]])
    return np.asarray(X), np.asarray(Y)


def head_inputs(ds: Any, scenes: Iterable[int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """What MANC's DMP head reads in every logged state of ``scenes`` (default: all) of
    ``ds``, in the order of :func:`demonstrations`: the lane targets ``(N, K, 2)`` and the
    motion ``(N, 2)`` (:func:`minimanc.inputs.motion_at`), float64."""
    lt = np.asarray(ds.lane_target)
    idx = np.arange(len(lt)) if scenes is None else np.asarray(list(scenes), dtype=np.int64)
    T = lt.shape[1]
    s, t = np.repeat(idx, T), np.tile(np.arange(T), len(idx))
    return (lt[s, t].astype(np.float64),
            inputs.motion_at(ds, s, t).astype(np.float64))


@dataclass
class Privileged:
    """A trained privileged learner: MLP ``params``, the features it reads (``keep``,
    indices into :data:`FEATURES`), their standardisation, the outputs' scales, its
    ``head`` (:data:`HEADS`) and, for the DMP head, the :class:`~minimanc.models.ModelConfig`
    whose look-ahead rules and ``dt`` it steps with."""

    params: dict
    keep: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    scale: np.ndarray
    losses: list[float] = field(default_factory=list)
    head: str = "acceleration"
    cfg: ModelConfig | None = None


def kept(drop: Sequence[str] = (), without: Sequence[str] = ()) -> np.ndarray:
    """Indices of the :data:`FEATURES` left when the groups ``drop`` and the single features
    ``without`` are removed."""
    bad = [g for g in drop if g not in FEATURE_GROUPS]
    if bad:
        raise ValueError(f"unknown feature groups {bad}; expected some of "
                         f"{tuple(FEATURE_GROUPS)}")
    bad = [f for f in without if f not in FEATURES]
    if bad:
        raise ValueError(f"unknown features {bad}; expected some of {FEATURES}")
    gone = {f for g in drop for f in FEATURE_GROUPS[g]} | set(without)
    idx = np.array([i for i, f in enumerate(FEATURES) if f not in gone], dtype=np.int64)
    if len(idx) == 0:
        raise ValueError("drop removes every feature")
    return idx


def _forward(params: dict, x: Any, xp: Any) -> Any:
    h = x
    n = len(params)
    for i in range(n - 1):
        h = xp.tanh(layers.dense(params[f"l{i}"], h, xp=xp))
    return layers.dense(params[f"l{n - 1}"], h, xp=xp)


def fit_privileged(X: np.ndarray, Y: np.ndarray, drop: Sequence[str] = (),
                   hidden: Sequence[int] = (64, 64), steps: int = 3000, batch: int = 256,
                   lr: float = 3e-3, seed: int = 0, init: Privileged | None = None,
                   without: Sequence[str] = (), head: str = "acceleration",
                   lane: np.ndarray | None = None, motion: np.ndarray | None = None,
                   scene_steps: int | None = None) -> Privileged:
    """Train the MLP by behaviour cloning on ``X (N, F)``, ``Y (N, 2)`` (see the module
    docstring) on the features :func:`kept` leaves (``drop``: groups, ``without``: single
    features); ``init`` continues from a trained learner (its inputs, standardisation and
    head kept). ``head="dmp"`` needs the :func:`head_inputs` ``lane (N, K, 2)`` and
    ``motion (N, 2)`` of the same states; its loss is the same (the speed error over
    ``Δt`` against the acceleration's scale, the yaw-rate error against its own).
    ``head="vagn"`` needs them too, and ``scene_steps``: its rows are whole scenes in order
    (as :func:`demonstrations` returns them), each a minibatch window; it does not continue
    from ``init``."""
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != len(FEATURES) or Y.shape != (len(X), 2) or len(X) == 0:
        raise ValueError(f"X must have shape (N, {len(FEATURES)}) and Y (N, 2) with N >= 1; "
                         f"got {X.shape} and {Y.shape}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
        raise ValueError("X and Y must be finite")
    steps = check_int("steps", steps, 1)
    batch = check_int("batch", batch, 1)
    head = init.head if init is not None else head
    if head not in HEADS:
        raise ValueError(f"head must be one of {HEADS}, got head={head!r}")
    if head != "acceleration":
        lane, motion = _check_head_inputs(lane, motion, len(X))
    if head.startswith("vagn") and init is not None:
        raise ValueError(f"head={head!r} trains from scratch: init must be None")
    rng = np.random.default_rng(seed)
    if init is None:
        keep = kept(drop, without)
        mean, std = X[:, keep].mean(0), X[:, keep].std(0) + 1e-6
        scale = Y.std(0) + 1e-6
        cfg = None if head == "acceleration" else ModelConfig(
            k_targets=int(lane.shape[1]),
            gains_input="q+predicates" if head == "vagn_predicates" else "q")
        n_out = 2 if head == "acceleration" else 4 if head == "dmp" else cfg.n_predicates
        sizes = [len(keep), *hidden, n_out]
        params = {f"l{i}": layers.init_dense(rng, a, b)
                  for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:]))}
        last = params[f"l{len(sizes) - 2}"]
        last["w"] = last["w"] * 0.1
        if head == "dmp":  # start at MANC's fixed gains, as its gains layer does
            last["b"] = np.asarray(gain_logits(DEFAULT_GAINS), dtype=np.float64)
        if head.startswith("vagn"):
            params.update(_automaton(rng, cfg))
    else:
        keep, mean, std, scale, params = init.keep, init.mean, init.std, init.scale, init.params
        cfg = init.cfg
    Z = (X[:, keep] - mean) / std
    if head.startswith("vagn"):
        return _fit_scenes(Privileged(params, keep, mean, std, scale, [], head, cfg), Z, X,
                           Y, lane, motion, _check_scene_steps(scene_steps, len(X)), steps,
                           batch, lr, rng)
    if head == "dmp":
        v = X[:, FEATURES.index("v")]
        T = np.stack([v + Y[:, 0] * DT, Y[:, 1]], axis=1) / (scale * np.array([DT, 1.0]))

        def loss(p: dict, x: Any, y: Any, lt: Any, mo: Any) -> Any:
            u, _ = dmp_head(_forward(p, x, anp), lt, mo, cfg, xp=anp)
            d = u / (scale * np.array([DT, 1.0])) - y
            return anp.mean(d * d)
    else:
        T = Y / scale

        def loss(p: dict, x: Any, y: Any, lt: Any, mo: Any) -> Any:
            d = _forward(p, x, anp) - y
            return anp.mean(d * d)

    step_fn = value_and_grad(loss)
    state = optim.adam_init(params)
    losses = []
    for k in range(steps):
        i = rng.integers(0, len(Z), size=min(batch, len(Z)))
        lr_k = lr * 0.5 * (1.0 + math.cos(math.pi * k / steps))  # cosine decay
        value, g = step_fn(params, Z[i], T[i], None if lane is None else lane[i],
                           None if motion is None else motion[i])
        params, state = optim.adam_update(g, state, params, lr=lr_k)
        losses.append(float(value))
    return Privileged(params, keep, mean, std, scale, losses, head, cfg)


def _automaton(rng: np.random.Generator, cfg: ModelConfig) -> dict:
    """MANC's vAGN weights and gains layer (eqs. 8–9, 11; the gains read what
    ``cfg.gains_input`` names), initialised as MANC's are."""
    M, N = cfg.n_predicates, cfg.n_states
    gains = gains_layer(rng, N + M if cfg.gains_input == "q+predicates" else N, cfg)
    return {"vagn": {"W": vagn.init_vagn(rng, M, N, scale=cfg.vagn_scale)}, "gains": gains}


def _mlp(params: dict) -> dict:
    return {k: v for k, v in params.items() if k.startswith("l")}


def advance(model: Privileged, Z: Any, lane: Any, motion: Any, q: Any, xp: Any = np
            ) -> tuple[Any, Any]:
    """One step of the ``"vagn"`` heads on standardised features ``Z (B, F')``: the MLP's
    predicates, then MANC's own head (its registered ``head``: vAGN, the gains FC and the DMP
    step); the controls ``[speed, yaw rate]`` ``(B, 2)`` and the next ``q (B, N)``."""
    p = 0.5 * (xp.tanh(0.5 * _forward(_mlp(model.params), Z, xp)) + 1.0)  # sigmoid
    enc = {"predicates": p, "lane_target": lane, "motion": motion}
    u, state, _ = spec("manc").head(model.params, enc, {"q": q}, model.cfg, engine_of(xp))
    return u, state["q"]


def _fit_scenes(model: Privileged, Z: np.ndarray, X: np.ndarray, Y: np.ndarray,
                lane: np.ndarray, motion: np.ndarray, T: int, steps: int, batch: int,
                lr: float, rng: np.random.Generator) -> Privileged:
    """Algorithm 1 for the ``head="vagn"`` learner: minibatches of whole scenes (the rows of
    ``X`` are scenes of ``T`` steps in order), ``q`` from uniform, the motion of the states
    as the DMP's."""
    S = len(X) // T
    v = X[:, FEATURES.index("v")]
    denom = model.scale * np.array([DT, 1.0])
    target = (np.stack([v + Y[:, 0] * DT, Y[:, 1]], axis=1) / denom).reshape(S, T, 2)
    Zs, ls, ms = Z.reshape(S, T, -1), lane.reshape(S, T, *lane.shape[1:]), motion.reshape(S, T, 2)
    q0 = vagn.uniform_state(model.cfg.n_states)
    b = max(1, min(S, batch // T))

    def loss(p: dict, z: Any, y: Any, lt: Any, mo: Any) -> Any:
        net = Privileged(p, model.keep, model.mean, model.std, model.scale, [], model.head,
                         model.cfg)
        q = np.broadcast_to(q0, (z.shape[0], len(q0)))
        total = 0.0
        for t in range(T):
            u, q = advance(net, z[:, t], lt[:, t], mo[:, t], q, xp=anp)
            d = u / denom - y[:, t]
            total = total + anp.mean(d * d)
        return total / T

    step_fn = value_and_grad(loss)
    params, state, losses = model.params, optim.adam_init(model.params), []
    for k in range(steps):
        i = rng.integers(0, S, size=b)
        lr_k = lr * 0.5 * (1.0 + math.cos(math.pi * k / steps))
        value, g = step_fn(params, Zs[i], target[i], ls[i], ms[i])
        params, state = optim.adam_update(g, state, params, lr=lr_k)
        losses.append(float(value))
    return Privileged(params, model.keep, model.mean, model.std, model.scale, losses,
                      model.head, model.cfg)


def _check_scene_steps(T: Any, n: int) -> int:
    if isinstance(T, bool) or not isinstance(T, int | np.integer) or T < 1 or n % T:
        raise ValueError(f"head='vagn' needs scene_steps, the steps of each scene (rows are "
                         f"whole scenes in order), dividing N = {n}; got scene_steps={T!r}")
    return int(T)


def _check_head_inputs(lane: Any, motion: Any, n: int) -> tuple[np.ndarray, np.ndarray]:
    if lane is None or motion is None:
        raise ValueError("head='dmp' or 'vagn' needs lane (N, K, 2) and motion (N, 2): see "
                         "head_inputs")
    lane = np.asarray(lane, dtype=np.float64)
    motion = np.asarray(motion, dtype=np.float64)
    if lane.ndim != 3 or lane.shape[0] != n or lane.shape[2] != 2 or motion.shape != (n, 2):
        raise ValueError(f"lane must have shape ({n}, K, 2) and motion ({n}, 2); got "
                         f"{lane.shape} and {motion.shape}")
    if not (np.all(np.isfinite(lane)) and np.all(np.isfinite(motion))):
        raise ValueError("lane and motion must be finite")
    return lane, motion


def predict(model: Privileged, X: np.ndarray, lane: np.ndarray | None = None,
            motion: np.ndarray | None = None, q: np.ndarray | None = None
            ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """The learner's ``[acceleration, yaw rate]`` ``(N, 2)`` for features ``X (N, F)``; the DMP
    heads (which need ``lane`` and ``motion``) give their speed command's change from the
    speed feature ``v`` over ``Δt``. The ``"vagn"`` head steps from the distributions ``q
    (N, n_states)`` (default: uniform) and also returns the next ones."""
    X = np.asarray(X, dtype=np.float64)
    Z = (X[:, model.keep] - model.mean) / model.std
    if model.head == "acceleration":
        return _forward(model.params, Z, np) * model.scale
    lane, motion = _check_head_inputs(lane, motion, len(Z))
    if model.head.startswith("vagn"):
        if q is None:
            q = np.broadcast_to(vagn.uniform_state(model.cfg.n_states), (len(Z),
                                                                          model.cfg.n_states))
        u, q = advance(model, Z, lane, motion, q)
    else:
        u, _ = dmp_head(_forward(model.params, Z, np), lane, motion, model.cfg, xp=np)
    a = np.stack([(u[:, 0] - X[:, FEATURES.index("v")]) / DT, u[:, 1]], axis=1)
    return (a, q) if model.head.startswith("vagn") else a


def predict_scenes(model: Privileged, X: np.ndarray, lane: np.ndarray | None = None,
                   motion: np.ndarray | None = None, scene_steps: int | None = None
                   ) -> np.ndarray:
    """:func:`predict` on rows that are whole scenes of ``scene_steps`` steps in order (as
    :func:`demonstrations` returns them): the ``"vagn"`` head carries ``q`` along each scene
    from uniform; the other heads read every row alone."""
    if not model.head.startswith("vagn"):
        return predict(model, X, lane, motion)
    X = np.asarray(X, dtype=np.float64)
    T = _check_scene_steps(scene_steps, len(X))
    lane, motion = _check_head_inputs(lane, motion, len(X))
    idx = np.arange(len(X)).reshape(-1, T)
    q, out = None, np.zeros((len(X), 2))
    for t in range(T):
        out[idx[:, t]], q = predict(model, X[idx[:, t]], lane[idx[:, t]], motion[idx[:, t]], q)
    return out


class _Reader:
    """Common part of the policies that ask the world's expert in the simulator's state."""

    model = None
    setting = "paper"
    keys = ("motion",)

    def __init__(self, teacher: WorldTeacher) -> None:
        self.teacher = teacher
        self.sim: Any = None
        self.prev: np.ndarray | None = None
        self.speeds: np.ndarray | None = None
        self.a_prev: np.ndarray = np.zeros(0)
        self.refused = 0

    def bind(self, sim: Any) -> None:
        self.sim, self.prev, self.speeds = sim, None, None

    def initial_state(self, scenes: np.ndarray) -> None:
        return None

    def situations(self, t: int) -> list[Situation | None]:
        poses, speeds, traffics = self.teacher.states(self.sim, self.prev)
        v = np.maximum(np.asarray(speeds, dtype=np.float64), 0.0)
        self.a_prev = np.zeros_like(v) if self.speeds is None else (v - self.speeds) / DT
        self.speeds = v
        out: list[Situation | None] = []
        for b, s in enumerate(np.asarray(self.sim.scenes)):
            try:
                out.append(self.teacher.expert.situation(int(s), int(t), poses[b],
                                                         max(speeds[b], 0.0), traffics[b]))
            except ValueError:  # the expert cannot be asked here
                out.append(None)
        return out

    def finish(self, u: np.ndarray, sits: list[Situation | None]) -> np.ndarray:
        bad = np.array([s is None for s in sits])
        if bad.any():
            self.refused += int(bad.sum())
            u[bad] = self.prev[bad] if self.prev is not None else 0.0
        self.prev = u
        return u


class ExpertPolicy(_Reader):
    """The world's human asked in every state the closed loop reaches (the upper bound)."""

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        sits = self.situations(t)
        u = np.zeros((len(sits), 2))
        for b, sit in enumerate(sits):
            if sit is not None:
                u[b] = self.teacher.expert.controls(sit)
        return self.finish(u, sits), state, {}


class PrivilegedPolicy(_Reader):
    """A :class:`Privileged` learner driving on the expert's perception (:func:`blur`-red by
    ``noise`` with a stream seeded by ``seed``: it then also forms its speed command from the
    speed it perceives); with ``record=True`` it keeps every visited state's features and
    the expert's label there (``visited``, as :func:`demonstrations` returns them)."""

    def __init__(self, model: Privileged, teacher: WorldTeacher, record: bool = False,
                 noise: Mapping[str, float] | None = None, seed: int = 0) -> None:
        super().__init__(teacher)
        self.net, self.record = model, record
        self.noise = dict(noise or {})
        self.rng = np.random.default_rng(seed)
        if model.head != "acceleration":
            self.keys = ("lane_target", "motion")
        self.X: list[np.ndarray] = []
        self.Y: list[list[float]] = []
        self.lanes: list[np.ndarray] = []
        self.motions: list[np.ndarray] = []

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        sits = self.situations(t)
        F = np.array([features(s, a) if s is not None else np.zeros(len(FEATURES))
                      for s, a in zip(sits, self.a_prev)])
        if self.noise:
            F = blur(F, self.noise, self.rng)
        u, state = self.act(F, sits, obs, state)
        return u, state, {}

    def initial_state(self, scenes: np.ndarray) -> np.ndarray | None:
        """The uniform ``q`` of each row for the ``"vagn"`` head (Algorithm 1's start)."""
        if not self.net.head.startswith("vagn"):
            return None
        N = self.net.cfg.n_states
        return np.broadcast_to(vagn.uniform_state(N), (len(scenes), N)).copy()

    def act(self, F: np.ndarray, sits: list[Situation | None], obs: dict | None = None,
            state: Any = None) -> tuple[np.ndarray, Any]:
        """The controls ``[clip(v + a Δt, 0, V_MAX), ω]`` of the learner on features ``F``
        (``v`` their speed; the DMP heads read ``obs``' lane target and motion, the
        ``"vagn"`` head steps ``state``, its ``q``) in the states ``sits``; with ``record``
        it keeps ``F`` (and what the DMP head read) and the expert's label in each state it
        can be asked in. Returns the controls and the next ``state``."""
        lane = motion = None
        if self.net.head != "acceleration":
            lane = np.asarray(obs["lane_target"], dtype=np.float64)
            motion = np.asarray(obs["motion"], dtype=np.float64)
        a = predict(self.net, F, lane, motion, state)
        if self.net.head.startswith("vagn"):
            a, state = a
        v = F[:, FEATURES.index("v")]
        u = np.stack([np.clip(v + a[:, 0] * DT, 0.0, V_MAX), a[:, 1]], axis=1)
        if self.record:
            for b, sit in enumerate(sits):
                if sit is not None:
                    lab = self.teacher.expert.controls(sit)
                    self.X.append(F[b])
                    self.Y.append([(lab[0] - v[b]) / DT, lab[1]])
                    if lane is not None:
                        self.lanes.append(lane[b])
                        self.motions.append(motion[b])
        return self.finish(u, sits), state

    def visited(self) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self.X).reshape(-1, len(FEATURES)), np.asarray(self.Y).reshape(-1, 2)

    def visited_head_inputs(self) -> tuple[np.ndarray, np.ndarray]:
        """What the DMP head read in the states :meth:`visited` returns (``head="dmp"``)."""
        K = self.net.cfg.k_targets if self.net.cfg is not None else 0
        return (np.asarray(self.lanes).reshape(-1, K, 2),
                np.asarray(self.motions).reshape(-1, 2))


def evaluate_policy(policy: _Reader, ds: Any, agents: str, progress: bool = False
                    ) -> dict[str, float]:
    """Drive ``policy`` (its teacher built on ``ds``) on every scene of ``ds`` under
    ``agents``: :func:`minimanc.metrics.evaluate`'s metrics, the mean along- and
    cross-track errors (:func:`minimanc.metrics.trajectory.along_cross_track`) and the
    number of ``refused`` states."""
    policy.refused = 0
    traj = rollout.simulate(policy, ds, agents=agents, progress=progress,
                            desc=f"{type(policy).__name__} ({agents})")
    out = metrics.evaluate(traj, ds)
    along, cross = along_cross_track(traj.ego, np.asarray(ds.ego, dtype=np.float64))
    out["along_track"] = float(np.abs(along).mean())
    out["cross_track"] = float(np.abs(cross).mean())
    out["refused"] = float(policy.refused)
    return out


@dataclass
class Round:
    """One DAgger round of the privileged learner: labels aggregated so far and its
    closed-loop metrics on the validation scenes."""

    labels: int
    metrics: dict[str, float]


def dagger_rounds(train: Any, val: Any, rounds: int, per_round: int, agents: str = "reactive",
                  seed: int = 0, drop: Sequence[str] = (), steps: int = 3000,
                  progress: bool = False, head: str = "acceleration") -> list[Round]:
    """DAgger for the privileged learner (with ``head``, :data:`HEADS`): round 0 trains on
    the demonstrations of ``train``; each further round drives ``per_round`` training scenes
    (in a seeded order, cycling) with the current learner under ``agents``, labels every
    state it reached with the expert, aggregates and retrains from the previous weights.
    Every round is evaluated closed loop on ``val`` under ``agents``."""
    rounds = check_int("rounds", rounds, 0)
    per_round = check_int("per_round", per_round, 1)
    if head not in ("acceleration", "dmp"):
        raise ValueError(f"DAgger of the privileged learner takes head 'acceleration' or "
                         f"'dmp' (a label per state, not per scene), got head={head!r}")
    teacher = WorldTeacher(train, agents=agents)
    vteacher = WorldTeacher(val, agents=agents)
    X, Y = demonstrations(train, expert=teacher.expert)
    lane, motion = head_inputs(train) if head == "dmp" else (None, None)
    model = fit_privileged(X, Y, drop=drop, steps=steps, seed=seed, head=head, lane=lane,
                           motion=motion)
    out = [Round(len(X), evaluate_policy(PrivilegedPolicy(model, vteacher), val, agents))]
    order = np.random.default_rng(seed).permutation(len(np.asarray(train.ego)))
    for r in range(rounds):
        pick = order[(np.arange(per_round) + r * per_round) % len(order)]
        policy = PrivilegedPolicy(model, teacher, record=True)
        rollout.simulate(policy, train, scenes=np.sort(pick), agents=agents, progress=progress,
                         desc=f"DAgger round {r + 1}")
        Xn, Yn = policy.visited()
        X, Y = np.concatenate([X, Xn]), np.concatenate([Y, Yn])
        if head == "dmp":
            ln, mn = policy.visited_head_inputs()
            lane, motion = np.concatenate([lane, ln]), np.concatenate([motion, mn])
        model = fit_privileged(X, Y, steps=steps, seed=seed + r + 1, init=model, lane=lane,
                               motion=motion)
        out.append(Round(len(X), evaluate_policy(PrivilegedPolicy(model, vteacher), val, agents)))
    return out
