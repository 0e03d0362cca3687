"""Faded history in the raster (:mod:`minimanc.world.history`), measured: the CNN and MANC
trained by behaviour cloning on the paper preset's draw with and without the last steps of
every vehicle drawn into the BEV, driven closed loop under both protocols.

The data is the paper preset's draw (data seed 0: 650 training, 40 tuning, 200 validation
scenes, in that order; only the validation scenes are driven); each raster variant is
generated once (``cache=True``). The paper setting (what each model is given) is kept;
only the image changes. Training: 6 epochs, learning rate ``--lr``, engine ``jax``.

Run: ``python research/why_it_crashes/history_fix.py
--out research/why_it_crashes/results/history_fix.md``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from scoring import cells, scores

from minimanc import models, rollout, train, world
from minimanc.dagger.teachers import AGENTS
from minimanc.studies import provenance

N_TRAIN, N_TUNE, N_VAL = 650, 40, 200
SHOW = ("ade", "along_track", "collision_rate", "at_fault_collision_rate", "off_road_rate")
HEAD = ("ADE m", "along m", "coll. %", "at fault %", "off road %")






def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--history", type=int, nargs="+", default=[0, 2])
    ap.add_argument("--models", nargs="+", default=["cnn", "manc"])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    t0 = time.perf_counter()
    rows = {a: [] for a in AGENTS}
    for h in args.history:
        ds = world.generate(N_TRAIN + N_TUNE + N_VAL, seed=0, cache=True,
                            raster=world.RasterConfig(history=h), progress=True)
        tr = ds.subset(slice(0, N_TRAIN))
        val = ds.subset(slice(N_TRAIN + N_TUNE, None))
        print(f"[{time.perf_counter() - t0:6.0f} s] data with history={h}", flush=True)
        for name in args.models:
            runs = {a: [] for a in AGENTS}
            for seed in range(args.seeds):
                cfg = models.ModelConfig()
                res = train.fit(name, tr, cfg, train.TrainConfig(epochs=args.epochs, lr=args.lr,
                                                                 seed=seed), progress=False)
                for a in AGENTS:
                    traj = rollout.closed_loop(name, res.params, val, cfg, progress=False,
                                               agents=a)
                    runs[a].append(scores(traj, val))
                print(f"[{time.perf_counter() - t0:6.0f} s] {name} history={h} seed {seed}: "
                      + ", ".join(f"{a} {runs[a][-1]['at_fault_collision_rate']:.1f} % at "
                                  f"fault, ADE {runs[a][-1]['ade']:.2f}" for a in AGENTS),
                      flush=True)
            for a in AGENTS:
                rows[a].append(f"| {models.spec(name).label} | {h} | {cells(runs[a], SHOW)} |")
    text = (f"# Faded history in the raster (paper preset draw: {N_TRAIN} training, {N_VAL} "
            f"validation scenes; {args.epochs} epochs, lr {args.lr:g}, {args.seeds} seeds, "
            "mean ± std)\n\n")
    for a in AGENTS:
        text += (f"## Agents `{a}`\n\n| model | history steps | " + " | ".join(HEAD) + " |\n"
                 + "|---" * (len(HEAD) + 2) + "|\n" + "\n".join(rows[a]) + "\n\n")
    provenance.publish(text, args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
