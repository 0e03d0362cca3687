"""Chapter 10 — the ``minimanc highway`` command (:mod:`minimanc.highway`): collect, train,
eval, render.

::

    minimanc highway collect --scenarios roundabout intersection highway-fast \\
        --episodes 20 --out highway.npz [--raster channels --extent 60 40 16]
    minimanc highway train --data highway.npz --models manc cnn --epochs 8 --out runs/
    minimanc highway eval --checkpoints runs/manc/checkpoint.npz runs/cnn/checkpoint.npz \\
        --episodes 10 --out eval.json
    minimanc highway render --scenario roundabout --seed 100000 --out frames/ \\
        [--checkpoint runs/manc/checkpoint.npz]

``collect`` draws the course's RGB raster (``--raster rgb``, the default) or a
learner's binary planes (``--raster channels``: the map's planes, the ego's route
ahead, which here runs along the lane the ego is in, and the ego and the vehicles
at ``t``, ``t − 1``, ``t − 2``), ``--size`` rows over the view ``--extent AHEAD
BEHIND SIDE`` (metres; default the devkit's 40 10 25, square pixels). ``eval`` and
``render`` draw what each checkpoint's model was trained on: the raster its
checkpoint records (:attr:`minimanc.train.FitResult.raster`), with the past steps
of the episode being driven. ``eval`` also runs the transfer experiment: give it a
checkpoint trained on the nuScenes-style world (``minimanc.train`` on
``minimanc.world`` data).
This module imports without highway-env; each command imports
:mod:`minimanc.highway` when it runs and, if highway-env is missing, prints
the install command and exits with status 2. Bad arguments (a negative seed,
zero episodes, an unwritable ``--out``, a missing or unreadable ``--data`` or
checkpoint) are one line on stderr and exit status 2, checked before any work.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from minimanc import models, rollout, train, world
from minimanc.checks import check_int, check_positive
from minimanc.cli.common import (
    add_engine_option,
    check_choices,
    check_option,
    check_out_dir,
    check_out_file,
    load_data,
)
from minimanc.errors import UsageError
from minimanc.inputs import SETTINGS

__all__ = ["SCENARIO_NAMES", "cmd_collect", "cmd_eval", "cmd_render", "cmd_train", "register"]

SCENARIO_NAMES = ("roundabout", "intersection", "highway-fast")
"""The sandbox scenarios (``minimanc.highway.SCENARIOS``), listed here so that the
parser does not need highway-env."""


def _highway() -> Any:
    """``minimanc.highway``, or None after printing why it cannot be imported."""
    try:
        import minimanc.highway as hw  # optional dependency: highway-env

        return hw
    except ImportError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return None


def _check_episode_args(args: argparse.Namespace) -> None:
    for option in ("episodes", "steps"):
        if hasattr(args, option):
            check_option(check_int, f"--{option}", getattr(args, option), 1)
    check_option(check_int, "--seed", args.seed, 0)


def _collect_raster(args: argparse.Namespace) -> world.RasterConfig:
    """The raster ``collect`` draws: ``--raster`` (channels: the learner's raster of chapter 7,
    with the ego's route and the last two steps), ``--size`` rows, the view ``--extent``."""
    check_option(check_int, "--size", args.size, 8)
    fields = ({"encoding": "channels", "route": True, "history": 2}
              if args.raster == "channels" else {})
    if args.extent is None:
        return world.RasterConfig(size=args.size, **fields)
    ahead, behind, side = args.extent
    for label, metres in (("AHEAD", ahead), ("SIDE", side), ("AHEAD + BEHIND", ahead + behind)):
        check_option(check_positive, f"--extent {label}", metres)
    if not behind >= 0:
        raise UsageError(f"--extent BEHIND must be >= 0, got --extent BEHIND={behind!r}")
    try:
        return world.RasterConfig.from_extent(ahead, side, (ahead + behind) / args.size,
                                              metres_behind=behind, **fields)
    except ValueError as e:
        raise UsageError(f"--extent {ahead:g} {behind:g} {side:g}: {e}") from None


def cmd_collect(args: argparse.Namespace) -> int:
    """Expert demonstrations (IDM/MOBIL) in the chapter-7 dataset format."""
    _check_episode_args(args)
    cfg = _collect_raster(args)
    check_out_file(args.out)
    hw = _highway()
    if hw is None:
        return 2
    ds = hw.collect_demonstrations(args.scenarios, n_episodes=args.episodes, seed=args.seed,
                                   steps=args.steps, cfg=cfg, progress=not args.quiet)
    path = world.save(ds, args.out)
    skipped = sum(ds.meta["attempts"]) - len(ds)
    print(f"wrote {len(ds)} expert episodes of {ds.n_steps} steps to {path} "
          f"({skipped} seeds skipped: the expert collided)")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    """Behaviour cloning (``minimanc.train.fit``) on collected demonstrations."""
    for option in ("epochs", "batch_size"):
        if getattr(args, option) is not None:
            check_option(check_int, "--" + option.replace("_", "-"), getattr(args, option), 1)
    if args.lr is not None:
        check_option(check_positive, "--lr", args.lr)
    check_option(check_int, "--seed", args.seed, 0)
    check_choices(args.models, "--models", models.names(), what="model(s)")
    given = {"epochs": args.epochs, "batch_size": args.batch_size, "lr": args.lr}
    try:
        tc = train.TrainConfig(seed=args.seed, **{k: v for k, v in given.items() if v is not None})
    except ValueError as e:
        raise UsageError(str(e)) from e
    out = check_out_dir(args.out)
    if _highway() is None:
        return 2
    ds = load_data(args.data)
    for name in args.models:  # the input shape is the data's (train.fit fills it in)
        cfg = models.ModelConfig(setting=args.setting, k_targets=int(ds.lane_target.shape[2]))
        try:
            res = train.fit(name, ds, cfg, tc, engine=args.engine, checkpoint_dir=out / name,
                            resume=args.resume, progress=not args.quiet)
        except train.CheckpointError as e:
            raise UsageError(str(e)) from e
        except train.TrainingDiverged as e:
            print(f"minimanc highway train: {e}", file=sys.stderr)
            return 1
        print(f"{name}: {len(res.history)} epochs, final loss {res.history[-1]:.4f}, "
              f"checkpoint {out / name / train.CHECKPOINT_NAME}")
    return 0


def _policy(path: str, engine: str, option: str = "--checkpoints"
            ) -> tuple[Any, world.RasterConfig]:
    """The checkpoint's model as a policy and the raster its training data was drawn with."""
    try:
        fit = train.load_fit(path)
    except ValueError as e:  # missing (ValueError) or unreadable (CheckpointError)
        raise UsageError(f"{option} {e}") from e
    return rollout.ModelPolicy(fit, engine=engine), fit.raster


def cmd_eval(args: argparse.Namespace) -> int:
    """Closed-loop evaluation of checkpoints against the expert, per scenario."""
    _check_episode_args(args)
    if args.out:
        check_out_file(args.out)
    hw = _highway()
    if hw is None:
        return 2
    policies = []
    for path in args.checkpoints:
        pol, cfg = _policy(path, args.engine)
        policies.append((Path(path).parent.name or Path(path).stem, pol, cfg))
    report: dict[str, dict] = {}
    header = (f"{'scenario':<13} {'driver':<16} {'collision %':>11} {'off-road %':>10} "
              f"{'ADE m':>7} {'speed m/s':>9} {'episodes/s':>10}")
    print(header)
    for sc in args.scenarios:
        experts, tries = hw.expert_episodes(sc, args.episodes, seed=args.seed, steps=args.steps,
                                            record_bev=False)
        rows = {"expert": hw.expert_result(sc, experts).metrics}
        for label, pol, cfg in policies:
            rows[label] = hw.drive_episodes(pol, sc, experts, cfg=cfg).metrics
        report[sc] = {"expert_seeds_tried": tries, **rows}
        for label, m in rows.items():
            print(f"{sc:<13} {label:<16} {m['collision_rate']:>11.1f} {m['off_road_rate']:>10.1f} "
                  f"{m['ade']:>7.2f} {m['mean_speed']:>9.2f} {m['episodes_per_second']:>10.2f}")
    if args.out:
        Path(args.out).write_text(json.dumps(report, indent=2, sort_keys=True))
        print(f"wrote {args.out}")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    """One episode headless: highway-env frames as PNG, the episode and the BEV as GIF."""
    _check_episode_args(args)
    check_out_dir(args.out)
    hw = _highway()
    if hw is None:
        return 2
    if args.checkpoint:
        pol, cfg = _policy(args.checkpoint, args.engine, option="--checkpoint")
        experts, _ = hw.expert_episodes(args.scenario, 1, seed=args.seed, steps=args.steps,
                                        record_bev=False)
        goal = experts[0].poses[args.steps - 1]
        paths = hw.render_episode(args.scenario, experts[0].seed, args.out,
                                  hw.plain_policy(pol, goal, cfg), steps=args.steps, goal=goal,
                                  cfg=cfg)
    else:
        paths = hw.render_episode(args.scenario, args.seed, args.out, "expert", steps=args.steps)
    n = sum(1 for k in paths if k.startswith("frame_"))
    print(f"wrote {n} frames, {paths['episode'].name} and {paths['bev'].name} to {args.out}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``minimanc highway collect|train|eval|render`` to the ``minimanc`` parser."""
    hp = subparsers.add_parser("highway", help="chapter 10: the controller in highway-env")
    sub = hp.add_subparsers(dest="highway_command", required=True)

    c = sub.add_parser("collect", help="expert (IDM/MOBIL) demonstrations -> dataset file")
    c.add_argument("--scenarios", nargs="+", choices=SCENARIO_NAMES, default=list(SCENARIO_NAMES))
    c.add_argument("--episodes", type=int, default=20, help="episodes per scenario")
    c.add_argument("--seed", type=int, default=0, help="first env seed")
    c.add_argument("--steps", type=int, default=24, help="actions of 0.5 s per episode")
    c.add_argument("--raster", choices=world.ENCODINGS, default="rgb",
                   help="rgb: the course's image; channels: a learner's binary planes with "
                        "the route and the last 2 steps (default rgb)")
    c.add_argument("--size", type=int, default=64, help="BEV raster rows (pixels)")
    c.add_argument("--extent", type=float, nargs=3, default=None,
                   metavar=("AHEAD", "BEHIND", "SIDE"),
                   help="the view in metres (default the devkit's 40 10 25: square)")
    c.add_argument("--out", default="highway.npz")
    c.add_argument("--quiet", action="store_true", help="no progress bar")
    c.set_defaults(func=cmd_collect)

    t = sub.add_parser("train", help="behaviour cloning on collected demonstrations")
    t.add_argument("--data", required=True, help="file written by `minimanc highway collect`")
    t.add_argument("--models", nargs="+", default=["manc", "cnn"])
    t.add_argument("--setting", default="paper", choices=SETTINGS)
    t.add_argument("--epochs", type=int, default=None, help="default: train.TrainConfig's")
    t.add_argument("--batch-size", type=int, default=None, help="default: train.TrainConfig's")
    t.add_argument("--lr", type=float, default=None, help="default: train.TrainConfig's")
    t.add_argument("--seed", type=int, default=0)
    add_engine_option(t, "training")
    t.add_argument("--out", default="highway_runs")
    t.add_argument("--resume", action="store_true")
    t.add_argument("--quiet", action="store_true")
    t.set_defaults(func=cmd_train)

    e = sub.add_parser("eval", help="closed loop in highway-env vs the expert")
    e.add_argument("--checkpoints", nargs="*", default=[],
                   help="train checkpoints (highway- or world-trained: the transfer experiment)")
    e.add_argument("--scenarios", nargs="+", choices=SCENARIO_NAMES, default=list(SCENARIO_NAMES))
    e.add_argument("--episodes", type=int, default=10)
    e.add_argument("--seed", type=int, default=100_000, help="first env seed (evaluation)")
    e.add_argument("--steps", type=int, default=24)
    add_engine_option(e, "the closed loop")
    e.add_argument("--out", default=None, help="write the metrics as JSON")
    e.set_defaults(func=cmd_eval)

    r = sub.add_parser("render", help="an episode headless: PNG frames and GIFs")
    r.add_argument("--scenario", default="roundabout", choices=SCENARIO_NAMES)
    r.add_argument("--seed", type=int, default=100_000)
    r.add_argument("--steps", type=int, default=24)
    r.add_argument("--checkpoint", default=None, help="drive with this model (default: expert)")
    add_engine_option(r, "the closed loop")
    r.add_argument("--out", default="highway_frames")
    r.set_defaults(func=cmd_render)
