"""Chapter 9 benchmark: what ``minimanc reproduce --preset paper`` costs, from measured pieces.

Counts the trainings and closed-loop rollouts of a preset (:func:`plan`), times one
training epoch of every model at the preset's data size and one closed loop on its
validation scenes, one at a time, and extrapolates the study's wall time: the serial sum,
and that sum shared by one worker per CPU (the study's pool; an ideal bound, since
workers that share the cores slow each other down). With
``--seeds-together`` it also times :func:`minimanc.train.fit_seeds` (the preset's seeds
of one configuration trained as one vmapped step).

    python benchmarks/bench_study.py [--preset paper] [--models cnn,manc] [--val 200]

Prints figures and ratios; never asserts timings. The machine is shared: repeat, or
compare ratios measured in the same run.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace

import numpy as np

from minimanc import models, rollout, train, world
from minimanc.studies.config import PRESETS, plan
from minimanc.studies.executors import usable_cpus


def timed(f, *a, **k):
    t0 = time.perf_counter()
    out = f(*a, **k)
    return out, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="paper", choices=sorted(PRESETS))
    ap.add_argument("--models", default="cnn,cnn_lstm,rvs_g,manc,vagn_only,dmp_only")
    ap.add_argument("--val", type=int, default=None, help="validation scenes driven "
                    "(default: the preset's n_val)")
    ap.add_argument("--seeds-together", action="store_true",
                    help="also time fit_seeds on the preset's seeds")
    ap.add_argument("--no-rollout", action="store_true")
    args = ap.parse_args()
    c = PRESETS[args.preset]
    p = plan(c)
    print(f"preset {args.preset}: {sum(p['train'].values())} trainings, rollouts {p['rollouts']}")
    n_val = args.val or c.n_val
    train_ds, val_ds = world.generate_splits(c.n_train, c.n_val, seed=c.data_seed,
                                             raster=c.raster,
                                             cache=True, progress=False)
    val = val_ds.subset(slice(0, n_val))
    names = args.models.split(",")
    rows = []
    for name in names:
        cfg = models.ModelConfig(n_states=c.n_states)
        tc = replace(c.training, epochs=1, lr=1e-3)
        warm, t_warm = timed(train.fit, name, train_ds, cfg, replace(tc, max_steps_per_epoch=2),
                             engine="jax", progress=False)
        res, t_epoch = timed(train.fit, name, train_ds, cfg, tc, engine="jax", progress=False)
        line = {"model": name, "steps": res.steps, "compile_s": t_warm, "epoch_s": t_epoch}
        if args.seeds_together:
            _, t_seeds = timed(train.fit_seeds, name, train_ds, cfg, tc, c.seeds,
                               engine="jax", progress=False)
            line["seeds_s"] = t_seeds
        if not args.no_rollout:
            _, t_roll = timed(rollout.closed_loop, name, res.params, val, cfg, "jax",
                              progress=False)
            line["rollout_s"] = t_roll * c.n_val / n_val
        rows.append(line)
        print("  ".join(f"{k}={v:.1f}" if isinstance(v, float) else f"{k}={v}"
                        for k, v in line.items()), flush=True)
    by = {r["model"]: r for r in rows}
    print("\n| component | count | s each | total s |\n|---|---|---|---|")
    total_train = total_seeds = 0.0
    for (m, f), n in sorted(p["train"].items()):
        if m not in by:
            continue
        epochs = c.training.epochs
        each = epochs * by[m]["epoch_s"] * f
        total_train += n * each
        print(f"| train {m} f={f:g} ({epochs} epochs) | {n} | {each:.0f} | {n * each:.0f} |")
        if "seeds_s" in by[m]:
            total_seeds += n / len(c.seeds) * epochs * by[m]["seeds_s"] * f
    n_roll = sum(p["rollouts"].values())
    n_cpu = usable_cpus()
    roll_each = float(np.mean([r["rollout_s"] for r in rows if "rollout_s" in r] or [math.nan]))
    tune_each = roll_each * c.n_tune / c.n_val
    roll_total = p["rollouts"]["val"] * roll_each + p["rollouts"]["tune"] * tune_each
    print(f"| rollout val ({c.n_val} scenes) | {p['rollouts']['val']} | {roll_each:.0f} | "
          f"{p['rollouts']['val'] * roll_each:.0f} |")
    print(f"| rollout tune ({c.n_tune} scenes) | {p['rollouts']['tune']} | {tune_each:.0f} | "
          f"{p['rollouts']['tune'] * tune_each:.0f} |")
    print(f"\ntraining {total_train / 60:.0f} min, rollouts {roll_total / 60:.0f} min "
          f"(serial sum {(total_train + roll_total) / 60:.0f} min; {n_roll} rollouts); on "
          f"{n_cpu} workers at best {(total_train + roll_total) / 60 / n_cpu:.0f} min")
    if total_seeds:
        print(f"seeds trained together: training {total_seeds / 60:.0f} min "
              f"({total_train / total_seeds:.2f}x)")


if __name__ == "__main__":
    main()
