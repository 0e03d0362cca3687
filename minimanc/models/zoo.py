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

What eq. 7's linear layer reads is :attr:`ModelConfig.predicate_readout`: ``GAP(f)`` as the
paper writes it ("gap", the default), or ``flatten(f)``, which keeps where a feature fires
("flatten", :mod:`minimanc.models.readout`).

MANC's pieces are public, each one equation, so that a variant is a new
:class:`~minimanc.models.ModelSpec` of a few lines (the contract of ``init``, ``encode`` and
``head`` is the spec's docstring):

* parameters: :func:`predicate_layer` (eq. 7), :func:`vagn_layer` (eqs. 8–9),
  :func:`gains_layer` (the FC of eq. 11);
* per frame: :func:`dmp_encode` (the lane target and the motion the DMP head reads);
* per step: :func:`vagn_step` (q from q' and the predicates), :func:`gains_fc` (the gains'
  four logits), :func:`dmp_step` (one DMP step, eqs. 10–11 → ``[speed, yaw rate]``);
* MANC itself: :func:`manc_init` and :func:`manc_head`, made of the above.

For example MANC whose gains read q and the predicates, ``FC(q ⊕ p)``::

    from minimanc import models
    from minimanc.models import zoo

    def init(rng, cfg, n_num):
        return {"predicates": zoo.predicate_layer(rng, cfg), "vagn": zoo.vagn_layer(rng, cfg),
                "gains": zoo.gains_layer(rng, cfg.n_states + cfg.n_predicates, cfg)}

    def head(params, enc, state, cfg, eng):
        q = zoo.vagn_step(params, enc, state, eng)
        x = eng.xp.concatenate([q, enc["predicates"]], axis=-1)
        controls, aux = zoo.dmp_step(zoo.gains_fc(params, x, eng), enc, cfg, eng)
        return controls, {"q": q}, {"q": q, **aux}

    models.register_model(models.ModelSpec(
        "manc_qp", "MANC FC(q ⊕ p)", "vagn", models.registry.observes_structured(),
        init, zoo.dmp_encode, head, window="dmp_seq_len", dmp=True))
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

__all__ = ["BUILTIN", "control_scale", "dmp_encode", "dmp_step", "flat_size", "gains_fc",
           "gains_layer", "manc_head", "manc_init", "predicate_layer", "vagn_layer", "vagn_step"]


def flat_size(cfg: ModelConfig) -> int:
    """Length of the flattened backbone features.

    Parameters
    ----------
    cfg : ModelConfig

    Returns
    -------
    int
        ``h · w · channels[-1]``, ``(h, w) = cfg.feature_shape``.
    """
    h, w = cfg.feature_shape
    return h * w * cfg.channels[-1]


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
    """Eq. 7's predicate layer ``Linear(readout(f))``, as ``params["predicates"]``.

    A model whose parameters hold ``"predicates"`` gets ``enc["predicates"]`` ``(B, M)``
    from the shared encoder (:func:`minimanc.models.forward.encode`; the read-out of
    ``cfg.predicate_readout``, :mod:`minimanc.models.readout`, then
    ``cfg.predicate_activation``). "gap" reads ``GAP(f)`` (eq. 7 as the paper writes it);
    "flatten" reads ``flatten(f)`` and starts as exactly the same function: the same draw,
    each position's weights ``w / (h·w)``, so that the two read-outs differ only in what
    training makes of them (and the later layers get the same draws).

    Parameters
    ----------
    rng : numpy.random.Generator
    cfg : ModelConfig
        Its ``channels[-1]`` (C), ``n_predicates`` (M), ``predicate_readout`` and, for
        "flatten", ``feature_shape`` (h, w).

    Returns
    -------
    dict
        ``w`` ``(C, M)`` ("gap") or ``(h·w·C, M)`` ("flatten", :func:`flat_size` rows),
        ``b`` ``(M,)``.
    """
    layer = layers.init_dense(rng, cfg.channels[-1], cfg.n_predicates)
    if cfg.predicate_readout == "flatten":
        h, w = cfg.feature_shape
        layer["w"] = np.tile(np.asarray(layer["w"]), (h * w, 1)) / (h * w)
    return layer


def vagn_layer(rng: np.random.Generator, cfg: ModelConfig) -> dict:
    """The vAGN's weights ``W^p`` (eqs. 8–9), as ``params["vagn"]``.

    Parameters
    ----------
    rng : numpy.random.Generator
    cfg : ModelConfig
        Its ``n_predicates`` (M), ``n_states`` (N) and ``vagn_scale`` (the weights'
        standard deviation, :func:`minimanc.vagn.init_vagn`).

    Returns
    -------
    dict
        ``{"W": (M, N, N)}``.
    """
    return {"W": vagn.init_vagn(rng, cfg.n_predicates, cfg.n_states, scale=cfg.vagn_scale)}


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


def dmp_encode(params: dict, obs: dict, f: Any, num: Any, cfg: ModelConfig, eng: Any) -> dict:
    """The ``encode`` of the DMP models: what the DMP head reads of each frame.

    Parameters
    ----------
    params, f, num, cfg
        As every ``encode`` (:class:`~minimanc.models.ModelSpec`); unused.
    obs : dict
        ``lane_target`` ``(B, K, 2)`` and ``motion`` ``(B, 2)``.
    eng : Engine

    Returns
    -------
    dict
        ``{"lane_target", "motion"}`` as arrays of the engine (the head's inputs; in training
        windows ``motion`` is fed back from the previous step, ``motion_feedback``).
    """
    return {"lane_target": eng.xp.asarray(obs["lane_target"]),
            "motion": eng.xp.asarray(obs["motion"])}


def vagn_step(params: dict, enc: dict, state: dict, eng: Any) -> Any:
    """One step of the automaton (eqs. 8–9): q from the previous q' and the predicates.

    Parameters
    ----------
    params : dict
        With ``"vagn"`` (:func:`vagn_layer`).
    enc : dict
        With ``"predicates"`` ``(B, M)`` (the model has a :func:`predicate_layer`).
    state : dict
        ``{"q": (B, N)}``, q' (the vAGN family's state).
    eng : Engine

    Returns
    -------
    array, shape (B, N)
        q, a distribution per row (:func:`minimanc.vagn.step`).
    """
    return vagn.step(state["q"], enc["predicates"], params["vagn"]["W"], xp=eng.xp)


def gains_fc(params: dict, x: Any, eng: Any) -> Any:
    """The gains FC of eq. 11 on its input ``x`` (q for MANC, p for DMP-only).

    Parameters
    ----------
    params : dict
        With ``"gains"`` (:func:`gains_layer` of ``x``'s width).
    x : array, shape (B, n_in)
    eng : Engine

    Returns
    -------
    array, shape (B, 4)
        The logits of ``(α_y, β_y, α_q, β_q)`` (:func:`dmp_step` maps them into the gain box).
    """
    return dense(params["gains"], x, eng.xp)


def dmp_step(logits: Any, enc: dict, cfg: ModelConfig, eng: Any) -> tuple[Any, dict]:
    """One DMP step of the head of eqs. 10–11 at the gains ``logits``, towards the lane target.

    Parameters
    ----------
    logits : array, shape (B, 4)
        From :func:`gains_fc`.
    enc : dict
        With ``lane_target`` ``(B, K, 2)`` and ``motion`` ``(B, 2)`` (:func:`dmp_encode`).
    cfg : ModelConfig
        The look-ahead rules and ``dt`` (:func:`minimanc.models.dmp_head`).
    eng : Engine

    Returns
    -------
    controls : array, shape (B, 2)
        ``[speed, yaw rate]``.
    aux : dict
        ``alpha`` and ``beta`` ``(B, 2)``: the (position, orientation) gains.
    """
    return dmp_head(logits, enc["lane_target"], enc["motion"], cfg, xp=eng.xp)


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


def manc_init(rng: np.random.Generator, cfg: ModelConfig, n_num: int) -> dict:
    """MANC's ``init``: eq. 7's :func:`predicate_layer`, the :func:`vagn_layer` and the
    :func:`gains_layer` of eq. 11 on q (or on q ⊕ p: :attr:`ModelConfig.gains_input`).

    Parameters
    ----------
    rng : numpy.random.Generator
    cfg : ModelConfig
    n_num : int
        Unused (MANC sees no numbers besides the DMP's inputs).

    Returns
    -------
    dict
        ``{"predicates", "vagn", "gains"}``.
    """
    width = cfg.n_states + (cfg.n_predicates if cfg.gains_input == "q_p" else 0)
    return {"predicates": predicate_layer(rng, cfg),
            "vagn": vagn_layer(rng, cfg),
            "gains": gains_layer(rng, width, cfg)}


def manc_head(params: dict, enc: dict, state: dict, cfg: ModelConfig, eng: Any) -> tuple:
    """MANC's ``head``: q = vAGN(p, q') (:func:`vagn_step`), gains = FC(q) (:func:`gains_fc`;
    FC(q ⊕ p) with ``cfg.gains_input`` "q_p"), one DMP step (:func:`dmp_step`) →
    ``[speed, yaw rate]``.

    Parameters
    ----------
    params : dict
        From :func:`manc_init`.
    enc : dict
        ``predicates``, ``lane_target``, ``motion`` (:func:`dmp_encode`).
    state : dict
        ``{"q": (B, N)}``.
    cfg : ModelConfig
    eng : Engine

    Returns
    -------
    controls : array, shape (B, 2)
    new_state : dict
        ``{"q": (B, N)}``.
    aux : dict
        ``q``, ``alpha``, ``beta``.
    """
    q = vagn_step(params, enc, state, eng)
    x = eng.xp.concatenate([q, enc["predicates"]], axis=-1) if cfg.gains_input == "q_p" else q
    controls, aux = dmp_step(gains_fc(params, x, eng), enc, cfg, eng)  # FC(q) of eq. 11
    return controls, {"q": q}, {"q": q, **aux}


# --------------------------------------------------------------------------- vagn_only


def _vagn_only_init(rng: np.random.Generator, cfg: ModelConfig, n_num: int) -> dict:
    N, H = cfg.n_states, cfg.hidden
    return {"predicates": predicate_layer(rng, cfg),
            "vagn": vagn_layer(rng, cfg),
            "fc1": layers.init_dense(rng, N + n_num, H),
            "out": layers.init_dense(rng, H, 2)}


def _vagn_only_encode(params: dict, obs: dict, f: Any, num: Any, cfg: ModelConfig,
                      eng: Any) -> dict:
    return {"num": num}


def _vagn_only_head(params: dict, enc: dict, state: dict, cfg: ModelConfig, eng: Any) -> tuple:
    q = vagn_step(params, enc, state, eng)
    x = _with_num([q], enc["num"], eng.xp)
    h = activate(dense(params["fc1"], x, eng.xp), cfg, eng)
    return _direct(params, h, eng), {"q": q}, {"q": q}


# --------------------------------------------------------------------------- dmp_only


def _dmp_only_init(rng: np.random.Generator, cfg: ModelConfig, n_num: int) -> dict:
    M = cfg.n_predicates
    return {"predicates": predicate_layer(rng, cfg),
            "gains": gains_layer(rng, M, cfg)}


def _dmp_only_head(params: dict, enc: dict, state: dict, cfg: ModelConfig, eng: Any) -> tuple:
    controls, aux = dmp_step(gains_fc(params, enc["predicates"], eng), enc, cfg, eng)
    return controls, dict(state), aux


BUILTIN: tuple[ModelSpec, ...] = (
    ModelSpec("cnn", "CNN", "feedforward", observes_goal(), _cnn_init, _cnn_encode, _cnn_head,
              colour="#1f77b4"),
    ModelSpec("cnn_lstm", "CNN-LSTM", "lstm", observes_goal(), _cnn_lstm_init,
              _cnn_lstm_encode, _lstm_head, window="seq_len", colour="#ff7f0e"),
    ModelSpec("rvs_g", "RvS-G", "lstm", observes_goal(("goal_bev",)), _rvs_g_init,
              _rvs_g_encode, _lstm_head, window="seq_len", colour="#9467bd"),
    ModelSpec("manc", "MANC", "vagn", observes_structured(), manc_init, dmp_encode,
              manc_head, window="dmp_seq_len", dmp=True, colour="#d62728"),
    ModelSpec("vagn_only", "vAGN-only", "vagn", observes_goal(), _vagn_only_init,
              _vagn_only_encode, _vagn_only_head, window="q_seq_len", colour="#2ca02c"),
    ModelSpec("dmp_only", "DMP-only", "feedforward", observes_structured(), _dmp_only_init,
              dmp_encode, _dmp_only_head, window="dmp_seq_len", dmp=True, colour="#8c564b"),
)
"""The six controllers, registered in this order when :mod:`minimanc.models` is imported."""

for _spec in BUILTIN:
    register_model(_spec, replace=True)
del _spec
