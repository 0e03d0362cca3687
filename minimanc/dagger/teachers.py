"""Chapter 11 — the experts DAgger asks: :class:`WorldTeacher` (the world's human driver)
and :class:`HighwayTeacher` (highway-env's IDM/MOBIL), over the :class:`Teacher` protocol
(see :mod:`minimanc.dagger`)."""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from typing import Any, Protocol

import numpy as np

from minimanc import metrics, rollout
from minimanc.dagger.expert import HumanExpert, Situation
from minimanc.rollout import AGENTS, BATCH_SIZE, LogReplay, Simulator
from minimanc.rollout.reactive import ReactiveSim
from minimanc.world.geometry import DT, wrap_angle
from minimanc.world.scenes import Dataset

__all__ = ["AGENTS", "SIMS", "HighwayTeacher", "Teacher", "WorldTeacher"]
# AGENTS (the ados' protocols a WorldTeacher takes) is minimanc.rollout's, re-exported here.

SIMS: tuple[str, ...] = ("world", "highway")
"""The simulators a :class:`Teacher` exists for."""


def _highway() -> Any:
    """:mod:`minimanc.highway`, imported on first use: DAgger on the world runs without the
    optional highway-env, which that package needs."""
    from minimanc import highway  # optional dependency: highway-env (pip install '.[highway]')

    return highway


# --------------------------------------------------------------------------- teachers


class Teacher(Protocol):
    """An expert that can label the states of a simulation a policy drove.

    ``name`` one of :data:`SIMS`; ``pool`` the demonstrations (a
    :class:`minimanc.world.Dataset` whose scenes can be driven again);
    ``simulator(scenes)`` a :class:`minimanc.rollout.Simulator` over pool scenes;
    ``groups(scenes)`` the batches of scenes driven together; ``label(sim, t, prev)``
    the expert's controls ``(B, 2)`` in the simulator's current state (``prev (B, 2)``
    the controls applied at ``t − 1``, ``None`` at ``t = 0``) and, per row, ``None`` or
    why that state cannot be labelled (that row is then NaN); ``evaluate(policy)``
    closed-loop metrics of a policy (``{}`` without validation scenes). A teacher whose
    ``perceive`` is not ``None`` also has ``label_and_perceive`` (:class:`WorldTeacher`).
    """

    name: str
    pool: Dataset

    def groups(self, scenes: np.ndarray) -> list[np.ndarray]: ...

    def simulator(self, scenes: np.ndarray) -> Simulator: ...

    def label(self, sim: Any, t: int, prev: np.ndarray | None
              ) -> tuple[np.ndarray, list[str | None]]: ...

    def evaluate(self, policy: Any, progress: bool = False) -> dict[str, float]: ...



