"""Chapter 7 — the "human" ego driver and the scene simulation that logs it.

The human drives a unicycle (controls ``[speed, yaw rate]``, explicit Euler
at ``DT``) along the map's route with a per-scene :class:`HumanStyle`:

* **longitudinal** — the Intelligent Driver Model of
  :mod:`minimanc.world.traffic` with the style's desired speed ``v0``, time
  headway ``T``, comfortable acceleration ``a_max`` and deceleration ``b``,
  jam distance ``s0``; the desired speed slowly wanders (``speed_sigma``) and
  anticipates curves (``a_lat``). It follows leaders, yields at junction and
  roundabout entries (gap acceptance with the style's critical gap), brakes
  for vehicles cutting in. Its commands reach the pedals after a
  **reaction delay** (``reaction`` s), except hard braking, and change with
  bounded jerk;
* **lateral** — pure pursuit of a point ``lookahead`` metres ahead on the
  route's centreline, shifted by a slowly wandering **lateral offset**
  (Ornstein–Uhlenbeck, std ``lat_sigma``, time constant ``lat_tau``).

:func:`simulate_scene` runs one scene: it places the ego and the ados, steps
everything ``T`` times and returns the log (ego poses and controls, ado boxes)
with tags. Scenes where the ego leaves the drivable area or touches an ado
are rejected by the dataset generator (:mod:`minimanc.world.generation`), which
then draws the scene again from the next sub-seed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from minimanc.world.geometry import (
    DT,
    EGO_LENGTH,
    EGO_WIDTH,
    box_corners,
    boxes_overlap,
    project_to_polyline,
    unicycle_step,
    wrap_angle,
)
from minimanc.world.lanes import Map
from minimanc.world.traffic import B_MAX, Path, Traffic, Vehicle

T_STEPS = 40
"""Steps per scene: 20 s at 2 Hz, as nuScenes."""
MAX_ADOS = 40
"""Ado slots per scene (the ``A`` axis of the dataset)."""


@dataclass(frozen=True)
class HumanStyle:
    """Per-scene driving style of the human (all SI units)."""

    v0: float  # desired speed (m/s)
    T: float  # time headway (s)
    a_max: float  # comfortable acceleration (m/s^2)
    b: float  # comfortable deceleration (m/s^2)
    s0: float  # jam distance (m)
    a_lat: float  # accepted lateral acceleration in curves (m/s^2)
    lat_sigma: float  # std of the lateral offset from the lane centre (m)
    lat_tau: float  # its time constant (s)
    speed_sigma: float  # relative std of the wandering desired speed
    reaction: float  # reaction delay (s)
    gap_crit: float  # critical gap accepted at junctions (s)
    lookahead: float  # pure-pursuit lookahead gain
    jerk: float  # comfortable jerk bound (m/s^3)


def random_style(rng: np.random.Generator) -> HumanStyle:
    """Draw a human style; calm and sporty drivers both occur."""
    sport = float(rng.beta(2.0, 2.0))  # 0 calm ... 1 sporty, styles are correlated
    j = lambda lo, hi, spread=0.25: float(  # noqa: E731
        np.clip(lo + (hi - lo) * (sport + rng.uniform(-spread, spread)), lo, hi))
    return HumanStyle(
        v0=j(7.5, 15.0), T=float(np.clip(2.2 - 1.3 * sport + rng.normal(0, 0.15), 0.8, 2.4)),
        a_max=j(0.9, 2.6), b=j(1.6, 3.4), s0=float(rng.uniform(1.5, 3.5)),
        a_lat=j(1.4, 3.2), lat_sigma=float(rng.uniform(0.03, 0.35)),
        lat_tau=float(rng.uniform(2.0, 6.0)), speed_sigma=float(rng.uniform(0.0, 0.08)),
        reaction=float(rng.uniform(0.0, 1.0)),
        gap_crit=float(np.clip(3.4 - 1.8 * sport + rng.normal(0, 0.2), 1.5, 3.8)),
        lookahead=float(rng.uniform(0.85, 1.3)), jerk=j(2.0, 6.0),
    )


@dataclass
class SceneLog:
    """Raw log of one simulated scene (world frame)."""

    ego: np.ndarray  # (T, 3)
    controls: np.ndarray  # (T, 2)
    final_pose: np.ndarray  # (3,) pose after the last control (not part of the log)
    ado: np.ndarray  # (T, A, 5)
    ado_valid: np.ndarray  # (T, A)
    tags: dict


class HumanDriver:
    """The ego's controller: IDM + reaction delay + pure pursuit with lateral wander."""

    def __init__(self, m: Map, style: HumanStyle, rng: np.random.Generator, dt: float) -> None:
        self.m = m
        self.style = style
        self.rng = rng
        self.dt = dt
        self.lat = float(rng.normal(0.0, style.lat_sigma))
        self.speed_factor = 1.0
        self.a_hist: list[float] = []
        self.a_prev = 0.0

    def act(self, veh: Vehicle, path: Path, pose: np.ndarray, gap: float, v_lead: float,
            stop: float, a_curve: float) -> tuple[float, float, float]:
        """Controls ``(speed, yaw_rate)`` for this step and the applied acceleration.

        ``gap``/``v_lead``: the leader; ``stop``: distance to a junction stop
        point where the human must yield; ``a_curve``: the acceleration bound of
        the curves ahead (all from :meth:`Traffic.perceive`).
        """
        st, dt, rng = self.style, self.dt, self.rng
        # wandering desired speed and lateral offset (Ornstein-Uhlenbeck)
        n1, n2 = rng.normal(size=2)
        self.speed_factor += (-(self.speed_factor - 1.0) / 8.0) * dt + st.speed_sigma * math.sqrt(
            2 * dt / 8.0) * n1
        self.lat += -self.lat / st.lat_tau * dt + st.lat_sigma * math.sqrt(
            2 * dt / st.lat_tau) * n2
        self.lat = _clip(self.lat, -0.4, 0.4)
        v = veh.v
        v0 = max(st.v0 * self.speed_factor, 1e-3)
        # interactions reach the pedals after the reaction delay; the road geometry
        # (a_curve) is anticipated and not delayed
        a_cmd = _acc_scalar(v, v0, gap, v_lead, st)
        if stop < math.inf:
            a_cmd = min(a_cmd, _acc_scalar(v, v0, stop, 0.0, st))
        a_cmd = _clip(a_cmd, -B_MAX, st.a_max)
        self.a_hist.append(a_cmd)
        # reaction delay: the command issued `reaction` seconds ago (linear interpolation)
        k = len(self.a_hist) - 1 - st.reaction / dt
        k0 = math.floor(k)
        f = k - k0
        h = self.a_hist
        a_del = h[max(k0, 0)] * (1 - f) + h[max(min(k0 + 1, len(h) - 1), 0)] * f
        a = a_del if a_cmd >= -1.5 else min(a_cmd, a_del)  # reflex for hard braking
        if a_cmd > -3.0:  # bounded jerk unless braking hard
            a = _clip(a, self.a_prev - st.jerk * dt, self.a_prev + st.jerk * dt)
        a = min(a, max(a_curve, -B_MAX))
        v_new = _clip(v + a * dt, 0.0, 22.0)
        if v_new < 0.05:
            v_new = 0.0
        self.a_prev = (v_new - v) / dt
        # pure pursuit towards the route, offset by the lateral wander
        ld = _clip(st.lookahead * (0.75 * max(v_new, v) + 4.0), 4.5, 20.0)
        (px, py), h_t = path.pose(veh.s + ld)
        px, py = px - self.lat * math.sin(h_t), py + self.lat * math.cos(h_t)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        dx, dy = px - pose[0], py - pose[1]
        tx, ty = c * dx + s * dy, -s * dx + c * dy
        kappa = _clip(2.0 * ty / max(tx * tx + ty * ty, 1e-6), -0.25, 0.25)
        omega = _clip(v_new * kappa, -1.2, 1.2)
        return v_new, omega, self.a_prev


