"""Chapter 9 — the drivers: a trained model (:class:`ModelPolicy`, :func:`closed_loop`, and
:func:`replay`, its open-loop trace on the log) and the DMP head at constant gains
(:class:`FixedGainsPolicy`, :func:`fixed_gains`).

A trained model is given whole, as the :class:`~minimanc.train.FitResult` of
:func:`minimanc.train.fit` or :func:`minimanc.train.load_fit`
(``closed_loop(fit, ds, agents="reactive")``), or in parts, its ``name``, ``params`` and
``cfg`` (``closed_loop("manc", params, ds, cfg)``): :func:`minimanc.train.accepts_fit`. The
engine is ``engine=`` everywhere, a name of :data:`minimanc.engine.ENGINES` or an engine."""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np

from minimanc import inputs, models
from minimanc.checks import check_int
from minimanc.engine import get_engine
from minimanc.models.forward import cast_tree
from minimanc.rollout.driver import AUX_KEYS, drive
from minimanc.rollout.log import (
    BATCH_SIZE,
    LogReplay,
    Rollout,
    check_agents,
    check_dataset,
    scene_index,
)
from minimanc.rollout.protocols import simulate
from minimanc.train import FitResult, accepts_fit
from minimanc.tree import leaves

__all__ = ["FixedGainsPolicy", "ModelPolicy", "closed_loop", "fixed_gains",
           "jitted_policy_step", "open_loop", "policy_step", "replay"]


def policy_step(name: str, cfg: models.ModelConfig, eng: Any) -> Callable:
    """One control step of model ``name``, ``(params, obs, state) → (u, state, aux)``, its
    aux outputs those of :data:`~minimanc.rollout.driver.AUX_KEYS`."""
    def step(p: dict, obs: dict, state: dict) -> tuple[Any, dict, dict]:
        u, new_state, aux = models.step(name, p, obs, state, cfg, eng)
        return u, new_state, {k: v for k, v in aux.items() if k in AUX_KEYS}

    return step


@lru_cache(maxsize=32)
def jitted_policy_step(name: str, cfg: models.ModelConfig, eng: Any) -> Callable:
    """:func:`policy_step` jitted, one function per ``(name, cfg, eng)``: the drivers of
    one model (every DAgger round, every evaluation) share its compilations."""
    return eng.jit(policy_step(name, cfg, eng))  # jit is the identity on the NumPy engine


class ModelPolicy:
    """A :mod:`minimanc.models` controller as a :class:`Policy`.

    ``ModelPolicy(fit, engine="jax")`` with the :class:`~minimanc.train.FitResult` of
    :func:`minimanc.train.fit`, or ``ModelPolicy(name, params, cfg, engine)`` with its
    parts: ``cfg`` is the model's :class:`~minimanc.models.ModelConfig` (its ``setting``
    decides what the model sees); ``engine`` a name of :data:`minimanc.engine.ENGINES` or
    an engine (``"jax"`` jits the step once per model configuration and batch size, shared by
    every policy of that configuration, unless ``jit=False``). The
    recurrent state starts as :func:`minimanc.models.initial_state` with ``q_init``
    ("uniform", Algorithm 1's ``UniformInit``, or "random" with ``seed``: one generator per
    scene, so that a row does not depend on its batch), or as ``initial`` (the state of one
    row, repeated for every row) when given, and is carried over between steps.
    Parameters and observations are cast to ``dtype``; the aux outputs come back in it.
    """

    @accepts_fit()
    def __init__(self, name: str | FitResult, params: dict, cfg: Any, engine: Any = "jax",
                 q_init: str = "uniform", seed: int = 0, dtype: Any = np.float32,
                 initial: dict | None = None, jit: bool = True) -> None:
        models.check_name(name)
        if q_init not in ("uniform", "random"):
            raise ValueError(f"q_init must be 'uniform' or 'random'; got q_init={q_init!r}")
        eng = get_engine(engine) if isinstance(engine, str) else engine
        self.model = name
        self.setting = cfg.setting
        self.cfg = cfg
        self.engine = eng
        self.q_init = q_init
        self.seed = int(seed)
        self.dtype = dtype
        self.initial = initial
        self.params = cast_tree(params, dtype)

        self._step = jitted_policy_step(name, cfg, eng) if jit else policy_step(name, cfg, eng)

    def initial_state(self, scenes: np.ndarray) -> dict:
        if self.initial is not None:
            return {k: self.engine.xp.asarray(np.repeat(np.asarray(v), len(scenes), axis=0))
                    for k, v in self.initial.items()}
        if self.q_init == "uniform" or models.spec(self.model).family != "vagn":
            return models.initial_state(self.model, len(scenes), self.cfg, xp=self.engine.xp,
                                        dtype=self.dtype)
        rows = [np.asarray(models.initial_state(
            self.model, 1, self.cfg, rng=np.random.default_rng([self.seed, int(s)]),
            mode="random", dtype=self.dtype)["q"]) for s in scenes]
        return {"q": self.engine.xp.asarray(np.concatenate(rows))}

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        obs = {k: np.asarray(v, dtype=self.dtype) for k, v in obs.items()}
        u, state, aux = self._step(self.params, obs, state)
        return (np.asarray(_value(u), dtype=np.float64), state,
                {k: np.asarray(_value(v)) for k, v in aux.items()})


