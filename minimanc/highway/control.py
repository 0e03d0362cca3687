"""Chapter 10 — the action adapter and the expert driver.

* **Action adapter** (:func:`controls_to_action`, :class:`ActionAdapter`):
  the package's controls ``[speed, yaw rate]`` (the output of MANC's DMP
  step, paper eqs. 10–11, integrated once; DT = 0.5 s) become highway-env's
  ``ContinuousAction`` ``[acceleration, steering]`` on its kinematic bicycle.
* **Expert** (:class:`ExpertVehicle`, :func:`install_expert`): the ego is
  replaced by highway-env's own IDM/MOBIL vehicle following the route (plus
  gap acceptance at roundabout entries) — the "human" of this chapter.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from highway_env.road.lane import CircularLane
from highway_env.vehicle.behavior import IDMVehicle

from minimanc.highway.env import SIMULATION_FREQUENCY
from minimanc.highway.mapping import route_edges
from minimanc.world.geometry import DT


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
    edges = route_edges(net, start, getattr(u, "destination", None))
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

