"""Fixes to the behaviour-cloning pipeline, measured one at a time: models trained by
Algorithm 1 on the paper preset's draw under *variants* of what they see and how their
speed is learned, driven closed loop under both protocols.

A variant is ``model:setting:history:speed_output:speed_scale[:perception]``:

* ``setting`` (:mod:`minimanc.inputs`): "paper" (what the paper gives each model) or
  "parity" (every model also sees the lane target and its own motion);
* ``history``: steps of faded history in the raster (:mod:`minimanc.world.history`);
* ``speed_output`` (:class:`minimanc.models.ModelConfig`): the direct heads predict the
  speed ("level") or its change over one step ("change");
* ``speed_scale`` (:class:`minimanc.train.TrainConfig`): the loss divides the speed error by
  the std of the speed ("level") or of its change over one step ("change");
* ``perception`` (optional, default 0): the weight of the auxiliary perception loss
  (``TrainConfig.perception_weight``) whose targets are :data:`PERCEIVE`, what the world's
  human perceives in each state (:func:`minimanc.diagnose.perceived`).

The data is the paper preset's draw (data seed 0: 650 training, 40 tuning, 200 validation
scenes, in that order; only the validation scenes are driven); each raster variant is
generated once (``cache=True``). Training: ``--epochs`` epochs, learning rate ``--lr``,
engine ``jax``, ``--seeds`` seeds (mean ± std); ``--channels`` the backbone's stride-2
convolutions (``ModelConfig.channels``: one more layer doubles the receptive field) and
``--predicates`` the number of visual predicates of eq. 7 (``ModelConfig.n_predicates``),
``--predicate-pool`` how they read the features (``ModelConfig.predicate_pool``) and
``--states`` the number of vAGN's q-states (``ModelConfig.n_states``; eq. 11's gains are a
linear function of them), ``--gains-input`` what MANC's gains FC reads
(``ModelConfig.gains_input``).

Run: ``python research/why_it_crashes/fixes.py --variants cnn:parity:0:change:change
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
from minimanc.diagnose import privileged as P
from minimanc.studies import provenance as results

N_TRAIN, N_TUNE, N_VAL = 650, 40, 200
SHOW = ("ade", "along_track", "collision_rate", "at_fault_collision_rate", "off_road_rate")
PERCEIVE = tuple(f for f in P.FEATURES if f != "a_prev")
"""The auxiliary loss's targets: every feature of the privileged learner a raster can hold
(its last acceleration is the only one left out)."""
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


def parse(variant: str) -> tuple[str, str, int, str, str, float]:
    """``model:setting:history:speed_output:speed_scale[:perception]`` → its six parts."""
    parts = variant.split(":")
    if len(parts) not in (5, 6):
        raise ValueError(f"a variant is model:setting:history:speed_output:speed_scale"
                         f"[:perception], got {variant!r}")
    name, setting, history, out, scale = parts[:5]
    return name, setting, int(history), out, scale, float(parts[5]) if len(parts) == 6 else 0.0






def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", nargs="+", required=True)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--channels", type=int, nargs="+", default=None)
    ap.add_argument("--predicates", type=int, default=None)
    ap.add_argument("--predicate-pool", choices=("global", "flat"), default=None)
    ap.add_argument("--states", type=int, default=None)
    ap.add_argument("--gains-input", choices=("q", "q+predicates"), default=None)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    variants = [parse(v) for v in args.variants]
    t0 = time.perf_counter()
    data: dict[int, tuple] = {}
    rows = {a: [] for a in AGENTS}
    contacts: list[str] = []
    perceived: dict[int, np.ndarray] = {}
    for name, setting, h, out, scale, w in variants:
        if h not in data:
            ds = world.generate(N_TRAIN + N_TUNE + N_VAL, seed=0, cache=True,
                                raster=world.RasterConfig(history=h), progress=True)
            data[h] = (ds.subset(slice(0, N_TRAIN)), ds.subset(slice(N_TRAIN + N_TUNE, None)))
        tr, val = data[h]
        if w > 0 and h not in perceived:
            perceived[h] = P.perceived(tr, PERCEIVE)
        shape = {} if args.channels is None else {"channels": tuple(args.channels)}
        if args.predicates is not None:
            shape["n_predicates"] = args.predicates
        if args.predicate_pool is not None:
            shape["predicate_pool"] = args.predicate_pool
        if args.states is not None:
            shape["n_states"] = args.states
        if args.gains_input is not None:
            shape["gains_input"] = args.gains_input
        cfg = models.ModelConfig(setting=setting, speed_output=out, **shape)
        runs = {a: [] for a in AGENTS}
        for seed in range(args.seeds):
            tc = train.TrainConfig(epochs=args.epochs, lr=args.lr, seed=seed, speed_scale=scale,
                                   perception_weight=w)
            res = train.fit(name, tr, cfg, tc, progress=False,
                            perception=perceived[h] if w > 0 else None)
            for a in AGENTS:
                traj = rollout.closed_loop(name, res.params, val, cfg, progress=False, agents=a)
                runs[a].append(scores(traj, val))
            print(f"[{time.perf_counter() - t0:6.0f} s] {name}:{setting}:{h}:{out}:{scale}:{w:g} "
                  f"seed {seed}: " + ", ".join(
                      f"{a} {runs[a][-1]['at_fault_collision_rate']:.1f} % at fault, ADE "
                      f"{runs[a][-1]['ade']:.2f}" for a in AGENTS), flush=True)
        for a in AGENTS:
            rows[a].append(f"| {models.spec(name).label} | {setting} | {h} | {out} | {scale} | "
                           f"{w:g} | {cells(runs[a], SHOW)} |")
        contacts.append(f"| {models.spec(name).label} | {setting} | {h} | {out} | {scale} | "
                        f"{w:g} | {contact_cells(runs['reactive'])} |")
    text = (f"# Fixes, one at a time (paper preset draw: {N_TRAIN} training, {N_VAL} "
            f"validation scenes; {args.epochs} epochs, lr {args.lr:g}, {args.seeds} seeds, "
            + ("" if args.channels is None else f"backbone channels {tuple(args.channels)}, ")
            + ("" if args.predicates is None else f"{args.predicates} predicates, ")
            + ("" if args.predicate_pool is None else f"predicates pooled {args.predicate_pool}, ")
            + ("" if args.states is None else f"{args.states} q-states, ")
            + ("" if args.gains_input is None else f"MANC's gains read {args.gains_input}, ")
            + "mean ± std)\n\n")
    for a in AGENTS:
        text += (f"## Agents `{a}`\n\n| model | setting | history | speed output | speed scale"
                 " | perception loss | " + " | ".join(HEAD) + " |\n" + "|---" * (6 + len(HEAD))
                 + "|\n"
                 + "\n".join(rows[a]) + "\n\n")
    text += ("## Collisions by kind, agents `reactive`\n\nFirst contacts per seed (mean over "
             "seeds; of the validation scenes) and, at the at-fault ones (pooled over the "
             "seeds), the ego's speed next to the human's at the same step of the same scene "
             "(m/s) and the share in which the ego was faster.\n\n"
             "| model | setting | history | speed output | speed scale | perception loss | "
             "at fault | front | stopped ado | lateral | ego m/s | human m/s | ego faster % |\n"
             + "|---" * 13 + "|\n" + "\n".join(contacts) + "\n\n")
    results.publish(text, args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
