"""The modular learner (:mod:`perceiving`, beside this script): a perception trained on the raster
to read the numbers the world's human drives on, and the privileged MLP trained on what it
reads, driven closed loop on the raster alone.

Two tables: how well the perception reads each feature on the validation scenes (R² and
RMSE; gap and closing speed also over the states with a leader within 30 m, where they
matter), and the closed loop under both protocols (mean ± std over ``--seeds`` seeds; each
seed trains both halves), for each ``--speed`` source: ``raster`` (the driver reads its own
speed from the raster too) and ``odometer`` (its own speed is the ego's, as MANC's DMP gets
it; only the rest is read). Both drivers of a seed share its perception. ``--oracle GROUP
...`` adds a diagnostic row per feature group of ``minimanc.diagnose.FEATURE_GROUPS``:
the odometer driver with that group taken from the world's own perception in the reached
state (``OraclePerceivingPolicy``), the rest still read: the gain of one exact group is what
its perception errors cost; ``--perceived GROUP ...`` the converse, every group exact but
that one (what its perception errors cost on their own; ``speed`` or ``history`` gives the
row with every feature exact, the bound of the pipeline). ``--dagger R`` adds DAgger for the
odometer driver (``dagger_driver``: R rounds of ``--per-round`` training scenes, the
perception fixed), reactive ados. Read it against
``results/privileged.md`` (the same MLP on the exact features, and on one frame) and
``results/privileged_noise.md`` (the same MLP with independent errors of known size). The
perception is trained on the perception loss alone (:func:`perceiving.fit_perception`).

The data is the paper preset's draw (data seed 0: 650 training, 40 tuning, 200 validation
scenes, then ``--extra`` further training scenes of the same draw, as
``data_scale.py`` takes them) rendered with ``--history`` steps of faded history
(``RasterConfig.history``).

Run: ``python research/why_it_crashes/perceive_drive.py
--out research/why_it_crashes/results/perceive_drive.md``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import perceiving as M
from scoring import HEAD, N_TRAIN, N_TUNE, N_VAL, SHOW, cells, log

from minimanc import world
from minimanc.dagger.teachers import AGENTS, WorldTeacher
from minimanc.diagnose import policies
from minimanc.diagnose import privileged as P
from minimanc.studies import provenance
from minimanc.studies.jobs import scene_families


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--history", type=int, default=2)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--speed", nargs="+", choices=("raster", "odometer"), default=["raster"])
    ap.add_argument("--hidden", type=int, default=0,
                    help="a read-out with one hidden ReLU layer of this many units (0: linear)")
    ap.add_argument("--route", action="store_true",
                    help="the perception also reads the lane targets (the route ahead)")
    ap.add_argument("--extra", type=int, default=0,
                    help="train both halves on this many further scenes of the same draw too")
    ap.add_argument("--oracle", nargs="*", default=[], choices=tuple(P.FEATURE_GROUPS))
    ap.add_argument("--perceived", nargs="*", default=[], choices=tuple(P.FEATURE_GROUPS))
    ap.add_argument("--dagger", type=int, default=0,
                    help="DAgger rounds for the odometer driver (its perception fixed)")
    ap.add_argument("--per-round", type=int, default=65)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    t0 = time.perf_counter()
    if args.extra < 0:
        raise SystemExit("perceive_drive: --extra must be >= 0")
    n = N_TRAIN + N_TUNE + N_VAL
    ds = world.generate(n + args.extra, seed=0, cache=True, progress=True,
                        raster=world.RasterConfig(history=args.history))
    tr = ds.subset(np.r_[np.arange(N_TRAIN), np.arange(n, n + args.extra)])
    val = ds.subset(slice(N_TRAIN + N_TUNE, n))
    y = P.perceived(tr, M.PERCEIVE)
    yv = P.perceived(val, M.PERCEIVE).reshape(-1, len(M.PERCEIVE))
    log("targets", t0)
    close = (yv[:, M.PERCEIVE.index("has_leader")] > 0) & (yv[:, M.PERCEIVE.index("gap")] < 30)
    r2, rmse, close_rmse = [], [], []
    T = np.asarray(val.ego).shape[1]
    families = {f: np.repeat(m, T) for f, m in scene_families(val).items()}
    fam_r2: dict[str, list] = {f: [] for f in families}
    oracles = {f"odometer, {g} exact": P.FEATURE_GROUPS[g] for g in args.oracle}
    for g in args.perceived:  # the odometer's groups are exact anyway: the all-exact bound
        odo = set(P.FEATURE_GROUPS[g]) <= set(M.ODOMETER)
        oracles["odometer, all exact" if odo else f"odometer, all exact but {g}"] = tuple(
            f for h, fs in P.FEATURE_GROUPS.items() if h != g for f in fs)
    rows = list(args.speed) + list(oracles)
    runs = {(r, a): [] for r in rows for a in AGENTS}
    curve: list[list] = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        perception = M.fit_perception(tr, y, epochs=args.epochs, lr=args.lr, seed=seed,
                                      hidden=args.hidden, route=args.route)
        read_tr = M.read_dataset(perception, tr)
        read_v = M.read_dataset(perception, val).reshape(yv.shape)
        err = read_v - yv
        for fam, rows_of in families.items():
            fam_r2[fam].append(1 - (err[rows_of] ** 2).mean(0) / (yv.var(0) + 1e-12))
        rmse.append(np.sqrt((err ** 2).mean(0)))
        r2.append(1 - (err ** 2).mean(0) / (yv.var(0) + 1e-12))
        close_rmse.append(np.sqrt((err[close] ** 2).mean(0)))
        log(f"seed {seed} perception: " + ", ".join(
            f"{n} R² {a:.2f}" for n, a in zip(M.PERCEIVE, r2[-1])), t0)
        for sp in args.speed:
            odo = sp == "odometer"
            driver = M.fit_driver(perception, tr, seed=seed, read=read_tr,
                                  exact=M.ODOMETER if odo else ())
            for a in AGENTS:
                policy = M.PerceivingPolicy(perception, driver, odometer=odo)
                runs[sp, a].append(policies.evaluate_policy(policy, val, a))
                log(f"seed {seed} speed from {sp}, {a}: "
                    f"{runs[sp, a][-1]['at_fault_collision_rate']:.1f} % at fault, "
                    f"ADE {runs[sp, a][-1]['ade']:.2f}", t0)
        for row, exact in oracles.items():
            driver = M.fit_driver(perception, tr, seed=seed, read=read_tr,
                                  exact=M.ODOMETER + tuple(exact))
            for a in AGENTS:
                policy = M.OraclePerceivingPolicy(perception, driver,
                                                  WorldTeacher(val, agents=a), exact)
                runs[row, a].append(policies.evaluate_policy(policy, val, a))
                log(f"seed {seed} {row}, {a}: "
                    f"{runs[row, a][-1]['at_fault_collision_rate']:.1f} % at fault, "
                    f"ADE {runs[row, a][-1]['ade']:.2f}", t0)
        if args.dagger:
            curve.append(M.dagger_driver(perception, tr, val, args.dagger, args.per_round,
                                         "reactive", seed=seed, read=read_tr))
            for i, r in enumerate(curve[-1]):
                log(f"seed {seed} dagger round {i}: "
                    f"{r.metrics['at_fault_collision_rate']:.1f} % at fault, "
                    f"ADE {r.metrics['ade']:.2f}", t0)
    r2, rmse, close_rmse = (np.mean(x, axis=0) for x in (r2, rmse, close_rmse))
    gi, di = M.PERCEIVE.index("gap"), M.PERCEIVE.index("dv")
    text = (f"# The modular learner: perception from the raster, then the privileged MLP "
            f"(paper preset draw: {N_TRAIN + args.extra} training, {N_VAL} validation "
            f"scenes; history "
            f"{args.history}; {args.epochs} epochs, lr {args.lr:g}, "
            + (f"hidden layer {args.hidden}" if args.hidden else "linear read-out")
            + (", route" if args.route else "")
            + f"; {args.seeds} seeds)\n\n## What the perception reads\n\n"
            "On the validation scenes, mean over seeds.\n\n"
            "| feature | R² | RMSE | RMSE, leader < 30 m |\n|---|---|---|---|\n"
            + "\n".join(f"| `{n}` | {r2[k]:.2f} | {rmse[k]:.2f} | "
                        + (f"{close_rmse[k]:.2f}" if k in (gi, di) else "") + " |"
                        for k, n in enumerate(M.PERCEIVE))
            + f"\n\n{int(close.sum())} of {len(close)} validation states have a leader within "
            "30 m.\n\nR² by scenario family (the validation states of each family's scenes, "
            "against the spread over all of them):\n\n| family | "
            + " | ".join(f"`{n}`" for n in M.PERCEIVE) + " |\n" + "|---" * (len(M.PERCEIVE) + 1)
            + "|\n" + "\n".join(f"| {f} | " + " | ".join(f"{x:.2f}" for x in np.mean(v, 0))
                                 + " |" for f, v in fam_r2.items())
            + "\n\n## Closed loop\n\n| speed from | agents | " + " | ".join(HEAD) + " |\n"
            + "|---" * (len(HEAD) + 2) + "|\n"
            + "\n".join(f"| {r} | `{a}` | {cells(runs[r, a], SHOW)} |"
                        for r in rows for a in AGENTS) + "\n\n")
    if curve:
        text += (f"## DAgger for the driver\n\nagents `reactive`, {args.per_round} training "
                 "scenes per round, the perception of each seed fixed; the odometer driver "
                 "asked in the simulator's state.\n\n| round | labels | " + " | ".join(HEAD)
                 + " |\n" + "|---" * (len(HEAD) + 2) + "|\n"
                 + "\n".join(f"| {i} | {curve[0][i].labels} | "
                             f"{cells([c[i].metrics for c in curve], SHOW)} |"
                             for i in range(args.dagger + 1)) + "\n\n")
    provenance.publish(text, args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