class WorldTeacher:
    """The world's human driver as a :class:`Teacher`
    (:class:`~minimanc.dagger.expert.HumanExpert`).

    ``pool`` a dataset made by :func:`minimanc.world.generate` (the demonstrations),
    ``val`` an optional validation dataset for :meth:`evaluate`, ``agents`` the
    protocol of the ados while the policy drives and is evaluated: ``"reactive"``
    (:class:`~minimanc.rollout.reactive.ReactiveSim`, default) or ``"replay"``
    (:class:`~minimanc.rollout.LogReplay`, the paper's). ``perceive`` (optional) maps the
    expert's :class:`~minimanc.dagger.expert.Situation` in a labelled state to the numbers
    it perceives there and where each counts, ``(values (K,), mask (K,))`` (e.g.
    :func:`minimanc.diagnose.state_targets`): :meth:`label_and_perceive` then also returns
    them, and DAgger collects them as the targets of the auxiliary perception loss.
    """

    name = "world"

    def __init__(self, pool: Dataset, val: Dataset | None = None,
                 agents: str = "reactive",
                 perceive: Callable[[Situation], tuple[np.ndarray, np.ndarray]] | None = None
                 ) -> None:
        if agents not in AGENTS:
            raise ValueError(f"agents must be one of {AGENTS}, got agents={agents!r}")
        if not isinstance(pool, Dataset):
            raise ValueError(f"pool must be a minimanc.world.Dataset, got {type(pool)!r}")
        if perceive is not None and not callable(perceive):
            raise ValueError(f"perceive must be a function of a Situation or None, got "
                             f"{perceive!r}")
        self.pool, self.val, self.agents, self.perceive = pool, val, agents, perceive
        self.expert = HumanExpert(pool)

    def groups(self, scenes: np.ndarray) -> list[np.ndarray]:
        scenes = np.asarray(scenes, dtype=np.int64)
        return [scenes[i:i + BATCH_SIZE] for i in range(0, len(scenes), BATCH_SIZE)]

    def simulator(self, scenes: np.ndarray) -> Simulator:
        if self.agents == "reactive":
            return ReactiveSim(self.pool, scenes)
        return LogReplay(self.pool, scenes)

    def states(self, sim: Any, prev: np.ndarray | None
               ) -> tuple[np.ndarray, list[float], list[Any]]:
        """The ego poses ``(B, 3)``, speeds and ados (a live traffic, or ``None`` for the
        log's) of the simulator's current state, as the expert is asked in it: among
        reactive ados the simulated ego's speed, in a replay the speed of the controls
        applied last (``prev``; the logged start speed at ``t = 0``)."""
        scenes = np.asarray(sim.scenes)
        if self.agents == "reactive":
            speeds = [float(run.ego.v) for run in sim.runs]
            traffics = [run.traffic for run in sim.runs]
        else:
            speeds = ([self.expert.steps(int(s))[0].speed for s in scenes] if prev is None
                      else [float(v) for v in np.asarray(prev)[:, 0]])
            traffics = [None] * len(scenes)
        return np.asarray(sim.observe().pose, dtype=np.float64), speeds, traffics

    def label(self, sim: Any, t: int, prev: np.ndarray | None
              ) -> tuple[np.ndarray, list[str | None]]:
        out, why, _ = self.label_and_perceive(sim, t, prev)
        return out, why

    def label_and_perceive(self, sim: Any, t: int, prev: np.ndarray | None
                           ) -> tuple[np.ndarray, list[str | None],
                                      tuple[np.ndarray, np.ndarray] | None]:
        """:meth:`label`, and with ``perceive`` what the expert perceives in each state:
        ``(values (B, K), mask (B, K))`` (NaN and ``False`` in a row that cannot be
        labelled); ``None`` without ``perceive``."""
        poses, speeds, traffics = self.states(sim, prev)
        scenes = np.asarray(sim.scenes)
        out = np.full((len(scenes), 2), np.nan)
        why: list[str | None] = [None] * len(scenes)
        rows: list[tuple[np.ndarray, np.ndarray] | None] = [None] * len(scenes)
        for b, s in enumerate(scenes):
            try:
                sit = self.expert.situation(int(s), int(t), poses[b], max(speeds[b], 0.0),
                                            traffics[b])
                out[b] = self.expert.controls(sit)
            except ValueError as e:  # the driver cannot be asked in this state
                why[b] = str(e)
                continue
            if self.perceive is not None:
                rows[b] = self.perceive(sit)
        if self.perceive is None:
            return out, why, None
        k = next((len(r[0]) for r in rows if r is not None), 0)
        values = np.stack([np.full(k, np.nan) if r is None else np.asarray(r[0], np.float64)
                           for r in rows]).reshape(len(scenes), k)
        mask = np.stack([np.zeros(k, bool) if r is None else np.asarray(r[1], bool)
                         for r in rows]).reshape(len(scenes), k)
        return out, why, (values, mask)

    def evaluate(self, policy: Any, progress: bool = False) -> dict[str, float]:
        if self.val is None:
            return {}
        traj = rollout.simulate(policy, self.val, progress=progress, agents=self.agents)
        return metrics.evaluate(traj, self.val)


