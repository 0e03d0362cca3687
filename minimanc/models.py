"""Chapter 8 — MANC and the comparison controllers as pure functions ``(params, inputs)``.

Six controllers share **one CNN backbone** (:func:`backbone`: 3×3 convolutions,
stride 2, zero padding 1, SiLU; 64×64 → 8×8 with the default channels
``(16, 32, 32)``) and differ in their heads (paper section V, "Comparison cases"
and the self-ablation):

============= =================================================================
name          forward pass (``f`` = backbone features, ``n`` = numbers it sees)
============= =================================================================
``cnn``       flatten(f) ⊕ n → FC(64) → FC(2)                     (Farag 2018)
``cnn_lstm``  flatten(f) ⊕ n → FC(64) → LSTM(64) → FC(2)
``rvs_g``     flatten(f(bev)) ⊕ flatten(f(goal_bev)) ⊕ n → LSTM(64) → FC(2)
``manc``      p = σ(Linear(GAP(f))) (eq. 7) → q = vAGN(p, q') (eqs. 8–9) →
              gains = FC(q) → one DMP step (eqs. 10–11) → [speed, yaw rate]
``vagn_only`` p (eq. 7) → q = vAGN(p, q') → FC(64) on q ⊕ n → FC(2)
``dmp_only``  p (eq. 7) → gains = FC(p) → one DMP step → [speed, yaw rate]
============= =================================================================

What ``n`` contains per model and per information setting is the table of
:mod:`minimanc.inputs`. Direct heads output ``o`` and return
``o · CONTROL_SCALE`` (:data:`CONTROL_SCALE` = 10 m/s, 0.5 rad/s), so the last
layer works with numbers of order one. (Authors' RvS has a Gaussian action
head; ours predicts the mean only and is trained with the same MSE as all
others.)

The DMP head (MANC and DMP-only)
--------------------------------
``FC`` outputs four logits which :func:`minimanc.dmp.gains_from_logits` maps
into :data:`minimanc.dmp.ALPHA_RANGE` × :data:`minimanc.dmp.BETA_RANGE`: the
position gains ``(α_y, β_y)`` and the orientation gains ``(α_q, β_q)`` of
eq. 10. In that box the default integrator (semi-implicit Euler, 10 sub-steps)
is stable at ``dt = 0.5`` s (the spectral radius of :func:`minimanc.dmp.step_matrix`
stays below 1 at every corner; chapter 3). Then, all in
the current **ego frame** (+x forward, +y left), with ``v₀, ω₀`` the current
speed and yaw rate (``obs["motion"]``) and the lane target interpolated
linearly between its 4-m points (:func:`lane_point`):

* **Position DMP** (eq. 10, first row; :func:`minimanc.dmp.step`): state
  ``y₀ = (0, 0)``, ``ẏ₀ = (v₀, 0)``; goal ``g`` = the lane point
  ``L_y = clip(d_y + τ_y v₀, 4, 4K)`` metres ahead (``d_y`` =
  :attr:`ModelConfig.position_lookahead` = 4 m, ``τ_y`` =
  :attr:`ModelConfig.position_lookahead_time` = 2 s). One step of ``dt``
  gives ``y₁``; the **speed** is the forward displacement over the step,
  ``y₁ₓ / dt`` — what the unicycle of :func:`minimanc.world.unicycle_step`
  does with a speed control. Far from the goal ``ẏ → β_y (g − y)``, so
  ``β_y τ_y ≈ 1`` keeps the speed, larger speeds up, smaller brakes; ``α_y``
  sets how quickly. The goal moves with the speed because the network never
  sees the speed: with a fixed goal distance the gains alone would have to
  encode it. ``d_y`` lets a standing car start. A bend ahead shortens
  ``gₓ`` and slows the car by itself. The price: ``β_y τ_y > 1`` compounds
  from step to step, so a model trained only on one-step predictions can
  run away in closed loop; :mod:`minimanc.train` therefore trains the DMP
  models on windows in which the DMP's velocity carries over
  (``TrainConfig.motion_feedback``). The equilibrium speed of this goal
  rule, ``v* ≈ β_y d_y / (1 − β_y τ_y)`` for a fully relaxed step, is very
  sensitive to ``β_y`` near ``β_y τ_y = 1``, which is why the windows span
  whole scenes (:mod:`minimanc.train`).
* **Orientation DMP** (eq. 10, second row — the quaternion DMP of eq. 2 about
  the vertical axis): ``q₀`` = identity (the ego frame), ``η₀ = (0, 0, ω₀)``,
  goal ``g_q`` = the yaw ``ψ_g = clip(κ v₀ τ_q, ±π/2)`` with ``κ = 2 p_y /
  |p|²`` the curvature of the circular arc that leaves the ego tangentially
  and passes through the lane point ``p`` at ``L_q = clip(d_q + t_q v₀, d_q,
  22 m)`` (pure pursuit; ``d_q`` = :attr:`ModelConfig.heading_lookahead` = 5 m,
  ``t_q`` = :attr:`ModelConfig.heading_lookahead_time` = 1 s) and ``τ_q`` =
  :attr:`ModelConfig.heading_horizon` = 1 s: ``ψ_g`` is the heading the ego
  would have after ``τ_q`` seconds on that arc. Unlike the lane's own
  heading, ``p`` contains the lateral offset — a car left of the lane sees
  ``p`` to its right and turns back (an attractor towards the lane heading
  alone has no term that corrects a lateral offset). Far from the goal
  ``η → β_q ψ_g``, i.e. the pure-pursuit yaw rate ``κ v₀`` when
  ``β_q τ_q = 1``. The **yaw rate** is the mean over the step,
  ``yaw(q₁) / dt``, as the logs' ``Δψ / dt``. For yaw-only motion the
  quaternion DMP equals the 1-D DMP on the yaw angle
  (:func:`minimanc.quaternion.quaternion_step`), which is what runs by
  default (``orientation="yaw"``; ``"quaternion"`` runs eq. 2 literally and
  gives the same numbers, tested, but compiles far more slowly under XLA).

These look-ahead rules are a textbook pure-pursuit prior: the synthetic human
of :mod:`minimanc.world.driver` steers by pure pursuit too (with a per-scene
look-ahead gain of 0.85–1.3 and an unobservable lateral wander), so the prior
suits the data — that is the structural advantage the paper claims for the
DMP ("lane following built in"): with constant gains (no CNN at all) the
head already steers along the lane (chapter 8 measures it against the logs).
The speed is the hard part: it must come from the CNN (leaders, yields,
bends). Initial gains: :data:`DEFAULT_GAINS`.

Two choices the paper leaves open, made here for trainability
----------------------------------------------------------------
* **Predicates in (0, 1).** Eq. 7 is ``p = Linear(GAP(f))``; we follow it
  with a sigmoid (:attr:`ModelConfig.predicate_activation`, ``"linear"``
  gives eq. 7 literally), reading ``p_i`` as "how much predicate ``i``
  holds". With the linear form the predicates can grow without bound during
  training, the column softmax of eq. 9 saturates, q becomes the same for
  every image and the gains stop depending on the scene. Bounded predicates
  leave the scale of ``W^p`` to the vAGN weights, and the automaton stays
  responsive. The CAMs of chapter 6 are those of the logits.
* **Scales at initialisation.** vAGN weights ``N(0, 4²)``
  (:attr:`ModelConfig.vagn_scale`) so that q moves visibly from image to
  image, and the gains FC (N → 4) starts ``gains_scale`` = 3 times larger
  than Glorot, so a change of q moves the gains (q lives on the simplex:
  its entries change by hundredths).

The goal pose itself is not used by the DMP models (the paper's ``g, g_q``
track the moving lane target). During training ``q'`` is uniform or random
per minibatch (Algorithm 1); in closed loop the state returned by
:func:`step` is fed back, so ``q`` carries over from step to step.

Every function takes an engine ``eng`` (``minimanc.engine("numpy"|"jax")``)
and uses only ``eng.xp``/``eng.nn``: the same code runs on both, and
gradients agree to 1e-6 in float64 (``tests/test_models.py``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from minimanc import cam, dmp, inputs, layers, quaternion, vagn
from minimanc.tree import leaves as tree_leaves

__all__ = [
    "CONTROL_SCALE",
    "DMP_MODELS",
    "LSTM_MODELS",
    "MODEL_NAMES",
    "VAGN_MODELS",
    "ModelConfig",
    "backbone",
    "dmp_head",
    "explain",
    "gain_logits",
    "init",
    "initial_state",
    "lane_point",
    "param_count",
    "param_counts",
    "replay",
    "sequence",
    "step",
]

MODEL_NAMES: tuple[str, ...] = inputs.MODEL_NAMES
"""``("cnn", "cnn_lstm", "rvs_g", "manc", "vagn_only", "dmp_only")``."""

VAGN_MODELS: tuple[str, ...] = ("manc", "vagn_only")
"""Models whose recurrent state is the q-distribution of vAGN."""

LSTM_MODELS: tuple[str, ...] = ("cnn_lstm", "rvs_g")
"""Models whose recurrent state is an LSTM's ``(h, c)``."""

