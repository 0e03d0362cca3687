"""Chapter 9 — the closed loop: the policy drives the ego, the ados replay the log.

The paper's evaluation (section V-A): "we control the ego vehicle with our
learned planner, the ado vehicles move according to the trajectories
recorded in the dataset with synchronized time".  For every validation scene,
all scenes batched:

1. the ego starts at the logged pose ``ego[:, 0]``, moving at the logged
   initial speed (:func:`minimanc.inputs.initial_motion`);
2. at each step ``t = 0 … T−2`` the observation is rebuilt from the ego's
   *own* pose (:func:`minimanc.inputs.from_state`): the BEV is re-rasterised
   (:func:`minimanc.world.rasterize_batch`) with the ados at their logged
   boxes of time ``t``, the goal (the human's final pose) is re-expressed in
   the current ego frame, the lane targets are recomputed from the map at the
   ego's projection on its route, and ``motion`` is the policy's own previous
   control;
3. the policy returns ``[speed, yaw rate]`` and its new state (the vAGN
   distribution ``q`` of eq. 9, or an LSTM carry), which is carried over;
4. the ego moves by one explicit-Euler unicycle step of ``DT = 0.5`` s
   (:func:`minimanc.world.unicycle_step`).

The result is a :class:`Rollout`: poses ``(S, T, 3)`` on the log's clock,
the applied controls ``(S, T−1, 2)`` and, per step, the model's explanation
outputs (``q``, DMP ``alpha`` and ``beta``, ``predicates``) for the paper's
explainability figures.  :func:`human` is the replay of the logged ego — the
"Human" row of Table I — and :func:`fixed_gains` drives with MANC's DMP head
at constant gains and no network at all (eqs. 10–11 with ``FC(q)`` replaced
by a constant): the structured prior alone, the reference that tells how much
the learned part adds.

Any object with ``model``, ``setting``, ``initial_state(scenes)`` and
``__call__(obs, state, t, scenes) -> (controls, state, aux)`` can drive
(:class:`Policy`); :class:`ModelPolicy` wraps :func:`minimanc.models.step`.
The loop itself is :func:`drive`, written once over a :class:`Simulator`
(reset, observe, step): :class:`LogReplay` is the log above, and
:class:`minimanc.highway.HighwaySim` is highway-env (chapter 10). The
open-loop trace of chapter 8 (:func:`replay`) is the same loop in a
:class:`LogReplay` whose ego follows the log (``follow_log=True``) while the
model is queried.

The recorded ``aux`` arrays keep the dtype the model computed them in (a
float32 model's ``q`` stays float32), so their precision is known downstream.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from minimanc import inputs
from minimanc.checks import check_int
from minimanc.world.geometry import DT, unicycle_step

__all__ = [
    "AUX_KEYS",
    "BATCH_SIZE",
    "BadControls",
    "Drive",
    "LogReplay",
    "SceneState",
    "Simulator",
    "check_controls",
    "drive",
    "observation",
    "FixedGainsPolicy",
    "Policy",
    "ModelPolicy",
    "Rollout",
    "human",
    "replay",
    "simulate",
    "closed_loop",
    "fixed_gains",
]

AUX_KEYS: tuple[str, ...] = ("q", "alpha", "beta", "predicates")
"""The per-step model outputs a rollout records (when the model returns them)."""

BATCH_SIZE: int = 8
"""Default number of scenes driven together (see :func:`simulate`)."""


class BadControls(ValueError):
    """A policy returned controls of the wrong shape or not finite (NaN or infinite)."""


class Policy(Protocol):
    """What :func:`simulate` needs from a driver.

    ``model`` (a name of :data:`minimanc.inputs.MODEL_NAMES`, or ``None`` for
    every key but ``goal_bev``) and ``setting`` choose which observation keys
    are built (:func:`minimanc.inputs.visible`); a policy may instead name them
    in an optional ``keys`` attribute (a driver that reads no image then costs
    no rasterising).  ``scenes`` are the dataset indices of the batch rows.
    """

    model: str | None
    setting: str

    def initial_state(self, scenes: np.ndarray) -> Any: ...

    def __call__(
        self, obs: dict, state: Any, t: int, scenes: np.ndarray
    ) -> tuple[np.ndarray, Any, dict]: ...


@dataclass
class Rollout:
    """A batch of closed-loop (or replayed) trajectories.

    ``ego (S, T, 3)`` world poses with ``ego[:, 0]`` the logged start;
    ``controls (S, T−1, 2)`` the ``[speed, yaw rate]`` applied from ``t`` to
    ``t + 1``; ``aux[key] (S, T−1, ...)`` the model outputs at each decision
    (keys of :data:`AUX_KEYS` the model returned); ``scenes (S,)`` the
    dataset indices of the rows.
    """

    name: str
    setting: str
    ego: np.ndarray
    controls: np.ndarray
    aux: dict[str, np.ndarray] = field(default_factory=dict)
    scenes: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.ego = np.asarray(self.ego, dtype=np.float64)
        self.controls = np.asarray(self.controls, dtype=np.float64)
        if self.ego.ndim != 3 or self.ego.shape[-1] != 3:
            raise ValueError(f"ego must have shape (S, T, 3); got shape {self.ego.shape}")
        S, T = self.ego.shape[:2]
        if self.controls.shape != (S, T - 1, 2):
            raise ValueError(
                f"controls must have shape ({S}, {T - 1}, 2); got shape {self.controls.shape}"
            )
        if self.scenes is None:
            self.scenes = np.arange(S)
        self.scenes = np.asarray(self.scenes, dtype=np.int64)
        if self.scenes.shape != (S,):
            raise ValueError(f"scenes must have shape ({S},); got shape {self.scenes.shape}")

    def __len__(self) -> int:
        return self.ego.shape[0]

    def save(self, path: str | Path) -> Path:
        """Write to ``path`` (``.npz``), atomically (temporary file, then rename)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp.npz")
        arrays = {f"aux_{k}": v for k, v in self.aux.items()}
        np.savez_compressed(tmp, name=np.array(self.name), setting=np.array(self.setting),
                            ego=self.ego, controls=self.controls, scenes=self.scenes, **arrays)
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Rollout:
        """Read a rollout written by :meth:`save`."""
        with np.load(Path(path), allow_pickle=False) as z:
            aux = {k[4:]: z[k] for k in z.files if k.startswith("aux_")}
            return cls(str(z["name"]), str(z["setting"]), z["ego"], z["controls"], aux,
                       z["scenes"])


