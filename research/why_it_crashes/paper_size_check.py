"""Chapter 9 spot check: MANC and the CNN trained on the paper's data size, driven closed loop.

One seed, 650 training scenes (the paper's nuScenes split size), 6 epochs, learning rate
1e-3 for both, closed loop on the first ``--val`` of the 200 validation scenes, against the
human replay and MANC's DMP head at fixed gains (no learning). A cheap look at the data
regime the ``full`` preset of ``minimanc reproduce`` does not reach; the complete study at
this size is ``minimanc reproduce --preset paper``.

    python research/why_it_crashes/paper_size_check.py [--val 100] [--epochs 6] [--out FILE.md]

Prints the figures and writes them, with the run's provenance (command, date, versions,
machine), to ``--out`` (markdown, quoted by the README; ``--out ''`` writes nothing).
The data come from :func:`minimanc.world.generate_splits` with ``cache=True`` (generated
once, then loaded in seconds).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from minimanc import metrics, models, rollout, train, world
from minimanc.studies import provenance

COLUMNS = ("close_encounters", "max_acceleration", "ade", "goal_distance", "collision_rate")
HEADS = ("% close enc.", "max |a| (m/s²)", "ADE (m)", "goal dist. (m)", "% collisions",
         "mean speed (m/s)")


def row(label: str, traj: rollout.Rollout, val: world.Dataset) -> list[str]:
    m = metrics.evaluate(traj, val)
    cells = [label] + [f"{m[k]:.2f}" for k in COLUMNS] \
        + [f"{float(np.mean(traj.controls[..., 0])):.2f}"]
    print("  ".join(cells), flush=True)
    return cells


def markdown(rows: list[list[str]], args: argparse.Namespace, seconds: float) -> str:
    lines = ["# Spot check at the paper's data size", "",
             f"## Closed loop on {args.val} validation scenes, 650 training scenes, one seed", "",
             f"{args.epochs} epochs, learning rate 1e-3, seed 0, engine `jax` (log-replay ados).",
             "", "| controller | " + " | ".join(HEADS) + " |",
             "|---" * (len(HEADS) + 1) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines) + "\n\n" + provenance.provenance_markdown(provenance.provenance(),
                                                                    wall_time_s=seconds)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--val", type=int, default=100, help="validation scenes driven")
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--out", default="research/why_it_crashes/results/paper_size_check.md",
                    help="markdown file for the figures ('' = print only)")
    args = ap.parse_args()
    t_start = time.perf_counter()
    train_ds, val_ds = world.generate_splits(650, 200, seed=0, cache=True, progress=True)
    val = val_ds.subset(slice(0, args.val))
    cfg = models.ModelConfig()
    rows = [row("human (log replay)", rollout.human(val), val),
            row("DMP head, fixed gains", rollout.fixed_gains(val, cfg=cfg), val)]
    for name in ("manc", "cnn"):
        t0 = time.perf_counter()
        res = train.fit(name, train_ds, cfg, train.TrainConfig(epochs=args.epochs, lr=1e-3),
                        progress=False)
        rows.append(row(f"{name} (650 scenes, seed 0)",
                        rollout.closed_loop(name, res.params, val, cfg, progress=False), val))
        print(f"  trained and driven in {time.perf_counter() - t0:.0f} s", flush=True)
    if args.out:
        path = provenance.write_text(args.out, markdown(rows, args,
                                                     time.perf_counter() - t_start))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
