"""Chapter 8 — the DMP head of MANC and DMP-only (eqs. 10–11): four gain logits, one DMP step,
``[speed, yaw rate]``.

``FC`` outputs four logits which :func:`minimanc.dmp.gains_from_logits` maps
into :data:`minimanc.dmp.ALPHA_RANGE` × :data:`minimanc.dmp.BETA_RANGE`: the
position gains ``(α_y, β_y)`` and the orientation gains ``(α_q, β_q)`` of
eq. 10 (:class:`~minimanc.models.ModelConfig` refuses a ``dt`` for which the
default integrator is unstable anywhere in that box; chapter 3). Then, all in
the current **ego frame** (+x forward, +y left), with ``v₀, ω₀`` the current
speed and yaw rate (``obs["motion"]``) and the lane target interpolated
linearly between its 4-m points (:func:`lane_point`):

* **Position DMP** (eq. 10, first row; :func:`minimanc.dmp.step`): state
  ``y₀ = (0, 0)``, ``ẏ₀ = (v₀, 0)``; goal ``g`` = the lane point
  ``L_y = clip(d_y + τ_y v₀, 4, 4K)`` metres ahead (``d_y`` =
  ``position_lookahead``, ``τ_y`` = ``position_lookahead_time``). One step of
  ``dt`` gives ``y₁``; the **speed** is the forward displacement over the
  step, ``y₁ₓ / dt`` (what the unicycle of :func:`minimanc.world.unicycle_step`
  does with a speed control). Far from the goal ``ẏ → β_y (g − y)``, so
  ``β_y τ_y ≈ 1`` keeps the speed, larger speeds up, smaller brakes; ``α_y``
  sets how quickly. The goal moves with the speed because the network never
  sees the speed; ``d_y`` lets a standing car start; a bend ahead shortens
  ``gₓ`` and slows the car by itself. The equilibrium speed of this rule,
  ``v* ≈ β_y d_y / (1 − β_y τ_y)`` for a fully relaxed step, is very
  sensitive to ``β_y`` near ``β_y τ_y = 1``: ``β_y τ_y > 1`` compounds from
  step to step, which is why :mod:`minimanc.train` trains the DMP models on
  windows in which the DMP's velocity carries over (``motion_feedback``).
* **Orientation DMP** (eq. 10, second row — the quaternion DMP of eq. 2 about
  the vertical axis): ``q₀`` = identity, ``η₀ = (0, 0, ω₀)``, goal ``g_q`` =
  the yaw ``ψ_g = clip(κ v₀ τ_q, ±π/2)`` with ``κ = 2 p_y / |p|²`` the
  curvature of the circular arc that leaves the ego tangentially and passes
  through the lane point ``p`` at ``L_q = clip(d_q + t_q v₀, d_q, 22 m)``
  (pure pursuit; ``d_q`` = ``heading_lookahead``, ``t_q`` =
  ``heading_lookahead_time``, ``τ_q`` = ``heading_horizon``): ``ψ_g`` is the
  heading after ``τ_q`` seconds on that arc. ``p`` contains the lateral
  offset, so a car left of the lane turns back towards it. Far from the goal
  ``η → β_q ψ_g``, the pure-pursuit yaw rate ``κ v₀`` when ``β_q τ_q = 1``.
  The **yaw rate** is the mean over the step, ``yaw(q₁) / dt``. For yaw-only
  motion the quaternion DMP equals the 1-D DMP on the yaw angle
  (:func:`minimanc.quaternion.quaternion_step`), which runs by default
  (``orientation="yaw"``; ``"quaternion"`` runs eq. 2 literally, same numbers).

The goal pose itself is not used (the paper's ``g, g_q`` track the moving lane target).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc import dmp, quaternion
from minimanc.engine import fused_kernel
from minimanc.models.config import TARGET_SPACING, ModelConfig, lookahead_rule
from minimanc.models.head_vjp import fused_head

__all__ = ["dmp_head", "head_ops", "lane_point", "lane_points"]


def lane_point(lane_target: Any, dist: Any, xp: Any = np,
               spacing: float = TARGET_SPACING) -> Any:
    """The lane-target point ``dist`` metres ahead, by linear interpolation.

    The weights are hat functions ``max(1 − |dist/spacing − k|, 0)``, so the
    result is differentiable in the points (and works on both engines).

    Parameters
    ----------
    lane_target : array, shape (B, K, 2)
        The points at ``spacing · (1 … K)`` m of route, ego frame.
    dist : array, shape (B,)
        Distances in ``[spacing, K · spacing]`` m.
    xp : module
        The engine's array namespace.
    spacing : float
        Metres between lane-target points.

    Returns
    -------
    array, shape (B, 2)
    """
    return lane_points(lane_target, xp.expand_dims(dist, -1), xp, spacing)[:, 0]


def lane_points(lane_target: Any, dist: Any, xp: Any = np,
                spacing: float = TARGET_SPACING) -> Any:
    """:func:`lane_point` at several distances at once: ``dist (B, J)`` → ``(B, J, 2)``.

    Parameters
    ----------
    lane_target : array, shape (B, K, 2)
        The points at ``spacing · (1 … K)`` m of route, ego frame.
    dist : array, shape (B, J)
        Distances in ``[spacing, K · spacing]`` m.
    xp : module
        The engine's array namespace.
    spacing : float
        Metres between lane-target points.

    Returns
    -------
    array, shape (B, J, 2)
        ``[b, j]`` is the lane point ``dist[b, j]`` metres ahead (hat-function weights,
        one matrix product).
    """
    K = lane_target.shape[1]
    idx = np.arange(1, K + 1, dtype=np.float32)
    w = xp.maximum(1.0 - xp.abs(xp.expand_dims(dist, -1) / spacing - idx), 0.0)  # (B, J, K)
    return w @ lane_target


def dmp_head(logits: Any, lane_target: Any, motion: Any, cfg: ModelConfig,
             xp: Any = np) -> tuple[Any, dict]:
    """Eqs. 10–11: four gain logits → one DMP step → controls (module docstring).

    :func:`head_ops`, except that with ``orientation="yaw"`` and an argument traced
    by the NumPy engine the whole head is one node of its tape
    (:data:`minimanc.models.head_vjp.fused_head`, the same arithmetic with a
    hand-written VJP).

    Parameters
    ----------
    logits : array, shape (B, 4)
        ``(z_αy, z_βy, z_αq, z_βq)``; the β logits are ignored when
        ``cfg.critically_damped``.
    lane_target : array, shape (B, K, 2)
        The moving lane target, ego frame (m); ``K = cfg.k_targets``.
    motion : array, shape (B, 2)
        The current ``[speed, yaw rate]``: the DMPs' initial velocities.
    cfg : ModelConfig
        Look-ahead rules, ``orientation`` and ``dt``.
    xp : module
        The engine's array namespace.

    Returns
    -------
    controls : array, shape (B, 2)
        ``[speed (m/s), yaw rate (rad/s)]`` over the step.
    aux : dict
        ``alpha``, ``beta`` ``(B, 2)`` = (position, orientation) gains, the
        position goal ``g`` ``(B, 2)`` and the yaw goal ``psi_g`` ``(B,)``.
    """
    if cfg.orientation == "yaw" and fused_kernel(xp, logits, lane_target, motion) is not None:
        controls, alpha, beta, g, psi_g = fused_head(xp.asarray(logits), xp.asarray(lane_target),
                                                     xp.asarray(motion), cfg)
        return controls, {"alpha": alpha, "beta": beta, "g": g, "psi_g": psi_g}
    return head_ops(logits, lane_target, motion, cfg, xp)


def head_ops(logits: Any, lane_target: Any, motion: Any, cfg: ModelConfig,
             xp: Any = np) -> tuple[Any, dict]:
    """:func:`dmp_head` operation by operation, on any engine (JAX differentiates this).

    It is also the reference the VJP of :data:`~minimanc.models.head_vjp.fused_head`
    is tested against.

    Parameters
    ----------
    logits : array, shape (B, 4)
        ``(z_αy, z_βy, z_αq, z_βq)``; the β logits are ignored when
        ``cfg.critically_damped``.
    lane_target : array, shape (B, K, 2)
        The moving lane target, ego frame (m); ``K = cfg.k_targets``.
    motion : array, shape (B, 2)
        The current ``[speed, yaw rate]``: the DMPs' initial velocities.
    cfg : ModelConfig
        Look-ahead rules, ``orientation`` and ``dt``.
    xp : module
        The engine's array namespace.

    Returns
    -------
    controls : array, shape (B, 2)
        ``[speed (m/s), yaw rate (rad/s)]`` over the step.
    aux : dict
        ``alpha``, ``beta`` ``(B, 2)`` = (position, orientation) gains, the
        position goal ``g`` ``(B, 2)`` and the yaw goal ``psi_g`` ``(B,)``.
    """
    lt = xp.asarray(lane_target)
    mot = xp.asarray(motion)
    v0, w0 = mot[:, 0:1], mot[:, 1:2]  # (B, 1) each
    crit = cfg.critically_damped
    # both DMPs' gains at once: columns (position, orientation)
    alpha, beta = dmp.gains_from_logits(logits[:, 0::2], None if crit else logits[:, 1::2],
                                        xp=xp, critically_damped=crit)
    # the look-ahead distances of the position goal (tau_y seconds ahead) and of the
    # pure-pursuit point, one (B, 2) array; both points from one interpolation
    near, per_speed, lo, hi = lookahead_rule(cfg)
    dist = xp.clip(near + per_speed * v0, lo, hi)
    points = lane_points(lt, dist, xp)  # (B, 2, 2): [goal g, pursuit point p]
    g, p = points[:, 0], points[:, 1]
    # orientation goal: the heading after tau_q seconds on the pure-pursuit arc
    kappa = 2.0 * p[:, 1:2] / xp.maximum(xp.sum(p * p, axis=-1, keepdims=True), 1e-6)
    half_pi = float(np.pi / 2)
    psi_g = xp.clip(kappa * v0 * cfg.heading_horizon, -half_pi, half_pi)  # (B, 1)
    zero = xp.zeros_like(v0)
    if cfg.orientation == "quaternion":
        y1, _, _ = dmp.step(xp.zeros_like(g), xp.concatenate([v0, zero], axis=-1), g,
                            alpha[:, 0:1], beta[:, 0:1], dt=cfg.dt, xp=xp)
        z = zero[:, 0]
        q0 = xp.stack([z + 1.0, z, z, z], axis=-1)  # identity, in v0's dtype
        eta0 = xp.stack([z, z, w0[:, 0]], axis=-1)
        g_q = quaternion.from_yaw(psi_g[:, 0], xp=xp)
        q1, _, _ = quaternion.quaternion_step(q0, eta0, g_q, alpha[:, 1:2], beta[:, 1:2],
                                              dt=cfg.dt, xp=xp)
        psi1 = xp.expand_dims(quaternion.to_yaw(q1, xp=xp), -1)
        controls = xp.concatenate([y1[:, 0:1], psi1], axis=-1) / cfg.dt
    else:
        # the quaternion DMP written on the yaw angle (exact for yaw-only motion) is a
        # 1-D DMP; the position DMP (x, y) and it are one diagonal DMP on (x, y, psi)
        # with gains (a_y, a_y, a_q), (b_y, b_y, b_q): one step of the three coordinates
        cols = [0, 0, 1]
        goal = xp.concatenate([g, psi_g], axis=-1)
        r1, _, _ = dmp.step(xp.zeros_like(goal), xp.concatenate([v0, zero, w0], axis=-1),
                            goal, alpha[:, cols], beta[:, cols], dt=cfg.dt, xp=xp)
        controls = r1[:, 0::2] / cfg.dt
    # speed = forward displacement over the step, yaw rate = mean over the step
    aux = {"alpha": alpha, "beta": beta, "g": g, "psi_g": psi_g[:, 0]}
    return controls, aux