def _value(x: Any) -> Any:
    return getattr(x, "_value", getattr(x, "value", x))


@accepts_fit()
def replay(name: str | FitResult, params: dict, ds: Any, scene: int, cfg: Any = None,
           engine: Any = None, q_mode: str = "uniform") -> dict:
    """Open-loop trace of one logged scene: :func:`drive` in a :class:`LogReplay` that follows
    the log, so that the model sees the human's observations step by step while its
    recurrent state carries over (q for vAGN models).

    ``replay(fit, ds, scene)`` with a :class:`~minimanc.train.FitResult`, or
    ``replay(name, params, ds, scene, cfg)`` with its parts.

    Parameters
    ----------
    name : str or FitResult
        A registered model, or the training result (then leave out ``params`` and ``cfg``).
    params : dict
        Its parameters; the model runs in their dtype.
    ds : dataset
        A :mod:`minimanc.world` dataset.
    scene : int
        The scene index.
    cfg : ModelConfig, optional
    engine : Engine or str, optional
        Default: the NumPy engine. The step is not jitted.
    q_mode : str
        The initial q of vAGN models: "uniform", or "random" (one ``RandomInit`` draw
        from ``numpy.random.default_rng(0)``).

    Returns
    -------
    dict
        NumPy arrays over the ``T`` steps, in the parameters' dtype: ``controls``
        ``(T, 2)`` and, where the model has them, ``q`` ``(T, N)``, ``alpha``/``beta``
        ``(T, 2)``, ``predicates`` ``(T, M)``; and ``human`` ``(T, 2)`` float64, the
        logged controls.

    Raises
    ------
    ValueError
        For an unknown model, scene or ``q_mode``.
    """
    name = models.check_name(name)
    cfg = cfg or models.ModelConfig()
    eng = get_engine(engine) if isinstance(engine, str) else (engine or get_engine("numpy"))
    S, T = check_dataset(ds)
    idx = scene_index(check_int("scene", scene, 0), S)
    if q_mode not in ("uniform", "random"):
        raise ValueError(f"q_mode must be 'uniform' or 'random'; got q_mode={q_mode!r}")
    dtype = np.asarray(_value(leaves(params)[0])).dtype
    rng = None if q_mode == "uniform" else np.random.default_rng(0)
    start = models.initial_state(name, 1, cfg, xp=np, rng=rng, mode=q_mode)
    policy = ModelPolicy(name, params, cfg, eng, dtype=dtype, initial=start, jit=False)
    run = drive(policy, LogReplay(ds, idx, follow_log=True), T)
    out = {"controls": run.controls[0].astype(dtype)}
    out.update({k: v[0] for k, v in run.aux.items()})
    out["human"] = np.asarray(ds.controls[int(scene)], dtype=np.float64)
    return out


@accepts_fit()
def open_loop(name: str | FitResult, params: dict, ds: Any, cfg: Any, engine: Any = "numpy",
              scenes: Any = None, batch_size: int | None = None) -> dict[str, np.ndarray]:
    """The open-loop trace of :func:`replay` on many scenes at once: the model sees the
    logged human's observations at every step (the ego follows the log) while its
    recurrent state carries over from the uniform initial q. ``open_loop(fit, ds)`` with a
    :class:`~minimanc.train.FitResult`, or ``open_loop(name, params, ds, cfg)`` with its parts.

    Parameters
    ----------
    name : str or FitResult
        A registered model, or the training result (then leave out ``params`` and ``cfg``).
    params : dict
        Its parameters.
    ds : dataset
        A :mod:`minimanc.world` dataset.
    cfg : ModelConfig
        The model's configuration.
    engine : Engine or str
        Runs the step (jitted on JAX, once per batch size).
    scenes : array_like of int, optional
        Default: all.
    batch_size : int, optional
        Scenes driven together (default :data:`BATCH_SIZE`); a row does not depend on
        its batch.

    Returns
    -------
    dict
        ``controls`` ``(S, T, 2)`` and the model's aux outputs (``q`` ``(S, T, N)``,
        ``alpha``, ``beta``, ``predicates``) over all ``T`` logged steps, in float32.
    """
    S, T = check_dataset(ds)
    idx = scene_index(scenes, S)
    bs = BATCH_SIZE if batch_size is None else check_int("batch_size", batch_size, 1)
    policy = ModelPolicy(name, params, cfg, engine)
    parts = []
    for i in range(0, len(idx), bs):
        run = drive(policy, LogReplay(ds, idx[i: i + bs], follow_log=True), T)
        parts.append({"controls": run.controls, **run.aux})
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


