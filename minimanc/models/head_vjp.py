"""Chapter 8 — the DMP head of eqs. 10–11 as one differentiable function with its own VJP.

:func:`minimanc.models.dmp_head.head_ops` maps four gain logits ``z``, the lane target
``L`` ``(B, K, 2)`` and the current motion ``(v₀, ω₀)`` to the controls (the module
:mod:`minimanc.models.dmp_head` states the model). With ``orientation="yaw"`` it is,
in order:

* the gains ``α = α_lo + (α_hi − α_lo) σ(z_α)``, likewise ``β`` (eq. 10's gain map;
  ``β = α/4`` when critically damped), ``σ(z) = ½ (1 + tanh(z/2))``;
* the look-ahead distances ``d = clip(near + per_speed · v₀, lo, hi)``
  (:func:`~minimanc.models.config.lookahead_rule`) and the hat weights
  ``w_jk = max(1 − |d_j / 4 − k|, 0)``, so the goal ``g`` and the pursuit point ``p``
  are the rows of ``w L``;
* the curvature ``κ = 2 p_y / max(|p|², 10⁻⁶)`` and the yaw goal
  ``ψ_g = clip(κ v₀ τ_q, ±π/2)``;
* one DMP step (eq. 10, :func:`minimanc.dmp.flow.flow_forward`) of ``(x, y, ψ)`` from
  rest at the origin with velocity ``(v₀, 0, ω₀)``, goal ``(g, ψ_g)`` and gains
  ``(α_y, α_y, α_q)``, ``(β_y, β_y, β_q)``; the controls are ``(x₁, ψ₁) / dt``.

Traced by the generic tape that is about 35 operations per control step.
:data:`fused_head` is the same arithmetic, in the same order, as **one** node
(:class:`minimanc.autodiff.custom_vjp`): the forward runs on plain NumPy arrays, the
backward is the chain rule written out, from the cotangents of the outputs back:

* the DMP step's own backward (:func:`minimanc.dmp.flow.flow_backward`) gives the
  cotangents of the goal, of the initial velocity and of the three gain columns;
* ``clip`` passes the cotangent where the value lies strictly inside its bounds, half
  of it on a bound and none outside (``clip = minimum(maximum(x, lo), hi)`` with the
  tie rule of the engine's ``maximum``, JAX's); the same rule at ``max(·, 0)`` and
  ``max(·, 10⁻⁶)``, and ``|u|′ = sign(u)``;
* ``κ = a / b`` gives ``ā = κ̄ / b``, ``b̄ = −κ̄ κ / b``; ``|p|²`` gives ``2 p``;
* ``P = w L`` gives ``w̄ = P̄ Lᵀ`` and ``L̄ = wᵀ P̄``; ``σ′ = ¼ (1 − tanh²(z/2))``.

The NumPy engine uses it (:func:`minimanc.models.dmp_head` calls it when an argument
is traced by :mod:`minimanc.autodiff`); JAX differentiates the plain code.
"""

from __future__ import annotations

import functools

import numpy as np

from minimanc import dmp
from minimanc.autodiff import custom_vjp, through_max, unbroadcast
from minimanc.dmp.flow import flow_backward, flow_forward
from minimanc.models.config import TARGET_SPACING, ModelConfig, lookahead_rule

__all__ = ["fused_head", "head_plain"]

COLS = [0, 0, 1]
"""The gain column of each DMP coordinate ``(x, y, ψ)``: position, position, orientation."""

HALF_PI = float(np.pi / 2)
"""The bound of the yaw goal (rad)."""


