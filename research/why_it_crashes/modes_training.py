"""Chapter 9 study: can a change to training make MANC's q-states driving modes?

``minimanc reproduce`` measures whether vAGN's most likely state says anything about the
human's mode (free road, following, yielding, junction, roundabout;
:func:`minimanc.metrics.modes.mode_information`, the rule of
:data:`minimanc.studies.report.MODE_MIN_EXCESS`). This script trains MANC on the paper
preset's data (650 training scenes, 6 epochs, its tuned learning rate) under a few
training variants, a few seeds each, and measures the same thing on the 200 validation
scenes, open loop (the model sees the human's observations):

- ``paper``: the preset's training (whole-scene windows from t = 0, uniform q');
- ``zeta``: plus the ζ penalty of eq. (13) (``zeta_weight``);
- ``random_q``: Algorithm 1's random initial state q' instead of the uniform one;
- ``short_windows``: 10-step windows from random offsets, with random q' (no window
  starts at the scene's first step, so q cannot count steps from a known start).

    python research/why_it_crashes/modes_training.py [--seeds 2] [--workers 2] \
        [--out research/why_it_crashes/results/modes_training.md]

Prints one row per variant and writes them, with the run's provenance, to ``--out``
(markdown, quoted by the README; ``--out ''`` writes nothing) and ``.json`` beside it.
The trainings run in ``--workers`` processes (one XLA thread each).
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from multiprocessing import get_context
from pathlib import Path

from minimanc import metrics, models, rollout, train, world
from minimanc.metrics import modes
from minimanc.studies import provenance
from minimanc.studies.config import PRESETS
from minimanc.studies.report import MODE_MIN_EXCESS

VARIANTS = {
    "paper": {},
    "zeta": {"zeta_weight": 1.0},
    "random_q": {"q_init": "random"},
    "short_windows": {"dmp_seq_len": 10, "q_init": "random"},
}
METRICS = ("mi_bits", "shuffled_mi_bits", "shuffled_mi_p95", "excess_bits", "q_change",
           "switch_rate", "states_used", "val_loss")


def data() -> tuple:
    c = PRESETS["paper"]
    return world.generate_splits(c.n_train, c.n_val, seed=c.data_seed,
                                 raster=c.raster, cache=True,
                                 progress=False)


def one_run(variant: str, seed: int, lr: float) -> dict:
    """Train MANC under ``variant`` at ``seed``; its q-states against the human's modes."""
    c = PRESETS["paper"]
    train_ds, val_ds = data()
    cfg = models.ModelConfig(n_states=c.n_states)
    tc = replace(c.training, lr=lr, seed=seed, **VARIANTS[variant])
    t0 = time.perf_counter()
    fit = train.fit("manc", train_ds, cfg, tc, engine="jax", progress=False)
    q = rollout.open_loop("manc", fit.params, val_ds, cfg, "jax")["q"]
    out = modes.mode_information(q, modes.human_modes(val_ds))
    out["val_loss"] = train.open_loop_loss("manc", fit.params, val_ds, cfg, "jax",
                                           std=fit.control_std, q_init=tc.q_init)
    out["seconds"] = time.perf_counter() - t0
    return out


def verdict(agg: dict) -> bool:
    """The rule of ``minimanc reproduce``'s finding: above the shuffled baseline's 95th
    percentile and at least ``MODE_MIN_EXCESS`` bits above its mean."""
    mi = agg["mi_bits"]["mean"]
    return mi > agg["shuffled_mi_p95"]["mean"] and \
        mi - agg["shuffled_mi_bits"]["mean"] >= MODE_MIN_EXCESS


def markdown(rows: dict, n_seeds: int, lr: float, prov: dict, wall: float) -> str:
    head = ("| training | I(argmax q; mode) (bits) | shuffled mean (bits) | shuffled p95 (bits) "
            "| excess (bits) | q change per step | argmax switches (%) | open-loop val loss "
            "| modes? |\n|---|---|---|---|---|---|---|---|---|\n")
    lines = []
    for v, agg in rows.items():
        m = {k: agg[k]["mean"] for k in METRICS}
        s = {k: agg[k]["std"] for k in METRICS}
        lines.append(
            f"| {v} | {m['mi_bits']:.3f} ± {s['mi_bits']:.3f} | {m['shuffled_mi_bits']:.3f} "
            f"| {m['shuffled_mi_p95']:.3f} | {m['excess_bits']:.3f} ± {s['excess_bits']:.3f} "
            f"| {m['q_change']:.2f} | {100 * m['switch_rate']:.0f} | {m['val_loss']:.3f} "
            f"| {'yes' if verdict(agg) else 'no'} |")
    return ("# MANC's q-states under training variants\n\n"
            f"MANC on the paper preset's data (650 training, 200 validation scenes, 6 epochs, "
            f"learning rate {lr:g}), mean ± std over {n_seeds} seeds; open loop on the "
            "validation scenes. Modes? applies the rule of `minimanc reproduce` (above the "
            f"shuffled baseline's 95th percentile and at least {MODE_MIN_EXCESS:g} bits above "
            "its mean).\n\n## Modes by training variant\n\n" + head + "\n".join(lines) + "\n\n"
            + provenance.provenance_markdown(prov, wall))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--lr", type=float, default=3e-4, help="MANC's learning rate (default: "
                    "the one the paper preset's tuning picks)")
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--out", default="research/why_it_crashes/results/modes_training.md")
    args = ap.parse_args()
    names = args.variants.split(",")
    unknown = [v for v in names if v not in VARIANTS]
    if unknown or args.seeds < 1 or args.workers < 1:
        raise SystemExit(f"modes_training: bad arguments (variants {unknown}, seeds "
                         f"{args.seeds}, workers {args.workers})")
    prov = provenance.provenance()
    t0 = time.perf_counter()
    data()  # generate (or load) the cached splits once, before the workers read them
    jobs = [(v, s) for v in names for s in range(args.seeds)]
    with ProcessPoolExecutor(args.workers, mp_context=get_context("spawn")) as pool:
        futs = {job: pool.submit(one_run, *job, args.lr) for job in jobs}
        per = {job: f.result() for job, f in futs.items()}
    rows = {v: metrics.aggregate([per[(v, s)] for s in range(args.seeds)]) for v in names}
    wall = time.perf_counter() - t0
    text = markdown(rows, args.seeds, args.lr, prov, wall)
    print(text)
    if args.out:
        out = Path(args.out)
        provenance.write_text(out, text)
        provenance.write_text(out.with_suffix(".json"), json.dumps(
            {"variants": VARIANTS, "lr": args.lr, "seeds": args.seeds,
             "runs": {f"{v}-{s}": r for (v, s), r in per.items()},
             "provenance": prov, "wall_time_s": wall}, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
