"""Chapter 9 — ``minimanc reproduce``: the paper's Table I, studies and figures
(:func:`minimanc.studies.reproduce`)."""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from minimanc.checks import check_int
from minimanc.cli.common import add_engine_option, check_option, check_out_dir
from minimanc.errors import UsageError
from minimanc.studies import PRESETS, raster_text, reproduce, table_markdown
from minimanc.studies.config import FORMS, form_of, with_form
from minimanc.studies.executors import EXECUTORS
from minimanc.studies.recorded import REACTIVE_REFUSAL, data_config, is_recorded
from minimanc.studies.reproduction import with_data_notes
from minimanc.world import DatasetFileError

__all__ = ["cmd_reproduce", "register"]


def cmd_reproduce(args: argparse.Namespace) -> int:
    """Run a preset's studies, print Table I and the findings, and list the files written."""
    import matplotlib  # matplotlib only when a figure is drawn

    matplotlib.use("Agg")
    preset = args.preset or ("quick" if args.quick else "full")
    config = PRESETS[preset]
    named = preset
    if args.form is not None and args.form != form_of(config):
        config = with_form(config, args.form)
        named = f"{preset}-{args.form}"
    form = form_of(config) or "custom"
    if args.seeds is not None:
        config = replace(config, n_seeds=check_option(check_int, "--seeds", args.seeds, 1))
    training = {field: check_option(check_int, option, value, 1) for field, value, option in (
        ("epochs", args.epochs, "--epochs"), ("dmp_seq_len", args.dmp_seq_len, "--dmp-seq-len"))
        if value is not None}
    if training:
        config = replace(config, training=replace(config.training, **training))
    if args.workers is not None:
        check_option(check_int, "--workers", args.workers, 0)
    if args.ray_address is not None and args.executor != "ray":
        raise UsageError(f"--ray-address is for --executor ray; got --executor {args.executor}")
    agents = ("replay", "reactive") if args.agents == "both" else (args.agents,)
    default_out = Path("minimanc_results") / named
    if args.data is not None:
        try:
            config = data_config(config, args.data)
        except (DatasetFileError, OSError, ValueError) as e:  # not readable, not fitting
            raise UsageError(f"--data {e}") from e
        default_out = Path("minimanc_results") / f"{named}-{Path(args.data).stem}"
        if is_recorded(config) and config.dagger_rounds > 0:
            raise UsageError(f"form {form} trains on-policy with the world's "
                             "expert, which recorded data (--data) has not: add --form paper")
        if is_recorded(config):
            if args.dagger:
                raise UsageError("--dagger needs the world's expert in states the log never "
                                 "visited; recorded data (--data) has none")
            if "reactive" in agents:
                print(f"minimanc reproduce: {REACTIVE_REFUSAL}; running agents replay only")
                agents = ("replay",)
    out = check_out_dir(Path(args.out) if args.out else default_out)
    progress = not args.no_progress
    t0 = time.perf_counter()
    print(f"minimanc reproduce: preset {preset}, form {form}, "
          f"engine {args.engine}, {config.n_seeds} "
          f"seed(s), agents {' and '.join(agents)}, output {out}")
    if config.data_file:
        print(f"data {config.data_file} ({config.data_source}): {config.n_train} training, "
              f"{config.n_tune} tuning, {config.n_val} validation scenes, "
              f"{raster_text(config.raster)}")
    log = (lambda msg: print(msg, flush=True)) if args.verbose else None
    results = reproduce(config, out, engine=args.engine, workers=args.workers,
                        command=getattr(args, "command_line", None),
                        executor=args.executor, ray_address=args.ray_address,
                        dagger=args.dagger,
                        progress=progress, log=log, agents=agents)
    dt = time.perf_counter() - t0
    md = with_data_notes(table_markdown(results), config)
    print(md.split("## Per scenario family")[0].split("## Sample efficiency")[0].rstrip())
    print()
    for f in results["findings"]:
        mark = {True: "holds", False: "does NOT hold", None: "n/a"}[f["holds"]]
        print(f"- {f['claim']}: {mark}")
    print(f"\nfinished in {dt / 60:.1f} min; wrote")
    print(f"  {results['files']['table1']}")
    print(f"  {results['files']['results']}")
    figs = results["files"].get("figures", [])
    if figs:
        print(f"  {len(figs)} figures in {Path(figs[0]).parent}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``minimanc reproduce`` to the ``minimanc`` parser."""
    p = subparsers.add_parser(
        "reproduce",
        help="train every model, run the closed loop, write Table I, the studies and figures",
        description="Reproduce the paper's Table I and studies (section V) on generated data, "
                    "or on a dataset file (--data, e.g. imported from nuScenes). "
                    "Cached under --out: a re-run is fast, an interrupted run resumes.",
    )
    p.add_argument("--quick", action="store_true",
                   help="small data, few epochs, one seed (minutes on 2 cores)")
    p.add_argument("--preset", choices=sorted(PRESETS), default=None,
                   help="a named configuration (overrides --quick)")
    p.add_argument("--form", choices=sorted(FORMS), default=None,
                   help="how the models learn: paper (RGB raster, behaviour cloning, eq. 7 "
                        "over pooled features) or learner (binary channels with the route and "
                        "the vehicles' history, DAgger with the world's expert, eq. 7 over "
                        "flattened features); default: the preset's")
    add_engine_option(p)
    p.add_argument("--data", default=None, metavar="FILE",
                   help="train and evaluate on this dataset file instead of generating data: "
                        "one imported by `minimanc data import-nuscenes` (its train/val "
                        "splits; the last 5 %% of train tune; replay protocol only, no bound "
                        "rows) or a generated one that fits the preset")
    p.add_argument("--out", default=None,
                   help="output directory (default minimanc_results/<preset>, "
                        "<preset>-<file name> with --data)")
    p.add_argument("--seeds", type=int, default=None, help="number of training seeds")
    p.add_argument("--epochs", type=int, default=None,
                   help="training epochs of every model (default: the preset's)")
    p.add_argument("--dmp-seq-len", type=int, default=None,
                   help="training window of the DMP models in steps (default: the preset's, "
                        "a whole scene)")
    p.add_argument("--agents", choices=("replay", "reactive", "both"), default="both",
                   help="the other vehicles in closed loop: replayed from the log (the paper's "
                        "protocol), reactive to the policy's ego, or Table I under both "
                        "(default)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes running the trainings and closed-loop evaluations "
                        "(default: one per CPU; 0 = everything in this process)")
    p.add_argument("--executor", choices=EXECUTORS, default="local",
                   help="where the trainings and evaluations run: this machine's process "
                        "pool, or Ray tasks (install minimanc[ray]; default local)")
    p.add_argument("--ray-address", default=None,
                   help="a Ray cluster to join (default: the RAY_ADDRESS environment "
                        "variable, else a local Ray with --workers CPUs)")
    p.add_argument("--dagger", action="store_true",
                   help="also behaviour cloning against DAgger at equal labels, MANC and the "
                        "CNN (chapter 11)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--verbose", action="store_true", help="one line per training")
    p.set_defaults(func=cmd_reproduce)