class HighwayTeacher:
    """highway-env's IDM/MOBIL expert as a :class:`Teacher`.

    ``pool`` demonstrations from :func:`minimanc.highway.collect_demonstrations` /
    :func:`~minimanc.highway.to_dataset` (their tags name the scenario, env seed and
    the expert's desired speed); a scene is driven again from ``env.reset(seed)`` in a
    :class:`minimanc.highway.HighwaySim` with the demonstration's final pose as goal.
    A state is labelled by installing the expert (:func:`minimanc.highway.install_expert`,
    the scene's desired speed) on a deep copy of the env and stepping the copy once: the
    label is the speed it reaches and its mean yaw rate over the step, the format of
    :attr:`minimanc.highway.Episode.controls`. ``val`` optional expert episodes
    (:func:`minimanc.highway.expert_episodes`, one scenario) for :meth:`evaluate`
    (:func:`minimanc.highway.drive_episodes`).
    """

    name = "highway"

    def __init__(self, pool: Dataset, val: Sequence[Any] | None = None) -> None:
        _highway()  # a clear ImportError now, not at the first label, without highway-env
        if not isinstance(pool, Dataset):
            raise ValueError(f"pool must be a minimanc.world.Dataset, got {type(pool)!r}")
        tags = pool.meta.get("tags", [])
        if not tags or any(t.get("source") != "highway-env" for t in tags):
            raise ValueError("pool must be highway-env demonstrations "
                             "(minimanc.highway.collect_demonstrations)")
        self.pool, self.val = pool, list(val) if val is not None else None

    def groups(self, scenes: np.ndarray) -> list[np.ndarray]:
        scenes = np.asarray(scenes, dtype=np.int64)
        out = []
        for sc in dict.fromkeys(self.pool.tags[int(s)]["scenario"] for s in scenes):
            same = scenes[[self.pool.tags[int(s)]["scenario"] == sc for s in scenes]]
            out += [same[i:i + BATCH_SIZE] for i in range(0, len(same), BATCH_SIZE)]
        return out

    def simulator(self, scenes: np.ndarray) -> Simulator:
        hw = _highway()
        tags = [self.pool.tags[int(s)] for s in scenes]
        if len({t["scenario"] for t in tags}) != 1:
            raise ValueError("a highway simulator drives scenes of one scenario; use groups()")
        T = self.pool.n_steps
        goals = np.asarray(self.pool.ego, dtype=np.float64)[np.asarray(scenes), -1]
        sim = hw.HighwaySim(tags[0]["scenario"], [t["env_seed"] for t in tags], T, list(goals),
                            self.pool.raster,
                            k_targets=int(np.asarray(self.pool.lane_target).shape[2]))
        sim.scenes = np.asarray(scenes, dtype=np.int64)  # rows are pool scenes
        return sim

    def label(self, sim: Any, t: int, prev: np.ndarray | None
              ) -> tuple[np.ndarray, list[str | None]]:
        hw = _highway()
        out = np.full((len(sim.runs), 2), np.nan)
        for b, (run, s) in enumerate(zip(sim.runs, np.asarray(sim.scenes))):
            env = copy.deepcopy(run.env)
            yaw0 = float(hw.ego_pose(env)[2])
            hw.install_expert(env, float(self.pool.tags[int(s)]["expert_speed"]))
            env.step(None)
            out[b] = [float(env.unwrapped.vehicle.speed),
                      float(wrap_angle(float(hw.ego_pose(env)[2]) - yaw0)) / DT]
            env.close()
        return out, [None] * len(out)

    def evaluate(self, policy: Any, progress: bool = False) -> dict[str, float]:
        if not self.val:
            return {}
        hw = _highway()
        res = hw.drive_episodes(policy, self.val[0].scenario, self.val, cfg=self.pool.raster,
                             progress=progress)
        out = res.metrics
        out.pop("episodes_per_second", None)  # wall clock, not a property of the policy
        return out
