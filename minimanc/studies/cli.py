"""Chapter 9 — :func:`reproduce` (every study of a configuration, written to ``table1.md``,
``results.json`` and ``figures/``) and the ``minimanc reproduce`` command (:func:`register`,
found by :mod:`minimanc.cli`)."""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from minimanc.studies.config import PRESETS, StudyConfig
from minimanc.studies.figures import write_figures
from minimanc.studies.jobs import write_json
from minimanc.studies.report import json_safe, table_markdown
from minimanc.studies.runner import Study


def reproduce(config: StudyConfig, out: str | Path, engine: str = "jax", workers: int = 1,
              progress: bool = True, figures: bool = True,
              log: Callable[[str], None] | None = None) -> dict:
    """Run every study of ``config`` and write ``table1.md``, ``results.json`` and
    ``figures/`` under ``out``. Returns the results dict (also with ``"files"``)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    study = Study(config, out, engine=engine, workers=workers, progress=progress, log=log)
    try:
        results = study.run()
        files = {"table1": str(out / "table1.md"), "results": str(out / "results.json")}
        if figures:
            t0 = time.perf_counter()
            paths = write_figures(study, results, out / "figures")
            study.timing["figures"] = time.perf_counter() - t0
            results["timing_s"]["figures"] = round(study.timing["figures"], 1)
            files["figures"] = [str(p) for p in paths]
    finally:
        study.close()
    results["files"] = files
    (out / "table1.md").write_text(table_markdown(results))
    write_json(out / "results.json", json_safe(results))
    return results


def _cmd_reproduce(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    from minimanc.world.cli import check_int, check_out_dir

    preset = args.preset or ("quick" if args.quick else "full")
    config = PRESETS[preset]
    if args.seeds is not None:
        config = replace(config, n_seeds=check_int(args.seeds, "--seeds", 1))
    check_int(args.workers, "--workers", 0)
    out = check_out_dir(Path(args.out) if args.out else Path("minimanc_results") / preset)
    progress = not args.no_progress
    t0 = time.perf_counter()
    print(f"minimanc reproduce: preset {preset}, engine {args.engine}, {config.n_seeds} "
          f"seed(s), output {out}")
    log = (lambda msg: print(msg, flush=True)) if args.verbose else None
    results = reproduce(config, out, engine=args.engine, workers=args.workers,
                        progress=progress, log=log)
    dt = time.perf_counter() - t0
    print(table_markdown(results).split("## Sample efficiency")[0].rstrip())
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
    """Add ``minimanc reproduce`` to the ``minimanc`` command (called by :mod:`minimanc.cli`)."""
    p = subparsers.add_parser(
        "reproduce",
        help="train every model, run the closed loop, write Table I, the studies and figures",
        description="Reproduce the paper's Table I and studies (section V) on generated data. "
                    "Cached under --out: a re-run is fast, an interrupted run resumes.",
    )
    p.add_argument("--quick", action="store_true",
                   help="small data, few epochs, one seed (about 10 minutes on 2 cores)")
    p.add_argument("--preset", choices=sorted(PRESETS), default=None,
                   help="a named configuration (overrides --quick)")
    p.add_argument("--engine", choices=["jax", "numpy"], default="jax",
                   help="autodiff engine for training and the closed loop (default jax)")
    p.add_argument("--out", default=None,
                   help="output directory (default minimanc_results/<preset>)")
    p.add_argument("--seeds", type=int, default=None, help="number of training seeds")
    p.add_argument("--workers", type=int, default=1,
                   help="processes running closed-loop rollouts while training (0 = inline)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--verbose", action="store_true", help="one line per training")
    p.set_defaults(func=_cmd_reproduce)
