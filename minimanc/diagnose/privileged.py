"""Chapter 12 — the learners that read the world's own numbers: the expert as a policy, and
a behaviour-cloned MLP given exactly what the expert perceives (a *privileged* learner).

Behaviour cloning (the paper's Algorithm 1) can fail for two reasons: the learning (the
closed loop, the labels) or the information (what the learner sees). A learner given the
expert's own inputs separates them (the "privileged agent" of Chen et al. 2019, *Learning
by Cheating*): if it drives like the expert, learning works and what the image-based models
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
the driver's memory of its last commands, so it is bounded by the style floor
(:mod:`minimanc.diagnose.bounds`), not by the expert.

**Model.** An MLP (tanh hidden layers, :func:`minimanc.layers.dense`) on standardised
features predicts the acceleration ``a = (v_{t+1} − v_t)/Δt`` and the yaw rate ``ω``; the
control applied is ``[clip(v + a Δt, 0, V_MAX), ω]``. :func:`fit_privileged` trains it by
Algorithm 1 (minibatches, the mean squared error of both outputs each divided by its
standard deviation over the demonstrations, Adam with a cosine decay: :func:`descend`)
with :mod:`minimanc.autodiff`. ``drop`` removes feature groups (the ablation: a group
dropped is not an input).

**A perception that errs.** :func:`blur` adds independent Gaussian errors ``N(0, σ_f²)`` to
chosen features (distances then clipped at ``FAR``): a learner trained on blurred
demonstrations and driven by :class:`~minimanc.diagnose.policies.PrivilegedPolicy` with the
same ``noise`` shows how exact a perception has to be for the privileged learner to stay safe.

The learner drives closed loop as :class:`minimanc.diagnose.policies.PrivilegedPolicy`,
next to the expert (:class:`~minimanc.diagnose.policies.ExpertPolicy`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from minimanc import layers, optim
from minimanc.autodiff import numpy as anp
from minimanc.autodiff import value_and_grad
from minimanc.checks import check_int
from minimanc.dagger.expert import HumanExpert, Situation
from minimanc.world.geometry import DT, wrap_angle
from minimanc.world.traffic import B_MAX

__all__ = [
    "AHEAD", "FAR", "FEATURES", "FEATURE_GROUPS", "V_MAX", "Privileged", "blur",
    "demonstrations", "descend", "features", "fit_privileged", "kept", "mlp_outputs",
    "perceived", "predict", "standardise",
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


def features(sit: Situation, a_prev: float = 0.0) -> np.ndarray:
    """What the human perceives in a situation, as the vector :data:`FEATURES`.

    Parameters
    ----------
    sit : minimanc.dagger.expert.Situation
        The ego's state among the step's ados (:meth:`HumanExpert.situation`).
    a_prev : float, optional (default: 0)
        The ego's last acceleration (m/s²).

    Returns
    -------
    numpy.ndarray, shape (len(FEATURES),), float64
        Speed, last acceleration, leader gap (clipped at :data:`FAR`), speed difference and
        presence, stop distance (clipped) and presence, the curves' braking bound (clipped
        to ``[−B_MAX, 4]``), lateral offset, heading error and the path's lateral position
        :data:`AHEAD` metres ahead in the ego frame.
    """
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
    """Features with independent Gaussian errors: a perception that errs.

    Parameters
    ----------
    X : array_like, shape (N, len(FEATURES))
        Features (not changed).
    noise : mapping of str to float
        Feature name → σ in the feature's unit; ``N(0, σ²)`` is added to it (σ = 0 leaves
        it exact).
    rng : numpy.random.Generator
        The errors' stream.

    Returns
    -------
    numpy.ndarray, shape (N, len(FEATURES))
        A copy with the errors added, the distances (``gap``, ``stop``) then clipped at
        :data:`FAR` and the speed ``v`` at 0.

    Raises
    ------
    ValueError
        If ``X`` has the wrong shape, a name is not a feature or a σ is not a finite
        number ``>= 0``.
    """
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


def demonstrations(ds: Any, scenes: Iterable[int] | None = None,
                   expert: HumanExpert | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The demonstrations of Algorithm 1 on the expert's perception.

    Parameters
    ----------
    ds : minimanc.world.Dataset
        A generated dataset (its human can be re-simulated).
    scenes : iterable of int, optional
        The scenes to read (default: all), in this order.
    expert : minimanc.dagger.expert.HumanExpert, optional
        The expert of ``ds`` (built when not given).

    Returns
    -------
    X : numpy.ndarray, shape (N, len(FEATURES))
        The :func:`features` of every logged state, scene after scene.
    Y : numpy.ndarray, shape (N, 2)
        The human's logged controls there as ``[acceleration, yaw rate]``.
    """
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


