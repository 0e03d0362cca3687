"""MANC's own parts on the expert's perception: the privileged learner of
:mod:`minimanc.diagnose.privileged` driving through MANC's DMP head, or through its vAGN
automaton and DMP head, to ask which part keeps MANC from driving.

* ``head="dmp"``: the MLP predicts MANC's four gain logits and the control is one step of
  MANC's DMP head (:func:`minimanc.models.dmp_head`, eqs. 10–11) from the ego's motion
  towards its lane target (:func:`head_inputs`), clipped as the plain learner's is: MANC's
  head given the expert's perception.
* ``head="vagn"``: the MLP's outputs are MANC's predicates (a sigmoid: eq. 7 on the expert's
  perception instead of the image), and the rest is MANC's registered head: vAGN (eqs.
  8–9) carries ``q`` from step to step, ``FC(q)`` gives the gain logits (eq. 11) and the DMP
  head the control; trained on whole scenes from the uniform ``q``. It separates what the
  automaton and its linear read-out cost from what the visual perception costs.
* ``head="vagn_predicates"``: the same with the gains reading the predicates beside ``q``,
  ``FC(q ⊕ p)`` (the DMP-only model's path added to MANC's; not the paper's form).

Each learner's loss is the plain learner's: the speed error over ``Δt`` against the
acceleration's scale, the yaw-rate error against its own, minimised by
:func:`minimanc.diagnose.privileged.descend`. :class:`HeadPolicy` drives any of them closed
loop, as :class:`~minimanc.diagnose.policies.PrivilegedPolicy` drives the plain one.
``"acceleration"`` in :data:`HEADS` is the plain learner itself (:func:`fit_any`,
:func:`policy_of` and :func:`predict_scenes` take either).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from minimanc import inputs, layers, models, vagn
from minimanc.autodiff import numpy as anp
from minimanc.checks import check_int
from minimanc.dagger import WorldTeacher
from minimanc.diagnose import policies
from minimanc.diagnose import privileged as P
from minimanc.engine import engine_of
from minimanc.models import DEFAULT_GAINS, ModelConfig, dmp_head, gain_logits
from minimanc.models.zoo import gains_layer
from minimanc.world.geometry import DT

HEADS: tuple[str, ...] = ("acceleration", "dmp", "vagn", "vagn_predicates")
"""What the MLP predicts: the acceleration and yaw rate (the plain learner), the gain logits
of MANC's DMP head, or MANC's predicates (vAGN, ``FC(q)`` or ``FC(q ⊕ p)`` and the DMP head
follow)."""
AUTOMATON: tuple[str, ...] = ("vagn", "vagn_predicates")
"""The heads that carry vAGN's ``q`` along a scene (trained on whole scenes)."""


@dataclass
class HeadLearner:
    """A privileged learner with one of MANC's heads: ``net`` (the MLP's layers and, for the
    automaton heads, MANC's ``vagn`` and ``gains`` parameters, with the plain learner's
    standardisation and scales), its ``head`` and the :class:`~minimanc.models.ModelConfig`
    whose look-ahead rules, ``dt`` and automaton size it steps with."""

    net: P.Privileged
    head: str
    cfg: ModelConfig


