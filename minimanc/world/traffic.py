"""Chapter 7 — traffic: ado vehicles that follow lanes with the Intelligent Driver Model.

Every vehicle (the ados here, and the human ego of :mod:`minimanc.world.driver`)
drives along a *path* — a sequence of lanes concatenated into one polyline —
and chooses its acceleration with the **Intelligent Driver Model** (Treiber,
Hennecke & Helbing 2000)::

    a = a_max [ 1 - (v / v0)^4 - (s* / gap)^2 ],
    s* = s0 + max(0, v T + v (v - v_lead) / (2 sqrt(a_max b)))

against the most constraining of

* the **leader**: any vehicle whose box overlaps the vehicle's corridor
  ahead (its path, widened by the two half widths) — this covers car
  following, vehicles merging or cutting in, and vehicles standing across
  the path;
* **junction conflicts**: where its path crosses or merges with another
  vehicle's path inside an intersection or roundabout (the map's conflict
  table), the vehicle without priority treats the conflict entry as a
  stopped obstacle. Priority: a vehicle that can no longer stop
  (*committed*) goes first; the roundabout ring has priority over entries;
  at intersections the first to arrive goes first. A yielding vehicle may
  still go when the other one is far enough (gap acceptance: the other's
  earliest arrival is later than its own clearing time plus a critical gap);
* the **speed profile** of the path: curvature limits the speed to
  ``sqrt(a_lat / |kappa|)`` and the desired speed anticipates curves with a
  comfortable deceleration.

Ados are placed along the lanes at the start (density varies per scene),
spawn at the map's entry lanes over time, leave at its exits, and some of
them *cut in* in front of the ego: they drive faster in the adjacent lane and
change lanes when a few metres ahead of it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from minimanc.world.car_following import (
    acc_acceleration,
    curve_braking,
    earliest_arrival,
    idm_acceleration,
)
from minimanc.world.geometry import project_to_polyline, wrap_angle
from minimanc.world.lanes import LANE_WIDTH, Map
from minimanc.world.paths import (
    Path,
    PathBank,
    Vehicle,
    corridor_leaders,
    random_lane_walk,
    random_vehicle_size,
)

__all__ = [
    "B_COMFORT",
    "B_COMMIT",
    "B_MAX",
    "CONFLICT_MARGIN",
    "LANE_OFFSET",
    "Path",
    "PathBank",
    "Traffic",
    "Vehicle",
    "WIN_POINTS",
    "WIN_STRIDE",
    "acc_acceleration",
    "corridor_leaders",
    "curve_braking",
    "earliest_arrival",
    "idm_acceleration",
    "random_lane_walk",
    "random_vehicle_size",
]

LANE_OFFSET = LANE_WIDTH
"""Lateral distance between adjacent same-direction lanes (m)."""

B_COMMIT = 4.0
"""Deceleration (m/s^2) above which a vehicle can no longer stop before a conflict: committed."""
B_COMFORT = 2.0
"""A vehicle that accepted a gap only gives it up if it can stop braking at most this (m/s^2)."""
B_MAX = 8.0
"""Physical braking limit (m/s^2)."""
CONFLICT_MARGIN = 0.5
"""Yielding vehicles treat ``conflict entry - CONFLICT_MARGIN`` as the stop point (m)."""


WIN_STRIDE = 2
"""Corridor samples take every 2nd path vertex (~2 m apart; vertices are <= 1 m apart)."""
WIN_POINTS = 44
"""Corridor samples per vehicle: from just behind it to ~85 m ahead."""


def _fields(vehicles: list[Vehicle], *names: str) -> tuple[np.ndarray, ...]:
    """One array per attribute name, over ``vehicles`` in order."""
    return tuple(np.array([getattr(v, n) for v in vehicles]) for n in names)


class Traffic:
    """All vehicles of a scene and the rules that move them (the ego included).

    ``vehicles[0]`` is the ego (its pose is written by the driver); the ados
    follow. Each step: :meth:`perceive` (every vehicle's binding constraint
    and curve-limited desired speed, vectorised), then
    :meth:`ado_accelerations` and :meth:`step_ados`.
    """

    def __init__(self, m: Map, rng: np.random.Generator, dt: float, density: float,
                 max_ados: int, spawn_rate: float) -> None:
        self.m = m
        self.rng = rng
        self.dt = dt
        self.density = density
        self.max_ados = max_ados
        self.spawn_rate = spawn_rate
        self.bank = PathBank()
        self._pids: dict[tuple[int, ...], int] = {}
        self.vehicles: list[Vehicle] = []
        self.sources = [ln.id for ln in m.lanes if ln.kind == "road" and not ln.predecessors]
        self.cut_in_done = False
        self.going: set = set()  # (i, j, lane_i, lane_j) where i accepted a gap and goes
        self.scripted_walks: dict[int, list[int]] | None = None  # see own_lane_walk
        self.walk_log: dict[int, list[int]] | None = None

    def path(self, veh: Vehicle) -> Path:
        return self.bank.paths[veh.pid]

    # ------------------------------------------------------------------ population
    def ado_params(self, length: float, width: float) -> dict:
        r = self.rng
        big = length > 7.0
        return dict(
            length=length, width=width,
            v0=float(r.uniform(7.0, 12.0) if big else r.uniform(8.0, 14.5)),
            T=float(r.uniform(1.0, 2.0)),
            a_max=float(r.uniform(0.8, 1.2) if big else r.uniform(1.0, 2.2)),
            b=float(r.uniform(1.8, 2.8)), s0=float(r.uniform(1.8, 3.0)),
            a_lat=float(r.uniform(1.8, 2.8)), gap_crit=float(r.uniform(1.6, 3.2)),
        )

    def add_ado(self, lanes: list[int], s: float, v: float, **extra) -> Vehicle | None:
        if len(self.vehicles) - 1 >= self.max_ados:
            return None
        L, W = random_vehicle_size(self.rng)
        p = self.ado_params(L, W)
        p.update(extra)
        pid = self.path_id(lanes)
        path = self.bank.paths[pid]
        veh = Vehicle(pid=pid, s=s, v=v, **p)
        xy, h = path.pose(s)
        veh.xy, veh.yaw = xy, h
        self.vehicles.append(veh)
        return veh

    def path_id(self, lanes: list[int]) -> int:
        """The index in :attr:`bank` of the path along ``lanes`` (added on first use: vehicles
        on the same lane sequence share one path)."""
        key = tuple(int(i) for i in lanes)
        pid = self._pids.get(key)
        if pid is None:
            pid = self._pids[key] = self.bank.add(Path.from_lanes(self.m, list(key)))
        return pid

    def insert(self, veh: Vehicle, lanes: list[int]) -> Vehicle:
        """Append a copy of ``veh`` (a vehicle of another run of this scene) on the path along
        ``lanes``, at its arc length, speed and parameters; returns the copy."""
        new = replace(veh, pid=self.path_id(lanes), xy=np.array(veh.xy, dtype=np.float64),
                      cut_in=None if veh.cut_in is None else dict(veh.cut_in))
        self.vehicles.append(new)
        return new

    def place(self, vehicles: list[Vehicle]) -> None:
        """Set ``xy`` and ``yaw`` of path-following vehicles from their ``s`` and offset."""
        if not vehicles:
            return
        pid, s, off, rate, speed = _fields(vehicles, "pid", "s", "offset", "offset_rate", "v")
        speed = np.maximum(speed, 1.0)
        xy, h, _ = self.bank.query(pid, s)
        xy = xy + off[:, None] * np.stack([-np.sin(h), np.cos(h)], axis=1)
        yaw = wrap_angle(h + np.arctan2(rate, speed))
        for veh, p, y in zip(vehicles, xy, yaw.tolist()):
            veh.xy = p
            veh.yaw = y

    def clear_of(self, xy: np.ndarray, radius: float) -> bool:
        pts = [v.xy for v in self.vehicles if v.active]
        if not pts:
            return True
        d = np.asarray(pts) - xy
        return bool(np.all(d[:, 0] ** 2 + d[:, 1] ** 2 >= radius * radius))

    def populate(self, ego_xy: np.ndarray, ego_keepout: float, radius: float = 250.0) -> None:
        """Place ados along the road lanes at the scene's density (not on junction lanes).

        Only within ``radius`` m of the ego (farther ados could not reach it
        within a scene) and outside ``ego_keepout``. Each lane is filled from
        its end backwards so that every new ado knows the one ahead and starts
        no faster than a safe following speed.
        """
        for lane in self.m.lanes:
            if lane.kind != "road":
                continue
            s = lane.length - 6.0 - float(self.rng.exponential(1.0 / self.density))
            ahead_s, ahead_v = np.inf, 0.0
            while s > 4.0:
                i = min(int(np.searchsorted(lane.s, s)), len(lane.s) - 1)
                xy = lane.points[i]
                d = float(np.hypot(*(xy - ego_xy)))
                if ego_keepout < d < radius and self.clear_of(xy, 9.0):
                    ids = random_lane_walk(self.m, self.rng, lane.id, 450.0 + s)
                    v = float(self.rng.uniform(5.0, 12.5))
                    if np.isfinite(ahead_s):
                        gap = ahead_s - s - 6.0
                        v = min(v, max((gap - 2.0) / 1.5, 0.0), ahead_v + 1.0)
                    veh = self.add_ado(ids, s, v)
                    if veh is None:
                        return
                    ahead_s, ahead_v = s, v
                s -= 9.0 + float(self.rng.exponential(1.0 / self.density))

    def spawn(self, ego_xy: np.ndarray, radius: float = 300.0) -> None:
        """Poisson arrivals at the map's entry lanes within ``radius`` m of the ego.

        Entries farther away cannot bring a vehicle near the ego within a scene.
        """
        for lid in self.sources:
            lane = self.m.lanes[lid]
            d = lane.points[0] - ego_xy
            if d[0] * d[0] + d[1] * d[1] > radius * radius:
                continue
            if self.rng.random() < self.spawn_rate * self.dt:
                if self.clear_of(lane.points[0], 16.0):
                    ids = random_lane_walk(self.m, self.rng, lid, 450.0)
                    self.add_ado(ids, 0.0, float(self.rng.uniform(6.0, 11.0)))

    # ------------------------------------------------------------------ perception
    def perceive(self) -> dict[str, np.ndarray]:
        """Every vehicle's binding constraint (vectorised corridors + junction conflicts).

        Returns arrays over vehicles: ``gap``, ``v_lead`` and ``who`` of the
        leader (``inf``, 0, -1 if none), ``stop`` and ``stop_who`` — the
        distance to the stop point of a junction conflict where the vehicle
        must yield, and to whom (``inf``, -1 if none) — ``a_curve`` (the
        acceleration bound of the curves ahead) and ``v_curve`` (the lowest
        curve speed limit ahead). The vehicle obeys the most constraining of
        leader, stop point and curves.
        """
        vs = self.vehicles
        n = len(vs)
        act = [i for i, v in enumerate(vs) if v.active]
        sub = [vs[i] for i in act]
        boxes, speeds, pid, s, L, W, off = _fields(sub, "box", "v", "pid", "s", "length", "width",
                                                   "offset")
        win, wh, ws, wk, inside = self.bank.window(pid, s, WIN_POINTS, WIN_STRIDE)
        if np.any(off != 0.0):
            win = win + off[:, None, None] * np.stack([-np.sin(wh), np.cos(wh)], axis=-1)
        ahead = ws - s[:, None]  # distance of each sample ahead of the vehicle's centre
        look = 25.0 + 3.5 * speeds
        ok = inside & (ahead <= look[:, None])
        g, vl_, who_ = corridor_leaders(win, wh, ws, ok, s, L, W, boxes, speeds,
                                        np.ones(len(sub), bool), float(WIN_STRIDE))
        act_arr = np.array(act)
        gap = np.full(n, np.inf)
        vl = np.zeros(n)
        who = np.full(n, -1)
        gap[act_arr], vl[act_arr] = g, vl_
        who[act_arr] = np.where(who_ >= 0, act_arr[np.maximum(who_, 0)], -1)
        # junction conflicts (only for vehicles near a junction)
        windows = [self.junction_window(v) if v.active else [] for v in vs]
        near = [i for i in act if windows[i]]
        stop = np.full(n, np.inf)
        stop_who = np.full(n, -1)
        for i in near:
            if len(near) > 1:
                stop[i], stop_who[i] = self.conflict_stop(i, windows, near)
        # desired speed limited by the curvature ahead (braking-feasible)
        a_lat = np.array([v.a_lat for v in sub])[:, None]
        vlim2 = np.where(inside & (ahead >= 0.0), a_lat / np.maximum(wk, 1e-4), np.inf)
        a_curve = np.full(n, np.inf)
        a_curve[act_arr] = curve_braking(speeds, vlim2, np.maximum(ahead, 0.0), self.dt)
        v_curve = np.full(n, np.inf)
        v_curve[act_arr] = np.sqrt(vlim2.min(axis=1))
        return {"gap": gap, "v_lead": vl, "who": who, "stop": stop, "stop_who": stop_who,
                "a_curve": a_curve,
                "v_curve": v_curve}

    def committed(self, veh: Vehicle, s_in: float, b: float = B_COMMIT) -> bool:
        """Whether ``veh`` can no longer stop before the conflict entry ``s_in`` (braking ``b``)."""
        d = s_in - CONFLICT_MARGIN - (veh.s + veh.length / 2)
        return d <= 0.0 or veh.v * veh.v > 2.0 * b * d

    def junction_window(self, veh: Vehicle) -> list[tuple[int, float]]:
        """Junction lanes of ``veh``'s path it has not cleared, within its horizon."""
        horizon = 20.0 + 4.0 * veh.v
        rear = veh.s - veh.length / 2
        path = self.path(veh)
        if not path.junction_lanes or veh.s + horizon < path.junction_lanes[0][1]:
            return []
        out = []
        for lid, st in path.junction_lanes:
            if st + self.m.lanes[lid].length > rear and st < veh.s + horizon:
                out.append((lid, st))
        return out

    def conflict_stop(self, i: int, windows: list, near: list[int]) -> tuple[float, int]:
        """Distance from vehicle ``i``'s front to the nearest conflict where it must yield.

        ``windows[j]`` are the junction lanes ahead of vehicle ``j``; ``near`` the
        active vehicles that have any.
        """
        me = self.vehicles[i]
        best, who = np.inf, -1
        for j in near:
            if j == i:
                continue
            other = self.vehicles[j]
            for la, sa in windows[i]:
                for lb, sb in windows[j]:
                    c = self.m.conflicts.get((la, lb))
                    if c is None:
                        continue
                    cb = self.m.conflicts[(lb, la)]
                    i_in, i_out = sa + c[0], sa + c[1]
                    j_in, j_out = sb + cb[0], sb + cb[1]
                    if me.s - me.length / 2 > i_out or other.s - other.length / 2 > j_out:
                        continue  # one of them has cleared the conflict
                    if not self.must_yield(me, other, la, lb, i_in, i_out, j_in, (i, j, la, lb)):
                        continue
                    d = i_in - CONFLICT_MARGIN - (me.s + me.length / 2)
                    if d < best:
                        best, who = d, j
        return best, who

    def must_yield(self, me: Vehicle, other: Vehicle, la: int, lb: int,
                   i_in: float, i_out: float, j_in: float, key: tuple) -> bool:
        """Priority rules at a conflict between ``me`` (lane ``la``) and ``other`` (``lb``).

        A vehicle that accepted a gap keeps going unless it can still stop
        comfortably (hysteresis: no stop-and-go flicker when estimates change).
        """
        if self.committed(me, i_in):
            return False
        if key in self.going and self.committed(me, i_in, B_COMFORT):
            return False
        if not self.committed(other, j_in):
            ka, kb = self.m.lanes[la].kind, self.m.lanes[lb].kind
            if ka == "ring" and kb != "ring":
                return False
            if not (kb == "ring" and ka != "ring"):
                # first come, first served; ties: the one closer to the conflict
                if (me.stamp, i_in - me.s) < (other.stamp, j_in - other.s):
                    return False
        # gap acceptance: go anyway if the other arrives well after I have cleared
        t_other = earliest_arrival(j_in - (other.s + other.length / 2), other.v,
                                   other.v0, other.a_max)
        t_clear = earliest_arrival(i_out + me.length / 2 + 1.0 - me.s, me.v, me.v0, me.a_max)
        if t_other < t_clear + me.gap_crit:
            self.going.discard(key)
            return True
        self.going.add(key)
        return False

    def update_stamps(self, t: int) -> None:
        """Record when each vehicle reaches the approach zone of its junction."""
        for veh in self.vehicles:
            if not veh.active or np.isfinite(veh.stamp):
                continue
            for _lid, st in self.path(veh).junction_lanes:
                d = st - (veh.s + veh.length / 2)
                if -1.0 < d < 12.0 + veh.v * veh.v / 4.0:
                    veh.stamp = float(t)
                    break

    # ------------------------------------------------------------------ dynamics
    def ado_accelerations(self, per: dict[str, np.ndarray]) -> np.ndarray:
        """Accelerations ``(N,)`` from :meth:`perceive`.

        The ACC model against the leader and against the stop point, capped by
        curve braking.
        """
        vs = self.vehicles
        v, a_max, v0, b, s0, T = _fields(vs, "v", "a_max", "v0", "b", "s0", "T")
        a = acc_acceleration(v, v0, per["gap"], per["v_lead"], a_max, b, s0, T)
        a_stop = acc_acceleration(v, v0, per["stop"], 0.0, a_max, b, s0, T)
        return np.clip(np.minimum(np.minimum(a, a_stop), per["a_curve"]), -B_MAX, a_max)

    def step_ados(self, acc: np.ndarray, ego: Vehicle) -> None:
        """Move every active ado by one step (ballistic update, speeds never negative)."""
        dt = self.dt
        moved = []
        for i, veh in enumerate(self.vehicles):
            if veh.is_ego or not veh.active:
                continue
            a = float(acc[i])
            v_new = max(veh.v + a * dt, 0.0)
            if v_new == 0.0 and a < 0:  # stops within the step
                ds = veh.v * veh.v / (2 * -a) if veh.v > 0 else 0.0
            else:
                ds = 0.5 * (veh.v + v_new) * dt
            veh.s += ds
            veh.v = v_new
            if veh.cut_in is not None:
                self._cut_in_lateral(veh, ego)
            if veh.s >= self.path(veh).length - 0.5:
                veh.active = False
            moved.append(veh)
        self.place(moved)

    # ------------------------------------------------------------------ cut-ins
    def _cut_in_lateral(self, veh: Vehicle, ego: Vehicle) -> None:
        ci = veh.cut_in
        dt = self.dt
        if not ci["started"]:
            # rear of the ado ahead of the ego's front by the chosen gap, on the same path
            ahead = (veh.s - veh.length / 2) - (ego.s + ego.length / 2)
            if ci["gap"] <= ahead <= ci["gap"] + 8.0 and veh.v >= ego.v:
                if (veh.s + veh.v * ci["duration"] + 10.0 < ci["s_max"]
                        and self._room_ahead(veh) >= 4.0 + 0.7 * veh.v):
                    ci["started"] = True
                    ci["t"] = 0.0
            elif ahead > ci["gap"] + 8.0 or veh.s > ci["s_max"]:
                self._to_own_lane(veh)  # the chance has passed: stays in its lane
                return
        if ci["started"]:
            ci["t"] += dt
            f = min(ci["t"] / ci["duration"], 1.0)
            new = ci["d0"] * 0.5 * (1 + np.cos(np.pi * f))  # d0 -> 0 smoothly
            veh.offset_rate = (new - veh.offset) / dt
            veh.offset = float(new)
            if f >= 1.0:
                veh.offset, veh.offset_rate = 0.0, 0.0
                veh.cut_in = None
                self.cut_in_done = True

    def _room_ahead(self, veh: Vehicle) -> float:
        """Free distance ahead of ``veh`` along its path's centreline (the target lane)."""
        path = self.path(veh)
        w = path.window(veh.s, veh.s + 80.0)
        others = [o for o in self.vehicles if o is not veh and o.active and not o.is_ego]
        if not others or w.stop - w.start < 2:
            return np.inf
        xy = np.array([o.xy for o in others])
        s, lat = project_to_polyline(path.points[w], path.s[w], xy)
        lengths = np.array([o.length for o in others])
        gaps = s - lengths / 2 - (veh.s + veh.length / 2)
        ok = (np.abs(lat) < 2.2) & (s > veh.s) & (s < path.s[w][-1] - 0.5)
        return float(gaps[ok].min()) if ok.any() else np.inf

    def own_lane_walk(self, veh: Vehicle, lid: int) -> list[int]:
        """The lanes ``veh`` follows from lane ``lid`` when it gives up a cut-in.

        A random walk (:func:`random_lane_walk`), unless :attr:`scripted_walks`
        holds one for ``veh``'s index in :attr:`vehicles` (a replay of another
        run); each walk taken is written to :attr:`walk_log` when that is a dict.
        """
        k = next(i for i, v in enumerate(self.vehicles) if v is veh)
        if self.scripted_walks is not None and k in self.scripted_walks:
            ids = list(self.scripted_walks[k])
        else:
            ids = random_lane_walk(self.m, self.rng, lid, 450.0)
        if self.walk_log is not None:
            self.walk_log[k] = list(ids)
        return ids

    def _to_own_lane(self, veh: Vehicle) -> None:
        """Give up a cut-in: continue on the adjacent lane's own path."""
        lid = veh.cut_in["lane"]
        lane = self.m.lanes[lid]
        i = int(np.argmin(np.sum((lane.points - veh.xy) ** 2, axis=1)))
        ids = self.own_lane_walk(veh, lid)
        veh.pid = self.bank.add(Path.from_lanes(self.m, ids))
        veh.s = float(lane.s[i])
        veh.offset = veh.offset_rate = 0.0
        veh.stamp = np.inf
        veh.cut_in = None

    def add_cut_in(self, ego: Vehicle, ego_v0: float) -> bool:
        """Set up an ado that will cut in front of the ego from an adjacent lane.

        Looks for a route lane with a same-direction neighbour and at least
        60 m of it left ahead of the ego; the ado starts a little behind the
        ego in that neighbour lane, faster, and changes into the ego's lane
        once its rear is ``gap`` metres ahead of the ego's front.
        """
        path = self.path(ego)
        for lid, st in zip(path.lanes, path.starts):
            lane = self.m.lanes[lid]
            if lane.kind != "road":
                continue
            nb = [(n, sgn) for n, sgn in ((lane.left, 1.0), (lane.right, -1.0)) if n >= 0]
            end = st + lane.length - 15.0
            if not nb or end - ego.s < 60.0 or st > ego.s + 40.0:
                continue
            n, sgn = nb[int(self.rng.integers(len(nb)))]
            s = max(ego.s + float(self.rng.uniform(-20.0, 5.0)), st + 5.0)
            xy, h = path.pose(s)
            xy = xy + sgn * LANE_OFFSET * np.array([-np.sin(h), np.cos(h)])
            # make room in the neighbour lane
            self.vehicles = [v for v in self.vehicles
                             if v.is_ego or np.hypot(*(v.xy - xy)) >= 25.0]
            v = max(ego.v + float(self.rng.uniform(2.0, 5.5)), 6.0)
            veh = self.add_ado(list(path.lanes), s, v,
                               v0=ego_v0 + float(self.rng.uniform(2.0, 5.0)))
            if veh is None:
                return False
            veh.offset = sgn * LANE_OFFSET
            veh.xy = xy
            veh.cut_in = {"gap": float(self.rng.uniform(3.0, 10.0)),
                          "duration": float(self.rng.uniform(2.0, 3.5)),
                          "started": False, "s_max": end, "d0": sgn * LANE_OFFSET, "lane": n}
            return True
        return False
