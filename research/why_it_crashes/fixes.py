"""Fixes to the behaviour-cloning pipeline, measured one at a time: models trained by
Algorithm 1 on the paper preset's draw under *variants* of what they see, driven closed loop
under both protocols.

A variant is ``model:setting:history``:

* ``setting`` (:mod:`minimanc.inputs`): "paper" (what the paper gives each model) or
  "parity" (every model also sees the lane target and its own motion);
* ``history``: steps of faded history in the raster (:mod:`minimanc.world.history`).

The data is the paper preset's draw (data seed 0: 650 training, 40 tuning, 200 validation
scenes, in that order; only the validation scenes are driven); each raster variant is
generated once (``cache=True``). Training: ``--epochs`` epochs, learning rate ``--lr``,
engine ``jax``, ``--seeds`` seeds (mean ± std); ``--channels`` the backbone's stride-2
convolutions (``ModelConfig.channels``: one more layer doubles the receptive field),
``--predicates`` the number of visual predicates of eq. 7 (``ModelConfig.n_predicates``) and
``--states`` the number of vAGN's q-states (``ModelConfig.n_states``; eq. 11's gains are a
linear function of them).

The fixes measured and rejected (the speed as a change, the loss's speed scale, the auxiliary
perception loss, the flat predicates, MANC's gains reading the predicates) were options of
this script until they were deleted from the library; ``REPORT.md`` names the commit that
measured each.

Run: ``python research/why_it_crashes/fixes.py --variants cnn:parity:0
--out research/why_it_crashes/results/X.md``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scoring import cells, scores

from minimanc import models, rollout, train, world
from minimanc.dagger.teachers import AGENTS
from minimanc.studies import provenance as results

N_TRAIN, N_TUNE, N_VAL = 650, 40, 200
SHOW = ("ade", "along_track", "collision_rate", "at_fault_collision_rate", "off_road_rate")
HEAD = ("ADE m", "along m", "coll. %", "at fault %", "off road %")
CONTACTS = ("contacts_at_fault", "contacts_front", "contacts_stopped_ado", "contacts_lateral")
"""The first contacts by kind (:func:`minimanc.diagnose.collision_taxonomy`)."""
SPEEDS = ("contacts_ego_speed", "contacts_human_speed", "contacts_faster")
"""At the at-fault contacts: the ego's and the human's mean speed and the share faster."""


def contact_cells(runs: list[dict]) -> str:
    """Contacts by kind (mean over seeds) and, pooled over the seeds' at-fault contacts
    (weighted by their number), the ego's and the human's speed at contact and the share of
    them in which the ego was faster (%)."""
    counts = [f"{np.mean([r[k] for r in runs]):.1f}" for k in CONTACTS]
    n = np.array([r["contacts_at_fault"] for r in runs])
    if n.sum() == 0:
        return " | ".join(counts + ["–"] * len(SPEEDS))
    pooled = [float(np.nansum([r[k] * w for r, w in zip(runs, n)]) / n.sum()) for k in SPEEDS]
    return " | ".join(counts + [f"{pooled[0]:.1f}", f"{pooled[1]:.1f}",
                                f"{100 * pooled[2]:.0f}"])


def parse(variant: str) -> tuple[str, str, int]:
    """``model:setting:history`` → its three parts."""
    parts = variant.split(":")
    if len(parts) != 3 or not parts[2].isdigit():
        raise ValueError(f"a variant is model:setting:history, got {variant!r}")
    return parts[0], parts[1], int(parts[2])






def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", nargs="+", required=True)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--channels", type=int, nargs="+", default=None)
    ap.add_argument("--predicates", type=int, default=None)
    ap.add_argument("--states", type=int, default=None)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    try:
        variants = [parse(v) for v in args.variants]
    except ValueError as e:
        ap.error(str(e))
    t0 = time.perf_counter()
    data: dict[int, tuple] = {}
    rows = {a: [] for a in AGENTS}
    contacts: list[str] = []
    for name, setting, h in variants:
        if h not in data:
            ds = world.generate(N_TRAIN + N_TUNE + N_VAL, seed=0, cache=True,
                                raster=world.RasterConfig(history=h), progress=True)
            data[h] = (ds.subset(slice(0, N_TRAIN)), ds.subset(slice(N_TRAIN + N_TUNE, None)))
        tr, val = data[h]
        shape = {} if args.channels is None else {"channels": tuple(args.channels)}
        if args.predicates is not None:
            shape["n_predicates"] = args.predicates
        if args.states is not None:
            shape["n_states"] = args.states
        cfg = models.ModelConfig(setting=setting, **shape)
        runs = {a: [] for a in AGENTS}
        for seed in range(args.seeds):
            tc = train.TrainConfig(epochs=args.epochs, lr=args.lr, seed=seed)
            res = train.fit(name, tr, cfg, tc, progress=False)
            for a in AGENTS:
                traj = rollout.closed_loop(name, res.params, val, cfg, progress=False, agents=a)
                runs[a].append(scores(traj, val))
            print(f"[{time.perf_counter() - t0:6.0f} s] {name}:{setting}:{h} "
                  f"seed {seed}: " + ", ".join(
                      f"{a} {runs[a][-1]['at_fault_collision_rate']:.1f} % at fault, ADE "
                      f"{runs[a][-1]['ade']:.2f}" for a in AGENTS), flush=True)
        for a in AGENTS:
            rows[a].append(f"| {models.spec(name).label} | {setting} | {h} | "
                           f"{cells(runs[a], SHOW)} |")
        contacts.append(f"| {models.spec(name).label} | {setting} | {h} | "
                        f"{contact_cells(runs['reactive'])} |")
    text = (f"# Fixes, one at a time (paper preset draw: {N_TRAIN} training, {N_VAL} "
            f"validation scenes; {args.epochs} epochs, lr {args.lr:g}, {args.seeds} seeds, "
            + ("" if args.channels is None else f"backbone channels {tuple(args.channels)}, ")
            + ("" if args.predicates is None else f"{args.predicates} predicates, ")
            + ("" if args.states is None else f"{args.states} q-states, ")
            + "mean ± std)\n\n")
    for a in AGENTS:
        text += (f"## Agents `{a}`\n\n| model | setting | history | " + " | ".join(HEAD)
                 + " |\n" + "|---" * (3 + len(HEAD))
                 + "|\n"
                 + "\n".join(rows[a]) + "\n\n")
    text += ("## Collisions by kind, agents `reactive`\n\nFirst contacts per seed (mean over "
             "seeds; of the validation scenes) and, at the at-fault ones (pooled over the "
             "seeds), the ego's speed next to the human's at the same step of the same scene "
             "(m/s) and the share in which the ego was faster.\n\n"
             "| model | setting | history | "
             "at fault | front | stopped ado | lateral | ego m/s | human m/s | ego faster % |\n"
             + "|---" * 10 + "|\n" + "\n".join(contacts) + "\n\n")
    results.publish(text, args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
