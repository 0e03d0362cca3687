"""Chapter 9 spot check: MANC and the CNN trained on the paper's data size, driven closed loop.

Prints figures, asserts nothing. One seed, 650 training scenes (the paper's
nuScenes split size), 6 epochs, learning rate 1e-3 for both, closed loop on
the first ``--val`` of the 200 validation scenes, against the human replay
and MANC's DMP head at fixed gains (no learning). A cheap look at the data
regime the ``full`` preset of ``minimanc reproduce`` does not reach; the
complete study at this size is ``minimanc reproduce --preset paper`` (hours).

    python benchmarks/paper_size_check.py [--val 100] [--epochs 6]

The data come from :func:`minimanc.world.generate_splits` with ``cache=True``
(generated once, a few minutes; then loaded in seconds).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from minimanc import metrics, models, rollout, train, world

COLUMNS = ("close_encounters", "max_acceleration", "ade", "goal_distance", "collision_rate")


def show(label: str, traj: rollout.Rollout, val: world.Dataset) -> None:
    m = metrics.evaluate(traj, val)
    print(f"{label:<26}" + "  ".join(f"{k} {m[k]:6.2f}" for k in COLUMNS)
          + f"  mean speed {np.mean(traj.controls[..., 0]):.2f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--val", type=int, default=100, help="validation scenes driven")
    ap.add_argument("--epochs", type=int, default=6)
    args = ap.parse_args()
    train_ds, val_ds = world.generate_splits(650, 200, seed=0, cache=True, progress=True)
    val = val_ds.subset(slice(0, args.val))
    cfg = models.ModelConfig()
    show("human (log replay)", rollout.human(val), val)
    show("DMP head, fixed gains", rollout.fixed_gains(val, cfg=cfg), val)
    for name in ("manc", "cnn"):
        t0 = time.perf_counter()
        res = train.fit(name, train_ds, cfg, train.TrainConfig(epochs=args.epochs, lr=1e-3),
                        progress=False)
        show(f"{name} (650 scenes, seed 0)", rollout.closed_loop(name, res.params, val, cfg,
                                                                progress=False), val)
        print(f"  trained and driven in {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
