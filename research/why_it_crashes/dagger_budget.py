"""DAgger at a real budget for the image models, at the paper's size, against behaviour
cloning given the same number of labels as extra demonstrations.

The draw of ``data_scale.py`` (data seed 0): the pool is the paper split's 650
training scenes and the next ``rounds × per_round`` scenes of the draw (scenes 890 on), the
policies are driven on its 200 validation scenes. Round 0 is behaviour cloning on 650 scenes
of the pool; each of ``--rounds`` DAgger rounds drives ``--per-round`` more pool scenes with
the β-mixture of the policy and the world's human (β_i = ``--beta``^i), labels every visited
state with the human (:class:`minimanc.dagger.WorldTeacher`, ados ``--agents``), aggregates
and retrains from scratch (:func:`minimanc.dagger.dagger`). Behaviour cloning at equal
labels trains on all the pool scenes' demonstrations (:func:`minimanc.dagger.behaviour_cloning`).
Every round is scored among reactive ados (at fault, ADE); the last round and BC are also
driven among replayed ados. With ``--perturb SPEED YAW_RATE TAU`` a third method is trained
at the same label count: perturbed demonstrations (:class:`minimanc.dagger.Perturbation`,
ChauffeurNet's augmentation): the 650 demonstrations of round 0 plus the world's human
driving the other pool scenes with an Ornstein–Uhlenbeck offset on its applied controls
(stationary σ ``SPEED`` m/s and ``YAW_RATE`` rad/s, correlation time ``TAU`` s), every
state labelled with its clean control; one training, no policy in the loop.

    python research/why_it_crashes/dagger_budget.py --model manc --seeds 3 \\
        --perturb 1.5 0.03 2 --out research/why_it_crashes/results/dagger_budget_manc.md

The last section reads the open-loop error of BC and of DAgger's last round on the human's
own validation states, by regime (:func:`regimes.error_by_regime`; the
regime of a state from what the human perceives there, :func:`minimanc.diagnose.
demonstrations`): whether a model predicts the human's braking where it follows a leader.

Each seed's rounds are checkpointed under ``--work`` (a rerun resumes), and its scores are
kept as JSON there when it ends; the table is written after every seed. (The committed
results were trained with the loss's speed scale "change" and MANC's with the flat
predicates: switches measured and deleted since, see ``REPORT.md``.)
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from regimes import REGIMES, error_by_regime, regimes
from scoring import HEAD, LABEL, N_TRAIN, N_TUNE, N_VAL, SHOW, cells, log, scores

from minimanc import dagger, models, rollout, train, world
from minimanc.diagnose import expert_rollout, floor_rollout, median_style
from minimanc.diagnose import privileged as P
from minimanc.metrics.safety import COLLISION_TYPES
from minimanc.studies import provenance
from minimanc.world.datareader import load
from minimanc.world.datawriter import save

N_DRAW = 2840
AGENTS = ("replay", "reactive")


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
    tc = train.TrainConfig(epochs=args.epochs, lr=1e-3, seed=seed)
    where = args.work / f"{args.model}-{cfg.setting}-{args.agents}-s{seed}"
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


def run_perturbed(args: argparse.Namespace, seed: int, ds: world.Dataset,
                  cfg: models.ModelConfig, t0: float) -> dict:
    """One seed of perturbed demonstrations at DAgger's label count, scored. The collected
    scenes and the training checkpoint are kept under ``--work`` (a rerun resumes)."""
    pool, val = split(ds, args.rounds * args.per_round)
    teacher = dagger.WorldTeacher(pool, val, agents=args.agents)
    order = dagger.scene_order(len(pool), seed)
    demos, drives = np.sort(order[:N_TRAIN]), np.sort(order[N_TRAIN:])
    perturb = dagger.Perturbation(*args.perturb)
    where = args.work / (f"{args.model}-{cfg.setting}-{args.agents}-perturb"
                         + "-".join(f"{v:g}" for v in args.perturb) + f"-s{seed}")
    where.mkdir(parents=True, exist_ok=True)
    stats = where / "collected.json"
    if stats.exists():
        got = provenance.read_json_or_none(stats)
        new = load(where / "data.npz")
    else:
        col = dagger.collect(None, teacher, drives, 1.0, seed=[seed, 99], perturb=perturb)
        save(col.data, where / "data.npz")
        got = {"labelled": col.labelled, "kept": len(col.kept), "refusals": col.refusals}
        provenance.write_json(stats, got)
        new = col.data
    log(f"{args.model} seed {seed} perturbed: {got['kept']} of {len(drives)} scenes kept", t0)
    tc = train.TrainConfig(epochs=args.epochs, lr=1e-3, seed=seed)
    fit = train.fit(args.model, dagger.concat([pool.subset(demos), new]), cfg, tc,
                    checkpoint_dir=where, resume=True, progress=False)
    out = {"labelled": N_TRAIN * pool.n_steps + got["labelled"], "kept": got["kept"],
           "refused": len(got["refusals"]), "perturb": list(args.perturb)}
    out["final"] = {a: scores(rollout.closed_loop(args.model, fit.params, val, cfg,
                                                  progress=False, agents=a), val)
                    for a in AGENTS}
    log(f"{args.model} seed {seed} perturbed: "
        f"{out['final']['reactive']['at_fault_collision_rate']:.1f} % at fault, "
        f"ADE {out['final']['reactive']['ade']:.2f}", t0)
    return out


def bound_rows(val: world.Dataset) -> dict:
    """The bounds on the validation scenes: the expert (the world's human driving closed loop)
    and MANC's DMP head at fixed gains (no learning) under both protocols, and the style
    floor's ADE (the human re-driving with the population's median style)."""
    out: dict = {"expert": {}, "fixed": {}}
    for a in AGENTS:
        out["expert"][a] = scores(expert_rollout(val, agents=a), val)
        out["fixed"][a] = scores(rollout.simulate(rollout.FixedGainsPolicy(), val, agents=a,
                                                  progress=False), val)
    out["floor_ade"] = scores(floor_rollout(val, median_style()), val)["ade"]
    return out


def regime_labels(val: world.Dataset) -> np.ndarray:
    """The regime of every logged state of ``val`` ``(S·T,)``, from what the human perceives
    there and the acceleration it applied."""
    X, Y = P.demonstrations(val)
    f = P.FEATURES.index
    gap = np.where(X[:, f("has_leader")] > 0.5, X[:, f("gap")], np.inf)
    stop = np.where(X[:, f("has_stop")] > 0.5, X[:, f("stop")], np.inf)
    return regimes(X[:, f("v")], gap, stop, Y[:, 0])


def change_by_regime(speed: np.ndarray, last: np.ndarray, labels: np.ndarray) -> dict:
    """``{regime: mean of speed[:, 0] − last[:, 0]}``: the speed command's mean change over the
    human's previous control, per regime."""
    d = speed[:, 0] - last[:, 0]
    return {g: float(d[labels == i].mean()) for i, g in enumerate(REGIMES) if (labels == i).any()}