@accepts_fit()
def closed_loop(
    name: str | FitResult,
    params: dict,
    ds: Any,
    cfg: Any,
    engine: Any = "jax",
    setting: str | None = None,
    scenes: Any = None,
    batch_size: int | None = None,
    q_init: str = "uniform",
    seed: int = 0,
    steps: int | None = None,
    progress: bool = True,
    agents: str = "replay",
) -> Rollout:
    """Closed-loop rollout of a trained model on the scenes of ``ds`` (:mod:`minimanc.rollout`).

    ``closed_loop(fit, ds, agents="reactive")`` with the :class:`~minimanc.train.FitResult`
    of :func:`minimanc.train.fit` (or :func:`~minimanc.train.load_fit`), or
    ``closed_loop(name, params, ds, cfg, agents="reactive")`` with its parts.

    Parameters
    ----------
    name : str or FitResult
        A registered model, or the training result (then leave out ``params`` and ``cfg``).
    params : dict
        The model's parameters.
    ds : dataset
        A :mod:`minimanc.world` dataset.
    cfg : ModelConfig
        The model's configuration.
    engine : Engine or str
        Runs the policy (jitted on JAX).
    setting : str, optional
        Must agree with ``cfg.setting`` (a model runs in the information setting it
        was trained in).
    scenes, batch_size, steps, progress
        As in :func:`simulate`.
    q_init, seed
        As in :class:`ModelPolicy`.
    agents : str
        The ados' protocol (:data:`AGENTS`): ``"replay"`` (the log, the paper's) or
        ``"reactive"`` (the world's rules, reacting to the policy's ego).

    Returns
    -------
    Rollout

    Raises
    ------
    ValueError
        If ``setting`` differs from ``cfg.setting``, for an unknown ``agents``, or if the
        dataset's raster draws other planes than the model reads
        (:func:`minimanc.models.check_input_shape`).
    """
    check_agents(agents)
    models.check_input_shape(cfg, inputs.raster_of(ds).input_shape, "ds")
    if setting is not None and setting != cfg.setting:
        raise ValueError(
            f"setting={setting!r} differs from cfg.setting={cfg.setting!r}: a model is run in "
            "the information setting it was trained in"
        )
    policy = ModelPolicy(name, params, cfg, engine, q_init=q_init, seed=seed)
    return simulate(policy, ds, scenes=scenes, batch_size=batch_size, steps=steps,
                    progress=progress, desc=f"closed loop {name} ({cfg.setting}, {agents})",
                    agents=agents)


class FixedGainsPolicy:
    """The DMP head of MANC (:func:`minimanc.models.dmp_head`, eqs. 10–11) at constant gains.

    No CNN, no vAGN: every step makes one DMP step towards the lane target
    from the current motion with the same ``gains = (α_y, β_y, α_q, β_q)``
    (default :data:`minimanc.models.DEFAULT_GAINS`, the gains MANC starts
    training from). It reads only the lane target and its own motion, so no
    BEV is drawn.
    """

    model = "dmp_only"
    setting = "paper"
    keys = ("lane_target", "motion")

    def __init__(self, cfg: Any = None, gains: Any = None) -> None:
        self.cfg = cfg or models.ModelConfig()
        self.logits = models.gain_logits(models.DEFAULT_GAINS if gains is None else gains)

    def initial_state(self, scenes: np.ndarray) -> None:
        return None

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        logits = np.tile(self.logits, (len(scenes), 1))
        u, aux = models.dmp_head(logits, np.asarray(obs["lane_target"], np.float64),
                                 np.asarray(obs["motion"], np.float64), self.cfg)
        return np.asarray(u), state, {"alpha": aux["alpha"], "beta": aux["beta"]}


def fixed_gains(ds: Any, scenes: Any = None, *, cfg: Any = None, gains: Any = None,
                progress: bool = False, agents: str = "replay") -> Rollout:
    """Closed loop of :class:`FixedGainsPolicy` on ``ds`` (the "DMP prior" reference).

    Parameters
    ----------
    ds : dataset
    scenes : array_like, optional
        Default: all.
    cfg : ModelConfig, optional
        The head's look-ahead rules.
    gains : array_like, shape (4,), optional
        Default :data:`minimanc.models.DEFAULT_GAINS`.
    progress : bool
    agents : str
        The ados' protocol, as in :func:`closed_loop`.

    Returns
    -------
    Rollout
        Named ``"dmp_prior"``.
    """
    check_agents(agents)
    policy = FixedGainsPolicy(cfg, gains)
    traj = simulate(policy, ds, scenes=scenes, progress=progress,
                    desc=f"closed loop DMP prior ({agents})", agents=agents)
    traj.name = "dmp_prior"
    return traj
