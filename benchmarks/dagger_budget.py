"""DAgger at a real budget for the image models, at the paper's size, against behaviour
cloning given the same number of labels as extra demonstrations.

The draw of ``benchmarks/data_scale.py`` (data seed 0): the pool is the paper split's 650
training scenes and the next ``rounds × per_round`` scenes of the draw (scenes 890 on), the
policies are driven on its 200 validation scenes. Round 0 is behaviour cloning on 650 scenes
of the pool; each of ``--rounds`` DAgger rounds drives ``--per-round`` more pool scenes with
the β-mixture of the policy and the world's human (β_i = ``--beta``^i), labels every visited
state with the human (:class:`minimanc.dagger.WorldTeacher`, ados ``--agents``), aggregates
and retrains from scratch (:func:`minimanc.dagger.dagger`). Behaviour cloning at equal
labels trains on all the pool scenes' demonstrations (:func:`minimanc.dagger.behaviour_cloning`).
Every round is scored among reactive ados (at fault, ADE); the last round and BC are also
driven among replayed ados.

    python benchmarks/dagger_budget.py --model manc --predicate-pool flat --seeds 3 \\
        --out results/dagger_budget_manc.md

Each seed's rounds are checkpointed under ``--work`` (a rerun resumes), and its scores are
kept as JSON there when it ends; the table is written after every seed.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scoring import cells, scores

from minimanc import dagger, models, rollout, train, world
from minimanc.metrics.safety import COLLISION_TYPES
from minimanc.models.forward import changes_speed
from minimanc.studies import provenance

N_TRAIN, N_TUNE, N_VAL, N_DRAW = 650, 40, 200, 2840
AGENTS = ("replay", "reactive")
SHOW = ("ade", "along_track", "cross_track", "collision_rate", "at_fault_collision_rate",
        "off_road_rate")
HEAD = ("ADE m", "along m", "cross m", "coll. %", "at fault %", "off road %")
LABEL = {"cnn": "CNN", "manc": "MANC", "cnn_lstm": "CNN-LSTM", "rvs_g": "RvS-G"}


def log(msg: str, t0: float) -> None:
    print(f"[{time.perf_counter() - t0:7.1f} s] {msg}", flush=True)


def split(ds: world.Dataset, extra: int) -> tuple[world.Dataset, world.Dataset]:
    """The pool (650 training scenes and ``extra`` scenes from 890 on) and the validation
    scenes of the draw."""
    base = N_TRAIN + N_TUNE + N_VAL
    pool = ds.subset(np.r_[np.arange(N_TRAIN), np.arange(base, base + extra)])
    return pool, ds.subset(slice(N_TRAIN + N_TUNE, base))


def run_seed(args: argparse.Namespace, seed: int, ds: world.Dataset, cfg: models.ModelConfig,
             t0: float) -> dict:
    """One seed: DAgger's rounds and BC at equal labels, scored."""
    pool, val = split(ds, args.rounds * args.per_round)
    teacher = dagger.WorldTeacher(pool, val, agents=args.agents)
    budget = dagger.Budget.fixed(pool.n_steps, N_TRAIN, args.per_round, args.rounds)
    tc = train.TrainConfig(epochs=args.epochs, lr=1e-3, seed=seed, speed_scale="change")
    where = args.work / f"{args.model}-{cfg.predicate_pool}-{args.agents}-s{seed}"
    common = dict(cfg=cfg, train_cfg=tc, engine="jax", out=where, seed=seed, progress=False)

    def on_round(r: dagger.RoundResult) -> None:
        log(f"{args.model} seed {seed} round {r.round}: {r.labelled} labels, "
            f"{r.metrics['at_fault_collision_rate']:.1f} % at fault, ADE {r.metrics['ade']:.2f}"
            f" ({r.seconds / 60:.1f} min)", t0)

    res = dagger.dagger(args.model, teacher, budget, args.rounds, args.beta, on_round=on_round,
                        **common)
    bc = dagger.behaviour_cloning(args.model, teacher, budget, args.rounds, **common)
    log(f"{args.model} seed {seed} BC: {bc.labelled} labels, "
        f"{bc.metrics['at_fault_collision_rate']:.1f} % at fault, ADE {bc.metrics['ade']:.2f}",
        t0)
    out = {"rounds": [r.to_json() for r in res.rounds], "bc": bc.to_json()}
    for method, params in (("dagger", res.params), ("bc", bc.params)):
        out[method + "_final"] = {
            a: scores(rollout.closed_loop(args.model, params, val, cfg, progress=False,
                                          agents=a), val) for a in AGENTS}
    return out


def curve(runs: list[dict], key: str, scale: float = 1.0) -> str:
    rows = []
    for i in range(len(runs[0]["rounds"])):
        v = np.array([r["rounds"][i]["metrics"][key] for r in runs]) * scale
        rows.append(f"{v.mean():.2f}" if len(v) == 1 else f"{v.mean():.2f} ± {v.std():.2f}")
    return " | ".join(rows)


