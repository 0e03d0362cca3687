"""The data every measurement of this study reads: the seed-0 draw and what the human perceives.

The draw is the paper preset's: 850 scenes of the world, seed 0, generated once with
``minimanc data generate --scenes 850 --seed 0`` into :data:`DATA_DIR` (outside git).
:func:`targets` computes, for every logged state, what the world's human perceives there
(:func:`minimanc.diagnose.privileged.features`, the targets of the perception) and what the
measurements need beyond it: the leader's box in the ego frame, its speed, and whether
the human brakes because of it (the car-following term binds). It is cached per block of
scenes under :data:`DATA_DIR` (a killed run resumes where it stopped).

The protocol, fixed before any validation number was looked at (see README.md): train on
scenes 0–299 (0–599 for the scale check), validate on scenes 600–799.
"""

from __future__ import annotations

import copy
import math
import os
from pathlib import Path

import numpy as np

from minimanc.dagger.expert import HumanExpert
from minimanc.diagnose import privileged
from minimanc.world import load, to_ego_frame
from minimanc.world.car_following import acc_acceleration
from minimanc.world.geometry import DT, EGO_LENGTH

DATA_DIR = Path(os.environ.get("SEEING_DATA",
                               Path(__file__).resolve().parents[2] / "runs" / "seeing_the_leader"))
"""Where the draw and every cache of this study live (``runs/seeing_the_leader`` of the
checkout, which git ignores; ``SEEING_DATA`` names another directory)."""
WORLD_FILE = Path(os.environ.get("SEEING_WORLD", DATA_DIR / "world_850x0.npz"))
"""The seed-0 draw (``minimanc data generate --scenes 850 --seed 0``); a longer draw of the
same seed (``SEEING_WORLD``) starts with the same 850 scenes and adds scenes for the data
scale check."""
TRAIN = range(0, 300)
"""Training scenes of every perception variant."""
TRAIN_LARGE = range(0, 600)
"""Training scenes of the scale check."""
VALIDATE = range(600, 800)
"""Validation scenes (the paper preset's 650/40/200 split keeps 650–849 apart; 600–799 are
never trained on here)."""
BLOCK = 50
"""Scenes per cache block of :func:`targets`."""
FEATURES = privileged.FEATURES
"""The expert's perceived numbers, in the order of :func:`minimanc.diagnose.privileged.features`."""
FAR = privileged.FAR
"""Distances are clipped here (m)."""


def world():
    """The seed-0 draw (:data:`WORLD_FILE`)."""
    if not WORLD_FILE.exists():
        raise SystemExit(f"{WORLD_FILE} is missing: run  minimanc data generate --scenes 850 "
                         f"--seed 0 --out {DATA_DIR}")
    return load(WORLD_FILE)


def _ego_frame_box(traffic, who: int, pose: np.ndarray) -> tuple[np.ndarray, float]:
    """Vehicle ``who``'s box ``[x, y, yaw, length, width]`` in the frame of ``pose`` and its
    speed (NaN for ``who < 0``)."""
    if who < 0:
        return np.full(5, np.nan), math.nan
    veh = traffic.vehicles[who]
    xy = to_ego_frame(np.asarray(veh.xy, dtype=np.float64), pose)
    return np.array([xy[0], xy[1], veh.yaw - pose[2], veh.length, veh.width]), float(veh.v)


def _state(expert: HumanExpert, s: int, t: int, pose: np.ndarray, a_prev: float,
           step) -> dict:
    """Everything about one logged state (see :func:`targets`)."""
    sit = expert.situation(s, t, pose, step.speed)
    feat = privileged.features(sit, a_prev)
    # the leader's identity: the same perception on a copy of the human's own run
    base = step.traffic
    w = copy.copy(base)
    w.vehicles = [copy.copy(v) for v in base.vehicles]
    w.going = set(base.going)
    w.update_stamps(int(t))
    per = w.perceive()
    box, v_lead = _ego_frame_box(w, int(per["who"][0]), pose)
    stop_box, _ = _ego_frame_box(w, int(per["stop_who"][0]), pose)
    st = step.driver.style
    v = float(step.speed)
    v0 = max(st.v0 * step.driver.speed_factor, 1e-3)
    kw = dict(a_max=st.a_max, b=st.b, s0=st.s0, T=st.T)
    a_free = float(acc_acceleration(v, v0, math.inf, 0.0, **kw))
    gap = float(per["gap"][0])
    a_lead = float(acc_acceleration(v, v0, gap, float(per["v_lead"][0]), **kw)) \
        if math.isfinite(gap) else math.inf
    stop = float(per["stop"][0])
    a_stop = float(acc_acceleration(v, v0, stop, 0.0, **kw)) if math.isfinite(stop) \
        else math.inf
    a_curve = float(per["a_curve"][0])
    return {"features": feat, "lead_box": box, "stop_box": stop_box, "v_lead": v_lead,
            "gap_raw": gap,
            "a_free": a_free, "a_lead": a_lead, "a_stop": a_stop, "a_curve": a_curve}


