"""Chapter 10 — a highway-env sandbox: the same controller in a real driving simulator.

`highway-env <https://github.com/Farama-Foundation/HighwayEnv>`_ (an optional
dependency: ``pip install 'minimanc[highway]'``) simulates roundabouts,
intersections and highways with IDM/MOBIL traffic that *reacts* to the ego —
unlike the chapter-7 logs, where the ados replay their recorded paths. This
module connects it to the rest of the package without a second copy of
anything:

* **Map adapter** (:func:`road_map`): each lane of highway-env's road network
  is sampled once per episode with ``lane.position(s, 0)`` (every ~1 m) and
  ``lane.width_at(s)`` into a :class:`minimanc.world.maps.Map` — lane
  centrelines, one drivable strip per lane (half width = half the lane width,
  so "off-road" means what highway-env's ``on_road`` means) and the ego's route.
  The chapter-7 rasteriser then draws it unchanged.
* **Frames**: highway-env's y axis points *down* the screen, so its
  coordinates are left-handed as seen on screen. We mirror them,
  ``x_w = x``, ``y_w = -y``, ``yaw_w = -heading`` (:func:`to_world`), which
  gives the world's right-handed convention (x east, y north, yaw
  counter-clockwise), keeps right-hand traffic on the right and the
  roundabout counter-clockwise, and makes the BEV look like highway-env's own
  rendering turned heading-up.
* **BEV observation** (:class:`BEVObservation`): a gymnasium observation
  wrapper returning the chapter-7 ego-centric raster (same size, colours,
  ego pixel; :mod:`minimanc.world.raster`).
* **Action adapter** (:func:`controls_to_action`, :class:`ActionAdapter`):
  the package's controls ``[speed, yaw rate]`` (the output of MANC's DMP
  step, paper eqs. 10–11, integrated once; DT = 0.5 s) become highway-env's ``ContinuousAction``
  ``[acceleration, steering]`` on its kinematic bicycle.
* **Expert** (:class:`ExpertVehicle`, :func:`install_expert`): the ego is
  replaced by highway-env's own IDM/MOBIL vehicle following the route (plus
  gap acceptance at roundabout entries) — the "human" of this chapter — and
  :func:`collect` records collision-free episodes in the chapter-7 dataset
  format (``world.Dataset``, maps as explicit recipes, so ``world.save`` /
  ``world.load`` and ``minimanc.train`` work unchanged). The logged controls
  are the speed reached at ``t + 1`` and the mean yaw rate over the step —
  what the action adapter realises (:attr:`Episode.controls`).
* **Closed loop** (:func:`closed_loop`): any chapter-9 policy
  (:class:`minimanc.rollout.ModelPolicy` for MANC and the baselines) drives
  the ego, observations from :func:`minimanc.inputs.from_state`; metrics
  (:attr:`ClosedLoopResult.metrics`): collision rate (highway-env's
  ``crashed``), off-road rate (:func:`minimanc.metrics.off_road`), ADE to the
  expert of the same seed (:func:`minimanc.metrics.ade`), mean speed and
  episodes per second.
* **Rendering**: headless with ``SDL_VIDEODRIVER=offscreen`` (``dummy`` gives
  black frames), frames to PNG and an episode to GIF (:func:`render_episode`).

Time step: the policy acts every ``DT = 0.5`` s (``policy_frequency = 2``),
highway-env integrates at ``simulation_frequency = 10`` Hz (5 sub-steps per
action). Same seed → bit-identical episodes.
"""

from __future__ import annotations

import os

if os.environ.get("SDL_VIDEODRIVER", "") in ("", "dummy"):
    # "dummy" renders black frames; "offscreen" renders real pixels without a display.
    os.environ["SDL_VIDEODRIVER"] = "offscreen"
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

try:
    import gymnasium as gym
    import highway_env  # noqa: F401  (registers the environments)
    from gymnasium import spaces
    from highway_env.envs.common.observation import ObservationType
    from highway_env.envs.highway_env import HighwayEnvFast
    from highway_env.envs.intersection_env import ConnectedLaneIntersectionEnv
    from highway_env.envs.roundabout_env import ConnectedLaneRoundaboutEnv
    from highway_env.road.lane import CircularLane, SineLane, StraightLane
    from highway_env.vehicle.behavior import IDMVehicle
except ImportError as exc:  # pragma: no cover - exercised with a monkeypatched sys.modules
    raise ImportError(
        "minimanc.highway needs the optional dependency highway-env (and gymnasium); "
        "install it with: pip install 'minimanc[highway]'"
    ) from exc

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from minimanc.world.geometry import (
    DT,
    goal_in_ego_frame,
    wrap_angle,
)
from minimanc.world.maps import (
    EXPLICIT_KIND,
    K_TARGETS,
    Lane,
    Map,
    build_map,
    concat_lanes,
    lane_targets,
    project_to_route,
)
from minimanc.world.raster import RasterConfig, rasterize

__all__ = [
    "SCENARIOS",
    "ENV_IDS",
    "POLICY_FREQUENCY",
    "SIMULATION_FREQUENCY",
    "DEFAULT_STEPS",
    "MAX_ADO",
    "make_env",
    "to_world",
    "ego_pose",
    "ado_boxes",
    "road_map",
    "map_recipe",
    "explicit_map",
    "RouteTracker",
    "BEVObservation",
    "controls_to_action",
    "ActionAdapter",
    "EXPERT_SPEEDS",
    "EVAL_SEED",
    "ExpertVehicle",
    "install_expert",
    "Episode",
    "run_episode",
    "replay_error",
    "expert_episodes",
    "to_dataset",
    "collect",
    "ClosedLoopResult",
    "closed_loop",
    "expert_result",
    "plain_policy",
    "render_frame",
    "save_png",
    "save_gif",
    "render_episode",
]

POLICY_FREQUENCY = 2
"""Actions per second: one action every ``DT = 0.5`` s, as in the chapter-7 logs."""
SIMULATION_FREQUENCY = 10
"""highway-env integration rate (Hz): 5 sub-steps of 0.1 s per action."""
DEFAULT_STEPS = 24
"""Steps per episode (12 s at 2 Hz): the roundabout and intersection tasks take ~11-13 s."""
MAX_ADO = 16
"""Ado vehicles kept per step (the nearest ones), as ``(A, 5)`` boxes."""

ENV_IDS = {
    "roundabout": "roundabout-v1",
    "intersection": "intersection-v2",
    "highway-fast": "highway-fast-v0",
}
"""highway-env ids the three sandbox scenarios are built on."""


# --------------------------------------------------------------------------- environments


class EgoStateObservation(ObservationType):
    """The env's raw observation here: the ego's world pose and speed ``[x, y, yaw, v]`` float32.

    highway-env's default ``Kinematics`` observation builds a pandas table of
    all vehicles every step (a third of the intersection's step time); the
    sandbox replaces it with this, and :class:`BEVObservation` turns the scene
    into the chapter-7 raster.
    """

    def space(self) -> spaces.Space:
        return spaces.Box(-np.inf, np.inf, shape=(4,), dtype=np.float32)

    def observe(self) -> np.ndarray:
        v = self.observer_vehicle
        xy, yaw = to_world(v.position, v.heading)
        return np.array([xy[0], xy[1], yaw, v.speed], dtype=np.float32)