# --------------------------------------------------------------------------- helpers


def _check_dataset(ds: Any) -> tuple[int, int]:
    for key in ("ego", "controls", "ado", "ado_valid", "maps"):
        if not hasattr(ds, key):
            raise ValueError(f"ds must be a minimanc.world dataset with .{key}; got {type(ds)!r}")
    ego = np.asarray(ds.ego)
    if ego.ndim != 3 or ego.shape[-1] != 3 or ego.shape[1] < 2:
        raise ValueError(f"ds.ego must have shape (S, T >= 2, 3); got shape {ego.shape}")
    return ego.shape[0], ego.shape[1]


def _scene_index(scenes: Any, S: int) -> np.ndarray:
    if scenes is None:
        return np.arange(S)
    idx = np.asarray(scenes)
    if idx.ndim == 0:
        idx = idx[None]
    if idx.ndim != 1 or idx.size == 0 or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"scenes must be a non-empty 1-D array of integers; got scenes={scenes!r}")
    if idx.min() < 0 or idx.max() >= S:
        raise ValueError(f"scenes must lie in [0, {S}); got scenes={scenes!r}")
    return idx.astype(np.int64)


def _raster_config(ds: Any) -> Any:
    cfg = getattr(ds, "raster", None)
    if cfg is None:
        from minimanc import world

        cfg = world.RasterConfig(size=int(np.asarray(ds.bev).shape[2]))
    return cfg


def _k_targets(ds: Any) -> int | None:
    lt = getattr(ds, "lane_target", None)
    return None if lt is None else int(np.asarray(lt).shape[2])


def human(ds: Any, scenes: Any = None) -> Rollout:
    """The logged human ego as a :class:`Rollout` (Table I's "Human" row).

    Its controls are the logged ones from ``t`` to ``t + 1``; replaying them
    with the unicycle reproduces ``ds.ego`` (the world's logging rule).
    """
    S, T = _check_dataset(ds)
    idx = _scene_index(scenes, S)
    ego = np.asarray(ds.ego, dtype=np.float64)[idx]
    controls = np.asarray(ds.controls, dtype=np.float64)[idx, : T - 1]
    return Rollout("human", "log", ego, controls, {}, idx)


