"""The privileged learner: behaviour cloning on the numbers the world's expert perceives
(:mod:`minimanc.diagnose.privileged`; MANC's heads: :mod:`heads`), driven closed loop on
the paper preset's split.

Five parts, each a section of the results file:

* **Behaviour cloning**: the MLP trained by Algorithm 1 on the human's logged states of
  the ``--train`` training scenes, over ``--seeds`` training seeds, driven on the
  ``--val`` validation scenes under both protocols, next to the expert driven the same
  way (:class:`~minimanc.diagnose.ExpertPolicy`): open-loop RMSE, ADE with its
  along-/cross-track split, collisions and at-fault collisions (mean ± std over seeds).
* **Ablation**: the same with one input group of
  :data:`~minimanc.diagnose.FEATURE_GROUPS` removed, reactive ados.
* **What one image can show** (``--parts information``): the learner without the speeds
  a single raster frame does not hold, under both protocols.
* **A perception that errs** (``--parts noise``): the learner trained on demonstrations
  whose features carry independent Gaussian errors (:func:`~minimanc.diagnose.blur`)
  and driven with the same errors, reactive ados: how exact gap, closing speed and own speed
  must be perceived for the privileged learner to stay safe.
* **DAgger**: ``--rounds`` rounds of ``--per-round`` training scenes each
  (:func:`rounds.dagger_rounds`, reactive ados), the closed-loop
  metrics after every round, against behaviour cloning given the same number of labels
  as extra demonstrations (more scenes of the same draw), over ``--dagger-seeds`` training
  seeds.

The data is the paper preset's draw (data seed ``--data-seed``: ``--train`` training,
40 tuning, ``--val`` validation scenes, in that order). ``--head dmp`` gives every learner
MANC's DMP head (the MLP predicts its gain logits): MANC's head on the expert's perception;
``--head vagn`` gives it MANC's automaton as well (the MLP predicts MANC's predicates, then
vAGN, ``FC(q)`` and the DMP head), ``--head vagn_predicates`` the same with ``FC(q ⊕ p)``;
these two in the parts ``bc``, ``ablation``, ``information`` and ``noise`` only.

Run: ``python research/why_it_crashes/privileged.py
--out research/why_it_crashes/results/privileged.md``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
from heads import HEADS, fit_any, head_inputs, policy_of, predict_scenes
from rounds import dagger_rounds
from scoring import cells, log

from minimanc import world
from minimanc.dagger.teachers import AGENTS, WorldTeacher
from minimanc.diagnose import policies
from minimanc.diagnose import privileged as P
from minimanc.studies import provenance

N_TUNE = 40
SHOW = ("ade", "along_track", "cross_track", "collision_rate", "at_fault_collision_rate",
        "off_road_rate", "refused")
HEAD = ("ADE m", "along m", "cross m", "coll. %", "at fault %", "off road %", "refused")
INFORMATION: dict[str, tuple[str, ...]] = {
    "one frame": ("v", "a_prev", "dv"),
    "one frame + own speed": ("a_prev", "dv"),
}
"""Features a raster cannot show, by what the image (and the setting) give."""
NOISE: dict[str, dict[str, float]] = {
    "exact": {},
    "gap σ 1 m": {"gap": 1.0},
    "gap σ 2.5 m": {"gap": 2.5},
    "gap σ 5 m": {"gap": 5.0},
    "dv σ 0.5 m/s": {"dv": 0.5},
    "dv σ 1 m/s": {"dv": 1.0},
    "dv σ 2 m/s": {"dv": 2.0},
    "v σ 0.5 m/s": {"v": 0.5},
    "v σ 1 m/s": {"v": 1.0},
    "v σ 2.5 m/s": {"v": 2.5},
    "gap σ 2.5 m, dv σ 1 m/s, v σ 0.5 m/s": {"gap": 2.5, "dv": 1.0, "v": 0.5},
    "gap σ 5 m, dv σ 2 m/s, v σ 2.5 m/s": {"gap": 5.0, "dv": 2.0, "v": 2.5},
}
"""Perception errors (feature → σ) the ``noise`` part drives with; the last is about what a
linear read-out of the image models' backbone features recovers (``results/perception_probe.md``:
gap RMSE 4.6–6.5 m with a leader within 30 m, closing speed about its own spread, own speed
R² ≈ 0.5 of a 3.5 m/s spread)."""




def row(name: str, runs: list[dict]) -> str:
    return f"| {name} | {cells(runs, SHOW)} |"


def table(rows: list[str], first: str = "driver") -> list[str]:
    return [f"| {first} | " + " | ".join(HEAD) + " |",
            "|---" * (len(HEAD) + 1) + "|", *rows]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--train", type=int, default=650)
    ap.add_argument("--val", type=int, default=200)
    ap.add_argument("--data-seed", type=int, default=0)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--ablation-seeds", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=10)
    ap.add_argument("--per-round", type=int, default=65)
    ap.add_argument("--dagger-seeds", type=int, default=1)
    ap.add_argument("--parts", default="bc,ablation,dagger")
    ap.add_argument("--head", choices=HEADS, default="acceleration")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    parts = args.parts.split(",")
    if args.head.startswith("vagn") and "dagger" in parts:
        raise SystemExit(f"privileged: --head {args.head} has no DAgger part (its learner is "
                         "trained on whole scenes); drop 'dagger' from --parts")
    t0 = time.perf_counter()
    extra = args.rounds * args.per_round if "dagger" in parts else 0
    n = args.train + N_TUNE + args.val
    ds = world.generate(n + extra, seed=args.data_seed, raster=world.RasterConfig(size=16))
    train, val = ds.subset(slice(0, args.train)), ds.subset(slice(args.train + N_TUNE, n))
    log(f"data: {n + extra} scenes", t0)
    X, Y = P.demonstrations(train)
    Xv, Yv = P.demonstrations(val)
    reads_lane = args.head != "acceleration"  # MANC's DMP head reads the lane and motion
    T = train.n_steps
    lane, motion = head_inputs(train) if reads_lane else (None, None)
    val_head = head_inputs(val) if reads_lane else (None, None)

    def fit(X: np.ndarray, Y: np.ndarray, **kw: Any) -> Any:  # one learner of --head
        return fit_any(args.head, X, Y, lane, motion, steps=args.steps, scene_steps=T, **kw)

    log(f"demonstrations: {len(X)} training, {len(Xv)} validation states", t0)
    teachers = {a: WorldTeacher(val, agents=a) for a in AGENTS}
    sections: dict[str, list[str]] = {}

    if "bc" in parts:
        lines, rmse = [], []
        runs: dict[str, list[dict]] = {a: [] for a in AGENTS}
        for seed in range(args.seeds):  # one learner per seed, driven under both protocols
            model = fit(X, Y, seed=seed)
            pred = predict_scenes(model, Xv, *val_head, scene_steps=T)
            rmse.append(np.sqrt(((pred - Yv) ** 2).mean(0)))
            for agents in AGENTS:
                runs[agents].append(policies.evaluate_policy(policy_of(model, teachers[agents]),
                                                      val, agents))
                log(f"bc {agents} seed {seed}: "
                    f"{runs[agents][-1]['at_fault_collision_rate']:.1f} % at fault, "
                    f"ADE {runs[agents][-1]['ade']:.2f}", t0)
        for agents in AGENTS:
            ex = policies.evaluate_policy(policies.ExpertPolicy(teachers[agents]), val,
                                          agents=agents)
            lines += [f"agents `{agents}`", "", *table([row("Expert", [ex]),
                                                        row("Privileged BC", runs[agents])]), ""]
        r = np.array(rmse)
        lines += [f"Open-loop RMSE on the validation states (human's logged controls), "
                  f"{args.seeds} seeds: acceleration {r[:, 0].mean():.3f} m/s² (their std "
                  f"{Yv[:, 0].std():.3f}), yaw rate {r[:, 1].mean():.4f} rad/s (std "
                  f"{Yv[:, 1].std():.4f})."]
        sections["Behaviour cloning"] = lines

    if "ablation" in parts:
        rows = []
        for drop in ((),) + tuple((g,) for g in P.FEATURE_GROUPS if g != "speed"):
            runs = []
            for seed in range(args.ablation_seeds):
                model = fit(X, Y, drop=drop, seed=seed)
                runs.append(policies.evaluate_policy(policy_of(model, teachers["reactive"]), val,
                                              "reactive"))
            name = "all inputs" if not drop else f"without `{drop[0]}`"
            rows.append(row(name, runs))
            log(f"ablation {name}: {np.mean([r['at_fault_collision_rate'] for r in runs]):.1f} "
                "% at fault", t0)
        sections["Ablation"] = [f"agents `reactive`, {args.ablation_seeds} seeds", "",
                                *table(rows, "inputs")]

    if "information" in parts:
        rows = []
        for name, without in INFORMATION.items():
            runs = {a: [] for a in AGENTS}
            for seed in range(args.ablation_seeds):
                model = fit(X, Y, without=without, seed=seed)
                for a in AGENTS:
                    runs[a].append(policies.evaluate_policy(policy_of(model, teachers[a]), val, a))
            for a in AGENTS:
                rows.append(row(f"{name}, `{a}`", runs[a]))
            log(f"information {name}: " + ", ".join(
                f"{a} {np.mean([r['at_fault_collision_rate'] for r in runs[a]]):.1f} %"
                for a in AGENTS), t0)
        sections["What one image can show"] = [
            f"{args.ablation_seeds} seeds. The privileged learner given only what a raster "
            "can show: one frame holds positions (gap, stop distance, curves, lane) but no "
            "speed (neither the ego's nor the closing speed: without "
            f"{', '.join(f'`{f}`' for f in INFORMATION['one frame'])}); a faded history "
            "adds them back.", "", *table(rows, "information")]

    if "noise" in parts:
        rows = []
        for name, noise in NOISE.items():
            runs = []
            for seed in range(args.ablation_seeds):
                Xn = P.blur(X, noise, np.random.default_rng([seed, 1]))
                model = fit(Xn, Y, seed=seed)
                runs.append(policies.evaluate_policy(policy_of(model, teachers["reactive"],
                                                        noise=noise, seed=seed),
                                              val, "reactive"))
            rows.append(row(name, runs))
            log(f"noise {name}: {np.mean([r['at_fault_collision_rate'] for r in runs]):.1f} "
                "% at fault", t0)
        sections["A perception that errs"] = [
            f"agents `reactive`, {args.ablation_seeds} seeds. Every input exact except the "
            "named ones, which carry an independent Gaussian error N(0, σ²) in every "
            "training and every driven state.", "", *table(rows, "perception")]

    if "dagger" in parts:
        per_seed, bc = [], []
        more = ds.subset(np.r_[np.arange(args.train), np.arange(n, n + extra)])
        Xm, Ym = P.demonstrations(more)
        more_lane, more_motion = head_inputs(more) if reads_lane else (None, None)
        for seed in range(args.dagger_seeds):
            per_seed.append(dagger_rounds(train, val, args.rounds, args.per_round,
                                          agents="reactive", steps=args.steps, seed=seed,
                                          head=args.head))
            for i, r in enumerate(per_seed[-1]):
                log(f"dagger seed {seed} round {i}: "
                    f"{r.metrics['at_fault_collision_rate']:.1f} % at fault", t0)
            model = fit_any(args.head, Xm, Ym, more_lane, more_motion, steps=args.steps,
                            seed=seed)
            bc.append(policies.evaluate_policy(policy_of(model, teachers["reactive"]), val,
                                        "reactive"))
            log(f"bc at equal labels seed {seed}: "
                f"{bc[-1]['at_fault_collision_rate']:.1f} % at fault", t0)
        lines = ["| round | labels | " + " | ".join(HEAD) + " |", "|---" * (len(HEAD) + 2) + "|"]
        for i in range(args.rounds + 1):
            runs = [rounds[i].metrics for rounds in per_seed]
            lines.append(f"| {i} | {per_seed[0][i].labels} | {cells(runs, SHOW)} |")
        last = [rounds[-1].metrics for rounds in per_seed]
        lines += ["", "Behaviour cloning at equal labels (the demonstrations of "
                  f"{args.train + extra} scenes, {len(Xm)} states), against DAgger's last "
                  "round:", "",
                  *table([row("BC, equal labels", bc), row(f"DAgger, round {args.rounds}",
                                                            last)])]
        seeds = ("training seed 0" if args.dagger_seeds == 1
                 else f"{args.dagger_seeds} training seeds (mean ± std)")
        sections["DAgger"] = [f"agents `reactive`, {args.per_round} scenes per round, {seeds}",
                              "", *lines]

    what = "The privileged learner" + {"acceleration": "", "dmp": " through MANC's DMP head",
                                       "vagn": " through MANC's vAGN and DMP head",
                                       "vagn_predicates": " through MANC's vAGN and DMP head, "
                                       "the gains reading q and the predicates"}[args.head]
    text = (f"# {what} (data seed {args.data_seed}: {args.train} training, "
            f"{args.val} validation scenes; {args.steps} Adam steps)\n\n")
    for title, lines in sections.items():
        text += f"## {title}\n\n" + "\n".join(lines) + "\n\n"
    provenance.publish(text, args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
