"""Chapter 11 — ``minimanc dagger``: DAgger against behaviour cloning at the same label
budget (:mod:`minimanc.dagger`), with checkpoints per round and a metric-vs-round figure.

::

    minimanc dagger --model manc --sim world --rounds 3 --beta 0.5 --scenes 16 \\
        --val-scenes 8 --epochs 4 --out runs/dagger
    minimanc dagger --model cnn --sim highway --scenario roundabout --steps 20 --out runs/hw

The pool of demonstrations is generated (``--sim world``: ``minimanc.world.generate``;
``--sim highway``: ``minimanc.highway.collect_demonstrations``) or read from ``--data``.
``--budget`` is the number of expert-labelled samples (default: every state of the pool); or give
``--initial`` and ``--per-round`` scenes, a plan that a rerun with more ``--rounds``
extends. Under ``--out``: ``round_<i>/`` per round and ``bc/`` (checkpoints; a rerun
loads the complete ones and resumes the rest), ``dagger.json`` and ``dagger.md`` (the
table) and ``figures/dagger_<metric>.png``. Bad arguments are one line on stderr, exit 2.
"""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

from minimanc import dagger, models, train, world
from minimanc.checks import check_int, check_positive
from minimanc.cli.common import (
    add_engine_option,
    check_choices,
    check_option,
    check_out_dir,
    load_data,
)
from minimanc.dagger import AGENTS, SIMS
from minimanc.errors import UsageError
from minimanc.inputs import SETTINGS
from minimanc.viz.dagger import plot_rounds

__all__ = ["SIM_METRICS", "cmd_dagger", "register"]

SIM_METRICS = {"world": ("ade", "collision_rate", "at_fault_collision_rate", "off_road_rate"),
               "highway": ("ade", "collision_rate", "off_road_rate")}
"""The metrics reported (table and figures) per simulator."""


def _check_beta(value: Any) -> float:
    ok = (not isinstance(value, bool) and isinstance(value, int | float)
          and math.isfinite(value) and 0.0 <= value <= 1.0)
    if not ok:
        raise UsageError(f"--beta must be a number in [0, 1], got {value!r}")
    return float(value)


def _check_args(args: argparse.Namespace) -> None:
    check_choices([args.model], "--model", models.names(), what="model")
    check_choices([args.sim], "--sim", SIMS, what="simulator")
    check_choices([args.agents], "--agents", AGENTS, what="protocol")
    check_choices([args.setting], "--setting", SETTINGS, what="setting")
    check_option(check_int, "--rounds", args.rounds, 1)
    _check_beta(args.beta)
    check_option(check_int, "--seed", args.seed, 0)
    check_option(check_int, "--epochs", args.epochs, 1)
    check_option(check_int, "--batch-size", args.batch_size, 1)
    check_option(check_positive, "--lr", args.lr)
    check_option(check_int, "--val-scenes", args.val_scenes, 0)
    check_option(check_int, "--size", args.size, 8)
    check_option(check_int, "--steps", args.steps, 2)
    if args.data is None:
        check_option(check_int, "--scenes", args.scenes, 2)
    for option in ("budget", "initial", "per_round"):
        value = getattr(args, option)
        if value is not None:
            check_option(check_int, "--" + option.replace("_", "-"), value, 1)
    if (args.initial is None) != (args.per_round is None):
        raise UsageError("--initial and --per-round go together (or give --budget)")
    if args.budget is not None and args.initial is not None:
        raise UsageError("give --budget or --initial/--per-round, not both")


def _world_teacher(args: argparse.Namespace) -> Any:
    if args.data is not None:
        ds = load_data(args.data)
        if args.val_scenes >= len(ds):
            raise UsageError(f"--val-scenes {args.val_scenes}: --data holds {len(ds)} scenes")
        if args.val_scenes == 0:
            pool, val = ds, None
        else:
            pool, val = ds.split(len(ds) - args.val_scenes)
    else:
        ds = world.generate(args.scenes + args.val_scenes, seed=args.seed,
                            raster=world.RasterConfig(size=args.size), progress=not args.quiet)
        pool, val = (ds, None) if args.val_scenes == 0 else ds.split(args.scenes)
    try:
        return dagger.WorldTeacher(pool, val, agents=args.agents)
    except ValueError as e:
        raise UsageError(f"--data {e}") from e


def _highway_teacher(args: argparse.Namespace) -> Any:
    try:
        import minimanc.highway as hw  # optional dependency: highway-env
    except ImportError as e:
        raise UsageError(str(e)) from e
    check_choices([args.scenario], "--scenario", tuple(hw.SCENARIOS), what="scenario")
    cfg = world.RasterConfig(size=args.size)
    if args.data is not None:
        pool = load_data(args.data)
        cfg = pool.raster
    else:
        pool = hw.collect_demonstrations(args.scenario, n_episodes=args.scenes, seed=args.seed,
                                         steps=args.steps, cfg=cfg, progress=not args.quiet)
    val = None
    if args.val_scenes:
        steps = pool.n_steps
        val, _ = hw.expert_episodes(args.scenario, args.val_scenes, seed=hw.EVAL_SEED,
                                    steps=steps, cfg=cfg, record_bev=False,
                                    progress=not args.quiet)
    try:
        return dagger.HighwayTeacher(pool, val)
    except ValueError as e:
        raise UsageError(f"--data {e}") from e