DMP_MODELS: tuple[str, ...] = ("manc", "dmp_only")
"""Models with the DMP head of eqs. 10–11."""

CONTROL_SCALE: tuple[float, float] = (10.0, 0.5)
"""Output scale of the direct heads: ``controls = o · (10 m/s, 0.5 rad/s)``."""

DEFAULT_GAINS: tuple[float, float, float, float] = (1.0, 0.45, 2.5, 1.15)
"""Initial ``(α_y, β_y, α_q, β_q)`` of the DMP heads (the bias of the gains FC):
the best constant gains on 120 simulated scenes (rounded); β_y τ_y ≈ 1 keeps
the speed, β_q τ_q ≈ 1 follows the pure-pursuit arc."""


def gain_logits(gains: Any) -> np.ndarray:
    """The four logits ``(4,)`` whose :func:`dmp_head` gains are ``gains = (α_y, β_y, α_q,
    β_q)`` (inverse of :func:`minimanc.dmp.gains_from_logits`; each gain strictly inside
    its range)."""
    g = np.asarray(gains, dtype=np.float64)
    if g.shape != (4,) or not np.all(np.isfinite(g)):
        raise ValueError(f"gains must be four finite numbers (alpha_y, beta_y, alpha_q, "
                         f"beta_q); got gains={gains!r}")
    za_y, zb_y = dmp.logits_from_gains(g[0], g[1])
    za_q, zb_q = dmp.logits_from_gains(g[2], g[3])
    return np.array([za_y, zb_y, za_q, zb_q], dtype=np.float64)