def head_plain(logits: np.ndarray, lane_target: np.ndarray, motion: np.ndarray,
               cfg: ModelConfig) -> tuple[np.ndarray, ...]:
    """The yaw head on plain NumPy arrays: ``(controls, alpha, beta, g, psi_g)``.

    Parameters
    ----------
    logits : array, shape (B, 4)
        ``(z_αy, z_βy, z_αq, z_βq)``.
    lane_target : array, shape (B, K, 2)
        The moving lane target, ego frame (m).
    motion : array, shape (B, 2)
        The current ``[speed, yaw rate]``.
    cfg : ModelConfig
        Look-ahead rules and ``dt`` (``orientation="yaw"``).

    Returns
    -------
    controls : array, shape (B, 2)
    alpha, beta : array, shape (B, 2)
        (position, orientation) gains.
    g : array, shape (B, 2)
        The position goal.
    psi_g : array, shape (B,)
        The yaw goal.
    """
    return _forward(np.asarray(logits), np.asarray(lane_target), np.asarray(motion), cfg)[0]


@functools.lru_cache(maxsize=64)
def _constants(cfg: ModelConfig, dtype: np.dtype, K: int) -> tuple:
    """Per head and dtype: the gain map's offsets, spans and slopes (logit order
    ``(α_y, β_y, α_q, β_q)``), the look-ahead rule, the hat weights' centres, and the map
    of the three DMP coordinates' gain cotangents back onto the four logits."""
    (a_lo, a_hi), (b_lo, b_hi) = dmp.ALPHA_RANGE, dmp.BETA_RANGE
    lo4 = np.array([a_lo, b_lo] * 2, dtype=dtype)
    span4 = np.array([a_hi - a_lo, b_hi - b_lo] * 2, dtype=dtype)
    idx = np.arange(1, K + 1, dtype=np.float32)
    # (x, y, psi) alpha cotangents -> logit columns 0, 0, 2; beta's -> 1, 1, 3
    gather = np.zeros((6, 4), dtype=dtype)
    gather[[0, 1, 2, 3, 4, 5], [0, 0, 2, 1, 1, 3]] = 1.0
    return lo4, span4, 0.25 * span4, idx, gather, lookahead_rule(cfg)


def _forward(logits, lt, mot, cfg):
    lo4, span4, _, idx, _, (near, per_speed, lo, hi) = _constants(cfg, logits.dtype,
                                                                  lt.shape[1])
    v0 = mot[:, 0:1]
    # eq. 10's gain map on the four logits at once
    t = np.tanh(0.5 * logits)
    gains = lo4 + span4 * (0.5 * (1.0 + t))
    alpha = gains[:, 0::2]
    beta = alpha / 4.0 if cfg.critically_damped else gains[:, 1::2]
    # the goal g and the pursuit point p from the hat weights
    pre = near + per_speed * v0
    dist = np.minimum(np.maximum(pre, lo), hi)
    u = np.expand_dims(dist, -1) / TARGET_SPACING - idx  # (B, 2, K)
    hat = 1.0 - np.abs(u)
    w = np.maximum(hat, 0.0)
    points = w @ lt  # (B, 2, 2): [goal g, pursuit point p]
    p = points[:, 1]
    ss = np.sum(p * p, axis=-1, keepdims=True)
    den = np.maximum(ss, 1e-6)
    kappa = 2.0 * p[:, 1:2] / den
    raw = kappa * v0 * cfg.heading_horizon
    psi_g = np.minimum(np.maximum(raw, -HALF_PI), HALF_PI)  # (B, 1)
    # one DMP step of (x, y, psi) from rest at the origin
    B = points.shape[0]
    goal = np.empty((B, 3), dtype=points.dtype)
    goal[:, 0:2] = points[:, 0]
    goal[:, 2:3] = psi_g
    vel = np.zeros((B, 3), dtype=mot.dtype)
    vel[:, 0::2] = mot
    (r1, _, _), flow_res = flow_forward(np.zeros_like(goal), vel, goal, alpha[:, COLS],
                                        beta[:, COLS], None, cfg.dt, dmp.DEFAULT_METHOD,
                                        dmp.DEFAULT_SUBSTEPS)
    controls = r1[:, 0::2] / cfg.dt
    outs = (controls, alpha, beta, points[:, 0], psi_g[:, 0])
    return outs, (t, v0, pre, u, hat, w, p, ss, den, kappa, raw, flow_res, r1.shape)