class _Sandbox:
    """Mixin for the sandbox envs: cheap ego-state observation, ``destination`` attribute."""

    destination: str | None = None

    def define_spaces(self) -> None:
        super().define_spaces()
        self.observation_type = EgoStateObservation(self)
        self.observation_space = self.observation_type.space()


class RoundaboutSandbox(_Sandbox, ConnectedLaneRoundaboutEnv):
    """``roundabout-v1`` that accepts ``ContinuousAction`` and picks the ego's exit.

    highway-env's roundabout reward evaluates ``action in [0, 2]`` (a discrete
    lane change), which raises on a continuous action array; the reward here
    scores lane changes as never happening. The ego's exit is drawn from the
    episode's RNG among east, north and west (``config["destination"]`` fixes it).
    """

    EXITS = ("exr", "nxr", "wxr")

    @classmethod
    def default_config(cls) -> dict:
        config = super().default_config()
        config["destination"] = None
        return config

    def _rewards(self, action: Any) -> dict[str, float]:
        return super()._rewards(1)  # 1 = IDLE: no discrete lane-change action exists here

    def _reset(self) -> None:
        fixed = self.config.get("destination")
        self.destination = fixed or str(self.np_random.choice(self.EXITS))
        super()._reset()


class IntersectionSandbox(_Sandbox, ConnectedLaneIntersectionEnv):
    """``intersection-v2`` whose ego destination (left, straight or right) is drawn per episode.

    With a continuous action the ego is a plain kinematic vehicle that cannot
    plan a route, so highway-env would forget the destination it draws; here
    it is drawn first (``config["destination"]`` fixes it) and kept.
    """

    @classmethod
    def default_config(cls) -> dict:
        config = super().default_config()
        config["destination"] = None
        return config

    def _reset(self) -> None:
        fixed = self.config.get("destination")
        self.destination = fixed or "o" + str(int(self.np_random.integers(1, 4)))
        saved = self.config["destination"]
        self.config["destination"] = self.destination
        try:
            super()._reset()
        finally:
            self.config["destination"] = saved


class HighwaySandbox(_Sandbox, HighwayEnvFast):
    """``highway-fast-v0``: three lanes, 20 IDM/MOBIL cars; no destination (keep driving)."""

    def _reset(self) -> None:
        self.destination = None
        super()._reset()


SCENARIOS: dict[str, type] = {
    "roundabout": RoundaboutSandbox,
    "intersection": IntersectionSandbox,
    "highway-fast": HighwaySandbox,
}
"""Scenario name → environment class (subclasses of the highway-env classes of :data:`ENV_IDS`)."""


def _check_scenario(scenario: str) -> str:
    if scenario not in SCENARIOS:
        raise ValueError(f"scenario must be one of {tuple(SCENARIOS)}, got {scenario!r}")
    return scenario


def make_env(
    scenario: str,
    steps: int = DEFAULT_STEPS,
    render: bool = False,
    config: dict | None = None,
):
    """A sandbox environment with ``ContinuousAction`` and the package's time step.

    ``scenario`` is one of :data:`SCENARIOS`; ``steps`` actions of ``DT`` s make
    an episode (the env's ``duration``); ``render=True`` sets
    ``render_mode="rgb_array"`` (headless, see :func:`render_frame`);
    ``config`` overrides highway-env settings (e.g. ``{"vehicles_count": 0}``).
    The env is the highway-env object itself (``env.unwrapped is env``).
    """
    _check_scenario(scenario)
    if int(steps) < 1:
        raise ValueError(f"steps must be >= 1, got {steps!r}")
    cfg = {
        "action": {"type": "ContinuousAction"},
        "policy_frequency": POLICY_FREQUENCY,
        "simulation_frequency": SIMULATION_FREQUENCY,
        "duration": float(steps) * DT,
    }
    if config:
        cfg.update(config)
    return SCENARIOS[scenario](config=cfg, render_mode="rgb_array" if render else None)


# --------------------------------------------------------------------------- world-frame state


def to_world(xy: np.ndarray, heading: np.ndarray | float | None = None):
    """highway-env coordinates → world frame: ``(x, y) → (x, -y)``, ``heading → -heading``.

    Returns the mirrored points ``(..., 2)``, or ``(points, yaw)`` when a
    heading is given (wrapped to (-pi, pi]). The map is its own inverse.
    """
    p = np.asarray(xy, dtype=np.float64)
    w = np.stack([p[..., 0], -p[..., 1]], axis=-1)
    if heading is None:
        return w
    return w, wrap_angle(-np.asarray(heading, dtype=np.float64))


def ego_pose(env) -> np.ndarray:
    """The ego's world pose ``[x, y, yaw]`` (float64)."""
    v = env.unwrapped.vehicle
    xy, yaw = to_world(v.position, v.heading)
    return np.array([xy[0], xy[1], float(yaw)])


def ado_boxes(env, max_ado: int = MAX_ADO) -> tuple[np.ndarray, np.ndarray]:
    """The ``max_ado`` nearest other vehicles: world boxes ``(A, 5)`` and a validity mask ``(A,)``.

    Each row is ``[x, y, yaw, length, width]`` (chapter-7 ``ado`` layout),
    nearest first; unused rows are zero and invalid.
    """
    if int(max_ado) < 0:
        raise ValueError(f"max_ado must be >= 0, got {max_ado!r}")
    u = env.unwrapped
    ego = u.vehicle
    others = [v for v in u.road.vehicles if v is not ego]
    boxes = np.zeros((int(max_ado), 5))
    valid = np.zeros(int(max_ado), dtype=bool)
    if not others or max_ado == 0:
        return boxes, valid
    pos = np.array([v.position for v in others], dtype=np.float64)
    order = np.argsort(np.linalg.norm(pos - ego.position, axis=1), kind="stable")[: int(max_ado)]
    for row, i in enumerate(order):
        v = others[i]
        xy, yaw = to_world(v.position, v.heading)
        boxes[row] = [xy[0], xy[1], float(yaw), float(v.LENGTH), float(v.WIDTH)]
        valid[row] = True
    return boxes, valid


# --------------------------------------------------------------------------- map adapter


def _lane_table(network) -> list[tuple]:
    """Lane indices ``(from, to, id)`` in the network's (deterministic) order: Map lane ids."""
    return list(network.lanes_dict().keys())


def _lane_kind(lane, scenario: str) -> str:
    if isinstance(lane, CircularLane):
        return "ring" if scenario == "roundabout" else "connector"
    if isinstance(lane, SineLane):
        return "connector"
    return "road"


