"""Chapter 8 — the six controllers of the paper (section V: comparison cases and self-ablation),
one :class:`~minimanc.models.registry.ModelSpec` each.

``f`` = backbone features, ``n`` = the numbers the model sees
(:func:`minimanc.inputs.numeric_features`), ``s`` = :data:`CONTROL_SCALE`:

============= =================================================================
name          forward pass
============= =================================================================
``cnn``       flatten(f) ⊕ n → FC(64) → FC(2) · s                 (Farag 2018)
``cnn_lstm``  flatten(f) ⊕ n → FC(64) → LSTM(64) → FC(2) · s
``rvs_g``     flatten(f(bev)) ⊕ flatten(f(goal_bev)) ⊕ n → LSTM(64) → FC(2) · s
``manc``      p = σ(Linear(GAP(f))) (eq. 7) → q = vAGN(p, q') (eqs. 8–9) →
              gains = FC(q) → one DMP step (eqs. 10–11) → [speed, yaw rate]
``vagn_only`` p (eq. 7) → q = vAGN(p, q') → FC(64) on q ⊕ n → FC(2) · s
``dmp_only``  p (eq. 7) → gains = FC(p) → one DMP step → [speed, yaw rate]
============= =================================================================

(The authors' RvS has a Gaussian action head; ours predicts the mean only and
is trained with the same MSE as all others.)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc import layers, vagn
from minimanc.layers import dense, flatten
from minimanc.models.backbone import activate, backbone
from minimanc.models.config import CONTROL_SCALE, DEFAULT_GAINS, ModelConfig, gain_logits
from minimanc.models.dmp_head import dmp_head
from minimanc.models.registry import (
    ModelSpec,
    observes_goal,
    observes_structured,
    register_model,
)

__all__ = ["BUILTIN", "control_scale", "flat_size", "gains_layer", "predicate_layer"]


def flat_size(cfg: ModelConfig) -> int:
    """Length of the flattened backbone features.

    Parameters
    ----------
    cfg : ModelConfig

    Returns
    -------
    int
        ``feature_size² · channels[-1]``.
    """
    return cfg.feature_size ** 2 * cfg.channels[-1]


def control_scale(eng: Any) -> Any:
    """The direct heads' output scale.

    Parameters
    ----------
    eng : Engine

    Returns
    -------
    array, shape (2,)
        :data:`CONTROL_SCALE`, float32 (it never promotes a float32 output).
    """
    return eng.xp.asarray(np.asarray(CONTROL_SCALE, dtype=np.float32))


def predicate_layer(rng: np.random.Generator, cfg: ModelConfig) -> dict:
    """Eq. 7's predicate layer ``Linear(GAP(f))``: ``w`` ``(C, M)``, ``b`` ``(M,)``."""
    return layers.init_dense(rng, cfg.channels[-1], cfg.n_predicates)


def gains_layer(rng: np.random.Generator, n_in: int, cfg: ModelConfig) -> dict:
    """The gains FC of eq. 11.

    Parameters
    ----------
    rng : numpy.random.Generator
    n_in : int
        Its inputs: ``N`` (MANC, from q) or ``M`` (DMP-only, from the predicates).
    cfg : ModelConfig
        Its ``gains_scale`` multiplies the Glorot weights.

    Returns
    -------
    dict
        ``w`` ``(n_in, 4)``, ``b`` ``(4,)`` = :func:`gain_logits` of :data:`DEFAULT_GAINS`.
    """
    gains = layers.init_dense(rng, n_in, 4)
    gains["w"] = cfg.gains_scale * np.asarray(gains["w"])
    gains["b"] = gain_logits(DEFAULT_GAINS)
    return gains


def _with_num(parts: list, num: Any, xp: Any) -> Any:
    return parts[0] if num is None and len(parts) == 1 else \
        xp.concatenate(parts + ([] if num is None else [num]), axis=-1)


