"""More demonstrations: each model (the training of ``results/fixes_speed_scale.md``: speed
scale "change", 6 epochs) trained on the paper split's 650 training scenes plus ``--extra``
more scenes of the same draw (data seed 0; scenes 890 on), tuned on its 40 and driven on its
200 validation scenes under both protocols, for ``--seeds`` seeds. ``--setting`` is what
each model sees (:mod:`minimanc.inputs`: "paper" or "parity") and ``--speed-output`` what its
direct head predicts (``ModelConfig.speed_output``: the speed, "level", or its change over
one step, "change", which needs the parity setting); ``--predicate-pool`` how MANC's
predicates read the features (``ModelConfig.predicate_pool``: "global", eq. 7's pooling, or
"flat").

Read it against ``fixes.py``'s tables of the same variant: the same models,
training and validation scenes with the 650 training scenes alone
(``results/fixes_speed_scale.md`` for the paper setting at speed level).

Each run (model, seed) is kept as JSON under ``--cache`` when it ends (written atomically), so
a stopped run resumes where it stopped; the table is written after every run, with the
number of seeds each row has.

Run: ``python research/why_it_crashes/data_scale.py --models cnn manc --extra 1950 --seeds 3
--out research/why_it_crashes/results/data_scale.md``, or for the CNN predicting its speed
change: ``--models cnn --setting parity --speed-output change
--out research/why_it_crashes/results/data_scale_parity.md``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scoring import HEAD, LABEL, N_TRAIN, N_TUNE, N_VAL, SHOW, cells, log, scores

from minimanc import models, rollout, train, world
from minimanc.models.forward import changes_speed
from minimanc.studies import provenance

AGENTS = ("replay", "reactive")


def run_one(name: str, seed: int, ds: world.Dataset, n_extra: int, epochs: int,
            cfg: models.ModelConfig) -> dict:
    """Train ``name`` on the 650 + ``n_extra`` scenes and drive it on the validation scenes."""
    base = N_TRAIN + N_TUNE + N_VAL
    tr = ds.subset(np.r_[np.arange(N_TRAIN), np.arange(base, base + n_extra)])
    val = ds.subset(slice(N_TRAIN + N_TUNE, base))
    tc = train.TrainConfig(epochs=epochs, lr=1e-3, seed=seed, speed_scale="change")
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
            f"speed output {cfg.speed_output}, predicates pooled {cfg.predicate_pool}, speed "
            f"scale change, {epochs} epochs, lr 0.001; "
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
    ap.add_argument("--speed-output", choices=("level", "change"), default="level")
    ap.add_argument("--predicate-pool", choices=("global", "flat"), default="global")
    ap.add_argument("--cache", type=Path, default=Path("runs/data_scale"))
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    try:
        cfg = models.ModelConfig(setting=args.setting, speed_output=args.speed_output,
                                 predicate_pool=args.predicate_pool)
        for name in args.models:  # an unknown model or variant fails here, before any data
            changes_speed(models.get(name), cfg)
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
            pool = "" if cfg.predicate_pool == "global" else f"-{cfg.predicate_pool}"
            path = args.cache / (f"{name}-{cfg.setting}-{cfg.speed_output}{pool}-x{args.extra}"
                                 f"-e{args.epochs}-s{seed}.json")
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
