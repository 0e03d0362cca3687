"""Chapter 9 — reactive traffic: the world's ados react to the policy's ego.

The paper's protocol replays the ados from the log (:class:`minimanc.rollout.LogReplay`):
an ado that braked for the human in the log brakes at the same time whatever the
policy does, so a policy ego a little slower than the human is rear-ended by a
follower that "does not see it". nuPlan reports a second protocol for this reason,
with reactive (IDM) agents. Here the reactive agents are the world's own: the ados
are driven by the same IDM / junction-yielding / gap-acceptance / cut-in rules that
generated the data (:class:`minimanc.world.traffic.Traffic`), with the policy's ego
as the vehicle they follow, yield to and cut in front of.

**Start.** Every scene of a dataset made by :func:`minimanc.world.generate` is
re-simulated from its seed: scene ``i`` of run ``seed`` was drawn from the stream
``default_rng([seed, scene_index, attempt])`` (:func:`scene_stream`), so the scene's
setup (:class:`minimanc.world.driver.SceneRun`) gives back the logged state at
``t = 0``: every ado with its path, speed and IDM parameters. The ego starts at the
logged pose ``ego[:, 0]`` with the logged initial speed, as in the log replay.

**Arrivals.** Ados that enter later (the Poisson arrivals at the map's entries) are
taken from the human's own run of the scene (:func:`record_human`): the same vehicle
(size, parameters, route) enters at the same step, whatever the policy does, so the
traffic demand is the log's. An arrival whose entry is not clear (another ado within
16 m, the world's own spawning rule) waits until it is. A cut-in ado that gives up
its cut-in continues on the walk it took in the log (if it gave up in the log; else
on a walk drawn from a stream of its own).

**Oracle.** Driven with the human's logged controls, the reactive simulation is the
log: the ados' boxes equal the logged ones to float32 rounding (``tests/test_reactive.py``
measures it), and there are no collisions.

:class:`ReactiveSim` implements :class:`minimanc.rollout.Simulator`;
``minimanc.rollout.simulate(policy, ds, agents="reactive")`` runs any
:class:`minimanc.rollout.Policy` in it and returns a :class:`minimanc.rollout.Rollout` that
also holds the ados as they were simulated (the metrics then use them instead of the log's);
:class:`LoggedControls` is the human's log as such a policy.
"""

from __future__ import annotations

import copy
import json
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np

from minimanc import inputs
from minimanc.rollout.driver import SceneState
from minimanc.rollout.log import AGENTS, k_targets_of
from minimanc.world.driver import SceneRun
from minimanc.world.generation import scene_stream
from minimanc.world.geometry import DT
from minimanc.world.history import latest_history
from minimanc.world.lanes import Map
from minimanc.world.paths import Vehicle
from minimanc.world.roads import build_map

__all__ = [
    "AGENTS",
    "SPAWN_CLEARANCE",
    "HumanRecord",
    "LoggedControls",
    "ReactiveSim",
    "SceneKey",
    "record_human",
    "scene_key",
    "scene_stream",
    "start_scene",
]

SPAWN_CLEARANCE: float = 16.0
"""An arrival enters only when no ado is within this distance (m) of its entry point
(the radius :meth:`minimanc.world.traffic.Traffic.spawn` uses)."""


# --------------------------------------------------------------------------- scene streams


@dataclass(frozen=True)
class SceneKey:
    """What identifies one generated scene: its run ``seed``, its ``index`` in that run,
    the ``attempt`` that was kept, the number of ado slots, steps and the step length."""

    seed: int
    index: int
    attempt: int
    max_ados: int
    steps: int
    dt: float


def _check_ds(ds: Any) -> tuple[int, int]:
    for key in ("ego", "controls", "ado", "ado_valid", "maps", "meta"):
        if not hasattr(ds, key):
            raise ValueError(f"ds must be a minimanc.world dataset with .{key}; got {type(ds)!r}")
    ego = np.asarray(ds.ego)
    if ego.ndim != 3 or ego.shape[-1] != 3 or ego.shape[1] < 2:
        raise ValueError(f"ds.ego must have shape (S, T >= 2, 3); got shape {ego.shape}")
    for key in ("seed", "scene_index", "attempts", "recipes"):
        if key not in ds.meta:
            raise ValueError(f"ds.meta has no {key!r}: reactive traffic needs a dataset made "
                             "by minimanc.world.generate")
    return ego.shape[0], ego.shape[1]


def _scenes(scenes: Any, S: int) -> np.ndarray:
    if scenes is None:
        return np.arange(S)
    idx = np.atleast_1d(np.asarray(scenes))
    if idx.ndim != 1 or idx.size == 0 or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"scenes must be a non-empty 1-D array of integers; got scenes={scenes!r}")
    if idx.min() < 0 or idx.max() >= S:
        raise ValueError(f"scenes must lie in [0, {S}); got scenes={scenes!r}")
    return idx.astype(np.int64)