# --------------------------------------------------------------------------- the driver


@dataclass
class SceneState:
    """What a :class:`Simulator` shows at one step, for a batch of ``B`` scenes.

    ``maps`` one :class:`minimanc.world.maps.Map` per row, ``pose (B, 3)`` the
    ego's world pose ``[x, y, yaw]``, ``ado (B, A, 5)`` the ado boxes
    ``[x, y, yaw, length, width]`` at this step with ``ado_valid (B, A)`` bool,
    ``goal (B, 3)`` the goal world pose.
    """

    maps: list
    pose: np.ndarray
    ado: np.ndarray
    ado_valid: np.ndarray
    goal: np.ndarray


class Simulator(Protocol):
    """A world that :func:`drive` runs a :class:`Policy` in, ``B`` scenes at a time.

    Attributes: ``scenes (B,)`` the integer ids of the rows (passed to the
    policy), ``raster`` the :class:`minimanc.world.RasterConfig` the BEV is
    drawn with, ``k_targets`` the number of lane-target points (``None``: the
    default :data:`minimanc.world.maps.K_TARGETS`).

    * ``reset()`` puts every row at its start and returns the ego's motion
      there, ``(B, 2)`` float32 ``[speed, yaw rate]`` (the ``motion`` input at
      ``t = 0``);
    * ``observe()`` returns the current :class:`SceneState` (ego poses
      ``(B, 3)``, ados ``(B, A, 5)`` and ``(B, A)``, maps, goals ``(B, 3)``);
    * ``step(controls)`` applies ``controls (B, 2)`` float64
      ``[speed, yaw rate]`` for one decision (``DT`` = 0.5 s) and returns
      ``None`` — or, when the ego does not move by the policy's controls (a
      replay that follows the log), the ``(B, 2)`` motion it actually had,
      which becomes the next ``motion`` input; the simulator keeps whatever
      trajectory it records.

    Implemented by :class:`LogReplay` (the chapter-9 log: ados replay their
    recorded boxes) and :class:`minimanc.highway.HighwaySim` (highway-env,
    reactive traffic).
    """

    scenes: np.ndarray
    raster: Any
    k_targets: int | None

    def reset(self) -> np.ndarray: ...

    def observe(self) -> SceneState: ...

    def step(self, controls: np.ndarray) -> None: ...


@dataclass
class Drive:
    """What :func:`drive` returns: ``controls (B, steps, 2)`` float64, the policy's controls,
    and, for the keys of :data:`AUX_KEYS` the policy returned at every step,
    ``aux[key] (B, steps, ...)`` in the dtype the policy returned."""

    controls: np.ndarray
    aux: dict[str, np.ndarray]


def observation(policy: Policy, scene: SceneState, motion: np.ndarray, raster: Any = None,
                k_targets: int | None = None) -> dict:
    """The observation ``policy`` sees in ``scene`` (:func:`minimanc.inputs.from_state`).

    The keys are ``policy.keys`` when the policy names them, else those its
    ``model`` and ``setting`` see; ``motion (B, 2)`` is its previous control.
    """
    return inputs.from_state(
        scene.maps, scene.pose, scene.ado, scene.ado_valid, scene.goal, raster, policy.setting,
        motion=motion, model=policy.model, k_targets=k_targets,
        keys=getattr(policy, "keys", None),
    )


def check_controls(controls: Any, batch: int, t: int, policy: Any = None) -> np.ndarray:
    """``controls`` as float64 ``(batch, 2)``, else :class:`BadControls` (shape or NaN/inf)."""
    u = np.asarray(controls, dtype=np.float64)
    if u.shape != (batch, 2) or not np.all(np.isfinite(u)):
        raise BadControls(
            f"policy {getattr(policy, 'model', None)!r} returned controls of shape {u.shape} "
            f"(finite: {bool(np.all(np.isfinite(u)))}) at step {t}; "
            f"expected finite ({batch}, 2)"
        )
    return u