def _direct(params: dict, h: Any, eng: Any) -> Any:
    return dense(params["out"], h, eng.xp) * control_scale(eng)


def _dmp(logits: Any, enc: dict, cfg: ModelConfig, eng: Any) -> tuple[Any, dict]:
    return dmp_head(logits, enc["lane_target"], enc["motion"], cfg, xp=eng.xp)


def _dmp_inputs(obs: dict, eng: Any) -> dict:
    return {"lane_target": eng.xp.asarray(obs["lane_target"]),
            "motion": eng.xp.asarray(obs["motion"])}


def _vagn_step(params: dict, enc: dict, state: dict, eng: Any) -> Any:
    return vagn.step(state["q"], enc["predicates"], params["vagn"]["W"], xp=eng.xp)


def _lstm(params: dict, enc: dict, state: dict, eng: Any) -> tuple[Any, dict, dict]:
    h, c = layers.lstm_cell(params["lstm"], (state["h"], state["c"]), enc["pre"], xp=eng.xp,
                            nn=eng.nn)
    return _direct(params, h, eng), {"h": h, "c": c}, {}


# --------------------------------------------------------------------------- cnn


def _cnn_init(rng: np.random.Generator, cfg: ModelConfig, n_num: int) -> dict:
    return {"fc1": layers.init_dense(rng, flat_size(cfg) + n_num, cfg.hidden),
            "out": layers.init_dense(rng, cfg.hidden, 2)}


def _cnn_encode(params: dict, obs: dict, f: Any, num: Any, cfg: ModelConfig, eng: Any) -> dict:
    return {"pre": _with_num([flatten(f, eng.xp)], num, eng.xp)}


def _cnn_head(params: dict, enc: dict, state: dict, cfg: ModelConfig, eng: Any) -> tuple:
    h = activate(dense(params["fc1"], enc["pre"], eng.xp), cfg, eng)
    return _direct(params, h, eng), dict(state), {}


# --------------------------------------------------------------------------- cnn_lstm


def _cnn_lstm_init(rng: np.random.Generator, cfg: ModelConfig, n_num: int) -> dict:
    H = cfg.hidden
    return {"fc1": layers.init_dense(rng, flat_size(cfg) + n_num, H),
            "lstm": layers.init_lstm(rng, H, H),
            "out": layers.init_dense(rng, H, 2)}


def _cnn_lstm_encode(params: dict, obs: dict, f: Any, num: Any, cfg: ModelConfig,
                     eng: Any) -> dict:
    x = _with_num([flatten(f, eng.xp)], num, eng.xp)
    return {"pre": activate(dense(params["fc1"], x, eng.xp), cfg, eng)}


def _lstm_head(params: dict, enc: dict, state: dict, cfg: ModelConfig, eng: Any) -> tuple:
    return _lstm(params, enc, state, eng)


# --------------------------------------------------------------------------- rvs_g


def _rvs_g_init(rng: np.random.Generator, cfg: ModelConfig, n_num: int) -> dict:
    return {"lstm": layers.init_lstm(rng, 2 * flat_size(cfg) + n_num, cfg.hidden),
            "out": layers.init_dense(rng, cfg.hidden, 2)}


def _rvs_g_encode(params: dict, obs: dict, f: Any, num: Any, cfg: ModelConfig,
                  eng: Any) -> dict:
    fg = flatten(backbone(params["backbone"], obs["goal_bev"], cfg, eng), eng.xp)
    reps = f.shape[0] // fg.shape[0]  # sequence(): one goal raster per window, for its L steps
    if reps > 1:
        fg = eng.xp.concatenate([fg] * reps, axis=0)
    return {"pre": _with_num([flatten(f, eng.xp), fg], num, eng.xp)}


# --------------------------------------------------------------------------- manc


def _manc_init(rng: np.random.Generator, cfg: ModelConfig, n_num: int) -> dict:
    M, N = cfg.n_predicates, cfg.n_states
    return {"predicates": predicate_layer(rng, cfg),
            "vagn": {"W": vagn.init_vagn(rng, M, N, scale=cfg.vagn_scale)},
            "gains": gains_layer(rng, N, cfg)}