def perceived(ds: Any, names: Sequence[str] = FEATURES, expert: HumanExpert | None = None
              ) -> np.ndarray:
    """What the human perceives in every logged state, scene by scene.

    Parameters
    ----------
    ds : minimanc.world.Dataset
        A generated dataset.
    names : sequence of str, optional (default: every feature)
        Some of :data:`FEATURES`, in the order wanted.
    expert : minimanc.dagger.expert.HumanExpert, optional
        The expert of ``ds`` (built when not given).

    Returns
    -------
    numpy.ndarray, shape (S, T, len(names))
        The features ``names`` of :func:`demonstrations`' states.

    Raises
    ------
    ValueError
        If ``names`` is empty or holds a name that is not a feature.
    """
    bad = [n for n in names if n not in FEATURES]
    if bad or not names:
        raise ValueError(f"names must be some of {FEATURES}; got {list(names)!r}")
    X, _ = demonstrations(ds, expert=expert)
    S, T = np.asarray(ds.ego).shape[:2]
    return X[:, [FEATURES.index(n) for n in names]].reshape(S, T, len(names))


def kept(drop: Sequence[str] = (), without: Sequence[str] = ()) -> np.ndarray:
    """The inputs of an ablated learner.

    Parameters
    ----------
    drop : sequence of str, optional
        Groups of :data:`FEATURE_GROUPS` to remove.
    without : sequence of str, optional
        Single features to remove.

    Returns
    -------
    numpy.ndarray of int64
        Indices of the :data:`FEATURES` left, in order.

    Raises
    ------
    ValueError
        If a group or feature is unknown, or nothing is left.
    """
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


@dataclass
class Privileged:
    """A trained privileged learner: the MLP's ``params`` (layers ``l0`` … ``l{n−1}``), the
    features it reads (``keep``, indices into :data:`FEATURES`), their standardisation
    (``mean``, ``std``), the outputs' scales (``scale``) and the training ``losses``."""

    params: dict
    keep: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    scale: np.ndarray
    losses: list[float] = field(default_factory=list)


def mlp_outputs(params: dict, Z: Any, xp: Any = np) -> Any:
    """The MLP's raw outputs.

    Parameters
    ----------
    params : dict
        Dense layers ``l0`` … ``l{n−1}`` (:func:`minimanc.layers.init_dense`); other keys
        are not read.
    Z : array_like, shape (N, F)
        Standardised features (:func:`standardise`).
    xp : module, optional (default: numpy)
        Array namespace (an engine's ``xp`` to differentiate).

    Returns
    -------
    array, shape (N, n_out)
        ``l{n−1}(tanh(… tanh(l0(Z))))``.
    """
    n = sum(1 for k in params if k[0] == "l" and k[1:].isdigit())
    h = Z
    for i in range(n - 1):
        h = xp.tanh(layers.dense(params[f"l{i}"], h, xp=xp))
    return layers.dense(params[f"l{n - 1}"], h, xp=xp)


def standardise(model: Privileged, X: Any) -> np.ndarray:
    """The inputs a learner reads.

    Parameters
    ----------
    model : Privileged
    X : array_like, shape (N, len(FEATURES))
        Features.

    Returns
    -------
    numpy.ndarray, shape (N, len(model.keep))
        ``(X[:, keep] − mean) / std``, float64.
    """
    X = np.asarray(X, dtype=np.float64)
    return (X[:, model.keep] - model.mean) / model.std