def drive(policy: Policy, sim: Simulator, steps: int,
          on_step: Callable[[int], None] | None = None) -> Drive:
    """Run ``policy`` in closed loop in ``sim`` for ``steps`` decisions.

    ``sim.reset()``, then at each step ``t``: observe the scene, build the
    policy's observation from the ego's own state (:func:`observation`, with
    ``motion`` the policy's previous control — or the motion ``sim.step``
    returned, when it returns one — and at ``t = 0`` the motion ``reset``
    returned), call the policy, check its controls (:func:`check_controls`),
    carry its state over and ``sim.step`` them. ``on_step(t)`` is called after
    each step (e.g. a progress bar).
    """
    steps = check_int("steps", steps, 1)
    scenes = np.asarray(sim.scenes)
    motion = np.asarray(sim.reset(), dtype=np.float32)
    state = policy.initial_state(scenes)
    controls, aux_steps = [], {}
    for t in range(int(steps)):
        obs = observation(policy, sim.observe(), motion, sim.raster, sim.k_targets)
        u, state, aux = policy(obs, state, t, scenes)
        u = check_controls(u, len(scenes), t, policy)
        for key in AUX_KEYS:
            if key in aux and aux[key] is not None:
                aux_steps.setdefault(key, []).append(np.asarray(aux[key]))
        moved = sim.step(u)
        motion = np.asarray(u if moved is None else moved, dtype=np.float32)
        controls.append(u)
        if on_step is not None:
            on_step(t)
    return Drive(np.stack(controls, axis=1),
                 {k: np.stack(v, axis=1) for k, v in aux_steps.items() if len(v) == steps})


class LogReplay:
    """The chapter-9 log as a :class:`Simulator`: the ego moves by the unicycle, the ados
    replay their logged boxes on the log's clock.

    ``ds`` a :mod:`minimanc.world` dataset, ``scenes`` the dataset indices of the
    batch rows (default: all). The ego starts at the logged pose ``ego[:, 0]``
    with the logged initial speed (:func:`minimanc.inputs.initial_motion`); the
    goal is the human's final pose; a step is one explicit-Euler unicycle step
    of ``DT`` (:func:`minimanc.world.unicycle_step`). :meth:`trajectory` gives
    the poses so far, ``(B, t + 1, 3)``.

    With ``follow_log=True`` the ego ignores the controls and moves along its
    logged poses; ``step`` then returns the logged motion (the human's control,
    :func:`minimanc.inputs.motion_at`), so the policy sees exactly the log's
    observations (open loop; :func:`replay`). Such a replay may run all ``T``
    steps: after the last one the ego stays at its final logged pose.
    """

    def __init__(self, ds: Any, scenes: Any = None, follow_log: bool = False) -> None:
        S, self.T = _check_dataset(ds)
        self.follow_log = bool(follow_log)
        self._ds = ds
        self.scenes = _scene_index(scenes, S)
        self.raster = _raster_config(ds)
        self.k_targets = _k_targets(ds)
        ego = np.asarray(ds.ego, dtype=np.float64)[self.scenes]
        self._start, self._goal = ego[:, 0], ego[:, -1]
        self._motion0 = inputs.initial_motion(ds)[self.scenes]
        self._maps = [ds.maps[s] for s in self.scenes]
        self._ado, self._ado_valid = np.asarray(ds.ado), np.asarray(ds.ado_valid)
        self._poses: list[np.ndarray] = []

    def reset(self) -> np.ndarray:
        self._poses = [self._start]
        return self._motion0

    def observe(self) -> SceneState:
        t = len(self._poses) - 1
        if t >= self.T:
            raise ValueError(f"the log has {self.T} steps; no observation at step {t}")
        return SceneState(self._maps, self._poses[-1], self._ado[self.scenes, t],
                          self._ado_valid[self.scenes, t], self._goal)

    def step(self, controls: np.ndarray) -> np.ndarray | None:
        if not self.follow_log:
            self._poses.append(unicycle_step(self._poses[-1], controls, DT))
            return None
        t = len(self._poses) - 1
        if t + 1 >= self.T:  # the log ends: stay at its last pose
            return np.asarray(controls, dtype=np.float32)
        self._poses.append(np.asarray(self._ds.ego, dtype=np.float64)[self.scenes, t + 1])
        return inputs.motion_at(self._ds, self.scenes, np.full(len(self.scenes), t + 1))

    def trajectory(self) -> np.ndarray:
        return np.stack(self._poses, axis=1)