def _lane_points(lane, s_lo: float, s_hi: float, spacing: float) -> tuple[np.ndarray, float]:
    """World-frame centreline samples of a highway-env lane between arc lengths ``s_lo, s_hi``.

    Straight lanes need only their two ends (the Map resamples them); curved
    ones are sampled every ``spacing`` m with ``lane.position(s, 0)``. Also
    returns the mean ``lane.width_at(s)``.
    """
    straight = isinstance(lane, StraightLane) and not isinstance(lane, SineLane)
    n = 1 if straight else max(int(np.ceil((s_hi - s_lo) / spacing)), 1)
    s = np.linspace(s_lo, s_hi, n + 1)
    pts = np.array([lane.position(si, 0.0) for si in s], dtype=np.float64)
    width = float(np.mean([lane.width_at(si) for si in np.linspace(s_lo, s_hi, 5)]))
    return to_world(pts), width


def _route_edges(network, start: tuple, destination: str | None, max_lanes: int = 32) -> list:
    """The road edges ``(from, to)`` from the ego's lane to ``destination``.

    Without a destination the route follows the road ahead: at each node the
    next road whose lane starts closest to the current lane's end
    (highway-env's own rule for vehicles without a plan).
    """
    edges = [tuple(start[:2])]
    if destination is not None:
        path = network.shortest_path(start[1], destination)
        edges += [(path[i], path[i + 1]) for i in range(len(path) - 1)]
        return edges
    current = start
    for _ in range(max_lanes):
        lane = network.get_lane(current)
        nxt = network.next_lane(current, route=None, position=lane.position(lane.length, 0.0))
        if tuple(nxt[:2]) in edges or nxt == current:
            break
        edges.append(tuple(nxt[:2]))
        current = nxt
    return edges


def _chain(network, first: tuple, edges: Sequence[tuple]) -> list[tuple]:
    """Lane indices along ``edges`` starting with lane ``first`` (on ``edges[0]``).

    Each next lane is the one of the next road whose start is closest to the
    current lane's end (the same id when the lanes line up).
    """
    chain = [tuple(first)]
    for a, b in edges[1:]:
        end = network.get_lane(chain[-1])
        end_pt = end.position(end.length, 0.0)
        lanes = network.graph[a][b]
        d = [np.linalg.norm(ln.position(0.0, 0.0) - end_pt) for ln in lanes]
        chain.append((a, b, int(np.argmin(d))))
    return chain


def _route_fields(lanes: list[Lane], route: list[int]) -> dict:
    """``route, route_points, route_heads, route_s`` of a lane sequence (as ``build_map``)."""
    rp, rh, rs, _ = concat_lanes(lanes, route)
    return {"route": [int(r) for r in route], "route_points": rp, "route_heads": rh,
            "route_s": rs}


def explicit_map(recipe: dict) -> Map:
    """The :class:`Map` of an explicit recipe (:func:`map_recipe`), via :func:`world.build_map`.

    Explicit recipes carry the geometry itself (lane polylines and widths,
    drivable strips, the route as lane ids) as JSON-able numbers, which is
    what lets :func:`minimanc.world.load` rebuild the maps of highway-env
    demonstrations without highway-env (see :mod:`minimanc.world.maps`).
    """
    if not isinstance(recipe, dict) or recipe.get("kind") != EXPLICIT_KIND:
        raise ValueError(f"recipe must be a dict with kind={EXPLICIT_KIND!r}, "
                         f"got {str(recipe)[:200]}")
    return build_map(recipe)


def _round(a: np.ndarray) -> list:
    return np.round(np.asarray(a, dtype=np.float64), 3).tolist()