@dataclass(frozen=True)
class ModelConfig:
    """Hyper-parameters shared by all six controllers.

    ``n_states`` q-states of vAGN (the paper studies 3–12), ``n_predicates``
    visual predicates of eq. 7, ``image_size`` of the square BEV, ``setting``
    ("paper"/"parity", see :mod:`minimanc.inputs`), ``channels`` of the 3×3
    stride-2 convolutions, ``activation`` ("silu"/"relu"), ``hidden`` units of
    the FC and LSTM layers (64 as in the paper), ``k_targets`` lane-target
    points, ``position_lookahead`` (m), ``position_lookahead_time`` (s),
    ``heading_lookahead`` (m), ``heading_lookahead_time`` (s) and
    ``heading_horizon`` (s) of the DMP head (module docstring),
    ``critically_damped`` (β = α/4, the paper's safe option),
    ``predicate_activation`` ("sigmoid" or "linear", see the module docstring),
    ``gains_scale`` (initial scale of the gains FC relative to Glorot),
    ``orientation`` ("yaw": the orientation DMP on the yaw angle, or
    "quaternion": literally eq. 2 with unit quaternions — equal results for
    yaw-only driving, but XLA compiles the quaternion form ~40× slower),
    ``vagn_scale`` the std of vAGN's initial weights, ``dt`` the step (s).
    """

    n_states: int = 6
    n_predicates: int = 8
    image_size: int = 64
    setting: str = "paper"
    channels: tuple[int, ...] = (16, 32, 32)
    activation: str = "silu"
    hidden: int = 64
    k_targets: int = 10
    position_lookahead: float = 4.0
    position_lookahead_time: float = 2.0
    heading_lookahead: float = 5.0
    heading_lookahead_time: float = 1.0
    heading_horizon: float = 1.0
    critically_damped: bool = False
    orientation: str = "yaw"
    predicate_activation: str = "sigmoid"
    gains_scale: float = 3.0
    vagn_scale: float = 4.0
    dt: float = dmp.DT

    def __post_init__(self) -> None:
        for name in ("n_states", "n_predicates", "image_size", "hidden", "k_targets"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {name}={v!r}")
        inputs.check_setting(self.setting)
        ch = tuple(self.channels)
        if not ch or any(isinstance(c, bool) or not isinstance(c, int | np.integer) or c < 1
                         for c in ch):
            raise ValueError(f"channels must be a non-empty tuple of positive integers, "
                             f"got channels={self.channels!r}")
        object.__setattr__(self, "channels", tuple(int(c) for c in ch))
        if self.activation not in ("silu", "relu"):
            raise ValueError(f"activation must be 'silu' or 'relu', got "
                             f"activation={self.activation!r}")
        reach = 4.0 * self.k_targets
        for name in ("position_lookahead", "heading_lookahead"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and 4.0 <= v <= min(reach, 22.0)):
                raise ValueError(f"{name} must be in [4, {min(reach, 22.0)}] m (the lane "
                                 f"target spans 4 .. 4·k_targets m), got {name}={v!r}")
        for name in ("position_lookahead_time", "heading_lookahead_time", "heading_horizon"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and v >= 0.0 and np.isfinite(v)):
                raise ValueError(f"{name} must be a finite number >= 0 s, got {name}={v!r}")
        if not self.heading_horizon > 0.0:
            raise ValueError(f"heading_horizon must be > 0 s, got "
                             f"heading_horizon={self.heading_horizon!r}")
        if self.orientation not in ("yaw", "quaternion"):
            raise ValueError(f"orientation must be 'yaw' or 'quaternion', got "
                             f"orientation={self.orientation!r}")
        if self.predicate_activation not in ("sigmoid", "linear"):
            raise ValueError(f"predicate_activation must be 'sigmoid' or 'linear', got "
                             f"predicate_activation={self.predicate_activation!r}")
        if not (isinstance(self.gains_scale, int | float) and self.gains_scale > 0.0):
            raise ValueError(f"gains_scale must be > 0, got gains_scale={self.gains_scale!r}")
        if not self.vagn_scale > 0.0:
            raise ValueError(f"vagn_scale must be > 0, got vagn_scale={self.vagn_scale!r}")
        if not self.dt > 0.0:
            raise ValueError(f"dt must be > 0, got dt={self.dt!r}")

    @property
    def feature_size(self) -> int:
        """Spatial size of the backbone's output (64 → 8 with three stride-2 layers)."""
        s = self.image_size
        for _ in self.channels:
            s = (s + 2 - 3) // 2 + 1
        return s

    def to_dict(self) -> dict:
        """A JSON-able dict (for checkpoints)."""
        d = asdict(self)
        d["channels"] = list(d["channels"])
        return d


def check_name(name: Any) -> str:
    """``name`` if it is one of :data:`MODEL_NAMES`, else a ValueError naming it."""
    if name not in MODEL_NAMES:
        raise ValueError(f"name must be one of {MODEL_NAMES}, got name={name!r}")
    return name


# --------------------------------------------------------------------------- parameters


def init(name: str, rng: np.random.Generator, cfg: ModelConfig | None = None,
         dtype: Any = np.float64) -> dict:
    """Initial parameters of model ``name``: a pytree (nested dicts/lists) of NumPy arrays."""
    name = check_name(name)
    cfg = cfg or ModelConfig()
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got rng={rng!r}")
    convs, c_in = [], 3
    for c in cfg.channels:
        convs.append(layers.init_conv(rng, 3, 3, c_in, c))
        c_in = c
    params: dict = {"backbone": {"convs": convs}}
    K, M, N, H = cfg.channels[-1], cfg.n_predicates, cfg.n_states, cfg.hidden
    flat = cfg.feature_size ** 2 * K
    n_num = inputs.numeric_size(name, cfg.setting, cfg.k_targets)
    if name in ("manc", "vagn_only", "dmp_only"):
        params["predicates"] = layers.init_dense(rng, K, M)
    if name in VAGN_MODELS:
        params["vagn"] = {"W": vagn.init_vagn(rng, M, N, scale=cfg.vagn_scale)}
    if name in DMP_MODELS:
        n_in = N if name == "manc" else M
        gains = layers.init_dense(rng, n_in, 4)
        gains["w"] = cfg.gains_scale * np.asarray(gains["w"])
        gains["b"] = gain_logits(DEFAULT_GAINS)
        params["gains"] = gains
    if name == "cnn":
        params["fc1"] = layers.init_dense(rng, flat + n_num, H)
        params["out"] = layers.init_dense(rng, H, 2)
    elif name == "cnn_lstm":
        params["fc1"] = layers.init_dense(rng, flat + n_num, H)
        params["lstm"] = layers.init_lstm(rng, H, H)
        params["out"] = layers.init_dense(rng, H, 2)
    elif name == "rvs_g":
        params["lstm"] = layers.init_lstm(rng, 2 * flat + n_num, H)
        params["out"] = layers.init_dense(rng, H, 2)
    elif name == "vagn_only":
        params["fc1"] = layers.init_dense(rng, N + n_num, H)
        params["out"] = layers.init_dense(rng, H, 2)
    return _cast(params, dtype)


def _cast(tree: Any, dtype: Any) -> Any:
    if isinstance(tree, dict):
        return {k: _cast(v, dtype) for k, v in tree.items()}
    if isinstance(tree, list | tuple):
        return type(tree)(_cast(v, dtype) for v in tree)
    return np.asarray(tree, dtype=dtype)


def param_count(params: dict) -> int:
    """Number of scalar parameters in a pytree."""
    return int(sum(int(np.prod(np.shape(x))) for x in tree_leaves(params)))


def param_counts(cfg: ModelConfig | None = None, names: tuple[str, ...] = MODEL_NAMES) -> dict:
    """``{name: param_count(init(name, ...))}`` for every model under ``cfg``."""
    cfg = cfg or ModelConfig()
    return {n: param_count(init(n, np.random.default_rng(0), cfg)) for n in names}


def initial_state(name: str, batch: int, cfg: ModelConfig | None = None, xp: Any = np,
                  rng: np.random.Generator | None = None, mode: str = "uniform",
                  dtype: Any = np.float32) -> dict:
    """The recurrent state at the start of a sequence, for ``batch`` rows.

    vAGN models: ``{"q": (B, N)}``, uniform (Algorithm 1's ``UniformInit``) or
    ``mode="random"`` (``RandomInit``: flat Dirichlet draws, needs ``rng``).
    LSTM models: ``{"h": 0, "c": 0}`` of shape ``(B, hidden)``. Others: ``{}``.
    """
    name = check_name(name)
    cfg = cfg or ModelConfig()
    if isinstance(batch, bool) or not isinstance(batch, int | np.integer) or batch < 1:
        raise ValueError(f"batch must be a positive integer, got batch={batch!r}")
    if mode not in ("uniform", "random"):
        raise ValueError(f"mode must be 'uniform' or 'random', got mode={mode!r}")
    if name in VAGN_MODELS:
        if mode == "random":
            if not isinstance(rng, np.random.Generator):
                raise ValueError(f"mode='random' needs rng=numpy.random.Generator, got rng={rng!r}")
            q = vagn.random_state(rng, cfg.n_states, size=int(batch))
        else:
            q = np.broadcast_to(vagn.uniform_state(cfg.n_states), (int(batch), cfg.n_states))
        return {"q": xp.asarray(np.asarray(q, dtype=dtype))}
    if name in LSTM_MODELS:
        z = np.zeros((int(batch), cfg.hidden), dtype=dtype)
        return {"h": xp.asarray(z), "c": xp.asarray(z)}
    return {}


# --------------------------------------------------------------------------- forward pieces


def backbone(params: dict, images: Any, cfg: ModelConfig, eng: Any) -> Any:
    """The shared CNN: 3×3 conv, stride 2, padding 1, activation, per layer. NHWC → NHWC."""
    act = eng.nn.silu if cfg.activation == "silu" else eng.nn.relu
    h = images
    for layer in params["convs"]:
        h = act(layers.conv2d(layer, h, eng.nn, stride=2, padding=1))
    return h


def _dense(p: dict, x: Any, eng: Any) -> Any:
    return layers.dense(p, x, xp=eng.xp)


def _act(x: Any, cfg: ModelConfig, eng: Any) -> Any:
    return eng.nn.silu(x) if cfg.activation == "silu" else eng.nn.relu(x)


def _flatten(f: Any, xp: Any) -> Any:
    return xp.reshape(f, (f.shape[0], -1))


def lane_point(lane_target: Any, dist: Any, xp: Any = np, spacing: float = 4.0) -> Any:
    """The lane-target point ``dist`` metres ahead, ``(B, 2)``, by linear interpolation.

    ``lane_target (B, K, 2)`` holds the points at ``spacing · (1 … K)`` m of
    route; ``dist (B,)`` must lie in ``[spacing, K · spacing]``. The weights are
    hat functions ``max(1 − |dist/spacing − k|, 0)``, so the result is
    differentiable in the points (and works on both engines).
    """
    K = lane_target.shape[1]
    idx = xp.asarray(np.arange(1, K + 1, dtype=np.float32))
    u = xp.expand_dims(dist, -1) / spacing
    w = xp.maximum(1.0 - xp.abs(u - idx), 0.0)
    return xp.sum(lane_target * xp.expand_dims(w, -1), axis=1)


def dmp_head(logits: Any, lane_target: Any, motion: Any, cfg: ModelConfig,
             xp: Any = np) -> tuple[Any, dict]:
    """Eqs. 10–11: four gain logits ``(B, 4)`` → one DMP step → controls ``(B, 2)``.

    See the module docstring for how ``g`` and ``g_q`` are built from the
    lane target ``(B, K, 2)`` and the current ``motion (B, 2)`` = [speed, yaw
    rate] (the DMPs' initial velocities), and how the step becomes [speed,
    yaw rate]. Returns ``(controls, aux)`` with ``aux["alpha"]``,
    ``aux["beta"]`` of shape ``(B, 2)`` = (position, orientation) gains, and
    the goals ``aux["g"]`` (B, 2) and ``aux["psi_g"]`` (B,).
    """
    K = cfg.k_targets
    lt = xp.asarray(lane_target)
    mot = xp.asarray(motion)
    v0, w0 = mot[:, 0], mot[:, 1]
    crit = cfg.critically_damped
    a_y, b_y = dmp.gains_from_logits(logits[:, 0:1], None if crit else logits[:, 1:2], xp=xp,
                                     critically_damped=crit)
    a_q, b_q = dmp.gains_from_logits(logits[:, 2:3], None if crit else logits[:, 3:4], xp=xp,
                                     critically_damped=crit)
    zero = xp.zeros_like(v0)
    # position DMP towards the lane point about tau_y seconds ahead
    L_y = xp.clip(cfg.position_lookahead + cfg.position_lookahead_time * v0, 4.0, 4.0 * K)
    g = lane_point(lt, L_y, xp)
    y0 = xp.stack([zero, zero], axis=-1)
    dy0 = xp.stack([v0, zero], axis=-1)
    y1, _, _ = dmp.step(y0, dy0, g, a_y, b_y, dt=cfg.dt, xp=xp)
    speed = y1[:, 0] / cfg.dt
    # orientation goal: the heading after tau_q seconds on the pure-pursuit arc
    top = min(22.0, 4.0 * K)
    L_q = xp.clip(cfg.heading_lookahead + cfg.heading_lookahead_time * v0,
                  cfg.heading_lookahead, top)
    p = lane_point(lt, L_q, xp)
    kappa = 2.0 * p[:, 1] / xp.maximum(p[:, 0] * p[:, 0] + p[:, 1] * p[:, 1], 1e-6)
    half_pi = float(np.pi / 2)
    psi_g = xp.clip(kappa * v0 * cfg.heading_horizon, -half_pi, half_pi)
    if cfg.orientation == "quaternion":
        q0 = xp.stack([zero + 1.0, zero, zero, zero], axis=-1)  # identity, in v0's dtype
        eta0 = xp.stack([zero, zero, w0], axis=-1)
        g_q = quaternion.from_yaw(psi_g, xp=xp)
        q1, _, _ = quaternion.quaternion_step(q0, eta0, g_q, a_q, b_q, dt=cfg.dt, xp=xp)
        yaw_rate = quaternion.to_yaw(q1, xp=xp) / cfg.dt
    else:  # the same quaternion DMP written on the yaw angle (exact for yaw-only motion)
        psi1, _, _ = dmp.step(xp.expand_dims(zero, -1), xp.expand_dims(w0, -1),
                              xp.expand_dims(psi_g, -1), a_q, b_q, dt=cfg.dt, xp=xp)
        yaw_rate = psi1[:, 0] / cfg.dt
    controls = xp.stack([speed, yaw_rate], axis=-1)
    aux = {
        "alpha": xp.concatenate([a_y, a_q], axis=-1),
        "beta": xp.concatenate([b_y, b_q], axis=-1),
        "g": g,
        "psi_g": psi_g,
    }
    return controls, aux


def _encode(name: str, params: dict, obs: dict, cfg: ModelConfig, eng: Any) -> dict:
    """Per-frame computations (no recurrence): features, predicates, numbers."""
    xp = eng.xp
    dtype = params["backbone"]["convs"][0]["w"].dtype
    obs = {k: xp.asarray(v, dtype=dtype) for k, v in obs.items()}
    f = backbone(params["backbone"], obs["bev"], cfg, eng)
    enc: dict = {"features": f}
    if "predicates" in params:
        gap = xp.mean(xp.mean(f, axis=1), axis=1)  # GAP of eq. 7
        z = _dense(params["predicates"], gap, eng)
        enc["predicates"] = eng.nn.sigmoid(z) if cfg.predicate_activation == "sigmoid" else z
    num = inputs.numeric_features(obs, name, cfg.setting, xp=xp)
    if name == "cnn":
        x = _flatten(f, xp) if num is None else xp.concatenate([_flatten(f, xp), num], axis=-1)
        enc["pre"] = x
    elif name == "cnn_lstm":
        x = _flatten(f, xp) if num is None else xp.concatenate([_flatten(f, xp), num], axis=-1)
        enc["pre"] = _act(_dense(params["fc1"], x, eng), cfg, eng)
    elif name == "rvs_g":
        fg = backbone(params["backbone"], obs["goal_bev"], cfg, eng)
        parts = [_flatten(f, xp), _flatten(fg, xp)] + ([] if num is None else [num])
        enc["pre"] = xp.concatenate(parts, axis=-1)
    elif name == "vagn_only":
        enc["num"] = num
    elif name in DMP_MODELS:
        enc["lane_target"] = xp.asarray(obs["lane_target"])
        enc["motion"] = xp.asarray(obs["motion"])
    return enc


def _head(name: str, params: dict, enc: dict, state: dict, cfg: ModelConfig,
          eng: Any) -> tuple[Any, dict, dict]:
    """One time step of the recurrent part and the head."""
    xp = eng.xp
    scale = xp.asarray(np.asarray(CONTROL_SCALE, dtype=np.float32))
    aux: dict = {}
    if "predicates" in enc:
        aux["predicates"] = enc["predicates"]
    new_state = dict(state)
    if name == "cnn":
        h = _act(_dense(params["fc1"], enc["pre"], eng), cfg, eng)
        return _dense(params["out"], h, eng) * scale, new_state, aux
    if name in LSTM_MODELS:
        h, c = layers.lstm_cell(params["lstm"], (state["h"], state["c"]), enc["pre"], xp=xp,
                                nn=eng.nn)
        new_state = {"h": h, "c": c}
        return _dense(params["out"], h, eng) * scale, new_state, aux
    if name in VAGN_MODELS:
        q = vagn.step(state["q"], enc["predicates"], params["vagn"]["W"], xp=xp)
        new_state = {"q": q}
        aux["q"] = q
        if name == "vagn_only":
            x = q if enc["num"] is None else xp.concatenate([q, enc["num"]], axis=-1)
            h = _act(_dense(params["fc1"], x, eng), cfg, eng)
            return _dense(params["out"], h, eng) * scale, new_state, aux
        logits = _dense(params["gains"], q, eng)  # FC(q) of eq. 11
    else:  # dmp_only
        logits = _dense(params["gains"], enc["predicates"], eng)
    controls, daux = dmp_head(logits, enc["lane_target"], enc["motion"], cfg, xp=xp)
    aux.update(daux)
    return controls, new_state, aux


def _check_obs(name: str, obs: dict, cfg: ModelConfig, lead: int) -> None:
    """Keys and shapes of an observation (``lead`` leading axes before the image axes)."""
    keys = inputs.visible(name, cfg.setting)
    missing = [k for k in keys if k not in obs]
    if missing:
        raise ValueError(f"obs lacks {missing} needed by model {name!r} in setting "
                         f"{cfg.setting!r}; got keys {sorted(obs)}")
    shape = tuple(obs["bev"].shape)
    want = (cfg.image_size, cfg.image_size, 3)
    if len(shape) != lead + 3 or shape[lead:] != want:
        raise ValueError(f"obs['bev'] must have shape {('B',) * lead + want} for "
                         f"image_size={cfg.image_size}, got {shape}")
    if "lane_target" in keys:
        lt = tuple(obs["lane_target"].shape)
        if lt[lead:] != (cfg.k_targets, 2):
            raise ValueError(f"obs['lane_target'] must end in ({cfg.k_targets}, 2) "
                             f"(k_targets={cfg.k_targets}), got {lt}")


def step(name: str, params: dict, obs: dict, state: dict, cfg: ModelConfig | None,
         eng: Any) -> tuple[Any, dict, dict]:
    """One control step: ``(controls (B, 2), new_state, aux)``.

    ``obs`` from :mod:`minimanc.inputs` (batched over B), ``state`` from
    :func:`initial_state` or the previous call. ``aux`` holds what the
    explainability figures need: ``predicates`` (B, M) for the vAGN/DMP
    models, ``q`` (B, N) for vAGN models, ``alpha`` and ``beta`` (B, 2) =
    (position, orientation) gains for DMP models, and ``features`` (the
    backbone's output, B × h × w × C).
    """
    name = check_name(name)
    cfg = cfg or ModelConfig()
    _check_obs(name, obs, cfg, 1)
    enc = _encode(name, params, obs, cfg, eng)
    controls, new_state, aux = _head(name, params, enc, state, cfg, eng)
    aux["features"] = enc["features"]
    return controls, new_state, aux


def sequence(name: str, params: dict, obs_seq: dict, state: dict, cfg: ModelConfig | None,
             eng: Any, feedback_motion: bool = False, return_aux: bool = False) -> tuple:
    """Run ``L`` steps on time-major observations ``(L, B, ...)``: ``(controls (L, B, 2), state)``.

    Equal to ``L`` calls of :func:`step` (tested), but the backbone runs once
    on all ``L·B`` frames, and the time loop is one ``eng.scan`` on both engines
    (on JAX compiled once instead of unrolled ``L`` times; on NumPy one tape node).
    Used to train the recurrent models on truncated
    back-propagation-through-time windows. With ``feedback_motion`` (DMP
    models), the DMP's initial velocities at step ``i > 0`` are the model's
    own controls of step ``i − 1`` instead of ``obs_seq["motion"][i]``: the
    DMP integrates its own state, as in closed loop, so that an error in the
    speed carries over and is penalised (only the first step uses the logged
    motion). With ``return_aux`` a third item holds the per-step ``aux``
    arrays of :func:`step` stacked along time (``features`` excluded).
    """
    name = check_name(name)
    cfg = cfg or ModelConfig()
    _check_obs(name, obs_seq, cfg, 2)
    xp = eng.xp
    L, B = obs_seq["bev"].shape[:2]
    flat = {k: xp.reshape(xp.asarray(v), (L * B,) + tuple(v.shape[2:]))
            for k, v in obs_seq.items() if k in inputs.visible(name, cfg.setting)}
    enc = _encode(name, params, flat, cfg, eng)
    enc.pop("features")
    feedback = feedback_motion and name in DMP_MODELS
    none_keys = [k for k, v in enc.items() if v is None]
    xs = {k: xp.reshape(v, (L, B) + tuple(v.shape[1:])) for k, v in enc.items() if v is not None}

    def body(carry: tuple, x: dict) -> tuple:
        st, prev, i = carry
        enc_i = dict(x)
        enc_i.update({k: None for k in none_keys})
        if feedback:
            enc_i["motion"] = xp.where(i > 0, prev, x["motion"])
        controls, new_st, aux = _head(name, params, enc_i, st, cfg, eng)
        controls = controls.astype(prev.dtype)
        new_st = {k: v.astype(st[k].dtype) for k, v in new_st.items()}
        return (new_st, controls, i + 1), (controls, aux if return_aux else {})

    dtype = params["backbone"]["convs"][0]["w"].dtype
    prev0 = xp.zeros((B, 2), dtype=dtype)
    (state, _, _), (outs, auxs) = eng.scan(body, (dict(state), prev0, 0), xs)
    if not return_aux:
        return outs, state
    return outs, state, auxs


# --------------------------------------------------------------------------- explainability


def explain(params: dict, obs: dict, q_prev: Any, cfg: ModelConfig | None = None,
            eng: Any = None, upsample_to_input: bool = True) -> dict:
    """Per-q-state saliency of a vAGN model (paper Figs. 3–4), NumPy arrays.

    Runs eq. 7 on ``obs["bev"]`` and one vAGN step from ``q_prev`` (B, N).
    Returns ``logits`` (B, M) = ``Linear(GAP(f))`` and ``predicates`` (B, M)
    (the logits through :attr:`ModelConfig.predicate_activation`), ``q``
    (B, N), ``cams`` (B, M, H, W) — the class activation maps of the logits
    (:func:`minimanc.cam.class_activation_maps`; ``mean_xy cams_i = logit_i −
    b_i``) —, ``jacobian`` (B, N, M) = ∂q/∂logits (chain rule through the
    sigmoid) and ``saliency`` (B, N, H, W) = ``Σ_i J_ji cams_i``
    (:func:`minimanc.cam.q_state_saliency`); maps are upsampled to the image
    unless ``upsample_to_input`` is False.
    """
    from minimanc import engine as _engine

    cfg = cfg or ModelConfig()
    eng = eng or _engine("numpy")
    if "vagn" not in params or "predicates" not in params:
        raise ValueError("explain needs the parameters of a vAGN model (manc or vagn_only); "
                         f"got params with keys {sorted(params)}")
    bev = np.asarray(obs["bev"], dtype=np.float64)
    f = np.asarray(_value(backbone(_value_tree(params["backbone"]), bev, cfg, eng)))
    w = np.asarray(_value(params["predicates"]["w"]), dtype=np.float64)
    b = np.asarray(_value(params["predicates"]["b"]), dtype=np.float64)
    z = f.mean(axis=(1, 2)) @ w + b
    if cfg.predicate_activation == "sigmoid":
        p = 0.5 * (1.0 + np.tanh(0.5 * z))
        dp_dz = p * (1.0 - p)
    else:
        p, dp_dz = z, np.ones_like(z)
    W = np.asarray(_value(params["vagn"]["W"]), dtype=np.float64)
    q_prev = np.asarray(q_prev, dtype=np.float64)
    q = vagn.step(q_prev, p, W)
    cams = cam.class_activation_maps(f, w)
    J = cam.vagn_jacobian(q_prev, p, W) * dp_dz[..., None, :]
    S = cam.q_state_saliency(cams, J)
    if upsample_to_input:
        size = tuple(bev.shape[1:3])
        cams, S = cam.upsample(cams, size), cam.upsample(S, size)
    return {"logits": z, "predicates": p, "q": q, "cams": cams, "jacobian": J, "saliency": S}


def _value(x: Any) -> Any:
    return getattr(x, "_value", getattr(x, "value", x))


def _value_tree(tree: Any) -> Any:
    if isinstance(tree, dict):
        return {k: _value_tree(v) for k, v in tree.items()}
    if isinstance(tree, list | tuple):
        return type(tree)(_value_tree(v) for v in tree)
    return np.asarray(_value(tree), dtype=np.float64)


def replay(name: str, params: dict, ds: Any, scene: int, cfg: ModelConfig | None = None,
           eng: Any = None, q_mode: str = "uniform") -> dict:
    """Open-loop trace of one logged scene: the model sees the human's observations
    step by step and its recurrent state carries over (q for vAGN models).

    Returns NumPy arrays over the ``T`` steps: ``controls`` (T, 2), ``human``
    (T, 2) and, where the model has them, ``q`` (T, N), ``alpha``/``beta``
    (T, 2), ``predicates`` (T, M). (The closed loop, where the model also
    drives, is :mod:`minimanc.rollout`.)
    """
    from minimanc import engine as _engine

    name = check_name(name)
    cfg = cfg or ModelConfig()
    eng = eng or _engine("numpy")
    T = np.asarray(ds.ego).shape[1]
    state = initial_state(name, 1, cfg, xp=eng.xp, mode="uniform") if q_mode == "uniform" \
        else initial_state(name, 1, cfg, xp=eng.xp, rng=np.random.default_rng(0), mode=q_mode)
    keep: dict = {"controls": []}
    for t in range(T):
        obs = inputs.from_dataset(ds, scene, t, cfg.setting, model=name)
        controls, state, aux = step(name, params, obs, state, cfg, eng)
        keep["controls"].append(np.asarray(_value(controls))[0])
        for k in ("q", "alpha", "beta", "predicates"):
            if k in aux:
                keep.setdefault(k, []).append(np.asarray(_value(aux[k]))[0])
    out = {k: np.stack(v) for k, v in keep.items()}
    out["human"] = np.asarray(ds.controls[scene], dtype=np.float64)
    return out
