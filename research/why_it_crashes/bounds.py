"""The bounds of Table I: the expert, and the style floor no style-blind learner can beat.

**Expert.** The world's human (:func:`minimanc.diagnose.expert_rollout`) drives the
validation scenes through the same simulators and the same time loop as the learned
policies, under both protocols (replayed and reactive ados); the metrics are
:func:`minimanc.metrics.evaluate`'s. A state the expert refuses to label (off the
drivable area, far from its route) is driven with the last applied controls and counted.

**Style floor.** Each scene's human draws a hidden style
(:func:`minimanc.world.driver.random_style`: desired speed, headway, reaction delay, ...)
that a controller seeing only the scene cannot know. Every validation scene is re-driven
by the world's own driver on the scene's own random stream (same map, traffic and noise
draws), with the style replaced by the population's median style (the median of each
field over ``--population`` draws; :func:`minimanc.diagnose.floor_rollout`), the
ados reacting to it: its ADE to the logged human (mean, median, 90th percentile), the
along- and cross-track parts (:func:`minimanc.metrics.trajectory.along_cross_track`), the
mean speed difference and its at-fault collisions. Re-driving with the scene's own style
must reproduce the log (checked first).

Run: ``python research/why_it_crashes/bounds.py --scenes 200 --seed 777
--out research/why_it_crashes/results/bounds.md``
"""

from __future__ import annotations

import argparse
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from minimanc import metrics, world
from minimanc.dagger.teachers import AGENTS
from minimanc.diagnose import expert_rollout, floor_rollout, median_style
from minimanc.metrics.trajectory import ade, along_cross_track
from minimanc.studies import provenance
from minimanc.world.geometry import DT


def expert_lines(ds) -> list[str]:
    out = [f"{'protocol':10s} {'ADE m':>7s} {'at fault %':>11s} {'collision %':>12s} "
           f"{'off road %':>11s} {'refused':>8s}"]
    for agents in AGENTS:
        traj = expert_rollout(ds, agents=agents)
        m = metrics.evaluate(traj, ds)
        out.append(f"{agents:10s} {m['ade']:7.2f} {m['at_fault_collision_rate']:11.1f} "
                   f"{m['collision_rate']:12.1f} {m['off_road_rate']:11.1f} {traj.refused:8d}")
    return out


def floor_lines(ds, population: int) -> list[str]:
    own = floor_rollout(ds, None, scenes=range(min(len(ds.ego), 4)))
    err = float(np.abs(own.ego[..., :2] - ds.ego[:len(own.ego), :, :2]).max())
    if err > 1e-3:
        raise SystemExit(f"bounds: self-check failed: the scenes' own style re-drives "
                         f"{err:.3g} m from the log (expected float32 rounding)")
    style = median_style(population)
    traj = floor_rollout(ds, style)
    human = np.asarray(ds.ego, dtype=np.float64)
    dist = ade(traj.ego, human)
    along, cross = along_cross_track(traj.ego, human)
    speed = lambda e: np.linalg.norm(np.diff(e[..., :2], axis=1), axis=-1) / DT  # noqa: E731
    fault = metrics.evaluate(traj, ds)["at_fault_collision_rate"]
    return [
        "median style " + ", ".join(f"{k}={v:.2f}" for k, v in asdict(style).items()),
        f"self-check: own-style re-drive of {len(own.ego)} scenes matches the log to "
        f"{err:.1e} m",
        f"ADE m: mean {dist.mean():.2f}, median {np.median(dist):.2f}, "
        f"90th percentile {np.percentile(dist, 90):.2f}",
        f"along-track m {np.abs(along).mean():.2f}, cross-track m {np.abs(cross).mean():.2f}, "
        f"mean |speed difference| m/s {np.abs(speed(traj.ego) - speed(human)).mean():.2f}",
        f"at-fault collisions of the median-style driver: {fault:.1f} %",
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=200)
    ap.add_argument("--seed", type=int, default=777)
    ap.add_argument("--population", type=int, default=20000)
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the figures and their provenance to this markdown file")
    args = ap.parse_args()
    t0 = time.perf_counter()
    ds = world.generate(args.scenes, seed=args.seed)
    parts = {"Expert": expert_lines(ds),
             "Style floor": floor_lines(ds, args.population)}
    text = f"# Bounds of Table I ({args.scenes} scenes of data seed {args.seed})\n\n"
    for title, lines in parts.items():
        text += f"## {title}\n\n```\n" + "\n".join(lines) + "\n```\n\n"
    provenance.publish(text, args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