def map_recipe(
    env,
    scenario: str | None = None,
    destination: str | None = None,
    spacing: float = 1.0,
    window: tuple[float, float] = (150.0, 1500.0),
    max_lane_length: float = 2000.0,
) -> dict:
    """The explicit recipe (:func:`explicit_map`) of the env's road network and the ego's route.

    Every lane is sampled with ``lane.position(s, 0)`` every ``spacing`` m
    (straight lanes: their two ends) and mirrored into the world frame
    (:func:`to_world`); its width is the mean of ``lane.width_at(s)``. Lanes
    longer than ``max_lane_length`` (the 10 km highway) are cropped to
    ``window = (behind, ahead)`` metres around the ego's position along them.
    The drivable area is one strip per lane (its centreline, half its width:
    "off-road" then means what highway-env's ``on_road`` means). The route
    starts on the ego's lane and runs along the roads to ``destination``
    (default: the env's ``destination``, else the road ahead); its roads are
    kept in ``recipe["source"]["edges"]``. highway-env has no walkways,
    crossings or junction polygons.
    """
    u = env.unwrapped
    scenario = scenario or _scenario_of(u)
    if not (np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing must be positive, got {spacing!r}")
    net = u.road.network
    table = _lane_table(net)
    lookup = {index: i for i, index in enumerate(table)}
    ego = u.vehicle
    specs = []
    for index in table:
        lane = net.get_lane(index)
        s_lo, s_hi = 0.0, float(lane.length)
        if s_hi > max_lane_length:
            s_ego = float(lane.local_coordinates(ego.position)[0])
            s_lo = float(np.clip(s_ego - window[0], 0.0, s_hi - 1.0))
            s_hi = float(np.clip(s_ego + window[1], s_lo + 1.0, s_hi))
        pts, width = _lane_points(lane, s_lo, s_hi, spacing)
        a, b, k = index
        succ = []
        for nb, group in net.graph.get(b, {}).items():
            for nk, nxt in enumerate(group):
                if np.linalg.norm(nxt.position(0.0, 0.0) - lane.position(lane.length, 0.0)) < 3.0:
                    succ.append(lookup[(b, nb, nk)])
        side = net.graph[a][b]
        specs.append({
            "points": _round(pts), "width": round(width, 4), "kind": _lane_kind(lane, scenario),
            "successors": succ, "left": lookup[(a, b, k - 1)] if k > 0 else -1,
            "right": lookup[(a, b, k + 1)] if k + 1 < len(side) else -1,
        })
    if destination is None:
        destination = getattr(u, "destination", None)
    start = tuple(ego.lane_index)
    edges = _route_edges(net, start, destination)
    route = [lookup[i] for i in _chain(net, start, edges)]
    kind = {"roundabout": "roundabout", "intersection": "intersection"}.get(scenario, "straight")
    return {
        "kind": EXPLICIT_KIND,
        "map_kind": kind,
        "lanes": specs,
        "strips": [{"lane": i, "half_width": sp["width"] / 2.0} for i, sp in enumerate(specs)],
        "route": route,
        "start_s": 0.0,
        "source": {"simulator": "highway-env", "scenario": scenario,
                   "env_id": ENV_IDS.get(scenario), "destination": destination,
                   "edges": [list(e) for e in edges], "lane_index": [list(i) for i in table]},
    }


def road_map(env, scenario: str | None = None, destination: str | None = None,
             **kwargs: Any) -> Map:
    """The env's road network as a chapter-7 :class:`Map`: ``explicit_map(map_recipe(env))``.

    Sampled once per episode; ``start_s`` is the ego's arc length on the
    route. Keyword arguments go to :func:`map_recipe`.
    """
    recipe = map_recipe(env, scenario, destination, **kwargs)
    m = explicit_map(recipe)
    pose = ego_pose(env)
    recipe["start_s"] = round(float(project_to_route(m, pose[:2], float(pose[2]))[0]), 3)
    m.start_s = recipe["start_s"]
    return m


def _scenario_of(u) -> str:
    for name, cls in SCENARIOS.items():
        if isinstance(u, cls):
            return name
    return "straight"


class RouteTracker:
    """The moving lane target on highway-env's road, from the ego's *own* position.

    The route's roads are fixed per episode (``Map.recipe["edges"]``); the lane
    on them is the one the ego is in now (highway-env's lane distance with
    heading), continued along the remaining roads. So after a lane change the
    target follows the new lane. :meth:`map_for` returns the episode map with
    that lane sequence as its route (same geometry and cache key, so the
    rasteriser's caches still hit), and :meth:`lane_targets` the chapter-7
    targets (:func:`minimanc.world.maps.lane_targets`) on it.
    """

    def __init__(self, env, m: Map) -> None:
        self.env = env.unwrapped
        self.map = m
        self.edges = [tuple(e) for e in m.recipe["source"]["edges"]]
        self.table = _lane_table(self.env.road.network)
        self.lookup = {index: i for i, index in enumerate(self.table)}
        self._cache: dict[tuple[int, ...], Map] = {tuple(m.route): m}

    def current_lane(self, pose: np.ndarray) -> tuple:
        """highway-env lane index of the route lane nearest to the world ``pose``."""
        net = self.env.road.network
        xy, heading = to_world(np.asarray(pose[:2]), float(pose[2]))
        best, best_d, best_e = None, np.inf, 0
        for e_i, (a, b) in enumerate(self.edges):
            for k, lane in enumerate(net.graph[a][b]):
                d = lane.distance_with_heading(xy, float(heading))
                if d < best_d - 1e-9:
                    best, best_d, best_e = (a, b, k), d, e_i
        self._edge = best_e
        return best

    def map_for(self, pose: np.ndarray) -> Map:
        """The episode map whose route runs from the ego's current lane to the destination."""
        first = self.current_lane(pose)
        chain = _chain(self.env.road.network, first, self.edges[self._edge:])
        key = tuple(self.lookup[i] for i in chain)
        m = self._cache.get(key)
        if m is None:
            m = dataclasses.replace(self.map, **_route_fields(self.map.lanes, list(key)))
            self._cache[key] = m
        return m

    def lane_targets(self, pose: np.ndarray, k: int = K_TARGETS) -> np.ndarray:
        """``(k, 2)`` lane target points every 4 m ahead, in the ego frame of ``pose``."""
        return lane_targets(self.map_for(pose), np.asarray(pose, dtype=np.float64), k)


# --------------------------------------------------------------------------- BEV observation


class BEVObservation(gym.ObservationWrapper):
    """Observation wrapper: the chapter-7 ego-centric BEV raster of a highway-env scene.

    ``observation_space`` is ``Box(0, 255, (H, W, 3), uint8)`` with ``H = W =
    cfg.size``. On ``reset`` the road network is sampled once into a
    :class:`minimanc.world.maps.Map` (:func:`road_map`, kept as ``self.map``);
    every observation is :func:`minimanc.world.raster.rasterize` of that map
    from the ego's pose with the ``max_ado`` nearest vehicles: drivable area
    white, lane centrelines coloured by heading, vehicles yellow, the ego red
    at ``cfg.ego_pixel``, heading up.
    """

    def __init__(self, env, cfg: RasterConfig | None = None, max_ado: int = MAX_ADO) -> None:
        super().__init__(env)
        self.cfg = cfg or RasterConfig()
        if int(max_ado) < 0:
            raise ValueError(f"max_ado must be >= 0, got {max_ado!r}")
        self.max_ado = int(max_ado)
        self.observation_space = spaces.Box(0, 255, self.cfg.shape, dtype=np.uint8)
        self.map: Map | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.map = road_map(self.env)
        return self.observation(obs), info

    def observation(self, observation: Any) -> np.ndarray:
        if self.map is None:
            raise RuntimeError("BEVObservation: call reset() before step()")
        ado, valid = ado_boxes(self.env, self.max_ado)
        return rasterize(self.map, ego_pose(self.env), ado, valid, self.cfg)


# --------------------------------------------------------------------------- action adapter


def controls_to_action(
    controls: np.ndarray,
    speed: float,
    *,
    length: float = 5.0,
    dt: float = DT,
    substep: float = 1.0 / SIMULATION_FREQUENCY,
    speed_gain: float | None = None,
    acceleration_range: tuple[float, float] = (-5.0, 5.0),
    steering_range: tuple[float, float] = (-np.pi / 4, np.pi / 4),
) -> np.ndarray:
    """Map controls ``[speed v*, yaw rate ω*]`` (world frame) to a ``ContinuousAction`` in [-1, 1]².

    highway-env moves the ego as a kinematic bicycle (``Vehicle.step``): with
    steering angle δ the slip angle is ``β = arctan(tan(δ) / 2)``, the heading
    rate ``ψ' = v sin β / (L / 2)`` and the speed rate the acceleration ``a``;
    an action is held for ``dt`` s, integrated in sub-steps of ``substep`` s.

    * **Speed**: a P-controller ``a = k (v* − v)`` with ``k = speed_gain``
      (default ``1 / dt``: the commanded speed is reached at the end of the
      step when ``|a|`` stays within ``acceleration_range``), clipped.
    * **Yaw rate**: invert the bicycle relation at the mean speed the
      sub-steps will use, ``v̄ = v + a (dt − substep) / 2``:
      ``β = arcsin(ψ'* L / (2 v̄))``, ``δ = arctan(2 tan β)`` — the same
      relation highway-env's own ``steering_control`` uses. The world yaw
      rate is the mirror image of highway-env's heading rate, ``ψ'* = −ω*``
      (:func:`to_world`). At ``|v̄| < 0.1`` m/s no yaw rate is reachable and
      δ = 0.

    Both are then scaled linearly from the physical ranges to [-1, 1] and
    clipped (steering saturates at ±π/4: ``|ω| ≤ 0.447 v / (L/2)``).
    """
    u = np.asarray(controls, dtype=np.float64)
    if u.shape != (2,) or not np.all(np.isfinite(u)):
        raise ValueError(f"controls must be 2 finite numbers [speed, yaw_rate], got {controls!r}")
    if not np.isfinite(speed):
        raise ValueError(f"speed must be finite, got {speed!r}")
    for name, val in (("length", length), ("dt", dt), ("substep", substep)):
        if not (np.isfinite(val) and val > 0):
            raise ValueError(f"{name} must be positive and finite, got {val!r}")
    k = 1.0 / dt if speed_gain is None else float(speed_gain)
    if not (np.isfinite(k) and k > 0):
        raise ValueError(f"speed_gain must be positive and finite, got {speed_gain!r}")
    a_lo, a_hi = acceleration_range
    d_lo, d_hi = steering_range
    a = float(np.clip(k * (u[0] - float(speed)), a_lo, a_hi))
    v_mean = float(speed) + a * (dt - min(substep, dt)) / 2.0
    heading_rate = -u[1]
    if abs(v_mean) < 0.1:
        delta = 0.0
    else:
        beta = np.arcsin(np.clip(heading_rate * length / (2.0 * v_mean), -1.0, 1.0))
        delta = float(np.clip(np.arctan(2.0 * np.tan(beta)), d_lo, d_hi))
    a_n = 2.0 * (a - a_lo) / (a_hi - a_lo) - 1.0
    d_n = 2.0 * (delta - d_lo) / (d_hi - d_lo) - 1.0
    return np.clip(np.array([a_n, d_n], dtype=np.float32), -1.0, 1.0)


@dataclass
class ActionAdapter:
    """:func:`controls_to_action` bound to an env: reads the ego's speed, length and the rates.

    ``adapter(controls)`` returns the normalised ``ContinuousAction`` for the
    current ego state; ``speed_gain`` as in :func:`controls_to_action`.
    """

    env: Any
    speed_gain: float | None = None

    def __call__(self, controls: np.ndarray) -> np.ndarray:
        u = self.env.unwrapped
        at = u.action_type
        return controls_to_action(
            controls, float(u.vehicle.speed), length=float(u.vehicle.LENGTH),
            dt=1.0 / u.config["policy_frequency"], substep=1.0 / u.config["simulation_frequency"],
            speed_gain=self.speed_gain, acceleration_range=tuple(at.acceleration_range),
            steering_range=tuple(at.steering_range),
        )


# --------------------------------------------------------------------------- expert


EXPERT_SPEEDS = {"roundabout": (8.0, 12.0), "intersection": (7.0, 10.0),
                 "highway-fast": (22.0, 30.0)}
"""Range of the expert's desired speed per scenario (m/s), drawn per episode (driving style)."""


class ExpertVehicle(IDMVehicle):
    """highway-env's IDM/MOBIL vehicle that also yields before merging into a roundabout.

    highway-env's IDM follows only the leader in its lane, so at a roundabout
    entry it drives into circulating traffic (about 40 % of episodes end in a
    crash). Gap acceptance: while approaching the first ring lane of its route
    (a ``CircularLane``), for every other vehicle on the ring heading towards
    the merge point, compare arrival times ``t = distance / speed``; if the
    other arrives within ``[t_ego - YIELD_AFTER, t_ego + YIELD_BEFORE]`` s, the
    expert brakes as IDM would for a stopped leader at the merge point. Else
    it is highway-env's ``IDMVehicle`` unchanged.
    """

    YIELD_BEFORE = 3.0
    YIELD_AFTER = 1.5
    MERGE_RADIUS = 40.0
    substep: float = 1.0 / SIMULATION_FREQUENCY
    """Integration step of the env (s): braking never reverses the car within one sub-step."""

    def act(self, action: Any = None) -> None:
        super().act(action)
        if self.crashed:
            return
        self._yield()
        # IDM's braking term can exceed the speed left: stop at 0 instead of reversing
        self.action["acceleration"] = float(max(self.action["acceleration"],
                                                -max(self.speed, 0.0) / self.substep))

    def _yield(self) -> None:
        if not self.route:
            return
        merge = self._merge_point()
        if merge is None:
            return
        d = float(np.linalg.norm(merge - self.position))
        if d > self.MERGE_RADIUS or d < 0.5:
            return
        t_ego = d / max(self.speed, 1.0)
        for v in self.road.vehicles:
            if v is self or not isinstance(getattr(v, "lane", None), CircularLane):
                continue
            to_merge = merge - v.position
            dist = float(np.linalg.norm(to_merge))
            if dist > self.MERGE_RADIUS or np.dot(v.velocity, to_merge) <= 0:
                continue
            t_other = dist / max(v.speed, 0.1)
            if t_ego - self.YIELD_AFTER <= t_other <= t_ego + self.YIELD_BEFORE:
                stop = self._idm_to_stop(d - 1.0)
                self.action["acceleration"] = float(np.clip(
                    min(self.action["acceleration"], stop), -self.ACC_MAX, self.ACC_MAX))
                return

    def _merge_point(self) -> np.ndarray | None:
        """Start of the first ring lane ahead on the route, if the ego is not on the ring yet."""
        if isinstance(self.lane, CircularLane):
            return None
        key = (self.lane_index, len(self.route))
        cached = getattr(self, "_merge_cache", None)
        if cached is not None and cached[0] == key:
            return cached[1]
        merge = self._find_merge_point()
        self._merge_cache = (key, merge)
        return merge

    def _find_merge_point(self) -> np.ndarray | None:
        net = self.road.network
        for a, b, k in self.route:
            group = net.graph[a][b]
            lane = group[k if k is not None and k < len(group) else 0]
            if isinstance(lane, CircularLane):
                starts = [ln.position(0.0, 0.0) for ln in group]
                return min(starts, key=lambda p: float(np.linalg.norm(p - self.position)))
        return None

    def _idm_to_stop(self, gap: float) -> float:
        """IDM acceleration behind a stopped leader ``gap`` m ahead."""
        v = max(self.speed, 0.0)
        ab = -self.COMFORT_ACC_MAX * self.COMFORT_ACC_MIN
        s_star = self.DISTANCE_WANTED + v * self.TIME_WANTED + v * v / (2.0 * np.sqrt(ab))
        free = 1.0 - (v / max(self.target_speed, 0.1)) ** self.DELTA
        return float(self.COMFORT_ACC_MAX * (free - (s_star / max(gap, 0.1)) ** 2))


def install_expert(env, target_speed: float | None = None) -> IDMVehicle:
    """Replace the ego by the expert (:class:`ExpertVehicle`: IDM/MOBIL, same state) on the route.

    Longitudinal: IDM car following towards ``target_speed`` (default: the
    ego's current speed), yielding at roundabout entries; lateral:
    highway-env's lane-keeping controller and MOBIL lane changes; at junctions
    the route to the env's destination; it brakes to a stop, never backwards.
    The expert is the env's ``vehicle``; step it with ``env.step(None)``.
    """
    u = env.unwrapped
    ego = u.vehicle
    net = u.road.network
    start = tuple(ego.lane_index)
    edges = _route_edges(net, start, getattr(u, "destination", None))
    route = [start] + [(a, b, None) for a, b in edges[1:]]
    expert = ExpertVehicle(
        u.road, np.array(ego.position, dtype=np.float64), heading=float(ego.heading),
        speed=float(ego.speed), target_lane_index=start,
        target_speed=float(ego.speed if target_speed is None else target_speed), route=route,
    )
    expert.substep = 1.0 / u.config["simulation_frequency"]
    i = next(j for j, v in enumerate(u.road.vehicles) if v is ego)
    u.road.vehicles[i] = expert
    u.vehicle = expert
    return expert


# --------------------------------------------------------------------------- episodes


@dataclass
class Episode:
    """One episode of ``T`` actions: ``T + 1`` recorded states (world frame).

    ``poses (T+1, 3)``, ``speeds (T+1,)``, ``ado (T+1, A, 5)``, ``ado_valid
    (T+1, A)``, ``lane_target (T+1, K, 2)`` (ego frame), ``bev (T+1, H, W, 3)``
    uint8 (when recorded), ``commands (T, 2)`` the ``[speed, yaw rate]`` a
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


class _Run:
    """One env driven step by step (the expert or a policy), recording an :class:`Episode`."""

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
            rec["bev"].append(rasterize(m_t, pose, ado, valid, self.cfg))
        if self.render:
            rec["frames"].append(render_frame(env))
        return {"pose": pose, "map": m_t, "ado": ado, "ado_valid": valid,
                "speed": float(env.vehicle.speed)}

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
    ``bev`` uint8 (H, W, 3), ``goal`` the world pose ``goal`` (typically the
    expert's final pose of the same seed; default the start pose) in the
    current ego frame, ``lane_target`` (K, 2), ``motion`` the previous
    command) — and its ``[speed, yaw rate]`` goes through
    :class:`ActionAdapter`. The episode runs to the end even after a crash
    (highway-env then brakes the ego to a stop). ``render=True`` keeps
    highway-env's frames in ``Episode.frames``.
    """
    _check_scenario(scenario)
    _check_steps(steps)
    if not (callable(policy) or policy == "expert"):
        raise ValueError(f"policy must be 'expert' or a callable, got {policy!r}")
    cfg = cfg or RasterConfig()
    expert = policy == "expert"
    run = _Run(scenario, seed, int(steps), expert, cfg, max_ado, record_bev, render, config,
               expert_speed, goal)
    goal_w = run.rec["poses"][0] if goal is None else np.asarray(goal, dtype=np.float64)
    motion = np.array([run.rec["speeds"][0], 0.0])
    for t in range(int(steps)):
        if expert:
            run.step(None)
            continue
        o = run.obs
        bev = run.rec["bev"][-1] if record_bev else rasterize(
            o["map"], o["pose"], o["ado"], o["ado_valid"], cfg)
        obs = {**o, "bev": bev, "t": t, "goal": goal_in_ego_frame(goal_w, o["pose"]),
               "lane_target": run.rec["targets"][-1], "motion": motion.copy()}
        controls = np.asarray(policy(obs), dtype=np.float64).reshape(2)
        if not np.all(np.isfinite(controls)):
            raise ValueError(f"policy returned non-finite controls {controls!r} at step {t}")
        run.step(controls)
        motion = controls
    return run.finish()


def _check_steps(steps: Any) -> int:
    if isinstance(steps, bool) or not isinstance(steps, int | np.integer) or steps < 2:
        raise ValueError(f"steps must be an integer >= 2, got {steps!r}")
    return int(steps)


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


# --------------------------------------------------------------------------- demonstrations


EVAL_SEED = 100_000
"""First env seed of evaluation episodes (training demonstrations start at 0)."""


def expert_episodes(
    scenario: str,
    n: int,
    seed: int = 0,
    steps: int = DEFAULT_STEPS,
    cfg: RasterConfig | None = None,
    max_ado: int = MAX_ADO,
    record_bev: bool = True,
    max_tries: int | None = None,
    progress: bool = False,
) -> tuple[list[Episode], int]:
    """``n`` collision-free expert episodes from env seeds ``seed, seed + 1, …``.

    IDM/MOBIL sometimes crashes (roundabout entries, intersections); such
    episodes are skipped, as chapter 7 redraws scenes where the human
    collides. Returns ``(episodes, tries)``; ``tries − n`` were skipped.
    Raises RuntimeError after ``max_tries`` (default ``3 n + 10``) attempts.
    """
    _check_scenario(scenario)
    _check_steps(steps)
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    limit = 3 * int(n) + 10 if max_tries is None else int(max_tries)
    out: list[Episode] = []
    tries = 0
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=int(n), desc=f"expert {scenario}", leave=False)
    try:
        while len(out) < n:
            if tries >= limit:
                raise RuntimeError(f"{scenario}: only {len(out)} collision-free expert "
                                   f"episodes in {tries} tries from seed {seed}")
            ep = run_episode(scenario, int(seed) + tries, "expert", steps=steps, cfg=cfg,
                             max_ado=max_ado, record_bev=record_bev)
            tries += 1
            if not ep.collided:
                out.append(ep)
                if bar is not None:
                    bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return out, tries


