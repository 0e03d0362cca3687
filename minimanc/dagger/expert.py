"""Chapter 11 — ask the world's driver: the human's controls in any state (a DAgger teacher).

Behaviour cloning only ever sees the states the human visited; DAgger (Ross, Gordon &
Bagnell 2011) asks an expert what to do in the states the *policy* visits. The world's
expert is its own human driver (:class:`minimanc.world.driver.HumanDriver`): its
:meth:`~minimanc.world.driver.HumanDriver.act` gives the controls for any ego state,
given what the driver perceives there (the leader in its corridor, the junction stop
point where it must yield, the curves ahead: :meth:`minimanc.world.traffic.Traffic.perceive`).

:class:`HumanExpert` answers "what would the human do here" for scene ``s`` of a
dataset at step ``t``, from an arbitrary ego pose ``(x, y, yaw)`` and speed:

* the **driver** is the human of that scene as it was at step ``t`` of its own run
  (re-simulated from the scene's seed, :mod:`minimanc.rollout.reactive`): its style, the
  wandering desired speed and lateral offset at ``t`` (the same random draws), its
  reaction-delay memory and its last acceleration (the human's own history);
* the **ados** are those of that simulation step: by default the log's (the human's
  run at step ``t``: the replay protocol), or the ados of a live simulation passed as
  ``traffic`` (e.g. ``ReactiveSim.runs[b].traffic``, the reactive protocol); they are
  read, never changed;
* the **ego** is put at the given pose and speed, on its route at the projection of the
  pose (:func:`minimanc.world.driver.project_on_path`).

On the logged states (the human's pose and speed at ``t``) it returns the logged
controls: exactly for the run's float64 states, to float32 rounding for the dataset's
(``tests/test_expert.py`` states the tolerances). It refuses, with a ``ValueError``, a
state it cannot label: not finite, a negative speed, off the drivable area, farther than
:data:`MAX_OFFSET` from the route or heading more than 90° away from it.
"""

from __future__ import annotations

import copy
import math
from collections import OrderedDict
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from minimanc.checks import check_int
from minimanc.rollout.reactive import SceneKey, record_human, scene_key, start_scene
from minimanc.world.driver import HumanDriver, project_on_path
from minimanc.world.geometry import wrap_angle
from minimanc.world.lanes import LANE_WIDTH, Map
from minimanc.world.maps import project_to_route
from minimanc.world.traffic import Path, Traffic, Vehicle

__all__ = ["MAX_OFFSET", "RUNS_KEPT", "DriverStep", "HumanExpert", "Situation", "human_run"]

MAX_OFFSET: float = 2.0 * LANE_WIDTH
"""Largest lateral distance (m) from the route at which the driver can still be asked."""


@dataclass
class DriverStep:
    """The human's run of one scene at step ``t``: the driver before its decision, the
    traffic after the junction stamps of ``t`` (the ego first), and the ego's speed."""

    driver: HumanDriver
    traffic: Traffic
    speed: float


@dataclass
class Situation:
    """What the human perceives in one asked state: its run's ``step``, the ``ego``
    vehicle put at the asked ``pose`` and speed on its ``path``, ``perceived``, the
    binding constraints of :meth:`minimanc.world.traffic.Traffic.perceive` for the ego
    (``gap`` and ``v_lead`` of its leader, ``stop`` distance, ``a_curve``), and
    ``leader``, the vehicle it names as the leader (a copy; ``None`` without one)."""

    step: DriverStep
    ego: Vehicle
    path: Path
    pose: np.ndarray
    perceived: dict[str, float]
    leader: Vehicle | None = None


RUNS_KEPT = 700
"""How many scenes' runs (:func:`human_run`) a process keeps for every expert it makes: each
of a study's on-policy runs asks about the same training scenes, 650 at the paper's size. A
scene's run (its driver and traffic at each step) takes about 1.3 MB."""
_RUNS: OrderedDict = OrderedDict()


def human_run(key: SceneKey, m: Map) -> list[DriverStep]:
    """The human's run of the scene ``key`` (its map ``m``), one :class:`DriverStep` per step
    ``0 … key.steps − 1``: re-simulated on first use, then kept (:data:`RUNS_KEPT`, least
    recently used first out). Its steps are read, never changed: :meth:`HumanExpert.situation`
    and :meth:`HumanExpert.controls` work on copies."""
    hit = _RUNS.pop(key, None)
    if hit is None:
        run = start_scene(key, m)
        memo_base = {id(run.m): run.m, id(run.traffic.bank): run.traffic.bank}
        hit = []
        for t in range(key.steps):
            run.traffic.update_stamps(t)  # what SceneRun.perceive does first (idempotent)
            memo = dict(memo_base)
            driver = copy.deepcopy(run.driver, memo)
            traffic = copy.deepcopy(run.traffic, memo)
            hit.append(DriverStep(driver, traffic, float(run.ego.v)))
            run.human_step()
        if len(_RUNS) >= RUNS_KEPT:
            _RUNS.popitem(last=False)
    _RUNS[key] = hit
    return hit