def _dmp_encode(params: dict, obs: dict, f: Any, num: Any, cfg: ModelConfig, eng: Any) -> dict:
    return _dmp_inputs(obs, eng)


def _manc_head(params: dict, enc: dict, state: dict, cfg: ModelConfig, eng: Any) -> tuple:
    q = _vagn_step(params, enc, state, eng)
    logits = dense(params["gains"], q, eng.xp)  # FC(q) of eq. 11
    controls, aux = _dmp(logits, enc, cfg, eng)
    return controls, {"q": q}, {"q": q, **aux}


# --------------------------------------------------------------------------- vagn_only


def _vagn_only_init(rng: np.random.Generator, cfg: ModelConfig, n_num: int) -> dict:
    M, N, H = cfg.n_predicates, cfg.n_states, cfg.hidden
    return {"predicates": predicate_layer(rng, cfg),
            "vagn": {"W": vagn.init_vagn(rng, M, N, scale=cfg.vagn_scale)},
            "fc1": layers.init_dense(rng, N + n_num, H),
            "out": layers.init_dense(rng, H, 2)}


def _vagn_only_encode(params: dict, obs: dict, f: Any, num: Any, cfg: ModelConfig,
                      eng: Any) -> dict:
    return {"num": num}


def _vagn_only_head(params: dict, enc: dict, state: dict, cfg: ModelConfig, eng: Any) -> tuple:
    q = _vagn_step(params, enc, state, eng)
    x = _with_num([q], enc["num"], eng.xp)
    h = activate(dense(params["fc1"], x, eng.xp), cfg, eng)
    return _direct(params, h, eng), {"q": q}, {"q": q}


# --------------------------------------------------------------------------- dmp_only


def _dmp_only_init(rng: np.random.Generator, cfg: ModelConfig, n_num: int) -> dict:
    M = cfg.n_predicates
    return {"predicates": predicate_layer(rng, cfg),
            "gains": gains_layer(rng, M, cfg)}


def _dmp_only_head(params: dict, enc: dict, state: dict, cfg: ModelConfig, eng: Any) -> tuple:
    logits = dense(params["gains"], enc["predicates"], eng.xp)
    controls, aux = _dmp(logits, enc, cfg, eng)
    return controls, dict(state), aux


BUILTIN: tuple[ModelSpec, ...] = (
    ModelSpec("cnn", "CNN", "feedforward", observes_goal(), _cnn_init, _cnn_encode, _cnn_head,
              colour="#1f77b4"),
    ModelSpec("cnn_lstm", "CNN-LSTM", "lstm", observes_goal(), _cnn_lstm_init,
              _cnn_lstm_encode, _lstm_head, window="seq_len", colour="#ff7f0e"),
    ModelSpec("rvs_g", "RvS-G", "lstm", observes_goal(("goal_bev",)), _rvs_g_init,
              _rvs_g_encode, _lstm_head, window="seq_len", colour="#9467bd"),
    ModelSpec("manc", "MANC", "vagn", observes_structured(), _manc_init, _dmp_encode,
              _manc_head, window="dmp_seq_len", dmp=True, colour="#d62728"),
    ModelSpec("vagn_only", "vAGN-only", "vagn", observes_goal(), _vagn_only_init,
              _vagn_only_encode, _vagn_only_head, window="q_seq_len", colour="#2ca02c"),
    ModelSpec("dmp_only", "DMP-only", "feedforward", observes_structured(), _dmp_only_init,
              _dmp_encode, _dmp_only_head, window="dmp_seq_len", dmp=True, colour="#8c564b"),
)
"""The six controllers, registered in this order when :mod:`minimanc.models` is imported."""

for _spec in BUILTIN:
    register_model(_spec, replace=True)
del _spec