def open_loop_errors(args: argparse.Namespace, seed: int, val: world.Dataset,
                     cfg: models.ModelConfig, labels: np.ndarray) -> dict:
    """``{method: error_by_regime}`` of BC's and DAgger's last checkpoints of one seed on the
    human's validation states: the RMSE of the speed command (m/s, ``rmse_0``) and the yaw
    rate (rad/s, ``rmse_1``); ``"last"`` is the copycat's, the human's previous control
    (its first at ``t = 0``)."""
    where = args.work / f"{args.model}-{cfg.setting}-{args.agents}-s{seed}"
    ctrl = np.asarray(val.controls, dtype=np.float64)
    human = ctrl.reshape(-1, 2)
    last = np.concatenate([ctrl[:, :1], ctrl[:, :-1]], axis=1).reshape(-1, 2)
    out = {"last": error_by_regime(last, human, labels),
           "change": {"human": change_by_regime(human, last, labels)}}
    for method, ck in (("bc", where / "bc"), ("dagger", dagger.round_dir(where, args.rounds))):
        fit = train.load_fit(ck / "checkpoint.npz")
        pred = rollout.open_loop(args.model, fit.params, val, cfg, engine="jax")["controls"]
        pred = np.asarray(pred, dtype=np.float64).reshape(-1, 2)
        out[method] = error_by_regime(pred, human, labels)
        out["change"][method] = change_by_regime(pred, last, labels)
    return out