def scene_key(ds: Any, i: int) -> SceneKey:
    """The :class:`SceneKey` of row ``i`` of ``ds`` (from ``ds.meta``)."""
    S, T = _check_ds(ds)
    if not (isinstance(i, int | np.integer) and 0 <= i < S):
        raise ValueError(f"i must be a scene index in [0, {S}); got i={i!r}")
    meta = ds.meta
    return SceneKey(int(meta["seed"]), int(meta["scene_index"][i]), int(meta["attempts"][i]) - 1,
                    int(np.asarray(ds.ado).shape[2]), T, float(meta.get("dt", DT)))


def start_scene(key: SceneKey, m: Map | None = None, recipe: dict | None = None) -> SceneRun:
    """The scene ``key`` at ``t = 0``, exactly as the world's generator started it.

    ``m`` the scene's map (built from the stream's recipe when ``None``); ``recipe``
    the recipe the dataset recorded, checked against the stream's (``ValueError``
    when they differ: the dataset was not generated by this version of the world).
    """
    rng, drawn = scene_stream(key.seed, key.index, key.attempt)
    if recipe is not None and json.dumps(drawn, sort_keys=True) != json.dumps(
            recipe, sort_keys=True):
        raise ValueError(f"scene {key.index} of seed {key.seed} (attempt {key.attempt}) does "
                         "not regenerate the dataset's map recipe: the dataset was made by "
                         "another version of minimanc.world")
    if m is None:
        m = build_map(drawn)
    return SceneRun(m, rng, key.dt, key.max_ados)


# --------------------------------------------------------------------------- the human's run


@dataclass
class HumanRecord:
    """What the human's run of a scene decides outside the ados' rules.

    ``arrivals[t]`` the ados that entered after step ``t`` (copies at their entry,
    with the lanes of their path), ``walks`` the lane walks taken by cut-in ados that
    gave up (by vehicle index), and the run's logs ``ego (T, 3)``, ``controls (T, 2)``,
    ``ado (T, A, 5)``, ``ado_valid (T, A)`` (float64, before the dataset's float32).
    """

    key: SceneKey
    arrivals: list[list[tuple[Vehicle, list[int]]]]
    walks: dict[int, list[int]]
    ego: np.ndarray
    controls: np.ndarray
    ado: np.ndarray
    ado_valid: np.ndarray


_RECORDS: OrderedDict = OrderedDict()
_RECORDS_SIZE = 1024


def record_human(ds: Any, i: int) -> HumanRecord:
    """Re-run the human's scene ``i`` of ``ds`` and record its arrivals (cached per scene).

    Raises ``ValueError`` when the run does not reproduce the dataset's logged ego
    poses and ado boxes exactly (after the dataset's float32 rounding).
    """
    key = scene_key(ds, i)
    rec = _RECORDS.get(key)
    if rec is not None:
        _RECORDS.move_to_end(key)
    else:
        rec = _record(key, ds.maps[i], ds.meta["recipes"][i])
        _RECORDS[key] = rec
        if len(_RECORDS) > _RECORDS_SIZE:
            _RECORDS.popitem(last=False)
    valid = rec.ado_valid
    same = (np.array_equal(rec.ego.astype(np.float32), np.asarray(ds.ego[i]))
            and np.array_equal(rec.controls.astype(np.float32), np.asarray(ds.controls[i]))
            and np.array_equal(valid, np.asarray(ds.ado_valid[i]))
            and np.array_equal(np.where(valid[..., None], rec.ado, 0.0).astype(np.float32),
                               np.where(valid[..., None], np.asarray(ds.ado[i]), 0.0)))
    if not same:
        raise ValueError(f"scene {i} of ds (seed {key.seed}, index {key.index}) does not "
                         "regenerate its log: the dataset was made by another version of "
                         "minimanc.world")
    return rec


def _record(key: SceneKey, m: Map, recipe: dict) -> HumanRecord:
    run = start_scene(key, m, recipe)
    run.traffic.walk_log = {}
    arrivals: list[list[tuple[Vehicle, list[int]]]] = []

    def spawner(r: SceneRun) -> None:
        n = len(r.traffic.vehicles)
        r.spawn_arrivals()
        arrivals.append([(copy.deepcopy(v), list(r.traffic.path(v).lanes))
                         for v in r.traffic.vehicles[n:]])

    run.spawner = spawner
    T, A = key.steps, key.max_ados
    ego, ctl = np.zeros((T, 3)), np.zeros((T, 2))
    ado, valid = np.zeros((T, A, 5)), np.zeros((T, A), bool)
    for t in range(T):
        ego[t] = run.pose
        ado[t], valid[t] = run.ado_boxes()
        ctl[t] = run.human_step()
    return HumanRecord(key, arrivals, dict(run.traffic.walk_log), ego, ctl, ado, valid)


# --------------------------------------------------------------------------- the simulator


