"""Chapter 8 — the hyper-parameters shared by every controller (:class:`ModelConfig`) and the
constants of the heads (:data:`CONTROL_SCALE`, :data:`DEFAULT_GAINS`, :func:`gain_logits`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from minimanc import dmp, inputs
from minimanc.checks import check_int
from minimanc.models.readout import check_readout
from minimanc.world.lanes import TARGET_SPACING
from minimanc.world.raster import RasterConfig

__all__ = ["CONTROL_SCALE", "DEFAULT_GAINS", "DEFAULT_INPUT_SHAPE", "TARGET_SPACING", "ModelConfig",
           "gain_box_corners", "gain_logits", "lookahead_rule"]

# TARGET_SPACING (the metres of route between the lane-target points the heads see,
# obs["lane_target"] at 4 · (1 … K) m) is the world's, re-exported for the heads.

CONTROL_SCALE: tuple[float, float] = (10.0, 0.5)
"""Output scale of the direct heads: ``controls = o · (10 m/s, 0.5 rad/s)``."""

GAINS_INPUTS: tuple[str, ...] = ("q", "q_p")
"""What MANC's gains FC (eq. 11) reads (:attr:`ModelConfig.gains_input`): q, or q ⊕ p."""

DEFAULT_GAINS: tuple[float, float, float, float] = (1.0, 0.45, 2.5, 1.15)
"""Initial ``(α_y, β_y, α_q, β_q)`` of the DMP heads (the bias of the gains FC):
β_y τ_y ≈ 1 keeps the speed, β_q τ_q ≈ 1 follows the pure-pursuit arc."""

DEFAULT_INPUT_SHAPE: tuple[int, int, int] = RasterConfig().input_shape
"""``(H, W, C)`` a model reads when :attr:`ModelConfig.input_shape` is unset and no data
says otherwise: the default raster's (64 × 64 RGB)."""


def gain_logits(gains: Any) -> np.ndarray:
    """The logits whose DMP-head gains are ``gains``.

    Parameters
    ----------
    gains : array_like, shape (4,)
        ``(α_y, β_y, α_q, β_q)``, each strictly inside
        :data:`minimanc.dmp.ALPHA_RANGE` / :data:`minimanc.dmp.BETA_RANGE`.

    Returns
    -------
    numpy.ndarray, shape (4,)
        The inverse of :func:`minimanc.dmp.gains_from_logits` (eq. 10's gain map).

    Raises
    ------
    ValueError
        If ``gains`` is not four finite numbers (or one lies outside its range).
    """
    g = np.asarray(gains, dtype=np.float64)
    if g.shape != (4,) or not np.all(np.isfinite(g)):
        raise ValueError(f"gains must be four finite numbers (alpha_y, beta_y, alpha_q, "
                         f"beta_q); got gains={gains!r}")
    za_y, zb_y = dmp.logits_from_gains(g[0], g[1])
    za_q, zb_q = dmp.logits_from_gains(g[2], g[3])
    return np.array([za_y, zb_y, za_q, zb_q], dtype=np.float64)


def gain_box_corners(critically_damped: bool = False) -> np.ndarray:
    """The corners ``(α, β)`` of the box the DMP head's gains live in.

    The default integrator's stability condition is monotone in α and β, so a
    step stable at every corner is stable on the whole box.

    Parameters
    ----------
    critically_damped : bool
        The head's β is α/4 (:attr:`ModelConfig.critically_damped`).

    Returns
    -------
    numpy.ndarray, shape (4, 2) or (2, 2)
        :data:`minimanc.dmp.ALPHA_RANGE` × :data:`minimanc.dmp.BETA_RANGE`, or the two
        ends of ``β = α/4``.
    """
    a_lo, a_hi = dmp.ALPHA_RANGE
    if critically_damped:
        return np.array([[a_lo, a_lo / 4.0], [a_hi, a_hi / 4.0]])
    b_lo, b_hi = dmp.BETA_RANGE
    return np.array([[a, b] for a in (a_lo, a_hi) for b in (b_lo, b_hi)])