def head_inputs(ds: Any, scenes: Iterable[int] | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """What MANC's DMP head reads in every logged state of ``scenes`` (default: all) of
    ``ds``, in the order of :func:`~minimanc.diagnose.privileged.demonstrations`: the lane
    targets ``(N, K, 2)`` and the motion ``(N, 2)`` (:func:`minimanc.inputs.motion_at`),
    float64."""
    lt = np.asarray(ds.lane_target)
    idx = np.arange(len(lt)) if scenes is None else np.asarray(list(scenes), dtype=np.int64)
    T = lt.shape[1]
    s, t = np.repeat(idx, T), np.tile(np.arange(T), len(idx))
    return (lt[s, t].astype(np.float64),
            inputs.motion_at(ds, s, t).astype(np.float64))


def check_head_inputs(lane: Any, motion: Any, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``lane (n, K, 2)`` and ``motion (n, 2)`` as float64, or a one-line ValueError."""
    if lane is None or motion is None:
        raise ValueError("MANC's heads need lane (N, K, 2) and motion (N, 2): see head_inputs")
    lane = np.asarray(lane, dtype=np.float64)
    motion = np.asarray(motion, dtype=np.float64)
    if lane.ndim != 3 or lane.shape[0] != n or lane.shape[2] != 2 or motion.shape != (n, 2):
        raise ValueError(f"lane must have shape ({n}, K, 2) and motion ({n}, 2); got "
                         f"{lane.shape} and {motion.shape}")
    if not (np.all(np.isfinite(lane)) and np.all(np.isfinite(motion))):
        raise ValueError("lane and motion must be finite")
    return lane, motion


def check_scene_steps(T: Any, n: int) -> int:
    """The steps of each scene for rows that are whole scenes in order, or a ValueError."""
    if isinstance(T, bool) or not isinstance(T, int | np.integer) or T < 1 or n % T:
        raise ValueError(f"the automaton heads need scene_steps, the steps of each scene "
                         f"(rows are whole scenes in order), dividing N = {n}; got "
                         f"scene_steps={T!r}")
    return int(T)


def advance(model: HeadLearner, Z: Any, lane: Any, motion: Any, q: Any, xp: Any = np
            ) -> tuple[Any, Any]:
    """One step of an automaton head on standardised features ``Z (B, F')``: the MLP's
    predicates, then vAGN, the gains FC and the DMP step (MANC's registered head for
    ``"vagn"``; ``FC(q ⊕ p)`` for ``"vagn_predicates"``); the controls ``[speed, yaw rate]``
    ``(B, 2)`` and the next ``q (B, N)``."""
    params = model.net.params
    p = 0.5 * (xp.tanh(0.5 * P.mlp_outputs(params, Z, xp)) + 1.0)  # sigmoid
    if model.head == "vagn":
        enc = {"predicates": p, "lane_target": lane, "motion": motion}
        u, state, _ = models.spec("manc").head(params, enc, {"q": q}, model.cfg,
                                               engine_of(xp))
        return u, state["q"]
    q = vagn.step(q, p, params["vagn"]["W"], xp=xp)
    logits = layers.dense(params["gains"], xp.concatenate([q, p], axis=-1), xp=xp)
    u, _ = dmp_head(logits, lane, motion, model.cfg, xp=xp)
    return u, q


def fit_head(X: np.ndarray, Y: np.ndarray, lane: np.ndarray, motion: np.ndarray,
             head: str = "dmp", drop: Sequence[str] = (), hidden: Sequence[int] = (64, 64),
             steps: int = 3000, batch: int = 256, lr: float = 3e-3, seed: int = 0,
             init: HeadLearner | None = None, without: Sequence[str] = (),
             scene_steps: int | None = None) -> HeadLearner:
    """Train a privileged learner with one of MANC's heads (arguments as in
    :func:`minimanc.diagnose.privileged.fit_privileged`; ``lane (N, K, 2)`` and
    ``motion (N, 2)`` what the head reads in the states of ``X``, :func:`head_inputs`).
    The automaton heads need ``scene_steps``: their rows are whole scenes in order (as
    :func:`~minimanc.diagnose.privileged.demonstrations` returns them), each minibatch
    ``batch // scene_steps`` scenes; they train from scratch (no ``init``)."""
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != len(P.FEATURES) or Y.shape != (len(X), 2) or len(X) == 0:
        raise ValueError(f"X must have shape (N, {len(P.FEATURES)}) and Y (N, 2) with N >= 1; "
                         f"got {X.shape} and {Y.shape}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
        raise ValueError("X and Y must be finite")
    steps = check_int("steps", steps, 1)
    batch = check_int("batch", batch, 1)
    head = init.head if init is not None else head
    if head not in HEADS[1:]:
        raise ValueError(f"head must be one of {HEADS[1:]}, got head={head!r}")
    lane, motion = check_head_inputs(lane, motion, len(X))
    if head in AUTOMATON and init is not None:
        raise ValueError(f"head={head!r} trains from scratch: init must be None")
    rng = np.random.default_rng(seed)
    if init is None:
        keep = P.kept(drop, without)
        mean, std = X[:, keep].mean(0), X[:, keep].std(0) + 1e-6
        scale = Y.std(0) + 1e-6
        cfg = ModelConfig(k_targets=int(lane.shape[1]))
        sizes = [len(keep), *hidden, 4 if head == "dmp" else cfg.n_predicates]
        params = {f"l{i}": layers.init_dense(rng, a, b)
                  for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:]))}
        last = params[f"l{len(sizes) - 2}"]
        last["w"] = last["w"] * 0.1
        if head == "dmp":  # start at MANC's fixed gains, as its gains layer does
            last["b"] = np.asarray(gain_logits(DEFAULT_GAINS), dtype=np.float64)
        else:
            M, N = cfg.n_predicates, cfg.n_states
            gains = gains_layer(rng, N + M if head == "vagn_predicates" else N, cfg)
            params["vagn"] = {"W": vagn.init_vagn(rng, M, N, scale=cfg.vagn_scale)}
            params["gains"] = gains
        net = P.Privileged(params, keep, mean, std, scale)
    else:
        net, cfg = init.net, init.cfg
    Z = P.standardise(net, X)
    denom = net.scale * np.array([DT, 1.0])
    v = X[:, P.FEATURES.index("v")]
    target = np.stack([v + Y[:, 0] * DT, Y[:, 1]], axis=1) / denom
    if head == "dmp":
        def loss(p: dict, z: Any, y: Any, lt: Any, mo: Any) -> Any:
            u, _ = dmp_head(P.mlp_outputs(p, z, anp), lt, mo, cfg, xp=anp)
            d = u / denom - y
            return anp.mean(d * d)

        def draw() -> tuple:
            i = rng.integers(0, len(Z), size=min(batch, len(Z)))
            return Z[i], target[i], lane[i], motion[i]
    else:
        T = check_scene_steps(scene_steps, len(X))
        S = len(X) // T
        Zs, ys = Z.reshape(S, T, -1), target.reshape(S, T, 2)
        ls, ms = lane.reshape(S, T, *lane.shape[1:]), motion.reshape(S, T, 2)
        q0 = vagn.uniform_state(cfg.n_states)
        b = max(1, min(S, batch // T))

        def loss(p: dict, z: Any, y: Any, lt: Any, mo: Any) -> Any:
            step = HeadLearner(P.Privileged(p, keep=net.keep, mean=net.mean, std=net.std,
                                            scale=net.scale), head, cfg)
            q = np.broadcast_to(q0, (z.shape[0], len(q0)))
            total = 0.0
            for t in range(T):
                u, q = advance(step, z[:, t], lt[:, t], mo[:, t], q, xp=anp)
                d = u / denom - y[:, t]
                total = total + anp.mean(d * d)
            return total / T

        def draw() -> tuple:
            i = rng.integers(0, S, size=b)
            return Zs[i], ys[i], ls[i], ms[i]
    params, losses = P.descend(loss, net.params, draw, steps, lr)
    return HeadLearner(P.Privileged(params, net.keep, net.mean, net.std, net.scale, losses),
                       head, cfg)


def predict_head(model: HeadLearner, X: np.ndarray, lane: np.ndarray, motion: np.ndarray,
                 q: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """The learner's ``[acceleration, yaw rate]`` ``(N, 2)`` for features ``X (N, F)`` (its
    speed command's change from the speed feature ``v`` over ``Δt``) and the next ``q``:
    the automaton heads step from ``q (N, n_states)`` (default: uniform); the DMP head has
    none (``q`` is returned as given)."""
    X = np.asarray(X, dtype=np.float64)
    Z = P.standardise(model.net, X)
    lane, motion = check_head_inputs(lane, motion, len(Z))
    if model.head in AUTOMATON:
        N = model.cfg.n_states
        if q is None:
            q = np.broadcast_to(vagn.uniform_state(N), (len(Z), N))
        u, q = advance(model, Z, lane, motion, q)
    else:
        u, _ = dmp_head(P.mlp_outputs(model.net.params, Z, np), lane, motion, model.cfg, xp=np)
    return np.stack([(u[:, 0] - X[:, P.FEATURES.index("v")]) / DT, u[:, 1]], axis=1), q


def predict_scenes(model: P.Privileged | HeadLearner, X: np.ndarray,
                   lane: np.ndarray | None = None, motion: np.ndarray | None = None,
                   scene_steps: int | None = None) -> np.ndarray:
    """The ``[acceleration, yaw rate]`` of any learner on rows that are whole scenes of
    ``scene_steps`` steps in order: the automaton heads carry ``q`` along each scene from
    uniform; the other learners read every row alone."""
    if isinstance(model, P.Privileged):
        return P.predict(model, X)
    if model.head not in AUTOMATON:
        return predict_head(model, X, lane, motion)[0]
    X = np.asarray(X, dtype=np.float64)
    T = check_scene_steps(scene_steps, len(X))
    lane, motion = check_head_inputs(lane, motion, len(X))
    idx = np.arange(len(X)).reshape(-1, T)
    q, out = None, np.zeros((len(X), 2))
    for t in range(T):
        rows = idx[:, t]
        out[rows], q = predict_head(model, X[rows], lane[rows], motion[rows], q)
    return out


class HeadPolicy(policies.PrivilegedPolicy):
    """A :class:`HeadLearner` driving closed loop on the expert's perception; its head reads
    the observation's lane target and motion, the automaton heads carry ``q`` as the
    policy's state. With ``record=True`` it also keeps what the head read in every
    recorded state (:meth:`visited_head_inputs`)."""

    keys = ("lane_target", "motion")

    def __init__(self, model: HeadLearner, teacher: WorldTeacher, record: bool = False,
                 noise: Mapping[str, float] | None = None, seed: int = 0) -> None:
        super().__init__(model.net, teacher, record=record, noise=noise, seed=seed)
        self.learner = model
        self.lanes: list[np.ndarray] = []
        self.motions: list[np.ndarray] = []

    def initial_state(self, scenes: np.ndarray) -> np.ndarray | None:
        """The uniform ``q`` of each row for the automaton heads (Algorithm 1's start)."""
        if self.learner.head not in AUTOMATON:
            return None
        N = self.learner.cfg.n_states
        return np.broadcast_to(vagn.uniform_state(N), (len(scenes), N)).copy()

    def accelerations(self, F: np.ndarray, obs: dict | None, state: Any
                      ) -> tuple[np.ndarray, Any]:
        """The head's ``[acceleration, yaw rate]`` and next ``q`` (see :func:`predict_head`)."""
        lane = np.asarray(obs["lane_target"], dtype=np.float64)
        motion = np.asarray(obs["motion"], dtype=np.float64)
        return predict_head(self.learner, F, lane, motion, state)

    def act(self, F: np.ndarray, sits: list, obs: dict | None = None, state: Any = None
            ) -> tuple[np.ndarray, Any]:
        """:meth:`minimanc.diagnose.policies.PrivilegedPolicy.act`, recording the head's
        inputs next to the labels."""
        u, state = super().act(F, sits, obs, state)
        if self.record:
            for b, sit in enumerate(sits):
                if sit is not None:
                    self.lanes.append(np.asarray(obs["lane_target"], dtype=np.float64)[b])
                    self.motions.append(np.asarray(obs["motion"], dtype=np.float64)[b])
        return u, state

    def visited_head_inputs(self) -> tuple[np.ndarray, np.ndarray]:
        """What the head read in the states :meth:`visited` returns."""
        K = self.learner.cfg.k_targets
        return (np.asarray(self.lanes).reshape(-1, K, 2),
                np.asarray(self.motions).reshape(-1, 2))


def fit_any(head: str, X: np.ndarray, Y: np.ndarray, lane: np.ndarray | None = None,
            motion: np.ndarray | None = None, **kw: Any) -> P.Privileged | HeadLearner:
    """The plain learner (``head="acceleration"``, :func:`~minimanc.diagnose.privileged.
    fit_privileged`; ``lane``, ``motion`` and ``scene_steps`` not read) or :func:`fit_head`."""
    if head == "acceleration":
        kw.pop("scene_steps", None)
        return P.fit_privileged(X, Y, **kw)
    return fit_head(X, Y, lane, motion, head=head, **kw)


def policy_of(model: P.Privileged | HeadLearner, teacher: WorldTeacher, **kw: Any
              ) -> policies.PrivilegedPolicy:
    """The closed-loop policy of any learner: :class:`HeadPolicy` or
    :class:`~minimanc.diagnose.policies.PrivilegedPolicy` (``kw``: ``record``, ``noise``,
    ``seed``)."""
    if isinstance(model, HeadLearner):
        return HeadPolicy(model, teacher, **kw)
    return policies.PrivilegedPolicy(model, teacher, **kw)