def table(args: argparse.Namespace, runs: list[dict], cfg: models.ModelConfig) -> str:
    name = LABEL.get(args.model, args.model)
    first = runs[0]
    labels = first["bc"]["labelled"]
    text = (f"# DAgger at a real budget against behaviour cloning at equal labels ({name}, "
            f"paper preset draw, data seed 0; {cfg.setting} setting, speed output "
            f"{cfg.speed_output}, predicates pooled {cfg.predicate_pool}, speed scale change, "
            f"{args.epochs} epochs per round from scratch, lr 0.001; {len(runs)} seed(s), "
            "mean ± std)\n\n"
            f"Round 0 is behaviour cloning on {N_TRAIN} scenes; then {args.rounds} DAgger rounds"
            f" of {args.per_round} scenes each (β = {args.beta}^i, labels by the world's human in "
            f"the state reached, ados `{args.agents}`), {labels} labelled samples in all. "
            f"BC at equal labels trains on the demonstrations of all "
            f"{N_TRAIN + args.rounds * args.per_round} pool scenes. "
            f"Driven on the draw's {N_VAL} validation scenes.\n\n")
    for a in AGENTS:
        text += (f"## Agents `{a}`\n\n| method | " + " | ".join(HEAD) + " |\n"
                 + "|---" * (len(HEAD) + 1) + "|\n")
        for method, label in (("bc", "BC at equal labels"),
                              ("dagger", f"DAgger, round {args.rounds}")):
            text += f"| {label} | " + cells([r[method + "_final"][a] for r in runs], SHOW) + " |\n"
        text += "\n"
    text += ("## Collisions by kind (ados `reactive`; contacts over the validation scenes, "
             "summed over seeds; the mean speeds at the at-fault contacts)\n\n| method | "
             + " | ".join(f"`{k}`" for k in COLLISION_TYPES)
             + " | at fault | ego m/s | human m/s |\n" + "|---" * (len(COLLISION_TYPES) + 4)
             + "|\n")
    for method, label in (("bc", "BC at equal labels"), ("dagger", f"DAgger, round {args.rounds}")):
        c = [r[method + "_final"]["reactive"] for r in runs]
        counts = [int(sum(x[f"contacts_{k}"] for x in c)) for k in (*COLLISION_TYPES, "at_fault")]
        n = sum(x["contacts_at_fault"] for x in c)
        speeds = [sum(x[f"contacts_{k}"] * x["contacts_at_fault"] for x in c
                      if x["contacts_at_fault"]) / n if n else float("nan")
                  for k in ("ego_speed", "human_speed")]
        text += (f"| {label} | " + " | ".join(map(str, counts)) + " | "
                 + " | ".join("-" if np.isnan(v) else f"{v:.1f}" for v in speeds) + " |\n")
    text += "\n"
    n = len(first["rounds"])
    text += ("## DAgger per round (ados `" + args.agents + "`)\n\n| | "
             + " | ".join(f"round {i}" for i in range(n)) + " |\n" + "|---" * (n + 1) + "|\n"
             + "| labels | " + " | ".join(str(r["labelled"]) for r in first["rounds"]) + " |\n"
             + "| at fault % | " + curve(runs, "at_fault_collision_rate") + " |\n"
             + "| off road % | " + curve(runs, "off_road_rate") + " |\n"
             + "| ADE m | " + curve(runs, "ade") + " |\n\n")
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="manc")
    ap.add_argument("--rounds", type=int, default=10)
    ap.add_argument("--per-round", type=int, default=65)
    ap.add_argument("--beta", type=float, default=0.5)
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--agents", choices=("reactive", "replay"), default="reactive")
    ap.add_argument("--setting", choices=("paper", "parity"), default="paper")
    ap.add_argument("--predicate-pool", choices=("global", "flat"), default="global")
    ap.add_argument("--work", type=Path, default=Path("runs/dagger_budget"))
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    try:
        cfg = models.ModelConfig(setting=args.setting, predicate_pool=args.predicate_pool)
        changes_speed(models.get(args.model), cfg)
    except (KeyError, ValueError) as e:
        raise SystemExit(f"dagger_budget: {e}") from None
    extra = args.rounds * args.per_round
    if args.rounds < 1 or args.per_round < 1 or args.seeds < 1 or args.epochs < 1:
        raise SystemExit("dagger_budget: --rounds, --per-round, --seeds and --epochs must be >= 1")
    if N_TRAIN + N_TUNE + N_VAL + extra > N_DRAW:
        raise SystemExit(f"dagger_budget: --rounds × --per-round must be at most "
                         f"{N_DRAW - N_TRAIN - N_TUNE - N_VAL}")
    t0 = time.perf_counter()
    ds = world.generate(N_DRAW, seed=0, cache=True, progress=True)
    log(f"data: {len(ds.ego)} scenes", t0)
    runs = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        path = args.work / (f"{args.model}-{cfg.predicate_pool}-{args.agents}-r{args.rounds}"
                            f"x{args.per_round}-e{args.epochs}-s{seed}.json")
        r = provenance.read_json_or_none(path) if path.exists() else None
        if r is None:
            r = run_seed(args, seed, ds, cfg, t0)
            provenance.write_json(path, r)
        runs.append(r)
        provenance.publish(table(args, runs, cfg), args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