def simulate(
    policy: Policy,
    ds: Any,
    scenes: Any = None,
    batch_size: int | None = None,
    steps: int | None = None,
    progress: bool = True,
    desc: str | None = None,
) -> Rollout:
    """Run ``policy`` in closed loop on the scenes ``scenes`` of ``ds`` (default: all).

    Scenes are processed ``batch_size`` at a time (default
    :data:`BATCH_SIZE` = 8: the world keeps the class grids of 8 maps cached,
    and a larger batch would rebuild every grid at every step); a row's
    result does not depend on the batch it is in.  ``steps`` limits the
    number of decisions (default ``T − 1``, the whole log).  Each batch is
    :func:`drive` in a :class:`LogReplay`; see the module docstring for what
    one step does.
    """
    S_all, T = _check_dataset(ds)
    idx = _scene_index(scenes, S_all)
    n_steps = T - 1 if steps is None else int(steps)
    if not 1 <= n_steps <= T - 1:
        raise ValueError(f"steps must lie in [1, {T - 1}]; got steps={steps!r}")
    bs = BATCH_SIZE if batch_size is None else check_int("batch_size", batch_size, 1)

    chunks = [idx[i: i + bs] for i in range(0, len(idx), bs)]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(chunks) * n_steps, desc=desc or f"closed loop {policy.model}",
                   unit="step", leave=False)
    egos, ctrls, auxs = [], [], []
    for chunk in chunks:
        sim = LogReplay(ds, chunk)
        run = drive(policy, sim, n_steps, None if bar is None else lambda t: bar.update(1))
        egos.append(sim.trajectory())
        ctrls.append(run.controls)
        auxs.append(run.aux)
    if bar is not None:
        bar.close()
    aux_all = {k_: np.concatenate([a[k_] for a in auxs]) for k_ in auxs[0]
               if all(k_ in a for a in auxs)}
    name = policy.model or "policy"
    return Rollout(name, policy.setting, np.concatenate(egos), np.concatenate(ctrls),
                   aux_all, idx)


class ModelPolicy:
    """A :mod:`minimanc.models` controller as a :class:`Policy`.

    ``params`` from :func:`minimanc.train.fit`; ``cfg`` its
    :class:`~minimanc.models.ModelConfig` (its ``setting`` decides what the
    model sees); ``eng`` an engine (``"jax"`` jits the step once per batch
    size, unless ``jit=False``). The recurrent state starts as
    :func:`minimanc.models.initial_state` with ``q_init`` ("uniform",
    Algorithm 1's ``UniformInit``, or "random" with ``seed``: one generator per
    scene, so that a row does not depend on its batch), or as ``initial`` (the
    state of one row, repeated for every row) when given, and is carried over
    between steps. Parameters and observations are cast to ``dtype``; the aux
    outputs come back in it.
    """

    def __init__(self, name: str, params: dict, cfg: Any, eng: Any,
                 q_init: str = "uniform", seed: int = 0, dtype: Any = np.float32,
                 initial: dict | None = None, jit: bool = True) -> None:
        from minimanc import models
        from minimanc.models.forward import cast_tree

        models.check_name(name)
        if q_init not in ("uniform", "random"):
            raise ValueError(f"q_init must be 'uniform' or 'random'; got q_init={q_init!r}")
        if isinstance(eng, str):
            from minimanc import engine

            eng = engine(eng)
        self.model = name
        self.setting = cfg.setting
        self.cfg = cfg
        self.eng = eng
        self.q_init = q_init
        self.seed = int(seed)
        self.dtype = dtype
        self.initial = initial
        self.params = cast_tree(params, dtype)

        def _fn(p: dict, obs: dict, state: dict) -> tuple[Any, dict, dict]:
            u, new_state, aux = models.step(name, p, obs, state, cfg, eng)
            aux = {k: v for k, v in aux.items() if k in AUX_KEYS}
            return u, new_state, aux

        self._step = eng.jit(_fn) if jit else _fn  # jit is the identity on the NumPy engine

    def initial_state(self, scenes: np.ndarray) -> dict:
        from minimanc import models

        if self.initial is not None:
            return {k: self.eng.xp.asarray(np.repeat(np.asarray(v), len(scenes), axis=0))
                    for k, v in self.initial.items()}
        if self.q_init == "uniform" or models.spec(self.model).family != "vagn":
            return models.initial_state(self.model, len(scenes), self.cfg, xp=self.eng.xp,
                                        dtype=self.dtype)
        rows = [np.asarray(models.initial_state(
            self.model, 1, self.cfg, rng=np.random.default_rng([self.seed, int(s)]),
            mode="random", dtype=self.dtype)["q"]) for s in scenes]
        return {"q": self.eng.xp.asarray(np.concatenate(rows))}

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        obs = {k: np.asarray(v, dtype=self.dtype) for k, v in obs.items()}
        u, state, aux = self._step(self.params, obs, state)
        return (np.asarray(_value(u), dtype=np.float64), state,
                {k: np.asarray(_value(v)) for k, v in aux.items()})