def _acc_scalar(v: float, v0: float, gap: float, v_lead: float, st: HumanStyle) -> float:
    """:func:`~minimanc.world.traffic.acc_acceleration` for one vehicle, in plain floats."""
    gap = max(gap, 1e-2)
    s_star = st.s0 + max(0.0, v * st.T + v * (v - v_lead) / (2.0 * math.sqrt(st.a_max * st.b)))
    a_idm = st.a_max * (1.0 - (v / v0) ** 4 - (s_star / gap) ** 2)
    a_cah = min(-(max(v - v_lead, 0.0) ** 2) / (2.0 * gap), st.a_max)
    if a_idm >= a_cah:
        return a_idm
    return 0.01 * a_idm + 0.99 * (a_cah + st.b * math.tanh((a_idm - a_cah) / st.b))


def _clip(x: float, lo: float, hi: float) -> float:
    return float(min(max(x, lo), hi))


def project_on_path(path: Path, s_prev: float, pose: np.ndarray) -> float:
    """Arc length of ``pose`` on ``path``, searched near the previous value ``s_prev``."""
    w = path.window(s_prev - 8.0, s_prev + 25.0)
    s, _ = project_to_polyline(path.points[w], path.s[w], pose[None, :2])
    return float(s[0])


class SceneRun:
    """One scene of the world, simulated step by step: the ego among the IDM ados.

    ``SceneRun(m, rng)`` draws the human style and the traffic and places the
    ego and the ados exactly as :func:`simulate_scene` does (it *is* the setup
    of :func:`simulate_scene`, which is ``SceneRun`` stepped ``T`` times by
    :meth:`human_step`). A step is split in two so that another controller
    can drive the ego: :meth:`perceive` (junction arrival stamps at step
    :attr:`t`, then every vehicle's binding constraint,
    :meth:`~minimanc.world.traffic.Traffic.perceive`), then :meth:`advance`
    with the ego's controls (the ego moves by one unicycle step, the ados by
    their IDM accelerations, new ados arrive through :attr:`spawner`).

    :attr:`spawner` is called with the run after the ados have moved; the
    default draws the Poisson arrivals of :meth:`Traffic.spawn` around the ego.
    """

    def __init__(self, m: Map, rng: np.random.Generator, dt: float = DT,
                 max_ados: int = MAX_ADOS) -> None:
        self.m, self.rng, self.dt, self.max_ados = m, rng, dt, max_ados
        style = random_style(rng)
        density = float(rng.uniform(1 / 70.0, 1 / 18.0))  # ados per metre of lane
        spawn_rate = float(rng.uniform(0.02, 0.12))  # arrivals per second per entry lane
        traffic = Traffic(m, rng, dt, density, max_ados, spawn_rate)
        path = Path.from_lanes(m, m.route)
        ego = Vehicle(pid=traffic.bank.add(path), s=m.start_s, v=0.0, length=EGO_LENGTH,
                      width=EGO_WIDTH, v0=style.v0, T=style.T, a_max=style.a_max, b=style.b,
                      s0=style.s0, a_lat=style.a_lat, gap_crit=style.gap_crit, is_ego=True)
        xy, h = path.pose(ego.s)
        lat0 = float(rng.normal(0.0, 0.5 * style.lat_sigma))
        xy = xy + lat0 * np.array([-np.sin(h), np.cos(h)])
        pose = np.array([xy[0], xy[1], float(wrap_angle(h + rng.normal(0.0, 0.01)))])
        ego.xy, ego.yaw = pose[:2].copy(), float(pose[2])
        traffic.vehicles.append(ego)
        traffic.populate(pose[:2], ego_keepout=14.0)
        # initial speed: sometimes from rest, else near the (curve-limited) desired speed
        per = traffic.perceive()
        v_des = min(style.v0, float(per["v_curve"][0]))
        ego.v = 0.0 if rng.random() < 0.12 else float(v_des * rng.uniform(0.55, 1.0))
        if rng.random() < 0.8:
            traffic.add_cut_in(ego, style.v0)
        # do not start closer to a leader than the style tolerates
        per = traffic.perceive()
        if np.isfinite(per["gap"][0]):
            ego.v = float(min(ego.v, max((per["gap"][0] - style.s0) / style.T, 0.0),
                              per["v_lead"][0] + 2.0))
        self.style, self.density = style, density
        self.traffic, self.path, self.ego, self.pose = traffic, path, ego, pose
        self.driver = HumanDriver(m, style, rng, dt)
        self.t = 0
        self.kinds: list[str] = []
        self.spawner: Callable[[SceneRun], None] = SceneRun.spawn_arrivals

    def restyle(self, style: HumanStyle) -> None:
        """Drive on from here with ``style`` in place of the drawn one (the start state, the
        traffic and the random stream stay as drawn): the human of another style in the
        same scene, e.g. the population's median style, which no controller that cannot
        see the style can beat."""
        self.style = style
        self.driver.style = style
        for name in ("v0", "T", "a_max", "b", "s0", "a_lat", "gap_crit"):
            setattr(self.ego, name, getattr(style, name))

    def spawn_arrivals(self) -> None:
        """The default :attr:`spawner`: Poisson arrivals at the entries near the ego."""
        self.traffic.spawn(self.pose[:2])

    def ado_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """The ado slots now: boxes ``(max_ados, 5)`` (zeros when unused) and valid flags."""
        boxes = np.zeros((self.max_ados, 5))
        valid = np.zeros(self.max_ados, dtype=bool)
        ados = self.traffic.vehicles[1:]
        if ados:
            boxes[:len(ados)] = [(v.xy[0], v.xy[1], v.yaw, v.length, v.width) for v in ados]
            valid[:len(ados)] = [v.active for v in ados]
        return boxes, valid

    def perceive(self) -> dict[str, np.ndarray]:
        """Stamp the junction arrivals of step :attr:`t`, then every vehicle's constraint."""
        self.traffic.update_stamps(self.t)
        return self.traffic.perceive()

    def human_controls(self, per: dict[str, np.ndarray]) -> tuple[float, float, float]:
        """The human's ``(speed, yaw rate, acceleration)`` now (:meth:`HumanDriver.act`)."""
        gap, stop = float(per["gap"][0]), float(per["stop"][0])
        v_cmd, omega, a = self.driver.act(self.ego, self.path, self.pose, gap,
                                          float(per["v_lead"][0]), stop,
                                          float(per["a_curve"][0]))
        binding = "yield" if stop < gap else ("leader" if gap < np.inf else "")
        self.kinds.append(binding if (a < -0.3 or (binding == "yield" and v_cmd < 0.5)) else "")
        return v_cmd, omega, a

    def advance(self, per: dict[str, np.ndarray], v_cmd: float, omega: float) -> None:
        """Move everything by one step: the ego with ``[v_cmd, omega]``, the ados by their IDM."""
        acc = self.traffic.ado_accelerations(per)
        pose = unicycle_step(self.pose, np.array([v_cmd, omega]), self.dt)
        ego = self.ego
        ego.xy, ego.yaw, ego.v = pose[:2].copy(), float(pose[2]), v_cmd
        ego.s = project_on_path(self.path, ego.s, pose)
        self.pose = pose
        self.traffic.step_ados(acc, ego)
        self.spawner(self)
        self.t += 1

    def human_step(self) -> tuple[float, float]:
        """One step with the human driving; returns its controls ``(speed, yaw rate)``."""
        per = self.perceive()
        v_cmd, omega, _ = self.human_controls(per)
        self.advance(per, v_cmd, omega)
        return v_cmd, omega