def regime_table(args: argparse.Namespace, runs: list[dict]) -> str:
    text = ("## Open loop by regime\n\nOn the human's validation states: the RMSE of the "
            "speed command (m/s) / of the yaw rate (rad/s), mean over seeds; the share of the "
            "states in each regime.\n\n| method | "
            + " | ".join(REGIMES) + " |\n" + "|---" * (len(REGIMES) + 1) + "|\n")
    first = runs[0]["open_loop"]
    named = (("last", "the human's previous control (copycat)"), ("bc", "BC at equal labels"),
             ("dagger", f"DAgger, round {args.rounds}"))
    for method, label in named:
        row = []
        for g in REGIMES:
            if g not in first[method]:
                row.append("-")
                continue
            v = np.array([r["open_loop"][method][g]["rmse_0"] for r in runs])
            w = np.array([r["open_loop"][method][g]["rmse_1"] for r in runs])
            row.append(f"{v.mean():.2f} / {w.mean():.3f}")
        text += f"| {label} | " + " | ".join(row) + " |\n"
    shares = [f"{100 * first['bc'][g]['share']:.0f} %" if g in first["bc"] else "-"
              for g in REGIMES]
    text += "| share | " + " | ".join(shares) + " |\n\n"
    text += ("## Speed change by regime\n\nOn the human's validation states: the mean change "
             "of the speed command over the human's previous control (m/s per step), mean over "
             "seeds; a model that brakes where the human brakes has the human's negative "
             "value.\n\n| method | " + " | ".join(REGIMES) + " |\n"
             + "|---" * (len(REGIMES) + 1) + "|\n")
    for method, label in (("human", "the human"), *named[1:]):
        vals = [np.mean([r["open_loop"]["change"][method][g] for r in runs])
                if g in first["change"][method] else float("nan") for g in REGIMES]
        text += (f"| {label} | " + " | ".join("-" if np.isnan(v) else f"{v:+.2f}" for v in vals)
                 + " |\n")
    return text + "\n"


def methods(args: argparse.Namespace, runs: list[dict]) -> list[tuple[str, str]]:
    """(key, label) of the methods every run has."""
    named = (("bc", "BC at equal labels"), ("perturbed", "perturbed demonstrations"),
             ("dagger", f"DAgger, round {args.rounds}"))
    return [(k, label) for k, label in named if all(k + "_final" in r for r in runs)]


def curve(runs: list[dict], key: str) -> str:
    rows = []
    for i in range(len(runs[0]["rounds"])):
        v = np.array([r["rounds"][i]["metrics"][key] for r in runs])
        rows.append(f"{v.mean():.2f}" if len(v) == 1 else f"{v.mean():.2f} ± {v.std():.2f}")
    return " | ".join(rows)


