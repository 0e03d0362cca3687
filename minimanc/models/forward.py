"""Chapter 8 — any registered controller as a pure function ``(params, inputs)``: its parameters
(:func:`init`), its recurrent state (:func:`initial_state`), one control step (:func:`step`) and
a sequence of steps with one time loop (:func:`sequence`).

Each model is a :class:`~minimanc.models.registry.ModelSpec`; this module runs the part they
share — the backbone on ``obs["bev"]``, eq. 7's predicates ``σ(Linear(GAP(f)))`` when the model
has them (or ``σ(Linear(flatten(f)))``, :attr:`ModelConfig.predicate_readout`), the numeric
inputs of :func:`minimanc.inputs.numeric_features` — and calls the spec's ``encode`` and
``head``. Every function takes an engine ``eng`` and uses only ``eng.xp`` /
``eng.nn`` / ``eng.scan``, so the same code runs on both engines.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc import inputs, layers, vagn
from minimanc.checks import check_int, check_rng
from minimanc.models import registry
from minimanc.models.backbone import backbone
from minimanc.models.config import ModelConfig
from minimanc.models.readout import predicate_logits
from minimanc.models.registry import ModelSpec, get
from minimanc.tree import leaves as tree_leaves
from minimanc.tree import map as tree_map

__all__ = [
    "cast_tree",
    "check_input_shape",
    "check_obs",
    "check_per_scene",
    "encode",
    "init",
    "initial_state",
    "param_count",
    "param_counts",
    "run_head",
    "sequence",
    "step",
]


def cast_tree(tree: Any, dtype: Any) -> Any:
    """A pytree with NumPy leaves of one dtype.

    Parameters
    ----------
    tree : pytree
        Dicts, lists and tuples of arrays (engine arrays are read through their value).
    dtype : dtype

    Returns
    -------
    pytree
        The same structure, every leaf ``numpy.asarray(leaf, dtype)``.
    """
    return tree_map(lambda x: np.asarray(getattr(x, "_value", x), dtype=dtype), tree)


def init(name: str, rng: np.random.Generator, cfg: ModelConfig | None = None,
         dtype: Any = np.float64) -> dict:
    """Initial parameters of model ``name``.

    Parameters
    ----------
    name : str
        A registered model (:func:`minimanc.models.names`).
    rng : numpy.random.Generator
        Draws the backbone's convolutions first, then the spec's own layers.
    cfg : ModelConfig, optional
        Defaults to ``ModelConfig()``; the first convolution reads ``cfg.bev_shape[2]``
        planes.
    dtype : dtype
        Of every leaf.

    Returns
    -------
    dict
        A pytree of NumPy arrays: ``"backbone": {"convs": [...]}`` and the spec's layers.

    Raises
    ------
    ValueError
        If ``name`` is not registered or ``rng`` is not a Generator.
    """
    spec = get(name)
    cfg = cfg or ModelConfig()
    check_rng("rng", rng)
    convs, c_in = [], cfg.bev_shape[2]
    for c in cfg.channels:
        convs.append(layers.init_conv(rng, 3, 3, c_in, c))
        c_in = c
    params: dict = {"backbone": {"convs": convs}}
    params.update(spec.init(rng, cfg, inputs.numeric_size(spec, cfg.setting, cfg.k_targets)))
    return cast_tree(params, dtype)


def param_count(params: dict) -> int:
    """Number of scalar parameters.

    Parameters
    ----------
    params : pytree

    Returns
    -------
    int
    """
    return int(sum(int(np.prod(np.shape(x))) for x in tree_leaves(params)))


def param_counts(cfg: ModelConfig | None = None, names: tuple[str, ...] | None = None) -> dict:
    """Parameter counts of several models under one configuration.

    Parameters
    ----------
    cfg : ModelConfig, optional
    names : tuple of str, optional
        Default: every registered model.

    Returns
    -------
    dict
        ``{name: param_count(init(name, ...))}``.
    """
    cfg = cfg or ModelConfig()
    chosen = registry.names() if names is None else tuple(names)
    return {n: param_count(init(n, np.random.default_rng(0), cfg)) for n in chosen}


def initial_state(name: str, batch: int, cfg: ModelConfig | None = None, xp: Any = np,
                  rng: np.random.Generator | None = None, mode: str = "uniform",
                  dtype: Any = np.float32) -> dict:
    """The recurrent state at the start of a sequence, for ``batch`` rows.

    Parameters
    ----------
    name : str
        A registered model; its ``family`` decides the state.
    batch : int
        Rows ``B``.
    cfg : ModelConfig, optional
    xp : module
        Namespace of the returned arrays.
    rng : numpy.random.Generator, optional
        Needed by ``mode="random"``.
    mode : str
        "uniform" (Algorithm 1's ``UniformInit``) or "random" (``RandomInit``: flat
        Dirichlet draws); vAGN models only.
    dtype : dtype

    Returns
    -------
    dict
        vAGN family: ``{"q": (B, N)}``; LSTM family: ``{"h", "c"}`` zeros ``(B, hidden)``;
        feed-forward: ``{}``.

    Raises
    ------
    ValueError
        For an unknown model, a bad ``batch`` or ``mode``, or ``mode="random"`` without
        ``rng``.
    """
    spec = get(name)
    cfg = cfg or ModelConfig()
    batch = check_int("batch", batch, 1)
    if mode not in ("uniform", "random"):
        raise ValueError(f"mode must be 'uniform' or 'random', got mode={mode!r}")
    if spec.family == "vagn":
        if mode == "random":
            if not isinstance(rng, np.random.Generator):
                raise ValueError(f"mode='random' needs rng=numpy.random.Generator, got rng={rng!r}")
            q = vagn.random_state(rng, cfg.n_states, size=batch)
        else:
            q = np.broadcast_to(vagn.uniform_state(cfg.n_states), (batch, cfg.n_states))
        return {"q": xp.asarray(np.asarray(q, dtype=dtype))}
    if spec.family == "lstm":
        z = np.zeros((batch, cfg.hidden), dtype=dtype)
        return {"h": xp.asarray(z), "c": xp.asarray(z)}
    return {}


def check_input_shape(cfg: ModelConfig, shape: Sequence[int], label: str) -> None:
    """Check that data whose BEV planes are ``shape`` fit a model built for ``cfg``.

    Parameters
    ----------
    cfg : ModelConfig
        Its :attr:`~ModelConfig.bev_shape`.
    shape : sequence of int
        ``(H, W, C)`` of the data's planes (its raster's ``input_shape``).
    label : str
        The data's argument, for the message.

    Raises
    ------
    ValueError
        If they differ: one line naming both shapes and the two ways to agree.
    """
    if tuple(shape) != cfg.bev_shape:
        raise ValueError(
            f"{label}'s BEV planes {tuple(shape)} (its raster's input_shape) do not match the "
            f"model's {cfg.bev_shape} (cfg.input_shape={cfg.input_shape}): use data drawn with "
            f"the raster the model was built for, or a models.ModelConfig without input_shape "
            f"(train.fit takes the data's)")


def check_obs(name: str, obs: dict, cfg: ModelConfig, lead: int) -> None:
    """Check the keys and shapes of an observation.

    Parameters
    ----------
    name : str
        A registered model (its keys in ``cfg.setting`` must be present).
    obs : dict
    cfg : ModelConfig
    lead : int
        Leading axes before the image axes: 1 for ``(B, ...)``, 2 for ``(L, B, ...)``.

    Raises
    ------
    ValueError
        For a missing key, a BEV not ``(..., *cfg.bev_shape)`` or a lane target not ending
        in ``(k_targets, 2)``.
    """
    keys = inputs.visible(get(name), cfg.setting)
    missing = [k for k in keys if k not in obs]
    if missing:
        raise ValueError(f"obs lacks {missing} needed by model {name!r} in setting "
                         f"{cfg.setting!r}; got keys {sorted(obs)}")
    shape = tuple(obs["bev"].shape)
    if len(shape) != lead + 3:
        raise ValueError(f"obs['bev'] must have shape {('B',) * lead + cfg.bev_shape}, got "
                         f"{shape}")
    check_input_shape(cfg, shape[lead:], "obs['bev']")
    if "lane_target" in keys:
        lt = tuple(obs["lane_target"].shape)
        if lt[lead:] != (cfg.k_targets, 2):
            raise ValueError(f"obs['lane_target'] must end in ({cfg.k_targets}, 2) "
                             f"(k_targets={cfg.k_targets}), got {lt}")


def check_per_scene(obs_seq: dict, seen: Sequence[str]) -> list[str]:
    """The keys of :data:`minimanc.inputs.SCENE_CONSTANT_KEYS` among ``seen`` in the time-major
    ``obs_seq``; ValueError if one of them, given as a NumPy array, differs between steps
    (a traced array is not inspected: the training batches repeat one scene's raster)."""
    keys = [k for k in inputs.SCENE_CONSTANT_KEYS if k in seen and k in obs_seq]
    for k in keys:
        v = obs_seq[k]
        if isinstance(v, np.ndarray) and not (v == v[:1]).all():
            raise ValueError(f"obs_seq[{k!r}] must be the same at every step of a window (it "
                             f"is a scene's, not a step's); got one that changes over time")
    return keys


def encode(spec: ModelSpec, params: dict, obs: dict, cfg: ModelConfig, eng: Any) -> dict:
    """The per-frame part of a model (no recurrence).

    Parameters
    ----------
    spec : ModelSpec
    params : dict
    obs : dict
        Observations ``(B, ...)``; cast to the parameters' dtype.
    cfg : ModelConfig
    eng : Engine

    Returns
    -------
    dict
        ``features`` ``(B, h, w, C)``, ``predicates`` ``(B, M)`` (eq. 7 with
        ``cfg.predicate_readout``, when the parameters have a ``"predicates"`` layer) and
        what ``spec.encode`` adds.
    """
    xp = eng.xp
    dtype = params["backbone"]["convs"][0]["w"].dtype
    obs = {k: xp.asarray(v, dtype=dtype) for k, v in obs.items()}
    f = backbone(params["backbone"], obs["bev"], cfg, eng)
    enc: dict = {"features": f}
    if "predicates" in params:
        z = predicate_logits(params["predicates"], f, cfg.predicate_readout, xp)
        enc["predicates"] = eng.nn.sigmoid(z) if cfg.predicate_activation == "sigmoid" else z
    num = inputs.numeric_features(obs, spec, cfg.setting, xp=xp)
    enc.update(spec.encode(params, obs, f, num, cfg, eng))
    return enc


def run_head(spec: ModelSpec, params: dict, enc: dict, state: dict, cfg: ModelConfig,
             eng: Any) -> tuple[Any, dict, dict]:
    """One time step of a model's recurrent part and head.

    Parameters
    ----------
    spec : ModelSpec
    params : dict
    enc : dict
        From :func:`encode` (one time step).
    state : dict
    cfg : ModelConfig
    eng : Engine

    Returns
    -------
    controls : array, shape (B, 2)
    new_state : dict
    aux : dict
        The spec's ``aux`` and, for models with eq. 7, ``predicates`` ``(B, M)``.
    """
    controls, new_state, aux = spec.head(params, enc, state, cfg, eng)
    if "predicates" in enc:
        aux = {"predicates": enc["predicates"], **aux}
    return controls, new_state, aux


def step(name: str, params: dict, obs: dict, state: dict, cfg: ModelConfig | None,
         eng: Any) -> tuple[Any, dict, dict]:
    """One control step of model ``name``.

    Parameters
    ----------
    name : str
        A registered model.
    params : dict
        From :func:`init` or :func:`minimanc.train.fit`.
    obs : dict
        Observations of :mod:`minimanc.inputs`, batched: ``bev`` ``(B, *cfg.bev_shape)`` and
        the other keys the model sees.
    state : dict
        From :func:`initial_state` or the previous call.
    cfg : ModelConfig or None
    eng : Engine

    Returns
    -------
    controls : array, shape (B, 2)
        ``[speed, yaw rate]``.
    new_state : dict
    aux : dict
        ``predicates`` ``(B, M)`` (models with eq. 7), ``q`` ``(B, N)`` (vAGN models),
        ``alpha`` and ``beta`` ``(B, 2)`` = (position, orientation) gains (DMP models),
        and ``features`` ``(B, h, w, C)``.
    """
    spec = get(name)
    cfg = cfg or ModelConfig()
    check_obs(name, obs, cfg, 1)
    enc = encode(spec, params, obs, cfg, eng)
    features = enc.pop("features")  # the head reads the features through encode only
    controls, new_state, aux = run_head(spec, params, enc, state, cfg, eng)
    aux["features"] = features
    return controls, new_state, aux


def sequence(name: str, params: dict, obs_seq: dict, state: dict, cfg: ModelConfig | None,
             eng: Any, feedback_motion: Any = False, return_aux: bool = False) -> tuple:
    """Run ``L`` steps on time-major observations.

    Equal to ``L`` calls of :func:`step` (tested), but the backbone runs once on
    all ``L·B`` frames (once per window on the observations of
    :data:`minimanc.inputs.SCENE_CONSTANT_KEYS`, which must be the same at every step)
    and the time loop is one ``eng.scan`` on both engines.
    Used to train the recurrent models on truncated back-propagation-through-time
    windows.

    Parameters
    ----------
    name, params, state, cfg, eng
        As in :func:`step`.
    obs_seq : dict
        Observations ``(L, B, ...)``.
    feedback_motion : bool or array of shape (B,)
        DMP models: the DMP's initial velocities at step ``i > 0`` are the model's own
        controls of step ``i − 1`` instead of ``obs_seq["motion"][i]`` (the DMP
        integrates its own state, as in closed loop; only step 0 uses the logged motion);
        an array chooses per window.
    return_aux : bool
        Also return the per-step ``aux`` of :func:`step` stacked along time
        (``features`` excluded).

    Returns
    -------
    controls : array, shape (L, B, 2)
    state : dict
        After the last step.
    aux : dict, only with ``return_aux``
        Arrays ``(L, B, ...)``.
    """
    spec = get(name)
    cfg = cfg or ModelConfig()
    check_obs(name, obs_seq, cfg, 2)
    xp = eng.xp
    L, B = obs_seq["bev"].shape[:2]
    seen = inputs.visible(spec, cfg.setting)
    per_scene = check_per_scene(obs_seq, seen)
    flat = {k: xp.asarray(v)[0] if k in per_scene else
            xp.reshape(xp.asarray(v), (L * B,) + tuple(v.shape[2:]))
            for k, v in obs_seq.items() if k in seen}
    enc = encode(spec, params, flat, cfg, eng)
    enc.pop("features")
    per_row = not isinstance(feedback_motion, bool)
    feedback = spec.dmp and (per_row or feedback_motion)
    rows = xp.reshape(xp.asarray(feedback_motion), (B, 1)) if feedback and per_row else True
    none_keys = [k for k, v in enc.items() if v is None]
    xs = {k: xp.reshape(v, (L, B) + tuple(v.shape[1:])) for k, v in enc.items() if v is not None}

    def body(carry: tuple, x: dict) -> tuple:
        st, prev, i = carry
        enc_i = dict(x)
        enc_i.update({k: None for k in none_keys})
        if feedback:
            enc_i["motion"] = xp.where(xp.logical_and(i > 0, rows), prev, x["motion"])
        controls, new_st, aux = run_head(spec, params, enc_i, st, cfg, eng)
        controls = controls.astype(prev.dtype)
        new_st = {k: v.astype(st[k].dtype) for k, v in new_st.items()}
        return (new_st, controls, i + 1), (controls, aux if return_aux else {})

    dtype = params["backbone"]["convs"][0]["w"].dtype
    prev0 = xp.zeros((B, 2), dtype=dtype)
    (state, _, _), (outs, auxs) = eng.scan(body, (dict(state), prev0, 0), xs)
    if not return_aux:
        return outs, state
    return outs, state, auxs