def to_dataset(episodes: Sequence[Episode], cfg: RasterConfig | None = None,
               seed: int = 0, attempts: Sequence[int] | None = None):
    """Chapter-7 :class:`minimanc.world.Dataset` from expert episodes of equal length.

    An episode of ``T`` actions gives one scene of ``T`` steps: ``ego`` the
    poses ``0 … T−1``, ``controls[t]`` (:attr:`Episode.controls`) from ``t`` to
    ``t + 1``, ``goal`` the last pose in each ego frame, the lane targets and
    ados recorded at each step, ``bev`` the rasters (re-rendered with ``cfg``
    if the episode has none), ``goal_bev`` the static raster at the goal, and
    ``maps`` the episode maps (explicit recipes in ``meta["recipes"]``).
    ``meta["tags"]`` records the scenario, env id and seed, destination and
    expert speed per scene.
    """
    from dataclasses import asdict

    from minimanc.world import dataset as wds

    cfg = cfg or RasterConfig()
    if len(episodes) == 0:
        raise ValueError("episodes must hold at least one episode, got 0")
    lengths = {ep.steps for ep in episodes}
    if len(lengths) != 1:
        raise ValueError(f"episodes must all have the same number of steps, got {sorted(lengths)}")
    As = {ep.ado.shape[1] for ep in episodes}
    if len(As) != 1:
        raise ValueError(f"episodes must all have the same number of ado rows, got {sorted(As)}")
    T = lengths.pop()
    cols: dict[str, list] = {f: [] for f in wds.ARRAY_FIELDS}
    for ep in episodes:
        ego = ep.poses[:T]
        bev = ep.bev[:T] if ep.bev is not None and ep.bev.shape[1:] == cfg.shape else None
        if bev is None:
            bev = np.stack([rasterize(ep.map, ep.poses[t], ep.ado[t], ep.ado_valid[t], cfg)
                            for t in range(T)])
        cols["bev"].append(bev)
        cols["ego"].append(ego.astype(np.float32))
        cols["controls"].append(ep.controls[:T].astype(np.float32))
        cols["goal"].append(goal_in_ego_frame(np.broadcast_to(ego[-1], ego.shape), ego)
                            .astype(np.float32))
        cols["lane_target"].append(ep.lane_target[:T].astype(np.float32))
        cols["ado"].append(ep.ado[:T].astype(np.float32))
        cols["ado_valid"].append(ep.ado_valid[:T])
        cols["goal_bev"].append(rasterize(ep.map, ego[-1], None, None, cfg))
    arrays = {f: np.stack(v) for f, v in cols.items()}
    tags = [{
        "kind": ep.map.kind, "source": "highway-env", "scenario": ep.scenario,
        "env_id": ENV_IDS[ep.scenario], "env_seed": ep.seed, "destination": ep.destination,
        "expert_speed": round(float(ep.expert_speed), 4),
        "has_junction": ep.map.kind == "intersection",
        "has_roundabout": ep.map.kind == "roundabout",
    } for ep in episodes]
    meta = {
        "seed": int(seed), "version": wds.FORMAT_VERSION, "dt": DT, "raster": asdict(cfg),
        "recipes": [ep.map.recipe for ep in episodes], "tags": tags,
        "attempts": [1] * len(episodes) if attempts is None else [int(a) for a in attempts],
        "scene_index": [ep.seed for ep in episodes], "source": "highway-env",
    }
    return wds.Dataset(**arrays, maps=[ep.map for ep in episodes], meta=meta)