def table(args: argparse.Namespace, runs: list[dict], cfg: models.ModelConfig,
          bounds: dict) -> str:
    name = LABEL.get(args.model, args.model)
    first = runs[0]
    labels = first["bc"]["labelled"] if "bc" in first else first["perturb_labelled"]
    text = (f"# DAgger at a real budget against behaviour cloning at equal labels: {name}\n\n"
            f"## Setup\n\nPaper preset draw, data seed 0; {cfg.setting} setting, "
            f"{args.epochs} epochs per training from scratch, lr 0.001; {len(runs)} seed(s), "
            "mean ± std over seeds.\n\n")
    if "rounds" in first:
        text += (f"Round 0 is behaviour cloning on {N_TRAIN} scenes; then {args.rounds} DAgger "
                 f"rounds of {args.per_round} scenes each (β = {args.beta}^i, labels by the "
                 f"world's human in the state reached, ados `{args.agents}`), {labels} labelled "
                 "samples in all. BC at equal labels trains on the demonstrations of all "
                 f"{N_TRAIN + args.rounds * args.per_round} pool scenes.\n\n")
    text += f"Every method is driven on the draw's {N_VAL} validation scenes.\n\n"
    if "rounds" in first:
        mins = [sum(x["seconds"] for x in r["rounds"]) / 60 for r in runs]
        text += ("DAgger's rounds took " + ", ".join(f"{m:.0f}" for m in mins)
                 + " min per seed (collection, training and the per-round drive; one core "
                 "each, the wall time below counts only what this run did not load from "
                 "`--work`).\n\n")
    if any(m == "perturbed" for m, _ in methods(args, runs)):
        sp, yr, tau = first["perturb"]
        text += (f"Perturbed demonstrations: the {N_TRAIN} demonstrations plus the human driving "
                 f"the other {args.rounds * args.per_round} pool scenes with an "
                 f"Ornstein–Uhlenbeck offset on its applied controls (σ {sp:g} m/s, "
                 f"{yr:g} rad/s, τ {tau:g} s), labelled with its clean controls; scenes kept "
                 "(the rest reached a state the human refuses to label, off the drivable "
                 "area): " + ", ".join(str(r["perturb_kept"]) for r in runs)
                 + f"; {labels} labelled samples in all.\n\n")
    for a in AGENTS:
        text += (f"## Agents `{a}`\n\n| method | " + " | ".join(HEAD) + " |\n"
                 + "|---" * (len(HEAD) + 1) + "|\n")
        text += "| Expert (bound) | " + cells([bounds["expert"][a]], SHOW) + " |\n"
        text += ("| DMP at fixed gains (no learning) | " + cells([bounds["fixed"][a]], SHOW)
                 + " |\n")
        for method, label in methods(args, runs):
            text += f"| {label} | " + cells([r[method + "_final"][a] for r in runs], SHOW) + " |\n"
        text += (f"\nThe style floor's ADE on these scenes (the human re-driving them with the "
                 f"population's median style): {bounds['floor_ade']:.2f} m.\n\n")
    text += ("## Collisions by kind\n\nAdos `reactive`; contacts over the validation scenes, "
             "summed over seeds; the mean speeds at the at-fault contacts.\n\n| method | "
             + " | ".join(f"`{k}`" for k in COLLISION_TYPES)
             + " | at fault | ego m/s | human m/s |\n" + "|---" * (len(COLLISION_TYPES) + 4)
             + "|\n")
    for method, label in methods(args, runs):
        c = [r[method + "_final"]["reactive"] for r in runs]
        counts = [int(sum(x[f"contacts_{k}"] for x in c)) for k in (*COLLISION_TYPES, "at_fault")]
        n = sum(x["contacts_at_fault"] for x in c)
        speeds = [sum(x[f"contacts_{k}"] * x["contacts_at_fault"] for x in c
                      if x["contacts_at_fault"]) / n if n else float("nan")
                  for k in ("ego_speed", "human_speed")]
        text += (f"| {label} | " + " | ".join(map(str, counts)) + " | "
                 + " | ".join("-" if np.isnan(v) else f"{v:.1f}" for v in speeds) + " |\n")
    text += "\n"
    if "rounds" not in first:
        return text
    if all("open_loop" in r for r in runs):
        text += regime_table(args, runs)
    n = len(first["rounds"])
    text += ("## DAgger per round\n\nAdos `" + args.agents + "`, mean ± std over seeds.\n\n| | "
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
    ap.add_argument("--perturb", type=float, nargs=3, default=None,
                    metavar=("SPEED", "YAW_RATE", "TAU"))
    ap.add_argument("--parts", nargs="+", choices=("dagger", "perturbed"),
                    default=["dagger", "perturbed"],
                    help="what to run (perturbed needs --perturb)")
    ap.add_argument("--work", type=Path, default=Path("runs/dagger_budget"))
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    try:
        cfg = models.ModelConfig(setting=args.setting)
        models.get(args.model)
        if args.perturb is not None:
            dagger.Perturbation(*args.perturb)
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
    bpath = args.work / "bounds.json"
    bounds = provenance.read_json_or_none(bpath) if bpath.exists() else None
    if bounds is None:
        bounds = bound_rows(split(ds, args.rounds * args.per_round)[1])
        provenance.write_json(bpath, bounds)
    runs = []
    labels = None
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        path = args.work / (f"{args.model}-{cfg.setting}-{args.agents}-r{args.rounds}"
                            f"x{args.per_round}-e{args.epochs}-s{seed}.json")
        r = provenance.read_json_or_none(path) if path.exists() else None
        if r is None and "dagger" in args.parts:
            r = run_seed(args, seed, ds, cfg, t0)
            provenance.write_json(path, r)
        r = r or {}
        if "rounds" in r:
            ol = path.with_name(path.stem + "-openloop.json")
            e = provenance.read_json_or_none(ol) if ol.exists() else None
            if e is None:
                val = split(ds, args.rounds * args.per_round)[1]
                labels = regime_labels(val) if labels is None else labels
                e = open_loop_errors(args, seed, val, cfg, labels)
                provenance.write_json(ol, e)
            r = {**r, "open_loop": e}
        if args.perturb is not None and "perturbed" in args.parts:
            pp = path.with_name(path.stem + "-perturb" + "-".join(f"{v:g}" for v in args.perturb)
                                + ".json")
            q = provenance.read_json_or_none(pp) if pp.exists() else None
            if q is None:
                q = run_perturbed(args, seed, ds, cfg, t0)
                provenance.write_json(pp, q)
            r = {**r, "perturbed_final": q["final"], "perturb": q["perturb"],
                 "perturb_kept": q["kept"], "perturb_labelled": q["labelled"]}
        runs.append(r)
        provenance.publish(table(args, runs, cfg, bounds), args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