def _largest_stable_dt(corners: np.ndarray) -> float:
    """Bisection on :func:`minimanc.dmp.step_stable` over the corners (for the message)."""
    lo, hi = 0.0, 1.0
    while bool(np.all(dmp.step_stable(corners[:, 0], corners[:, 1], dt=hi))):
        lo, hi = hi, 2.0 * hi
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if bool(np.all(dmp.step_stable(corners[:, 0], corners[:, 1], dt=mid))):
            lo = mid
        else:
            hi = mid
    return lo


@dataclass(frozen=True)
class ModelConfig:
    """Hyper-parameters shared by all controllers.

    ``n_states`` q-states of vAGN (the paper studies 3–12), ``n_predicates``
    visual predicates of eq. 7, ``input_shape`` ``(H, W, C)`` of the BEV planes the model
    reads (the raster's :attr:`minimanc.world.RasterConfig.input_shape`; ``None``, the
    default, takes it from the data: :func:`minimanc.train.fit` fills it in from the dataset,
    and a model built without data reads :data:`DEFAULT_INPUT_SHAPE`), ``setting``
    ("paper"/"parity", see :mod:`minimanc.inputs`), ``channels`` of the 3×3
    stride-2 convolutions, ``activation`` ("silu"/"relu"), ``hidden`` units of
    the FC and LSTM layers (64 as in the paper), ``k_targets`` lane-target
    points, ``position_lookahead`` (m), ``position_lookahead_time`` (s),
    ``heading_lookahead`` (m), ``heading_lookahead_time`` (s) and
    ``heading_horizon`` (s) of the DMP head (:func:`minimanc.models.dmp_head`),
    ``critically_damped`` (β = α/4, the paper's safe option),
    ``predicate_activation`` ("sigmoid" or "linear": eq. 7 literally),
    ``gains_scale`` (initial scale of the gains FC relative to Glorot),
    ``orientation`` ("yaw": the orientation DMP on the yaw angle, or
    "quaternion": eq. 2 with unit quaternions — equal results for yaw-only
    driving), ``vagn_scale`` the std of vAGN's initial weights, ``dt`` the
    step (s) and ``predicate_readout``, what eq. 7's linear layer reads of the features ``f``
    ``(B, h, w, C)`` (:mod:`minimanc.models.readout`): "gap", eq. 7 as the paper writes it,
    ``p = σ(Linear(GAP(f)))`` (weights ``(C, M)``); or "flatten", ``p = σ(Linear(flatten(f)))``
    (weights ``(h·w·C, M)``): each predicate a weighted sum over every position and channel,
    still linear in ``f`` but keeping *where* a feature fires, its CAM the per-position
    contribution ``Σ_c W(y, x, c) f_c(y, x)``. ``gains_input``, what MANC's gains FC of eq. 11
    reads (:data:`GAINS_INPUTS`): "q", the automaton's state as the paper writes it,
    ``FC(q)``; or "q_p", ``FC(q ⊕ p)``, the predicates of eq. 7 beside it.

    ``dt`` must keep the default DMP integrator (:data:`minimanc.dmp.DEFAULT_METHOD`,
    :data:`minimanc.dmp.DEFAULT_SUBSTEPS` sub-steps) stable at every corner of the gain
    box (:func:`gain_box_corners`); otherwise ValueError.
    """

    n_states: int = 6
    n_predicates: int = 8
    input_shape: tuple[int, int, int] | None = None
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
    predicate_readout: str = "gap"
    gains_input: str = "q"

    def __post_init__(self) -> None:
        for name in ("n_states", "n_predicates", "hidden", "k_targets"):
            check_int(name, getattr(self, name), 1)
        if self.input_shape is not None:
            shape = self.input_shape
            if not isinstance(shape, tuple | list) or len(shape) != 3 or any(
                    isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1
                    for n in shape):
                raise ValueError(f"input_shape must be three positive integers (H, W, C), e.g. "
                                 f"world.RasterConfig(...).input_shape, or None (the data's); "
                                 f"got input_shape={shape!r}")
            object.__setattr__(self, "input_shape", tuple(int(n) for n in shape))
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
        reach = TARGET_SPACING * self.k_targets
        for name in ("position_lookahead", "heading_lookahead"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and TARGET_SPACING <= v <= min(reach, 22.0)):
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
        check_readout(self.predicate_readout)
        if self.gains_input not in GAINS_INPUTS:
            raise ValueError(f"gains_input must be one of {GAINS_INPUTS}, got "
                             f"gains_input={self.gains_input!r}")
        if not (isinstance(self.gains_scale, int | float) and self.gains_scale > 0.0):
            raise ValueError(f"gains_scale must be > 0, got gains_scale={self.gains_scale!r}")
        if not self.vagn_scale > 0.0:
            raise ValueError(f"vagn_scale must be > 0, got vagn_scale={self.vagn_scale!r}")
        self._check_dt()

    def _check_dt(self) -> None:
        dt = self.dt
        if isinstance(dt, bool) or not isinstance(dt, int | float | np.floating) \
                or not np.isfinite(dt) or not dt > 0.0:
            raise ValueError(f"dt must be a finite number > 0 s, got dt={dt!r}")
        corners = gain_box_corners(self.critically_damped)
        stable = np.asarray(dmp.step_stable(corners[:, 0], corners[:, 1], dt=float(dt)))
        if np.all(stable):
            return
        a, b = corners[int(np.argmin(stable))]
        rho = float(dmp.spectral_radius(a, b, dt=float(dt)))
        raise ValueError(
            f"dt={dt!r} makes the DMP head's integrator ({dmp.DEFAULT_METHOD}, "
            f"{dmp.DEFAULT_SUBSTEPS} sub-steps) unstable at the gain-box corner alpha={a:g}, "
            f"beta={b:g} (spectral radius {rho:.4g} > 1; box alpha in {dmp.ALPHA_RANGE}, beta "
            f"in {dmp.BETA_RANGE}{', beta = alpha/4' if self.critically_damped else ''}); "
            f"use dt < {_largest_stable_dt(corners):.4g} s")

    @property
    def bev_shape(self) -> tuple[int, int, int]:
        """``(H, W, C)`` of ``obs["bev"]`` this model reads: :attr:`input_shape`, or
        :data:`DEFAULT_INPUT_SHAPE` while it is unset."""
        return self.input_shape or DEFAULT_INPUT_SHAPE

    @property
    def feature_shape(self) -> tuple[int, int]:
        """``(h, w)`` of the backbone's output: each stride-2 layer maps ``s`` to
        ``(s − 1) // 2 + 1`` (64 × 64 → 8 × 8 with three layers)."""
        h, w, _ = self.bev_shape
        for _ in self.channels:
            h, w = (h - 1) // 2 + 1, (w - 1) // 2 + 1
        return h, w

    def to_dict(self) -> dict:
        """A JSON-able dict (for checkpoints; :class:`ModelConfig` ``(**d)`` reads it back)."""
        d = asdict(self)
        d["channels"] = list(d["channels"])
        if d["input_shape"] is not None:
            d["input_shape"] = list(d["input_shape"])
        return d


def lookahead_rule(cfg: ModelConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The DMP head's two look-ahead distances as ``clip(near + per_speed · v₀, lo, hi)``.

    Columns (position goal, pure-pursuit point) of :func:`minimanc.models.dmp_head`:
    ``near = (d_y, d_q)``, ``per_speed = (τ_y, t_q)``, ``lo = (4, d_q)`` and
    ``hi = (4K, min(22, 4K))`` metres (``K = cfg.k_targets``).

    Parameters
    ----------
    cfg : ModelConfig
        The head's look-ahead fields and ``k_targets``.

    Returns
    -------
    near, per_speed, lo, hi : numpy.ndarray, shape (2,), float32
    """
    K = cfg.k_targets
    near = np.array([cfg.position_lookahead, cfg.heading_lookahead], dtype=np.float32)
    per_speed = np.array([cfg.position_lookahead_time, cfg.heading_lookahead_time],
                         dtype=np.float32)
    reach = TARGET_SPACING * K
    lo = np.array([TARGET_SPACING, cfg.heading_lookahead], dtype=np.float32)
    hi = np.array([reach, min(22.0, reach)], dtype=np.float32)
    return near, per_speed, lo, hi
