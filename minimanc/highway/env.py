"""Chapter 10 — the sandbox environments and the world frame.

The three scenarios (:data:`SCENARIOS`: roundabout, intersection,
highway-fast) are highway-env environments with ``ContinuousAction``, the
package's time step (:func:`make_env`) and a cheap ego-state observation
(:class:`EgoStateObservation`). highway-env's y axis points *down* the
screen, so its coordinates are mirrored into the world's right-handed frame,
``x_w = x``, ``y_w = -y``, ``yaw_w = -heading`` (:func:`to_world`); the ego's
pose (:func:`ego_pose`) and the nearest vehicles' boxes (:func:`ado_boxes`)
are read in that frame.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from highway_env.envs.common.observation import ObservationType
from highway_env.envs.highway_env import HighwayEnvFast
from highway_env.envs.intersection_env import ConnectedLaneIntersectionEnv
from highway_env.envs.roundabout_env import ConnectedLaneRoundaboutEnv

from minimanc.checks import check_int
from minimanc.world.geometry import DT, wrap_angle

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


def check_scenario(scenario: str) -> str:
    """``scenario`` if it names one of :data:`SCENARIOS`, else ``ValueError``."""
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
    check_scenario(scenario)
    steps = check_int("steps", steps, 1)
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
    max_ado = check_int("max_ado", max_ado, 0)
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


def scenario_of(u: Any) -> str:
    """The :data:`SCENARIOS` name of an unwrapped env (``"straight"`` for any other env)."""
    for name, cls in SCENARIOS.items():
        if isinstance(u, cls):
            return name
    return "straight"