def _value(x: Any) -> Any:
    return getattr(x, "_value", getattr(x, "value", x))


def replay(name: str, params: dict, ds: Any, scene: int, cfg: Any = None, eng: Any = None,
           q_mode: str = "uniform") -> dict:
    """Open-loop trace of one logged scene: :func:`drive` in a :class:`LogReplay` that follows
    the log, so that the model sees the human's observations step by step while its
    recurrent state carries over (q for vAGN models).

    Parameters
    ----------
    name : str
        A registered model.
    params : dict
        Its parameters; the model runs in their dtype.
    ds : dataset
        A :mod:`minimanc.world` dataset.
    scene : int
        The scene index.
    cfg : ModelConfig, optional
    eng : Engine or str, optional
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
    """
    from minimanc import engine as _engine
    from minimanc import models
    from minimanc.tree import leaves

    name = models.check_name(name)
    cfg = cfg or models.ModelConfig()
    eng = _engine(eng) if isinstance(eng, str) else (eng or _engine("numpy"))
    S, T = _check_dataset(ds)
    idx = _scene_index(check_int("scene", scene, 0), S)
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


def closed_loop(
    name: str,
    params: dict,
    ds: Any,
    cfg: Any,
    eng: Any = "jax",
    setting: str | None = None,
    scenes: Any = None,
    batch_size: int | None = None,
    q_init: str = "uniform",
    seed: int = 0,
    steps: int | None = None,
    progress: bool = True,
) -> Rollout:
    """Closed-loop rollout of model ``name`` on the scenes of ``ds`` (see the module docstring).

    ``setting`` overrides ``cfg.setting`` only if they agree (a model trained
    in one information setting cannot be run in the other: its inputs
    differ); the rest as in :class:`ModelPolicy` and :func:`simulate`.
    """
    if setting is not None and setting != cfg.setting:
        raise ValueError(
            f"setting={setting!r} differs from cfg.setting={cfg.setting!r}: a model is run in "
            "the information setting it was trained in"
        )
    policy = ModelPolicy(name, params, cfg, eng, q_init=q_init, seed=seed)
    return simulate(policy, ds, scenes=scenes, batch_size=batch_size, steps=steps,
                    progress=progress, desc=f"closed loop {name} ({cfg.setting})")


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
        from minimanc import models

        self.cfg = cfg or models.ModelConfig()
        self.logits = models.gain_logits(models.DEFAULT_GAINS if gains is None else gains)

    def initial_state(self, scenes: np.ndarray) -> None:
        return None

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        from minimanc import models

        logits = np.tile(self.logits, (len(scenes), 1))
        u, aux = models.dmp_head(logits, np.asarray(obs["lane_target"], np.float64),
                                 np.asarray(obs["motion"], np.float64), self.cfg)
        return np.asarray(u), state, {"alpha": aux["alpha"], "beta": aux["beta"]}


def fixed_gains(ds: Any, scenes: Any = None, cfg: Any = None, gains: Any = None,
                progress: bool = False) -> Rollout:
    """Closed loop of :class:`FixedGainsPolicy` on ``ds`` (the "DMP prior" reference)."""
    policy = FixedGainsPolicy(cfg, gains)
    traj = simulate(policy, ds, scenes=scenes, progress=progress, desc="closed loop DMP prior")
    traj.name = "dmp_prior"
    return traj