class ReactiveSim:
    """The world with reactive ados as a :class:`minimanc.rollout.Simulator`.

    ``ds`` a dataset made by :func:`minimanc.world.generate` (or a subset or split of
    one), ``scenes`` the dataset indices of the batch rows (default: all). See the
    module docstring for the start, the arrivals and what the ados react to. After
    :meth:`reset`, :attr:`runs` holds one live :class:`minimanc.world.driver.SceneRun`
    per row (the ego in it is the policy's); :meth:`trajectory` gives the ego poses so
    far ``(B, t + 1, 3)`` and :meth:`ado_trajectory` the ado boxes ``(B, t + 1, A, 5)``
    and their valid flags ``(B, t + 1, A)``.
    """

    def __init__(self, ds: Any, scenes: Any = None) -> None:
        S, self.T = _check_ds(ds)
        self.scenes = _scenes(scenes, S)
        self.raster = inputs.raster_of(ds)
        self.k_targets = k_targets_of(ds)
        self._ds = ds
        self._records = [record_human(ds, int(i)) for i in self.scenes]
        ego = np.asarray(ds.ego, dtype=np.float64)[self.scenes]
        self._start, self._goal = ego[:, 0], ego[:, -1]
        self._motion0 = inputs.initial_motion(ds)[self.scenes]
        self._maps = [ds.maps[int(s)] for s in self.scenes]
        self.runs: list[SceneRun] = []
        self._queues: list[list[tuple[Vehicle, list[int]]]] = []
        self._poses: list[np.ndarray] = []
        self._ado: list[np.ndarray] = []
        self._valid: list[np.ndarray] = []

    def _arrive(self, b: int, run: SceneRun) -> None:
        """The spawner of row ``b``: the log's arrivals of this step, when their entry is clear."""
        rec = self._records[b]
        queue = self._queues[b]
        if run.t < len(rec.arrivals):
            queue.extend(rec.arrivals[run.t])
        tr = run.traffic
        waiting = []
        for veh, lanes in queue:
            entry = tr.m.lanes[lanes[0]].points[0]
            if len(tr.vehicles) - 1 < tr.max_ados and tr.clear_of(entry, SPAWN_CLEARANCE):
                tr.insert(veh, lanes)
            else:
                waiting.append((veh, lanes))
        queue[:] = waiting

    def _observe_ados(self) -> None:
        boxes, valid = zip(*(run.ado_boxes() for run in self.runs))
        self._ado.append(np.stack(boxes))
        self._valid.append(np.stack(valid))

    def reset(self) -> np.ndarray:
        self.runs, self._queues = [], []
        for b, (rec, m) in enumerate(zip(self._records, self._maps)):
            run = start_scene(rec.key, m)
            # cut-in ados that give up do so along the log's walk; others draw their own
            run.traffic.scripted_walks = rec.walks
            run.traffic.rng = np.random.default_rng(
                [rec.key.seed, rec.key.index, rec.key.attempt, 1])
            run.pose = self._start[b].copy()
            run.ego.xy, run.ego.yaw = run.pose[:2].copy(), float(run.pose[2])
            run.spawner = lambda r, b=b: self._arrive(b, r)
            self.runs.append(run)
            self._queues.append([])
        self._poses = [self._start.copy()]
        self._ado, self._valid = [], []
        self._observe_ados()
        return self._motion0

    def observe(self) -> SceneState:
        t = len(self._poses) - 1
        if not self.runs:
            raise ValueError("call reset() before observe()")
        if t >= self.T:
            raise ValueError(f"the scenes have {self.T} steps; no observation at step {t}")
        past = None
        if self.raster.history:
            past = latest_history(np.stack(self._poses, axis=1), np.stack(self._ado, axis=1),
                                  np.stack(self._valid, axis=1), self.raster.history)
        return SceneState(self._maps, self._poses[-1], self._ado[-1], self._valid[-1],
                          self._goal, past)

    def step(self, controls: np.ndarray) -> None:
        u = np.asarray(controls, dtype=np.float64)
        if u.shape != (len(self.runs), 2) or not np.all(np.isfinite(u)):
            raise ValueError(f"controls must be finite with shape ({len(self.runs)}, 2); got "
                             f"shape {u.shape}")
        for run, (v, w) in zip(self.runs, u.tolist()):
            per = run.perceive()
            run.advance(per, v, w)
        self._poses.append(np.stack([run.pose for run in self.runs]))
        self._observe_ados()

    def trajectory(self) -> np.ndarray:
        return np.stack(self._poses, axis=1)

    def ado_trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        return np.stack(self._ado, axis=1), np.stack(self._valid, axis=1)


class LoggedControls:
    """A :class:`minimanc.rollout.Policy` that applies the human's logged controls of ``ds``
    (reads no observation but its motion): the human replay as a policy."""

    model = None
    setting = "paper"
    keys = ("motion",)

    def __init__(self, ds: Any) -> None:
        self.controls = np.asarray(ds.controls, dtype=np.float64)

    def initial_state(self, scenes: np.ndarray) -> None:
        return None

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        return self.controls[np.asarray(scenes), t], state, {}