def simulate_scene(m: Map, rng: np.random.Generator, T: int = T_STEPS, dt: float = DT,
                   max_ados: int = MAX_ADOS, style: HumanStyle | None = None) -> SceneLog:
    """Simulate one scene on map ``m``: the human ego among IDM ados. See the module doc.

    ``style`` (default: the drawn one) replaces the human's style after the scene is set
    up (:meth:`SceneRun.restyle`)."""
    run = SceneRun(m, rng, dt, max_ados)
    if style is not None:
        run.restyle(style)
    ego_log = np.zeros((T, 3))
    ctl_log = np.zeros((T, 2))
    ado_log = np.zeros((T, max_ados, 5))
    val_log = np.zeros((T, max_ados), dtype=bool)
    for t in range(T):
        ego_log[t] = run.pose
        ado_log[t], val_log[t] = run.ado_boxes()
        ctl_log[t] = run.human_step()
    return SceneLog(ego_log, ctl_log, run.pose, ado_log, val_log, scene_tags(run, ctl_log))


def scene_tags(run: SceneRun, controls: np.ndarray) -> dict:
    """The tags of a scene simulated by ``run`` with the human's ``controls (T, 2)``."""
    m, kinds, traffic = run.m, run.kinds, run.traffic
    return {
        "kind": m.kind,
        "has_junction": bool(m.has_junction),
        "has_roundabout": bool(m.has_roundabout),
        "has_cut_in": bool(traffic.cut_in_done),
        "turn": _route_turn(m),
        "yield_steps": int(sum(k == "yield" for k in kinds)),
        "follow_steps": int(sum(k == "leader" for k in kinds)),
        "stopped_steps": int(np.sum(controls[:, 0] < 0.3)),
        "n_ados": int(len(traffic.vehicles) - 1),
        "density": run.density,
        "style": asdict(run.style),
    }