def collect(
    scenarios: Sequence[str] | str = tuple(SCENARIOS),
    n_episodes: int = 20,
    seed: int = 0,
    steps: int = DEFAULT_STEPS,
    cfg: RasterConfig | None = None,
    max_ado: int = MAX_ADO,
    progress: bool = False,
):
    """Expert demonstrations in the chapter-7 format: ``n_episodes`` per scenario.

    Episodes come from :func:`expert_episodes` (env seeds from ``seed``,
    collisions skipped), scenario by scenario, and are assembled by
    :func:`to_dataset`; ``meta["attempts"]`` counts the seeds each scene took.
    Save with :func:`minimanc.world.save`; :func:`minimanc.world.load` reads
    it back (its maps are explicit recipes, see :func:`explicit_map`).
    """
    if isinstance(n_episodes, bool) or not isinstance(n_episodes, int | np.integer) \
            or n_episodes < 1:
        raise ValueError(f"n_episodes must be a positive integer, got {n_episodes!r}")
    names = [scenarios] if isinstance(scenarios, str) else list(scenarios)
    if not names:
        raise ValueError("scenarios must name at least one scenario, got none")
    for sc in names:
        _check_scenario(sc)
    cfg = cfg or RasterConfig()
    episodes: list[Episode] = []
    attempts: list[int] = []
    for sc in names:
        eps, tries = expert_episodes(sc, n_episodes, seed, steps, cfg, max_ado, True,
                                     progress=progress)
        prev = int(seed) - 1
        for ep in eps:
            attempts.append(ep.seed - prev)
            prev = ep.seed
        episodes += eps
    return to_dataset(episodes, cfg, seed=seed, attempts=attempts)


