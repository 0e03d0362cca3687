"""Chapter 9 benchmark: what ``minimanc reproduce --preset P`` costs, from measured pieces.

Counts the trainings and closed-loop rollouts of a preset in a form (:func:`plan`,
:func:`with_form`), times one training epoch of every model at the preset's data size and
raster and one closed loop on its validation scenes, one at a time, and extrapolates the
study's wall time: the serial sum, and that sum shared by one worker per CPU (the study's
pool; an ideal bound, since workers that share the cores slow each other down).

A run trained on-policy (:attr:`StudyConfig.dagger_rounds` > 0) is costed by DAgger's
schedule (:func:`minimanc.dagger.plan_budget` over the run's scenes): round 0 trains the
preset's epochs on its demonstrations, every later round ``round_epochs`` epochs on the
aggregate so far (the epochs counted in units of the measured epoch over the preset's
training scenes), and every scene a round drives costs one scene of the measured closed
loop. With ``--seeds-together`` it also times :func:`minimanc.train.fit_seeds` (the
preset's seeds of one configuration trained as one vmapped step).

    python benchmarks/bench_study.py [--preset paper] [--form learner|paper]
                                     [--models cnn,manc] [--val 200] [--threads 1]

Prints figures and ratios; never asserts timings. The machine is shared: repeat, or
compare ratios measured in the same run.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from threads import set_threads  # noqa: E402  (before NumPy and JAX are imported)


def timed(f, *a, **k):
    t0 = time.perf_counter()
    out = f(*a, **k)
    return out, time.perf_counter() - t0


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--form", default=None, help="learner or paper (default: the preset's)")
    ap.add_argument("--models", default="cnn,cnn_lstm,rvs_g,manc,vagn_only,dmp_only")
    ap.add_argument("--val", type=int, default=None, help="validation scenes driven "
                    "(default: the preset's n_val)")
    ap.add_argument("--seeds-together", action="store_true",
                    help="also time fit_seeds on the preset's seeds")
    ap.add_argument("--no-rollout", action="store_true")
    ap.add_argument("--threads", type=int, default=None,
                    help="BLAS and XLA threads (default: the library's, one XLA thread)")
    return ap.parse_args(argv)


def dagger_epochs(n_scenes: int, steps: int, rounds: int, epochs: int,
                  round_epochs: int) -> tuple[float, int]:
    """DAgger's training on ``n_scenes`` scenes in epochs over those scenes, and the scenes
    its rounds drive: round 0 ``epochs`` on the demonstrations, every later round
    ``round_epochs`` on the aggregate so far."""
    from minimanc import dagger

    b = dagger.plan_budget(n_scenes * steps, steps, rounds)
    seen = epochs * b.initial
    aggregate = b.initial
    for n in b.per_round:
        aggregate += n
        seen += round_epochs * aggregate
    return seen / n_scenes, sum(b.per_round)


def measure(names, c, train_ds, val, args) -> dict:
    """One epoch (after a two-step warm-up that compiles) and one closed loop per model."""
    from minimanc import rollout, train

    by = {}
    for name in names:
        cfg = c.model_config(c.n_states, "paper")
        tc = replace(c.training, epochs=1, lr=1e-3)
        _, t_warm = timed(train.fit, name, train_ds, cfg, replace(tc, max_steps_per_epoch=2),
                          engine="jax", progress=False)
        res, t_epoch = timed(train.fit, name, train_ds, cfg, tc, engine="jax", progress=False)
        line = {"model": name, "steps": res.steps, "compile_s": t_warm, "epoch_s": t_epoch}
        if args.seeds_together:
            _, line["seeds_s"] = timed(train.fit_seeds, name, train_ds, cfg, tc, c.seeds,
                                       engine="jax", progress=False)
        if not args.no_rollout:
            _, t_roll = timed(rollout.closed_loop, name, res.params, val, res.cfg, "jax",
                              progress=False)
            line["scene_s"] = t_roll / len(val)
        by[name] = line
        print("  ".join(f"{k}={v:.2f}" if isinstance(v, float) else f"{k}={v}"
                        for k, v in line.items()), flush=True)
    return by


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    set_threads(args.threads)
    import numpy as np

    from minimanc import world
    from minimanc.studies.config import PRESETS, form_of, plan, with_form
    from minimanc.studies.executors import usable_cpus

    c = PRESETS[args.preset]
    if args.form is not None:
        c = with_form(c, args.form)
    p = plan(c)
    print(f"preset {args.preset}, form {form_of(c)}: {sum(p['train'].values())} trainings "
          f"({sum(p['sweep'].values())} of the sweep), rollouts {p['rollouts']}")
    train_ds, val_ds = world.generate_splits(c.n_train, c.n_val, seed=c.data_seed,
                                             raster=c.raster, cache=True, progress=False)
    val = val_ds.subset(slice(0, args.val or c.n_val))
    by = measure(args.models.split(","), c, train_ds, val, args)
    scene_s = float(np.mean([r["scene_s"] for r in by.values() if "scene_s" in r] or [math.nan]))
    print("\n| component | count | s each | total s |\n|---|---|---|---|")
    total = 0.0
    for (m, f), n in sorted(p["train"].items()):
        if m not in by:
            continue
        swept = p["sweep"].get((m, f), 0)
        for kind, k in (("behaviour cloning", swept if c.on_policy else n),
                        ("DAgger", n - swept if c.on_policy else 0)):
            if k == 0:
                continue
            scenes = max(1, round(f * c.n_train))
            if kind == "DAgger":
                epochs, driven = dagger_epochs(scenes, train_ds.n_steps, c.dagger_rounds,
                                               c.training.epochs, c.round_epochs)
                each = epochs * f * by[m]["epoch_s"] + driven * scene_s
            else:
                each = c.training.epochs * f * by[m]["epoch_s"]
            total += k * each
            print(f"| {kind} {m} f={f:g} | {k} | {each:.0f} | {k * each:.0f} |")
    for split, n_scenes in (("val", c.n_val), ("tune", c.n_tune)):
        n = p["rollouts"][split]
        total += n * n_scenes * scene_s
        print(f"| rollout {split} ({n_scenes} scenes) | {n} | {n_scenes * scene_s:.0f} | "
              f"{n * n_scenes * scene_s:.0f} |")
    n_cpu = usable_cpus()
    print(f"\nserial sum {total / 60:.0f} min; on {n_cpu} workers at best "
          f"{total / 60 / n_cpu:.0f} min (the models measured: {', '.join(by)})")


if __name__ == "__main__":
    main()