def descend(loss: Callable[..., Any], params: dict, draw: Callable[[], tuple], steps: int,
            lr: float) -> tuple[dict, list[float]]:
    """Algorithm 1's optimiser for the privileged learners: Adam with a cosine decay.

    Parameters
    ----------
    loss : callable
        ``loss(params, *batch)``, a scalar written with :mod:`minimanc.autodiff.numpy`.
    params : dict
        The starting parameters (a pytree).
    draw : callable
        ``draw()`` returns the next minibatch, a tuple of ``loss``'s further arguments.
    steps : int
        Adam updates (:func:`minimanc.optim.adam_update`).
    lr : float
        The learning rate at step 0; step ``k`` takes ``lr · ½ (1 + cos(π k / steps))``.

    Returns
    -------
    params : dict
        After the last step.
    losses : list of float
        The loss of every step's minibatch, before its update.
    """
    grad = value_and_grad(loss)
    state = optim.adam_init(params)
    losses = []
    for k in range(steps):
        batch = draw()
        value, g = grad(params, *batch)
        lr_k = lr * 0.5 * (1.0 + math.cos(math.pi * k / steps))  # cosine decay
        params, state = optim.adam_update(g, state, params, lr=lr_k)
        losses.append(float(value))
    return params, losses


def fit_privileged(X: np.ndarray, Y: np.ndarray, drop: Sequence[str] = (),
                   hidden: Sequence[int] = (64, 64), steps: int = 3000, batch: int = 256,
                   lr: float = 3e-3, seed: int = 0, init: Privileged | None = None,
                   without: Sequence[str] = ()) -> Privileged:
    """Train the privileged MLP by behaviour cloning (Algorithm 1).

    The loss is the mean squared error of ``[acceleration, yaw rate]``, each divided by its
    standard deviation over ``Y``; minibatches of ``batch`` states drawn with replacement;
    :func:`descend`.

    Parameters
    ----------
    X : array_like, shape (N, len(FEATURES))
        Features (:func:`demonstrations`).
    Y : array_like, shape (N, 2)
        The labels ``[acceleration, yaw rate]``.
    drop : sequence of str, optional
        Feature groups the learner does not read (:func:`kept`).
    hidden : sequence of int, optional (default: (64, 64))
        The tanh hidden layers.
    steps : int, optional (default: 3000)
        Adam steps.
    batch : int, optional (default: 256)
        States per minibatch.
    lr : float, optional (default: 3e-3)
        Adam's learning rate before the decay.
    seed : int, optional (default: 0)
        The initialisation's and the minibatches' stream.
    init : Privileged, optional
        Continue from this learner (its inputs, standardisation and scales kept; ``drop``,
        ``without`` and ``hidden`` are then not read).
    without : sequence of str, optional
        Single features the learner does not read (:func:`kept`).

    Returns
    -------
    Privileged

    Raises
    ------
    ValueError
        If ``X`` and ``Y`` do not have the shapes above or are not finite.
    """
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != len(FEATURES) or Y.shape != (len(X), 2) or len(X) == 0:
        raise ValueError(f"X must have shape (N, {len(FEATURES)}) and Y (N, 2) with N >= 1; "
                         f"got {X.shape} and {Y.shape}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
        raise ValueError("X and Y must be finite")
    steps = check_int("steps", steps, 1)
    batch = check_int("batch", batch, 1)
    rng = np.random.default_rng(seed)
    if init is None:
        keep = kept(drop, without)
        mean, std = X[:, keep].mean(0), X[:, keep].std(0) + 1e-6
        scale = Y.std(0) + 1e-6
        sizes = [len(keep), *hidden, 2]
        params = {f"l{i}": layers.init_dense(rng, a, b)
                  for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:]))}
        last = params[f"l{len(sizes) - 2}"]
        last["w"] = last["w"] * 0.1
    else:
        keep, mean, std, scale, params = init.keep, init.mean, init.std, init.scale, init.params
    Z = (X[:, keep] - mean) / std
    target = Y / scale

    def loss(p: dict, z: Any, y: Any) -> Any:
        d = mlp_outputs(p, z, anp) - y
        return anp.mean(d * d)

    def draw() -> tuple[np.ndarray, np.ndarray]:
        i = rng.integers(0, len(Z), size=min(batch, len(Z)))
        return Z[i], target[i]

    params, losses = descend(loss, params, draw, steps, lr)
    return Privileged(params, keep, mean, std, scale, losses)


def predict(model: Privileged, X: Any) -> np.ndarray:
    """The learner's controls in features.

    Parameters
    ----------
    model : Privileged
    X : array_like, shape (N, len(FEATURES))
        Features.

    Returns
    -------
    numpy.ndarray, shape (N, 2)
        ``[acceleration (m/s²), yaw rate (rad/s)]``.
    """
    return mlp_outputs(model.params, standardise(model, X), np) * model.scale
