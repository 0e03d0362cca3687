"""More demonstrations: each model (6 epochs, learning rate 0.001) trained on the paper
split's 650 training scenes plus ``--extra`` more scenes of the same draw (data seed 0;
scenes 890 on), tuned on its 40 and driven on its 200 validation scenes under both
protocols, for ``--seeds`` seeds. ``--setting`` is what each model sees
(:mod:`minimanc.inputs`: "paper" or "parity").

Read it against ``fixes.py``'s tables of the same variant: the same models, training and
validation scenes with the 650 training scenes alone. (The committed results were trained
with the loss's speed scale "change" and, for some, the speed predicted as a change or the
flat predicates: switches measured and deleted since, see ``REPORT.md``.)

Each run (model, seed) is kept as JSON under ``--cache`` when it ends (written atomically), so
a stopped run resumes where it stopped; the table is written after every run, with the
number of seeds each row has.

Run: ``python research/why_it_crashes/data_scale.py --models cnn manc --extra 1950 --seeds 3
--out research/why_it_crashes/results/data_scale.md``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scoring import HEAD, LABEL, N_TRAIN, N_TUNE, N_VAL, SHOW, cells, log, scores

from minimanc import models, rollout, train, world
from minimanc.studies import provenance

AGENTS = ("replay", "reactive")


def run_one(name: str, seed: int, ds: world.Dataset, n_extra: int, epochs: int,
            cfg: models.ModelConfig) -> dict:
    """Train ``name`` on the 650 + ``n_extra`` scenes and drive it on the validation scenes."""
    base = N_TRAIN + N_TUNE + N_VAL
    tr = ds.subset(np.r_[np.arange(N_TRAIN), np.arange(base, base + n_extra)])
    val = ds.subset(slice(N_TRAIN + N_TUNE, base))
    tc = train.TrainConfig(epochs=epochs, lr=1e-3, seed=seed)
    res = train.fit(name, tr, cfg, tc, val_ds=ds.subset(slice(N_TRAIN, N_TRAIN + N_TUNE)),
                    progress=False)
    out = {"train_loss": [float(v) for v in res.history],
           "tune_loss": [float(v) for v in res.val_history], "scenes": int(len(tr.ego))}
    for a in AGENTS:
        traj = rollout.closed_loop(name, res.params, val, cfg, progress=False, agents=a)
        out[a] = scores(traj, val)
    return out


def table(runs: dict[str, list[dict]], n_extra: int, epochs: int,
          cfg: models.ModelConfig) -> str:
    text = (f"# More demonstrations (paper preset draw, data seed 0: {N_TRAIN} + {n_extra} "
            f"training scenes, {N_TUNE} tuning, {N_VAL} validation; {cfg.setting} setting, "
            f"{epochs} epochs, lr 0.001; "
            "mean ± std over seeds)\n\n"
            "Read against `fixes.py`'s rows of the same variant: the same models "
            f"and training on the {N_TRAIN} training scenes alone.\n\n")
    for a in AGENTS:
        text += (f"## Agents `{a}`\n\n| model | training scenes | seeds | " + " | ".join(HEAD)
                 + " |\n" + "|---" * (len(HEAD) + 3) + "|\n")
        for name, rs in runs.items():
            if rs:
                text += (f"| {LABEL.get(name, name)} | {rs[0]['scenes']} | {len(rs)} | "
                         + cells([r[a] for r in rs], SHOW) + " |\n")
        text += "\n"
    text += ("## Training and tuning loss per epoch (seed 0)\n\n| model | training | tuning |\n"
             "|---|---|---|\n")
    for name, rs in runs.items():
        if rs:
            text += (f"| {LABEL.get(name, name)} | "
                     + " ".join(f"{v:.1f}" for v in rs[0]["train_loss"]) + " | "
                     + " ".join(f"{v:.1f}" for v in rs[0]["tune_loss"]) + " |\n")
    return text + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", default=["cnn", "manc"])
    ap.add_argument("--extra", type=int, default=1950)
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--setting", choices=("paper", "parity"), default="paper")
    ap.add_argument("--cache", type=Path, default=Path("runs/data_scale"))
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    try:
        cfg = models.ModelConfig(setting=args.setting)
        for name in args.models:  # an unknown model fails here, before any data
            models.get(name)
    except (KeyError, ValueError) as e:
        raise SystemExit(f"data_scale: {e}") from None
    if args.extra < 0 or args.seeds < 1 or args.epochs < 1:
        raise SystemExit("data_scale: --extra must be >= 0, --seeds and --epochs >= 1")
    t0 = time.perf_counter()
    ds = world.generate(N_TRAIN + N_TUNE + N_VAL + args.extra, seed=0, cache=True,
                        progress=True)
    log(f"data: {len(ds.ego)} scenes", t0)
    runs: dict[str, list[dict]] = {name: [] for name in args.models}
    for seed in range(args.seeds):  # seeds outermost: a stopped run has every model's seeds
        for name in args.models:
            path = args.cache / f"{name}-{cfg.setting}-x{args.extra}-e{args.epochs}-s{seed}.json"
            if path.exists():
                r = provenance.read_json_or_none(path)
            else:
                r = run_one(name, seed, ds, args.extra, args.epochs, cfg)
                provenance.write_json(path, r)
            runs[name].append(r)
            log(f"{name} seed {seed}: " + ", ".join(
                f"{a} {r[a]['at_fault_collision_rate']:.1f} % at fault, ADE {r[a]['ade']:.2f}"
                for a in AGENTS), t0)
            provenance.publish(table(runs, args.extra, args.epochs, cfg), args.out,
                               time.perf_counter() - t0)


if __name__ == "__main__":
    main()