# --------------------------------------------------------------------------- closed loop


@dataclass
class ClosedLoopResult:
    """Policy episodes and the expert episodes of the same seeds, with :attr:`metrics`."""

    scenario: str
    name: str
    episodes: list[Episode]
    experts: list[Episode]
    seconds: float

    @property
    def metrics(self) -> dict[str, float]:
        """Collision and off-road rates (%), ADE to the expert (m), goal distance (m),
        mean speed (m/s) and episodes per second.

        * ``collision_rate``: episodes in which highway-env flags the ego
          ``crashed`` at some step (its own collision test, 5 m × 2 m boxes);
        * ``off_road_rate``: episodes in which the ego's centre leaves the
          drivable area (:func:`minimanc.metrics.off_road` on the episode map);
        * ``ade``: :func:`minimanc.metrics.ade` to the expert of the same
          seed, same clock; ``goal_distance`` to the expert's final position;
        * ``mean_speed``: mean of the ego's speed over all recorded steps;
        * ``episodes_per_second``: wall clock, environment and policy included.
        """
        from minimanc import metrics

        ego = np.stack([ep.poses for ep in self.episodes])
        ref = np.stack([ep.poses for ep in self.experts])
        return {
            "collision_rate": 100.0 * float(np.mean([ep.collided for ep in self.episodes])),
            "off_road_rate": 100.0 * float(metrics.off_road(
                ego, [ep.map for ep in self.episodes]).mean()),
            "ade": float(metrics.ade(ego, ref).mean()),
            "goal_distance": float(metrics.goal_distance(ego, ref[:, -1]).mean()),
            "mean_speed": float(np.mean([ep.speeds.mean() for ep in self.episodes])),
            "episodes_per_second": len(self.episodes) / max(self.seconds, 1e-9),
        }


def closed_loop(
    policy: Any,
    scenario: str,
    experts: Sequence[Episode],
    cfg: RasterConfig | None = None,
    max_ado: int = MAX_ADO,
    progress: bool = False,
    record_bev: bool = False,
) -> ClosedLoopResult:
    """Drive a chapter-9 policy (:class:`minimanc.rollout.ModelPolicy` or any
    :class:`minimanc.rollout.Policy`) in highway-env from the seeds of ``experts``.

    All episodes run in lock-step so the policy sees one batch per step. Each
    episode starts from ``env.reset(seed)`` of its expert, lasts ``T − 1``
    decisions (``T`` = the expert episode's recorded states minus one, as the
    chapter-9 closed loop makes ``T − 1`` decisions on a ``T``-step log) and
    at each step the observation comes from :func:`minimanc.inputs.from_state`
    at the ego's own pose: the BEV of the map with the live traffic, the goal
    = the expert's pose at ``T − 1``, the lane target on the route from the
    current lane, and ``motion`` = the policy's previous control (at ``t = 0``
    the ego's speed and yaw rate 0). Controls go through
    :class:`ActionAdapter`. The result's experts are cut to the same ``T``
    states.
    """
    from minimanc import inputs

    _check_scenario(scenario)
    if len(experts) == 0:
        raise ValueError("experts must hold at least one expert episode, got 0")
    if any(ep.scenario != scenario for ep in experts):
        raise ValueError(f"experts must all be {scenario!r} episodes")
    T = experts[0].steps
    if any(ep.steps != T for ep in experts):
        raise ValueError("experts must all have the same number of steps")
    cfg = cfg or RasterConfig()
    t0 = time.perf_counter()
    goals = np.stack([ep.poses[T - 1] for ep in experts])
    runs = [_Run(scenario, ep.seed, T, False, cfg, max_ado, record_bev, False, None, None,
                 goals[i]) for i, ep in enumerate(experts)]
    scenes = np.arange(len(runs))
    state = policy.initial_state(scenes)
    motion = np.array([[r.rec["speeds"][0], 0.0] for r in runs], dtype=np.float32)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=T - 1, desc=f"{scenario} {policy.model}", leave=False)
    for t in range(T - 1):
        obs = inputs.from_state(
            [r.obs["map"] for r in runs], np.stack([r.obs["pose"] for r in runs]),
            np.stack([r.obs["ado"] for r in runs]), np.stack([r.obs["ado_valid"] for r in runs]),
            goals, cfg, policy.setting, motion=motion, model=policy.model,
            k_targets=experts[0].lane_target.shape[1],
        )
        u, state, _ = policy(obs, state, t, scenes)
        u = np.asarray(u, dtype=np.float64)
        if u.shape != (len(runs), 2) or not np.all(np.isfinite(u)):
            raise ValueError(f"policy returned controls of shape {u.shape} "
                             f"(finite: {bool(np.all(np.isfinite(u)))}) at step {t}")
        for r, ui in zip(runs, u):
            r.step(ui)
        motion = u.astype(np.float32)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    episodes = [r.finish() for r in runs]
    cut = [dataclasses.replace(
        ep, poses=ep.poses[:T], speeds=ep.speeds[:T], ado=ep.ado[:T], ado_valid=ep.ado_valid[:T],
        lane_target=ep.lane_target[:T], commands=ep.commands[:T - 1], actions=ep.actions[:T - 1],
        crashed=ep.crashed[:T], on_road=ep.on_road[:T],
        bev=None if ep.bev is None else ep.bev[:T]) for ep in experts]
    name = getattr(policy, "model", None) or "policy"
    return ClosedLoopResult(scenario, str(name), episodes, cut, time.perf_counter() - t0)