def _block(ds, scenes: range) -> dict[str, np.ndarray]:
    expert = HumanExpert(ds, cache=2)
    pose = np.asarray(ds.ego, dtype=np.float64)
    rows: list[dict] = []
    for s in scenes:
        steps = expert.steps(s)
        for t, step in enumerate(steps):
            a_prev = (step.speed - steps[t - 1].speed) / DT if t else 0.0
            rows.append(_state(expert, s, t, pose[s, t], a_prev, step))
    return {k: np.stack([np.asarray(r[k], dtype=np.float64) for r in rows]) for k in rows[0]}


def targets(ds=None, progress: bool = True) -> dict[str, np.ndarray]:
    """Per logged state of the 850 scenes, ``(S, T, ...)`` arrays (cached under DATA_DIR):

    ``features`` (:data:`FEATURES`), ``lead_box`` the leader ``[x, y, yaw, length, width]``
    in the ego frame (NaN without one; the leader the human's perception finds, up to
    ``25 + 3.5 v`` m ahead along its path), ``stop_box`` the vehicle the human yields to at
    its yield point (NaN without one), ``v_lead``, ``gap_raw`` (unclipped, inf without
    a leader), and the human's commanded accelerations by constraint: ``a_free`` (free
    road), ``a_lead`` (the car-following term, inf without a leader), ``a_stop`` (the
    yield point), ``a_curve`` (curves).
    """
    ds = world() if ds is None else ds
    S, T = np.asarray(ds.ego).shape[:2]
    parts = []
    for a in range(0, S, BLOCK):
        path = DATA_DIR / "targets" / f"block_{a:04d}.npz"
        if not path.exists():
            if progress:
                print(f"targets: scenes {a}-{min(a + BLOCK, S) - 1}", flush=True)
            block = _block(ds, range(a, min(a + BLOCK, S)))
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(".tmp.npz")
            np.savez(tmp, **block)
            os.replace(tmp, path)
        with np.load(path) as f:
            parts.append({k: f[k] for k in f.files})
    out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    return {k: v.reshape(S, T, *v.shape[1:]) for k, v in out.items()}


def leader_brakes(tg: dict[str, np.ndarray], margin: float = 0.05) -> np.ndarray:
    """``(S, T)`` bool: the human brakes because of its leader — the car-following term is
    the binding one (below the free-road term by more than ``margin`` m/s², and not above
    the yield-point and curve terms) and asks for a deceleration."""
    a_lead = tg["a_lead"]
    binds = (np.isfinite(a_lead) & (a_lead < tg["a_free"] - margin)
             & (a_lead <= tg["a_stop"]) & (a_lead <= tg["a_curve"]))
    return binds & (a_lead < 0.0)


def leader_binds(tg: dict[str, np.ndarray], margin: float = 0.05) -> np.ndarray:
    """``(S, T)`` bool: the car-following term is the binding one (it lowers the command by
    more than ``margin`` m/s² and is not above the yield-point and curve terms), braking or
    not."""
    a_lead = tg["a_lead"]
    return (np.isfinite(a_lead) & (a_lead < tg["a_free"] - margin)
            & (a_lead <= tg["a_stop"]) & (a_lead <= tg["a_curve"]))


def leader_reach(tg: dict[str, np.ndarray]) -> np.ndarray:
    """``(S, T)`` how far ahead (m, ego frame) the raster must reach to show the leader's
    rear: the nearest point of its box along the ego's x axis (NaN without a leader)."""
    x, yaw, ln, wd = (tg["lead_box"][..., i] for i in (0, 2, 3, 4))
    half_x = 0.5 * (np.abs(np.cos(yaw)) * ln + np.abs(np.sin(yaw)) * wd)
    return x - half_x


def leader_side(tg: dict[str, np.ndarray]) -> np.ndarray:
    """``(S, T)`` the leader centre's lateral offset (m, ego frame; NaN without a leader)."""
    return tg["lead_box"][..., 1]


def in_view(tg: dict[str, np.ndarray], metres_ahead: float, metres_side: float) -> np.ndarray:
    """``(S, T)`` bool: there is a leader and its box reaches into a view of
    ``metres_ahead`` × ``±metres_side`` (its rear within reach, its centre within the side)."""
    reach = leader_reach(tg)
    side = np.abs(leader_side(tg))
    with np.errstate(invalid="ignore"):
        return np.isfinite(reach) & (reach < metres_ahead) & (side < metres_side)


EGO_HALF = EGO_LENGTH / 2
"""Half the ego's length (m): a gap (bumper to bumper) of ``g`` puts the leader's rear at
``g + EGO_HALF`` ahead of the ego's centre."""


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description="Compute (or complete) the cached per-state "
                                 "targets of the seed-0 draw.")
    ap.parse_args()
    tg = targets()
    print({k: v.shape for k, v in tg.items()})
