"""Chapter 10 — episodes: one env driven by the expert or a policy, step by step.

:func:`run_episode` drives one sandbox episode (the expert, or a policy
through the action adapter) and records an :class:`Episode` in the world
frame: poses, speeds, ados, lane targets, BEV rasters and highway-env's
flags. The logged controls (:attr:`Episode.controls`) are the speed reached
at ``t + 1`` and the mean yaw rate over the step — what the action adapter
realises, which :func:`replay_error` checks.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from minimanc.checks import check_int
from minimanc.highway.control import EXPERT_SPEEDS, ActionAdapter, install_expert
from minimanc.highway.env import (
    DEFAULT_STEPS,
    MAX_ADO,
    ado_boxes,
    check_scenario,
    ego_pose,
    make_env,
)
from minimanc.highway.mapping import RouteTracker, road_map
from minimanc.highway.render import render_frame
from minimanc.rollout import SceneState, check_controls, drive, observation
from minimanc.world.geometry import DT, goal_in_ego_frame, wrap_angle
from minimanc.world.history import History, latest_history
from minimanc.world.lanes import K_TARGETS, Map
from minimanc.world.maps import lane_targets
from minimanc.world.raster import RasterConfig, rasterize


@dataclass
class Episode:
    """One episode of ``T`` actions: ``T + 1`` recorded states (world frame).

    ``poses (T+1, 3)``, ``speeds (T+1,)``, ``ado (T+1, A, 5)``, ``ado_valid
    (T+1, A)``, ``lane_target (T+1, K, 2)`` (ego frame), ``bev (T+1, *cfg.shape)``
    uint8 as the raster stores it (when recorded; the RGB image, or the channels
    bit-packed), ``commands (T, 2)`` the ``[speed, yaw rate]`` a
    policy asked for (NaN for the expert), ``actions (T, 2)`` the
    ContinuousAction sent (NaN for the expert), ``crashed`` and ``on_road``
    ``(T+1,)`` highway-env's flags, the episode ``map`` (route from the start
    lane), ``seed``, ``scenario``, ``destination``, ``expert_speed`` (the
    expert's desired speed, NaN for a policy), highway-env ``frames`` (when
    rendered) and the wall-clock ``seconds``.
    """

    scenario: str
    seed: int
    destination: str | None
    map: Map
    poses: np.ndarray
    speeds: np.ndarray
    ado: np.ndarray
    ado_valid: np.ndarray
    lane_target: np.ndarray
    commands: np.ndarray
    actions: np.ndarray
    crashed: np.ndarray
    on_road: np.ndarray
    bev: np.ndarray | None = None
    expert_speed: float = float("nan")
    frames: list = field(default_factory=list)
    seconds: float = 0.0

    @property
    def steps(self) -> int:
        return len(self.poses) - 1

    @property
    def controls(self) -> np.ndarray:
        """The logged controls ``(T, 2)``: ``[speeds[t+1], wrap(yaw[t+1] − yaw[t]) / DT]``.

        The speed reached at the end of the step and the mean yaw rate over it:
        exactly what :func:`controls_to_action` realises (its P-controller
        reaches the commanded speed at the end of the step, its steering the
        yaw rate), so replaying an expert's controls through the adapter
        reproduces the expert (:func:`replay_error`). The chapter-7 unicycle
        replay of these controls is close but not exact: highway-env's bicycle
        slips sideways (β) in turns and accelerates within the step.
        """
        yaw_rate = wrap_angle(np.diff(self.poses[:, 2])) / DT
        return np.stack([self.speeds[1:], yaw_rate], axis=-1)

    @property
    def collided(self) -> bool:
        return bool(self.crashed.any())


PolicyFn = Callable[[dict], np.ndarray]
"""A plain policy: observation dict (see :func:`run_episode`) → controls ``[speed, yaw_rate]``."""


def _past(runs: list[EpisodeRun], steps: int) -> History:
    """The :class:`minimanc.world.history.History` of ``steps`` past steps of the runs'
    current frames (driven in lock-step): the ego's poses and the ados' boxes each run
    recorded, none before its first step (:func:`minimanc.world.history.latest_history`,
    as the world's closed loop keeps them)."""
    rec = [r.rec for r in runs]
    return latest_history(np.stack([np.array(r["poses"]) for r in rec]),
                          np.stack([np.array(r["ado"]) for r in rec]),
                          np.stack([np.array(r["valid"]) for r in rec]), steps)


class EpisodeRun:
    """One env driven step by step (the expert or a policy), recording an :class:`Episode`.

    Its BEV (``record_bev``) is drawn with ``cfg`` from the ego's pose on the map whose
    route runs from the ego's current lane (:class:`RouteTracker`), with the past steps
    ``cfg.history`` asks for from what this run recorded.
    """

    def __init__(self, scenario: str, seed: int, steps: int, expert: bool,
                 cfg: RasterConfig, max_ado: int, record_bev: bool, render: bool,
                 config: dict | None, expert_speed: float | None,
                 goal: np.ndarray | None) -> None:
        self.t0 = time.perf_counter()
        self.scenario, self.seed, self.expert = scenario, int(seed), expert
        self.cfg, self.max_ado, self.record_bev, self.render = cfg, max_ado, record_bev, render
        self.env = make_env(scenario, steps=steps, render=render, config=config)
        self.env.reset(seed=int(seed))
        self.map = road_map(self.env, scenario)
        self.tracker = RouteTracker(self.env, self.map)
        self.expert_speed = float("nan")
        if expert:
            lo, hi = EXPERT_SPEEDS[scenario]
            self.expert_speed = (float(np.random.default_rng(int(seed)).uniform(lo, hi))
                                 if expert_speed is None else float(expert_speed))
            install_expert(self.env, self.expert_speed)
        self.adapter = ActionAdapter(self.env)
        self.goal = None if goal is None else np.asarray(goal, dtype=np.float64)
        self.rec: dict[str, list] = {k: [] for k in ("poses", "speeds", "ado", "valid", "targets",
                                                     "bev", "crashed", "on_road", "commands",
                                                     "actions", "frames")}
        self.obs = self._record()

    def _record(self) -> dict:
        env, rec = self.env, self.rec
        pose = ego_pose(env)
        ado, valid = ado_boxes(env, self.max_ado)
        m_t = self.tracker.map_for(pose)
        rec["poses"].append(pose)
        rec["speeds"].append(float(env.vehicle.speed))
        rec["ado"].append(ado)
        rec["valid"].append(valid)
        rec["targets"].append(lane_targets(m_t, pose, K_TARGETS))
        rec["crashed"].append(bool(env.vehicle.crashed))
        rec["on_road"].append(bool(env.vehicle.on_road))
        if self.record_bev:
            rec["bev"].append(self.bev(m_t, pose, ado, valid))
        if self.render:
            rec["frames"].append(render_frame(env))
        return {"pose": pose, "map": m_t, "ado": ado, "ado_valid": valid,
                "speed": float(env.vehicle.speed)}

    def bev(self, m_t: Map, pose: np.ndarray, ado: np.ndarray, valid: np.ndarray
            ) -> np.ndarray:
        """The raster of the last recorded state (``cfg``; with its past when
        ``cfg.history > 0``), as stored."""
        past = _past([self], self.cfg.history) if self.cfg.history else None
        return rasterize(m_t, pose, ado, valid, self.cfg, history=past)

    def step(self, controls: np.ndarray | None) -> None:
        if controls is None:
            self.rec["commands"].append(np.full(2, np.nan))
            self.rec["actions"].append(np.full(2, np.nan, np.float32))
            self.env.step(None)
        else:
            u = np.asarray(controls, dtype=np.float64).reshape(2)
            action = self.adapter(u)
            self.rec["commands"].append(u)
            self.rec["actions"].append(action)
            self.env.step(action)
        self.obs = self._record()

    def finish(self) -> Episode:
        rec = self.rec
        ep = Episode(
            scenario=self.scenario, seed=self.seed,
            destination=getattr(self.env, "destination", None), map=self.map,
            poses=np.array(rec["poses"]), speeds=np.array(rec["speeds"]),
            ado=np.array(rec["ado"]), ado_valid=np.array(rec["valid"]),
            lane_target=np.array(rec["targets"]),
            commands=np.array(rec["commands"]).reshape(-1, 2),
            actions=np.array(rec["actions"], np.float32).reshape(-1, 2),
            crashed=np.array(rec["crashed"]), on_road=np.array(rec["on_road"]),
            bev=np.array(rec["bev"], dtype=np.uint8) if self.record_bev else None,
            expert_speed=self.expert_speed, frames=rec["frames"],
            seconds=time.perf_counter() - self.t0,
        )
        self.env.close()
        return ep


class HighwaySim:
    """highway-env as a :class:`minimanc.rollout.Simulator`: one env per row, in lock-step.

    Row ``i`` is the episode ``env.reset(seed=seeds[i])`` of ``scenario``
    (``steps`` the env's duration) recorded by an :class:`EpisodeRun`;
    ``goals (B, 3)`` the goal world poses (a row's ``None``: its start pose);
    ``raster`` the :class:`RasterConfig` of the policy's BEV (default ``cfg``,
    the one the episode's BEV is recorded with; its past steps, ``raster.history``, are
    those each row recorded), ``k_targets`` its lane-target
    points. The ego's motion at the start is ``[speed, 0]``; controls go
    through :class:`ActionAdapter`. :meth:`finish` closes the envs and returns
    the :class:`Episode` of each row.
    """

    def __init__(self, scenario: str, seeds: Any, steps: int, goals: Any = None,
                 cfg: RasterConfig | None = None, max_ado: int = MAX_ADO,
                 record_bev: bool = False, render: bool = False, config: dict | None = None,
                 raster: RasterConfig | None = None, k_targets: int | None = K_TARGETS) -> None:
        check_scenario(scenario)
        self.seeds = [int(s) for s in np.atleast_1d(seeds)]
        if len(self.seeds) == 0:
            raise ValueError(f"seeds must hold at least one seed; got seeds={seeds!r}")
        self.goals = [None] * len(self.seeds) if goals is None else list(goals)
        if len(self.goals) != len(self.seeds):
            raise ValueError(f"goals must have {len(self.seeds)} entries; got {len(self.goals)}")
        self.scenario, self.steps = scenario, int(steps)
        self.cfg = cfg or RasterConfig()
        self.raster = raster or self.cfg
        self.k_targets = k_targets
        self.scenes = np.arange(len(self.seeds))
        self._run_args = (max_ado, record_bev, render, config)
        self.runs: list[EpisodeRun] = []

    def reset(self) -> np.ndarray:
        max_ado, record_bev, render, config = self._run_args
        self.runs = [EpisodeRun(self.scenario, seed, self.steps, False, self.cfg, max_ado,
                                record_bev, render, config, None, goal)
                     for seed, goal in zip(self.seeds, self.goals)]
        self.goal = np.stack([r.rec["poses"][0] if r.goal is None else r.goal
                              for r in self.runs])
        return np.array([[r.rec["speeds"][0], 0.0] for r in self.runs], dtype=np.float32)

    def observe(self) -> SceneState:
        obs = [r.obs for r in self.runs]
        past = _past(self.runs, self.raster.history) if self.raster.history else None
        return SceneState([o["map"] for o in obs], np.stack([o["pose"] for o in obs]),
                          np.stack([o["ado"] for o in obs]),
                          np.stack([o["ado_valid"] for o in obs]), self.goal, past)

    def step(self, controls: np.ndarray) -> None:
        for r, u in zip(self.runs, controls):
            r.step(u)

    def finish(self) -> list[Episode]:
        return [r.finish() for r in self.runs]


class FunctionPolicy:
    """A :data:`PolicyFn` as a :class:`minimanc.rollout.Policy` in a one-row :class:`HighwaySim`.

    It asks :func:`minimanc.rollout.drive` for no observation key and hands
    ``fn`` the observation of :func:`run_episode` read from the episode being
    recorded: ``bev`` (uint8), ``goal``, ``lane_target`` and ``motion`` (the
    previous command, at ``t = 0`` ``[speed, 0]``) in float64.
    """

    model = None
    setting = "paper"
    keys: tuple[str, ...] = ()

    def __init__(self, fn: PolicyFn, sim: HighwaySim) -> None:
        self.fn, self.sim = fn, sim

    def initial_state(self, scenes: np.ndarray) -> None:
        return None

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        run = self.sim.runs[0]
        o, rec = run.obs, run.rec
        bev = rec["bev"][-1] if run.record_bev else run.bev(o["map"], o["pose"], o["ado"],
                                                            o["ado_valid"])
        motion = rec["commands"][-1] if rec["commands"] else np.array([rec["speeds"][0], 0.0])
        full = {**o, "bev": bev, "t": t, "goal": goal_in_ego_frame(self.sim.goal[0], o["pose"]),
                "lane_target": rec["targets"][-1], "motion": np.array(motion, dtype=np.float64)}
        return np.asarray(self.fn(full), dtype=np.float64).reshape(1, -1), state, {}


class PlainPolicy:
    """A chapter-9 policy for one ego as a :data:`PolicyFn` (made by ``plain_policy``).

    :func:`run_episode` drives ``policy`` itself (:func:`minimanc.rollout.drive`
    in a one-row :class:`HighwaySim` with this ``goal``, raster ``cfg`` and
    ``k_targets``); calling it with :func:`run_episode`'s observation builds the
    same observation (:func:`minimanc.rollout.observation`) and carries the
    policy's state, restarting it at ``t = 0``.
    """

    def __init__(self, policy: Any, goal: np.ndarray, cfg: RasterConfig | None = None) -> None:
        self.policy = policy
        self.goal = np.asarray(goal, dtype=np.float64).reshape(3)
        self.cfg = cfg or RasterConfig()
        self.k_targets = getattr(getattr(policy, "cfg", None), "k_targets", K_TARGETS)
        self.state = policy.initial_state(np.arange(1))

    def __call__(self, obs: dict) -> np.ndarray:
        t = int(obs["t"])
        if t == 0:
            self.state = self.policy.initial_state(np.arange(1))
        scene = SceneState([obs["map"]], obs["pose"][None], obs["ado"][None],
                           obs["ado_valid"][None], self.goal[None])
        o = observation(self.policy, scene, np.asarray(obs["motion"], np.float32)[None],
                        self.cfg, self.k_targets)
        u, self.state, _ = self.policy(o, self.state, t, np.arange(1))
        return check_controls(u, 1, t, self.policy)[0]


def run_episode(
    scenario: str,
    seed: int,
    policy: PolicyFn | str = "expert",
    steps: int = DEFAULT_STEPS,
    goal: np.ndarray | None = None,
    cfg: RasterConfig | None = None,
    max_ado: int = MAX_ADO,
    record_bev: bool = True,
    render: bool = False,
    config: dict | None = None,
    expert_speed: float | None = None,
) -> Episode:
    """Run one episode of ``steps`` actions from ``env.reset(seed=seed)``.

    ``policy="expert"`` drives with highway-env's IDM/MOBIL (:func:`install_expert`;
    desired speed ``expert_speed``, by default drawn from
    :data:`EXPERT_SPEEDS` with ``numpy.random.default_rng(seed)``).
    Otherwise ``policy(obs)`` is called every step with ``obs = {"bev",
    "goal", "lane_target", "motion", "pose", "speed", "map", "ado",
    "ado_valid", "t"}`` — the chapter-8 observation of one ego (unbatched:
    ``bev`` uint8 ``cfg.shape`` as stored, ``goal`` the world pose ``goal`` (typically the
    expert's final pose of the same seed; default the start pose) in the
    current ego frame, ``lane_target`` (K, 2), ``motion`` the previous
    command) — and its ``[speed, yaw rate]`` goes through
    :class:`ActionAdapter`. The episode runs to the end even after a crash
    (highway-env then brakes the ego to a stop). ``render=True`` keeps
    highway-env's frames in ``Episode.frames``. A policy is driven by
    :func:`minimanc.rollout.drive` in a one-row :class:`HighwaySim` (a
    chapter-9 policy wrapped by :func:`minimanc.highway.plain_policy` directly,
    with the observation of :func:`minimanc.highway.drive_episodes`).
    """
    check_scenario(scenario)
    check_steps(steps)
    if not (callable(policy) or policy == "expert"):
        raise ValueError(f"policy must be 'expert' or a callable, got {policy!r}")
    cfg = cfg or RasterConfig()
    if policy == "expert":
        run = EpisodeRun(scenario, seed, int(steps), True, cfg, max_ado, record_bev, render,
                         config, expert_speed, goal)
        for _ in range(int(steps)):
            run.step(None)
        return run.finish()
    if isinstance(policy, PlainPolicy):  # a chapter-9 policy: drive it directly
        sim = HighwaySim(scenario, [seed], int(steps), [policy.goal], cfg, max_ado, record_bev,
                         render, config, raster=policy.cfg, k_targets=policy.k_targets)
        drive(policy.policy, sim, int(steps))
    else:
        sim = HighwaySim(scenario, [seed], int(steps), [goal], cfg, max_ado, record_bev, render,
                         config)
        drive(FunctionPolicy(policy, sim), sim, int(steps))
    return sim.finish()[0]


def check_steps(steps: Any) -> int:
    """``steps`` as an int if it is an integer >= 2, else ``ValueError``."""
    return check_int("steps", steps, 2)


def replay_error(episode: Episode) -> float:
    """ADE (m) between an expert episode and the replay of its logged controls.

    The controls (:attr:`Episode.controls`) are sent through
    :class:`ActionAdapter` from the same seed; a small value means the
    adapter inverts the logging, so that a perfect imitator would reproduce
    the expert. (Traffic reacts to the ego, so tiny deviations can grow.)
    """
    u = episode.controls
    rp = run_episode(episode.scenario, episode.seed, lambda obs: u[obs["t"]],
                     steps=episode.steps, record_bev=False)
    return float(np.linalg.norm(rp.poses[:, :2] - episode.poses[:, :2], axis=1).mean())