def plain_policy(policy: Any, goal: np.ndarray, cfg: RasterConfig | None = None) -> PolicyFn:
    """Wrap a chapter-9 policy (e.g. :class:`minimanc.rollout.ModelPolicy`) as a
    :data:`PolicyFn` for :func:`run_episode` / :func:`render_episode` (one ego).

    Each call builds the observation with :func:`minimanc.inputs.from_state`
    exactly as :func:`closed_loop` does (``goal`` a world pose, ``cfg`` the
    raster of the model) and carries the policy's recurrent state.
    """
    from minimanc import inputs

    cfg = cfg or RasterConfig()
    g = np.asarray(goal, dtype=np.float64).reshape(1, 3)
    k = getattr(getattr(policy, "cfg", None), "k_targets", K_TARGETS)
    carry = {"state": policy.initial_state(np.arange(1))}

    def drive(obs: dict) -> np.ndarray:
        if obs["t"] == 0:
            carry["state"] = policy.initial_state(np.arange(1))
        o = inputs.from_state([obs["map"]], obs["pose"][None], obs["ado"][None],
                              obs["ado_valid"][None], g, cfg, policy.setting,
                              motion=np.asarray(obs["motion"], np.float32)[None],
                              model=policy.model, k_targets=k)
        u, carry["state"], _ = policy(o, carry["state"], int(obs["t"]), np.arange(1))
        return np.asarray(u, dtype=np.float64)[0]

    return drive


def expert_result(scenario: str, experts: Sequence[Episode]) -> ClosedLoopResult:
    """The experts as a :class:`ClosedLoopResult` (the "human" row: ADE 0 by definition)."""
    T = experts[0].steps
    cut = [dataclasses.replace(ep, poses=ep.poses[:T], speeds=ep.speeds[:T],
                               crashed=ep.crashed[:T]) for ep in experts]
    return ClosedLoopResult(scenario, "expert", cut, cut,
                            float(sum(ep.seconds for ep in experts)))


# --------------------------------------------------------------------------- rendering


def render_frame(env) -> np.ndarray:
    """highway-env's own top-down frame ``(H, W, 3)`` uint8, rendered headless.

    Needs ``render_mode="rgb_array"`` (``make_env(..., render=True)``). After
    rendering, ``enable_auto_render`` is switched off: otherwise every later
    ``step`` renders each sub-step too (about 4x slower).
    """
    u = env.unwrapped
    if u.render_mode != "rgb_array":
        raise ValueError(
            f"env.render_mode must be 'rgb_array' to render frames, got {u.render_mode!r}; "
            "use make_env(..., render=True)"
        )
    frame = np.asarray(u.render(), dtype=np.uint8)
    u.enable_auto_render = False
    return frame


def save_png(frame: np.ndarray, path: str | Path, scale: int = 1) -> Path:
    """Save an ``(H, W, 3)`` uint8 frame as PNG, optionally upscaled ``scale`` times (nearest)."""
    from PIL import Image

    f = _check_frame(frame)
    img = Image.fromarray(f)
    if int(scale) < 1:
        raise ValueError(f"scale must be >= 1, got {scale!r}")
    if scale > 1:
        img = img.resize((f.shape[1] * scale, f.shape[0] * scale), Image.NEAREST)
    path = Path(path)
    img.save(path, format="PNG")
    return path


def save_gif(frames: Sequence[np.ndarray], path: str | Path, fps: float = 2.0,
             scale: int = 1) -> Path:
    """Save frames ``(H, W, 3)`` uint8 as a looping GIF at ``fps`` frames per second."""
    from PIL import Image

    if len(frames) == 0:
        raise ValueError("frames must hold at least one frame, got 0")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps!r}")
    if int(scale) < 1:
        raise ValueError(f"scale must be >= 1, got {scale!r}")
    imgs = []
    for fr in frames:
        f = _check_frame(fr)
        img = Image.fromarray(f)
        if scale > 1:
            img = img.resize((f.shape[1] * scale, f.shape[0] * scale), Image.NEAREST)
        imgs.append(img)
    path = Path(path)
    imgs[0].save(path, format="GIF", save_all=True, append_images=imgs[1:],
                 duration=int(round(1000.0 / fps)), loop=0)
    return path


def _check_frame(frame: np.ndarray) -> np.ndarray:
    f = np.asarray(frame)
    if f.ndim != 3 or f.shape[2] != 3 or f.dtype != np.uint8:
        raise ValueError(f"frame must be an (H, W, 3) uint8 array, got {f.shape} {f.dtype}")
    return f


def render_episode(
    scenario: str,
    seed: int,
    out_dir: str | Path,
    policy: PolicyFn | str = "expert",
    steps: int = DEFAULT_STEPS,
    goal: np.ndarray | None = None,
    cfg: RasterConfig | None = None,
    bev_scale: int = 4,
) -> dict[str, Path]:
    """Run an episode headless and write highway-env's frames and the BEV frames to ``out_dir``.

    Writes ``frame_000.png`` … (highway-env's view), ``episode.gif`` (its
    frames at 2 fps = real time) and ``bev.gif`` (the policy's input, upscaled
    ``bev_scale`` times). Returns the paths by name.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ep = run_episode(scenario, seed, policy, steps=steps, goal=goal, cfg=cfg, render=True)
    paths: dict[str, Path] = {}
    for t, fr in enumerate(ep.frames):
        paths[f"frame_{t:03d}"] = save_png(fr, out / f"frame_{t:03d}.png")
    paths["episode"] = save_gif(ep.frames, out / "episode.gif", fps=POLICY_FREQUENCY)
    paths["bev"] = save_gif(list(ep.bev), out / "bev.gif", fps=POLICY_FREQUENCY, scale=bev_scale)
    return paths
