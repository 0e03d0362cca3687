"""Chapter 8 — what a trained controller shows: per-q-state saliency (:func:`saliency`, paper
Figs. 3–4). The open-loop trace of a logged scene is :func:`minimanc.rollout.replay`."""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc import cam, checks, vagn
from minimanc.engine import get_engine
from minimanc.layers import flatten
from minimanc.models.backbone import backbone
from minimanc.models.config import ModelConfig
from minimanc.models.forward import cast_tree
from minimanc.models.readout import logit_maps

__all__ = ["saliency"]


def saliency(params: dict, obs: dict, q_prev: Any, cfg: ModelConfig | None = None,
             engine: Any = None, upsample_to_input: bool = True) -> dict:
    """Per-q-state saliency of a vAGN model (paper Figs. 3–4), NumPy float64 arrays.

    Runs eq. 7 on ``obs["bev"]`` (with ``cfg.predicate_readout``,
    :mod:`minimanc.models.readout`) and one vAGN step (eqs. 8–9) from ``q_prev``.
    ``q_prev`` is checked as a distribution in its own precision (a float32 model's
    ``q``, say), then converted to float64 and renormalised.

    Parameters
    ----------
    params : dict
        Parameters of a vAGN model (``manc`` or ``vagn_only``).
    obs : dict
        ``bev`` ``(B, H, W, 3)``.
    q_prev : array, shape (B, N)
        The q-distribution before the step.
    cfg : ModelConfig, optional
    engine : Engine or str, optional
        Runs the backbone (default: the NumPy engine).
    upsample_to_input : bool
        Upsample the maps to the image size.

    Returns
    -------
    dict
        ``logits`` ``(B, M)`` = ``Linear(GAP(f))`` (or ``Linear(flatten(f))``);
        ``predicates`` ``(B, M)`` (through ``cfg.predicate_activation``); ``q`` ``(B, N)``;
        ``cams`` ``(B, M, H, W)`` — the class activation maps of the logits
        (:func:`minimanc.models.readout.logit_maps`; at feature resolution ``mean_xy cams_i =
        logit_i − b_i`` for "gap", ``sum_xy cams_i = logit_i − b_i`` for "flatten");
        ``jacobian`` ``(B, N, M)`` = ∂q/∂logits
        (chain rule through the sigmoid); ``saliency`` ``(B, N, H, W)`` = ``Σ_i J_ji
        cams_i`` (:func:`minimanc.cam.q_state_saliency`).

    Raises
    ------
    ValueError
        If ``params`` are not a vAGN model's, or ``q_prev`` is not a distribution.
    """
    cfg = cfg or ModelConfig()
    eng = get_engine(engine) if isinstance(engine, str) else (engine or get_engine("numpy"))
    if "vagn" not in params or "predicates" not in params:
        raise ValueError("saliency needs the parameters of a vAGN model (manc or vagn_only); "
                         f"got params with keys {sorted(params)}")
    p64 = cast_tree(params, np.float64)
    bev = np.asarray(obs["bev"], dtype=np.float64)
    f = np.asarray(cast_tree(backbone(p64["backbone"], bev, cfg, eng), np.float64))
    w, b = p64["predicates"]["w"], p64["predicates"]["b"]
    pooled = f.mean(axis=(1, 2)) if cfg.predicate_readout == "gap" else flatten(f)
    z = pooled @ w + b
    if cfg.predicate_activation == "sigmoid":
        p = 0.5 * (1.0 + np.tanh(0.5 * z))
        dp_dz = p * (1.0 - p)
    else:
        p, dp_dz = z, np.ones_like(z)
    W = p64["vagn"]["W"]
    q_in = np.asarray(getattr(q_prev, "_value", q_prev))
    checks.check_distribution("q_prev", q_in, W.shape[-1])
    q_prev = q_in.astype(np.float64)
    q_prev = q_prev / q_prev.sum(axis=-1, keepdims=True)
    q = vagn.step(q_prev, p, W)
    cams = logit_maps(f, w, cfg.predicate_readout)
    J = cam.vagn_jacobian(q_prev, p, W) * dp_dz[..., None, :]
    S = cam.q_state_saliency(cams, J)
    if upsample_to_input:
        size = tuple(bev.shape[1:3])
        cams, S = cam.upsample(cams, size), cam.upsample(S, size)
    return {"logits": z, "predicates": p, "q": q, "cams": cams, "jacobian": J, "saliency": S}
