"""Chapter 9 — the paper's protocol on the log: :class:`LogReplay` (the ego moves by the
unicycle, the ados replay their logged boxes), :func:`run_batches` (a policy on many scenes,
in batches, in the simulator of a protocol) and :class:`Rollout` (the trajectories and what
the model showed)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from minimanc import inputs
from minimanc.checks import check_int
from minimanc.rollout.driver import Policy, SceneState, Simulator, drive
from minimanc.world.geometry import DT, unicycle_step
from minimanc.world.history import latest_history

__all__ = ["AGENTS", "BATCH_SIZE", "LogReplay", "Rollout", "check_agents", "check_dataset",
           "k_targets_of", "run_batches", "scene_index"]

BATCH_SIZE: int = 8
"""Default number of scenes driven together (see :func:`simulate`)."""

AGENTS: tuple[str, ...] = ("replay", "reactive")
"""The closed-loop protocols for the ados: ``"replay"`` from the log (the paper's,
:class:`LogReplay`) or ``"reactive"`` (:mod:`minimanc.rollout.reactive`: the world's own
IDM / yielding / gap-acceptance rules react to the policy's ego)."""


def check_agents(agents: Any) -> str:
    """``agents`` if it is one of :data:`AGENTS`, else ValueError naming it."""
    if not isinstance(agents, str) or agents not in AGENTS:
        raise ValueError(f"agents must be one of {AGENTS}; got agents={agents!r}")
    return agents


@dataclass
class Rollout:
    """A batch of closed-loop (or replayed) trajectories.

    ``ego (S, T, 3)`` world poses with ``ego[:, 0]`` the logged start;
    ``controls (S, T−1, 2)`` the ``[speed, yaw rate]`` applied from ``t`` to
    ``t + 1``; ``aux[key] (S, T−1, ...)`` the model outputs at each decision
    (keys of :data:`AUX_KEYS` the model returned); ``scenes (S,)`` the
    dataset indices of the rows.  ``agents`` is the closed-loop protocol of the ados
    (:data:`AGENTS`); under ``"reactive"`` the rollout must hold the ados as they were
    simulated, ``ado (S, T, A, 5)`` and ``ado_valid (S, T, A)`` (the metrics use them
    instead of the dataset's log); under ``"replay"`` they are ``None`` (the log's).
    """

    name: str
    setting: str
    ego: np.ndarray
    controls: np.ndarray
    aux: dict[str, np.ndarray] = field(default_factory=dict)
    scenes: np.ndarray | None = None
    ado: np.ndarray | None = None
    ado_valid: np.ndarray | None = None
    agents: str = "replay"

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
        if self.agents not in AGENTS:
            raise ValueError(f"agents must be one of {AGENTS}; got agents={self.agents!r}")
        if (self.ado is None) != (self.ado_valid is None):
            raise ValueError("ado and ado_valid must be given together")
        if self.agents == "reactive" and self.ado is None:
            raise ValueError("a rollout of agents='reactive' holds the ados it simulated: ado "
                             "and ado_valid are required")
        if self.ado is not None:
            self.ado = np.asarray(self.ado, dtype=np.float64)
            self.ado_valid = np.asarray(self.ado_valid, dtype=bool)
            if self.ado.ndim != 4 or self.ado.shape[:2] != (S, T) or self.ado.shape[-1] != 5:
                raise ValueError(f"ado must have shape ({S}, {T}, A, 5); got shape "
                                 f"{self.ado.shape}")
            if self.ado_valid.shape != self.ado.shape[:3]:
                raise ValueError(f"ado_valid must have shape {self.ado.shape[:3]}; got shape "
                                 f"{self.ado_valid.shape}")

    def subset(self, rows: Any) -> Rollout:
        """The rows ``rows`` (positions in this rollout, not dataset indices) as a new
        :class:`Rollout` (a plain one: the ados, aux and protocol are kept)."""
        idx = np.atleast_1d(np.arange(len(self))[rows])
        return Rollout(self.name, self.setting, self.ego[idx], self.controls[idx],
                       {k: v[idx] for k, v in self.aux.items()}, self.scenes[idx],
                       None if self.ado is None else self.ado[idx],
                       None if self.ado_valid is None else self.ado_valid[idx], self.agents)

    def __len__(self) -> int:
        return self.ego.shape[0]

    def save(self, path: str | Path) -> Path:
        """Write to ``path`` (``.npz``), atomically (temporary file, then rename)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp.npz")
        arrays = {f"aux_{k}": v for k, v in self.aux.items()}
        if self.ado is not None:
            arrays.update(ado=self.ado, ado_valid=self.ado_valid)
        np.savez_compressed(tmp, name=np.array(self.name), setting=np.array(self.setting),
                            ego=self.ego, controls=self.controls, scenes=self.scenes,
                            agents=np.array(self.agents), **arrays)
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Rollout:
        """Read a rollout written by :meth:`save` (a file without ``agents`` is a log
        replay), as an instance of ``cls``."""
        with np.load(Path(path), allow_pickle=False) as z:
            aux = {k[4:]: z[k] for k in z.files if k.startswith("aux_")}
            ado = z["ado"] if "ado" in z.files else None
            valid = z["ado_valid"] if "ado_valid" in z.files else None
            agents = str(z["agents"]) if "agents" in z.files else "replay"
            return cls(str(z["name"]), str(z["setting"]), z["ego"], z["controls"], aux,
                       z["scenes"], ado, valid, agents)


# --------------------------------------------------------------------------- helpers


def check_dataset(ds: Any) -> tuple[int, int]:
    """The dataset's ``(S, T)``, or ValueError naming what it lacks."""
    for key in ("ego", "controls", "ado", "ado_valid", "maps"):
        if not hasattr(ds, key):
            raise ValueError(f"ds must be a minimanc.world dataset with .{key}; got {type(ds)!r}")
    ego = np.asarray(ds.ego)
    if ego.ndim != 3 or ego.shape[-1] != 3 or ego.shape[1] < 2:
        raise ValueError(f"ds.ego must have shape (S, T >= 2, 3); got shape {ego.shape}")
    return ego.shape[0], ego.shape[1]


def scene_index(scenes: Any, S: int) -> np.ndarray:
    """``scenes`` as dataset indices ``(B,)`` in ``[0, S)`` (default: all)."""
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


def k_targets_of(ds: Any) -> int | None:
    """The dataset's number of lane-target points (``None``: unknown)."""
    lt = getattr(ds, "lane_target", None)
    return None if lt is None else int(np.asarray(lt).shape[2])


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
        S, self.T = check_dataset(ds)
        self.follow_log = bool(follow_log)
        self._ds = ds
        self.scenes = scene_index(scenes, S)
        self.raster = inputs.raster_of(ds)
        self.k_targets = k_targets_of(ds)
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
        past = None
        if self.raster.history:
            past = latest_history(np.stack(self._poses, axis=1), self._ado[self.scenes, :t + 1],
                                  self._ado_valid[self.scenes, :t + 1], self.raster.history)
        return SceneState(self._maps, self._poses[-1], self._ado[self.scenes, t],
                          self._ado_valid[self.scenes, t], self._goal, past)

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


def run_batches(
    policy: Policy,
    ds: Any,
    make_sim: Callable[[Any, np.ndarray], Simulator],
    agents: str = "replay",
    scenes: Any = None,
    batch_size: int | None = None,
    steps: int | None = None,
    progress: bool = True,
    desc: str | None = None,
) -> Rollout:
    """Run ``policy`` in closed loop on the scenes ``scenes`` of ``ds`` (default: all), each
    batch of scenes in the simulator ``make_sim(ds, batch_scenes)`` of the protocol ``agents``.

    Scenes are processed ``batch_size`` at a time (default
    :data:`BATCH_SIZE` = 8: the world keeps the class grids of 8 maps cached,
    and a larger batch would rebuild every grid at every step); a row's
    result does not depend on the batch it is in.  ``steps`` limits the
    number of decisions (default ``T − 1``, the whole log).  Each batch is
    :func:`drive` in its simulator; see the module docstring for what one step does.
    Under ``agents="reactive"`` the rollout holds the ados as the simulator moved them
    (its ``ado_trajectory()``). :func:`minimanc.rollout.simulate` chooses the simulator.
    """
    check_agents(agents)
    S_all, T = check_dataset(ds)
    idx = scene_index(scenes, S_all)
    n_steps = T - 1 if steps is None else check_int("steps", steps, 1)
    if not 1 <= n_steps <= T - 1:
        raise ValueError(f"steps must lie in [1, {T - 1}]; got steps={steps!r}")
    bs = BATCH_SIZE if batch_size is None else check_int("batch_size", batch_size, 1)

    chunks = [idx[i: i + bs] for i in range(0, len(idx), bs)]
    bar = None
    if progress:
        what = "reactive closed loop" if agents == "reactive" else "closed loop"
        bar = tqdm(total=len(chunks) * n_steps, desc=desc or f"{what} {policy.model}",
                   unit="step", leave=False)
    egos, ctrls, auxs, ados, valids = [], [], [], [], []
    for chunk in chunks:
        sim = make_sim(ds, chunk)
        run = drive(policy, sim, n_steps, None if bar is None else lambda t: bar.update(1))
        egos.append(sim.trajectory())
        ctrls.append(run.controls)
        auxs.append(run.aux)
        if agents == "reactive":  # the ados as they were simulated
            a, v = sim.ado_trajectory()
            ados.append(a)
            valids.append(v)
    if bar is not None:
        bar.close()
    aux_all = {k_: np.concatenate([a[k_] for a in auxs]) for k_ in auxs[0]
               if all(k_ in a for a in auxs)}
    name = policy.model or "policy"
    return Rollout(name, policy.setting, np.concatenate(egos), np.concatenate(ctrls),
                   aux_all, idx, np.concatenate(ados) if ados else None,
                   np.concatenate(valids) if valids else None, agents)