def _through_clip(g, x, lo, hi):
    """``g · ∂ clip(x, lo, hi) / ∂x`` with ``clip = minimum(maximum(x, lo), hi)``
    (:func:`~minimanc.autodiff.through_max` at each of the two)."""
    return through_max(through_max(g, hi, np.maximum(x, lo)), x, lo)


def _fwd(logits, lt, mot, cfg):
    outs, res = _forward(logits, lt, mot, cfg)
    return outs, (logits, lt, mot) + res


def _bwd(cfg: ModelConfig, res: tuple, cts: tuple) -> tuple:
    logits, lt, mot, t, v0, pre, u, hat, w, p, ss, den, kappa, raw, flow_res, shape = res
    _, _, slope4, _, gather, (_, per_speed, lo, hi) = _constants(cfg, logits.dtype,
                                                                 lt.shape[1])
    g_controls, g_alpha, g_beta, g_g, g_psi = cts
    # the DMP step: controls = (x1, psi1) / dt
    g_r1 = np.zeros(shape, dtype=g_controls.dtype)
    g_r1[:, 0::2] = g_controls / cfg.dt
    zeros = np.zeros_like(g_r1)
    _, g_vel, g_goal, g_a3, g_b3, _ = flow_backward(cfg.dt, dmp.DEFAULT_METHOD,
                                                     dmp.DEFAULT_SUBSTEPS, flow_res,
                                                     (g_r1, zeros, zeros))
    # the yaw goal psi_g = clip(kappa v0 tau_q, ±pi/2), kappa = 2 p_y / max(|p|², 1e-6)
    g_kv = _through_clip(g_goal[:, 2:3] + g_psi[:, None], raw, -HALF_PI, HALF_PI) \
        * cfg.heading_horizon
    g_kappa = g_kv * v0
    g_den = -g_kappa * kappa / den
    g_points = np.empty((p.shape[0], 2, 2), dtype=g_goal.dtype)
    g_points[:, 0] = g_goal[:, 0:2] + g_g
    g_points[:, 1] = 2.0 * p * through_max(g_den, ss, 1e-6)
    g_points[:, 1, 1:2] += 2.0 * (g_kappa / den)
    # both points from the hat weights: points = w @ lt
    g_lt = np.swapaxes(w, -1, -2) @ g_points
    g_u = np.sign(u) * through_max(g_points @ np.swapaxes(lt, -1, -2), hat, 0.0)
    g_pre = _through_clip(g_u.sum(axis=-1) / -TARGET_SPACING, pre, lo, hi)
    g_mot = g_vel[:, 0::2].copy()
    g_mot[:, 0:1] += g_kv * kappa + (g_pre * per_speed).sum(axis=-1, keepdims=True)
    # the gains: the three coordinates' cotangents onto the logits' columns, then eq. 10's map
    g_gains = np.concatenate([g_a3, g_b3], axis=-1) @ gather  # (B, 4), logit order
    g_gains[:, 0::2] += g_alpha
    if cfg.critically_damped:  # beta = alpha / 4: the beta logits get nothing
        g_gains[:, 0::2] += (g_gains[:, 1::2] + g_beta) / 4.0
        g_gains[:, 1::2] = 0.0
    else:
        g_gains[:, 1::2] += g_beta
    g_logits = g_gains * (slope4 * (1.0 - t * t))
    return (unbroadcast(logits, g_logits), unbroadcast(lt, g_lt), unbroadcast(mot, g_mot))


fused_head = custom_vjp(head_plain, nondiff_argnums=(3,))
"""``fused_head(logits, lane_target, motion, cfg)``: :func:`head_plain` as one node of the
NumPy engine's tape, with the VJP of the module docstring (shapes as there)."""
fused_head.defvjp(_fwd, _bwd)
