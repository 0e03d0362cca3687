"""How far ahead and to the side must the raster reach? Where the leaders the human brakes for are.

For every logged state of the seed-0 draw (850 scenes × 40 steps, :mod:`leader_data`): the
leader the world's human perceives (its corridor, up to ``25 + 3.5 v`` m ahead along its
path) and whether the human *brakes because of it* — the car-following term is the binding
constraint (below the free-road, yield-point and curve terms) and asks for a deceleration.
The distance the raster must reach to show that leader is its box's nearest point along the
ego's axis; its centre's lateral offset says how wide the view must be. The same for the
vehicle the human yields to at a junction (whether to yield is one of the targets). Then the
cost of each view: pixels at today's 0.78 m/px and at 0.5 m/px, bytes per stored frame.

Run: ``python research/seeing_the_leader/reach.py`` (writes ``results/reach.md``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import leader_data as L
import numpy as np

from minimanc.studies import provenance
from minimanc.world import RasterConfig

RESULTS = Path(__file__).resolve().parent / "results"
AHEAD = (40.0, 45.0, 50.0, 55.0, 60.0, 70.0, 80.0)
SIDES = (12.0, 16.0, 20.0, 25.0)


def _pct(x: np.ndarray, q) -> str:
    return " / ".join(f"{v:.1f}" for v in np.percentile(x, q))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(RESULTS / "reach.md"))
    args = ap.parse_args()
    t0 = time.perf_counter()
    tg = L.targets(progress=False)
    ds = L.world()
    kind = np.array([t["kind"] for t in ds.tags])
    junction = np.broadcast_to(np.isin(kind, ("intersection", "roundabout"))[:, None],
                               tg["gap_raw"].shape)
    reach, side = L.leader_reach(tg), np.abs(L.leader_side(tg))
    has = np.isfinite(reach)
    brakes, binds = L.leader_brakes(tg), L.leader_binds(tg)
    gap = tg["gap_raw"]
    groups = {
        "the human brakes because of its leader": brakes,
        "the car-following term binds (braking or not)": binds,
        "every leader": has,
        "leaders within 60 m (gap)": has & (gap <= 60.0),
        "brakes, scenes with a junction or roundabout": brakes & junction,
        "brakes, roads without one": brakes & ~junction,
    }
    n = reach.size
    out = ["# How far must the raster reach?\n",
           f"Seed-0 draw, 850 scenes × 40 steps = {n} logged states; {has.mean():.1%} have a "
           f"leader, the human brakes because of it in {brakes.mean():.1%} "
           f"({brakes.sum()} states), the car-following term binds in {binds.mean():.1%}.\n",
           "## Distance ahead to the leader's nearest point (m)\n",
           "| states | n | median / 90 % / 95 % / 99 % | "
           + " | ".join(f"≤ {a:.0f} m" for a in AHEAD) + " |",
           "|---|---|---|" + "---|" * len(AHEAD)]
    for name, m in groups.items():
        r = reach[m]
        cover = " | ".join(f"{np.mean(r < a):.1%}" for a in AHEAD)
        out.append(f"| {name} | {m.sum()} | {_pct(r, [50, 90, 95, 99])} | {cover} |")
    out += ["", "## Lateral offset of the leader's centre (m, absolute)\n",
            "| states | median / 90 % / 95 % / 99 % | "
            + " | ".join(f"≤ {s:.0f} m" for s in SIDES) + " |",
            "|---|---|" + "---|" * len(SIDES)]
    for name in ("the human brakes because of its leader", "every leader"):
        y = side[groups[name]]
        out.append(f"| {name} | {_pct(y, [50, 90, 95, 99])} | "
                   + " | ".join(f"{np.mean(y < s):.1%}" for s in SIDES) + " |")
    # the vehicle the human yields to
    sb = tg["stop_box"]
    a_stop = tg["a_stop"]
    yields = (np.isfinite(a_stop) & (a_stop < tg["a_free"] - 0.05) & (a_stop <= tg["a_lead"])
              & (a_stop <= tg["a_curve"]) & (a_stop < 0.0) & np.isfinite(sb[..., 0]))
    sx, sy = sb[..., 0][yields], np.abs(sb[..., 1][yields])
    out += ["", "## The vehicle the human yields to (it brakes for its yield point)\n",
            f"{yields.sum()} states ({yields.mean():.1%}). Ahead (m, its centre): "
            f"{_pct(sx, [5, 50, 95, 99])} (5 / 50 / 95 / 99 %); to the side (m, absolute): "
            f"{_pct(sy, [50, 90, 95, 99])} (50 / 90 / 95 / 99 %).\n",
            "| view (ahead × side) | leaders braked for, in view | yielded-to vehicles in "
            "view |", "|---|---|---|"]
    in_view = lambda a, s: L.in_view(tg, a, s)  # noqa: E731
    for a in (40.0, 55.0, 60.0):
        for s in SIDES:
            yv = np.mean((sx < a) & (sx > -10.0) & (sy < s))
            out.append(f"| {a:.0f} m × ±{s:.0f} m | {np.mean(in_view(a, s)[brakes]):.1%} | "
                       f"{yv:.1%} |")
    # cost of a view
    out += ["", "## What a view costs (pixels, stored bytes per frame; 10 m behind)\n",
            "| view | m/px | H × W | pixels vs 64 × 64 | bytes/frame RGB | bytes/frame "
            "channels (12 planes, packed) | 850 scenes, channels |",
            "|---|---|---|---|---|---|---|"]
    for a, s in ((40.0, 25.0), (60.0, 25.0), (60.0, 20.0), (60.0, 16.0)):
        for res in (50 / 64, 0.5):
            cfg = RasterConfig.from_extent(a, s, res, encoding="channels", route=True,
                                           history=2)
            px = cfg.size * cfg.width
            b = int(np.prod(cfg.shape))
            out.append(f"| {a:.0f} m × ±{s:.0f} m | {res:.2f} | {cfg.size} × {cfg.width} | "
                       f"{px / 4096:.2f}× | {3 * px} | {b} | {b * 34000 / 1e6:.0f} MB |")
    provenance.publish("\n".join(out) + "\n", args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