def _route_turn(m: Map) -> str:
    for lid in m.route:
        if m.lanes[lid].turn in ("straight", "left", "right"):
            return m.lanes[lid].turn
    if m.kind == "roundabout":
        return f"exit{int(m.recipe['ego']['exits'])}"
    return "road"


def check_scene(m: Map, log: SceneLog, substeps: int = 4) -> tuple[bool, bool]:
    """(off_road, collision) for a scene log: ego footprint vs drivable area and ado boxes.

    Checks the logged steps and ``substeps - 1`` linear interpolations between
    consecutive steps (for ados valid at both ends).
    """
    T, A = log.ado_valid.shape
    poses = np.concatenate([log.ego, log.final_pose[None]], axis=0)
    ego_box = np.concatenate([poses, np.tile([EGO_LENGTH, EGO_WIDTH], (T + 1, 1))], axis=1)
    off_road = not bool(np.all(m.is_drivable(box_corners(ego_box[:T]))))
    f = np.arange(substeps) / substeps  # (F,)
    e0, e1 = ego_box[:-2], ego_box[1:-1]  # (T-1, 5): interpolate between logged steps
    e = e0[:, None, :] + f[None, :, None] * (e1 - e0)[:, None, :]
    e[..., 2] = e0[:, None, 2] + f[None, :] * wrap_angle(e1[:, 2] - e0[:, 2])[:, None]
    a0, a1 = log.ado[:-1], log.ado[1:]  # (T-1, A, 5)
    a = a0[:, None] + f[None, :, None, None] * (a1 - a0)[:, None]
    a[..., 2] = a0[:, None, :, 2] + f[None, :, None] * wrap_angle(a1[..., 2] - a0[..., 2])[:, None]
    ok = (log.ado_valid[:-1] & log.ado_valid[1:])[:, None, :].repeat(substeps, axis=1)
    ok[:, 0] = log.ado_valid[:-1]
    e = np.concatenate([e.reshape(-1, 5), ego_box[T - 1:T]], axis=0)  # + the last step
    a = np.concatenate([a.reshape(-1, A, 5), log.ado[T - 1:T]], axis=0)
    ok = np.concatenate([ok.reshape(-1, A), log.ado_valid[T - 1:T]], axis=0)
    near = ok & (np.hypot(a[..., 0] - e[:, None, 0], a[..., 1] - e[:, None, 1])
                 < (np.hypot(a[..., 3], a[..., 4]) + np.hypot(EGO_LENGTH, EGO_WIDTH)) / 2)
    ti, ai = np.nonzero(near)
    collision = bool(len(ti)) and bool(boxes_overlap(e[ti], a[ti, ai]).any())
    return off_road, collision