def cmd_dagger(args: argparse.Namespace) -> int:
    """DAgger rounds and behaviour cloning at the same budget; table, JSON and figures."""
    import matplotlib  # matplotlib only when a figure is drawn

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # matplotlib only when a figure is drawn

    _check_args(args)
    out = check_out_dir(args.out)
    teacher = _world_teacher(args) if args.sim == "world" else _highway_teacher(args)
    T = teacher.pool.n_steps
    try:
        if args.initial is not None:
            budget = dagger.Budget.fixed(T, args.initial, args.per_round, args.rounds)
        else:
            total = args.budget if args.budget is not None else len(teacher.pool) * T
            budget = dagger.plan_budget(total, T, args.rounds)
        if budget.scenes > len(teacher.pool):
            raise ValueError(f"the budget needs {budget.scenes} scenes; the pool holds "
                             f"{len(teacher.pool)} (raise --scenes)")
        tc = train.TrainConfig(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr,
                               seed=args.seed)
        cfg = dagger.default_config(teacher.pool, setting=args.setting)
    except ValueError as e:
        raise UsageError(str(e)) from e
    progress = not args.quiet
    common = dict(cfg=cfg, train_cfg=tc, engine=args.engine, out=out, seed=args.seed,
                  progress=progress)
    where = args.agents if args.sim == "world" else args.scenario
    plan = " + ".join(map(str, (budget.initial, *budget.per_round)))
    print(f"minimanc dagger: {args.model} in {args.sim} ({where}), {args.rounds} rounds, "
          f"beta {args.beta}, budget {budget.used} labelled samples ({plan} scenes of {T} "
          "steps)")
    try:
        bc = None if args.no_bc else dagger.behaviour_cloning(
            args.model, teacher, budget, args.rounds, **common)
        res = dagger.dagger(args.model, teacher, budget, args.rounds, args.beta, **common)
    except ValueError as e:  # another configuration in --out, an unreadable checkpoint
        raise UsageError(str(e)) from e
    keys = SIM_METRICS[args.sim]
    table = res.table(keys)
    if bc is not None:
        vals = " | ".join(f"{bc.metrics[k]:.2f}" if k in bc.metrics else "-" for k in keys)
        table += f"\n| BC | 1.000 | {bc.labelled} | {bc.samples} | {vals} |"
    print(table)
    (out / "dagger.md").write_text(table + "\n")
    summary = {"model": args.model, "sim": args.sim, "rounds": [r.to_json() for r in res.rounds],
               "bc": None if bc is None else bc.to_json(),
               "budget": {"total": budget.total, "steps": T, "initial": budget.initial,
                          "per_round": list(budget.per_round), "used": budget.used}}
    (out / "dagger.json").write_text(json.dumps(summary, indent=1))
    figs = out / "figures"
    figs.mkdir(exist_ok=True)
    written = []
    for key in keys:
        if not any(key in r.metrics for r in res.rounds):
            continue
        ax = plot_rounds([res], key, [] if bc is None else [bc])
        path = figs / f"dagger_{key}.png"
        ax.figure.savefig(path, dpi=120, bbox_inches="tight")
        plt.close(ax.figure)
        written.append(path)
    print(f"wrote {out / 'dagger.md'}, {out / 'dagger.json'} and {len(written)} figure(s) in "
          f"{figs}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``minimanc dagger`` to the ``minimanc`` parser."""
    p = subparsers.add_parser(
        "dagger", help="DAgger vs behaviour cloning at the same expert-label budget",
        description="Train by DAgger (drive with a beta-mixture of policy and expert, label "
                    "every visited state with the expert, aggregate, retrain) and by behaviour "
                    "cloning on as many labels; checkpoints per round under --out.")
    p.add_argument("--model", default="manc", help="a registered model (default manc)")
    p.add_argument("--sim", default="world", help="world or highway (default world)")
    p.add_argument("--rounds", type=int, default=3, help="DAgger rounds after BC (default 3)")
    p.add_argument("--beta", type=float, default=0.5,
                   help="p of the schedule beta_i = p^i (default 0.5)")
    p.add_argument("--budget", type=int, default=None,
                   help="expert-labelled samples (default: every state of the pool)")
    p.add_argument("--initial", type=int, default=None, help="demonstration scenes of round 0")
    p.add_argument("--per-round", type=int, default=None, help="scenes driven per round")
    p.add_argument("--data", default=None, help="the pool as a dataset file (else generated)")
    p.add_argument("--scenes", type=int, default=16, help="pool scenes to generate (default 16)")
    p.add_argument("--val-scenes", type=int, default=8,
                   help="validation scenes / episodes (default 8; 0: no evaluation)")
    p.add_argument("--agents", default="reactive",
                   help="world ados: reactive or replay (default reactive)")
    p.add_argument("--scenario", default="roundabout", help="highway scenario")
    p.add_argument("--steps", type=int, default=20, help="highway episode steps (default 20)")
    p.add_argument("--size", type=int, default=32, help="BEV size in pixels (default 32)")
    p.add_argument("--setting", default="paper", help="information setting: paper or parity")
    p.add_argument("--epochs", type=int, default=4, help="training epochs per round")
    p.add_argument("--batch-size", type=int, default=64, help="samples per step")
    p.add_argument("--lr", type=float, default=3e-3, help="Adam learning rate")
    p.add_argument("--seed", type=int, default=0, help="seed of data, scene order and coins")
    p.add_argument("--no-bc", action="store_true", help="skip the BC baseline")
    add_engine_option(p)
    p.add_argument("--out", required=True, help="output directory (checkpoints, table, figures)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=cmd_dagger)