class HumanExpert:
    """The world's human driver as an expert that can be asked in any state of ``ds``.

    ``ds`` a dataset made by :func:`minimanc.world.generate` (or a subset/split of one).
    The human's run of a scene is re-simulated on first use (:func:`human_run`, which every
    expert of the process shares); this expert keeps the runs it has checked against its
    dataset's log at hand (``cache`` scenes, least recently used first out), so that the log
    is compared once per scene, not at every question. See the module docstring.
    """

    def __init__(self, ds: Any, cache: int = 64) -> None:
        self.ds = ds
        self._S, self._T = np.asarray(ds.ego).shape[:2]
        self._cache_size = check_int("cache", cache, 1)
        self._runs: dict[int, list[DriverStep]] = {}

    # ------------------------------------------------------------------ the human's run
    def steps(self, scene: int) -> list[DriverStep]:
        """The human's run of ``scene``, one :class:`DriverStep` per step ``0 … T−1``."""
        if isinstance(scene, bool) or not isinstance(scene, int | np.integer) or not (
                0 <= scene < self._S):
            raise ValueError(f"scene must be an integer in [0, {self._S}); got scene={scene!r}")
        scene = int(scene)
        hit = self._runs.pop(scene, None)
        if hit is None:
            record_human(self.ds, scene)  # refuses a dataset that does not regenerate
            hit = human_run(scene_key(self.ds, scene), self.ds.maps[scene])
            if len(self._runs) >= self._cache_size:
                self._runs.pop(next(iter(self._runs)))
        self._runs[scene] = hit
        return hit

    # ------------------------------------------------------------------ asking
    def situation(self, scene: int, t: int, pose: Any, speed: float,
                  traffic: Traffic | None = None) -> Situation:
        """What the human perceives at step ``t`` of ``scene`` with the ego at
        ``pose = (x, y, yaw)`` moving at ``speed`` (arguments as :meth:`__call__`)."""
        steps = self.steps(scene)
        if isinstance(t, bool) or not isinstance(t, int | np.integer) or not 0 <= t < self._T:
            raise ValueError(f"t must be an integer in [0, {self._T}); got t={t!r}")
        p = np.asarray(pose, dtype=np.float64)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"pose must be a finite (x, y, yaw); got pose={pose!r}")
        if isinstance(speed, bool) or not isinstance(speed, int | float | np.integer |
                                                     np.floating) or not (
                math.isfinite(speed) and speed >= 0.0):
            raise ValueError(f"speed must be a finite number >= 0; got speed={speed!r}")
        step = steps[int(t)]
        m = step.driver.m
        if not bool(m.is_drivable(p[None, :2])[0]):
            raise ValueError(f"cannot label pose={p.tolist()} of scene {scene} at step {t}: "
                             "it is off the drivable area")
        s_ref, lat = project_to_route(m, p[:2], p[2])
        _, h_route = m.route_pose(s_ref)
        if abs(lat) > MAX_OFFSET or abs(float(wrap_angle(p[2] - h_route))) > math.pi / 2:
            raise ValueError(f"cannot label pose={p.tolist()} of scene {scene} at step {t}: "
                             f"{abs(lat):.1f} m from the route (at most {MAX_OFFSET:.1f} m) "
                             f"heading {float(wrap_angle(p[2] - h_route)):.2f} rad off it "
                             "(at most pi/2)")
        base = step.traffic if traffic is None else traffic
        path = base.path(base.vehicles[0])
        ego = replace(base.vehicles[0], xy=p[:2].copy(), yaw=float(p[2]), v=float(speed),
                      s=project_on_path(path, s_ref, p),
                      cut_in=None)
        world = copy.copy(base)  # perceive writes stamps and accepted gaps: on copies only
        world.vehicles = [ego] + [copy.copy(v) for v in base.vehicles[1:]]
        world.going = set(base.going)
        world.update_stamps(int(t))
        per = world.perceive()
        who = int(per["who"][0])
        return Situation(step, ego, path, p,
                         {k: float(per[k][0]) for k in ("gap", "v_lead", "stop", "a_curve")},
                         world.vehicles[who] if who >= 0 else None)

    def __call__(self, scene: int, t: int, pose: Any, speed: float,
                 traffic: Traffic | None = None) -> np.ndarray:
        """The controls ``[speed, yaw rate]`` (float64 ``(2,)``) the human would apply at
        step ``t`` of ``scene`` with the ego at ``pose = (x, y, yaw)`` moving at ``speed``.

        ``traffic``: the ados of that simulation step (a live
        :class:`minimanc.world.traffic.Traffic` whose ``vehicles[0]`` is the ego; it is
        not changed); default: the log's.
        """
        return self.controls(self.situation(scene, t, pose, speed, traffic))

    def controls(self, sit: Situation) -> np.ndarray:
        """The human's controls ``[speed, yaw rate]`` in a :class:`Situation` (its driver
        is copied, never advanced)."""
        driver = copy.deepcopy(sit.step.driver, {id(sit.step.driver.m): sit.step.driver.m})
        per = sit.perceived
        v, w, _ = driver.act(sit.ego, sit.path, sit.pose, per["gap"], per["v_lead"],
                             per["stop"], per["a_curve"])
        return np.array([v, w])

    def label(self, scenes: Any, t: int, poses: Any, speeds: Any,
              traffics: list[Traffic] | None = None) -> np.ndarray:
        """:meth:`__call__` for a batch: ``scenes (B,)``, ``poses (B, 3)``, ``speeds (B,)``
        (and ``traffics``, one per row, or ``None`` for the log's) → ``(B, 2)``."""
        sc = np.atleast_1d(np.asarray(scenes))
        P = np.asarray(poses, dtype=np.float64)
        V = np.atleast_1d(np.asarray(speeds, dtype=np.float64))
        if P.shape != (len(sc), 3) or V.shape != (len(sc),):
            raise ValueError(f"poses must have shape ({len(sc)}, 3) and speeds ({len(sc)},); "
                             f"got {P.shape} and {V.shape}")
        if traffics is not None and len(traffics) != len(sc):
            raise ValueError(f"traffics must hold one Traffic per row ({len(sc)}); got "
                             f"{len(traffics)}")
        return np.stack([self(int(s), t, P[b], float(V[b]),
                              None if traffics is None else traffics[b])
                         for b, s in enumerate(sc)])
