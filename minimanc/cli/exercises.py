"""Chapter 0 — ``minimanc exercises build|convert|run`` and ``minimanc grade NB``.

``exercises build`` regenerates ``exercises/`` from ``solutions/`` (``--check`` only
compares), ``convert`` turns a percent-format source into an executed notebook, ``run``
executes notebooks in place, and ``grade`` runs a notebook against the tests of its
solutions notebook (:mod:`minimanc.exercises`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from minimanc.checks import check_int
from minimanc.cli.common import check_option, project_root
from minimanc.errors import EXIT_FAILED, EXIT_OK, UsageError

__all__ = ["cmd_exercises", "cmd_grade", "parse_fail_under", "register"]


def _exercises() -> Any:
    """:mod:`minimanc.exercises`, imported when an exercises command runs: every other
    ``minimanc`` command starts without loading nbformat."""
    from minimanc import exercises  # deferred: nbformat/jsonschema take ~2 s to import

    return exercises


def cmd_exercises(args: argparse.Namespace) -> int:
    """``exercises build|convert|run``: exit 0 done, 1 ``build --check`` found stale files."""
    exercises = _exercises()
    root = project_root()
    if args.action == "build":
        try:
            changed = exercises.build(root / "solutions", root / "exercises", check=args.check)
        except (exercises.NotebookFormatError, FileNotFoundError) as exc:
            raise UsageError(str(exc)) from None
        if args.check:
            if changed:
                print("exercises/ is out of date for: " + ", ".join(changed), file=sys.stderr)
                print("run: minimanc exercises build", file=sys.stderr)
                return EXIT_FAILED
            print("exercises/ is in sync with solutions/")
            return EXIT_OK
        names = (": " + ", ".join(changed)) if changed else ""
        print(f"wrote {len(changed)} exercise notebook(s){names}")
        return EXIT_OK
    if args.action == "convert":
        source, target = Path(args.source), Path(args.target)
        if not source.is_file():
            raise UsageError(f"no percent-format source at {source}")
        try:
            exercises.convert(source, target, execute=not args.no_execute)
        except exercises.NotebookFormatError as exc:
            raise UsageError(str(exc)) from None
        print(f"wrote {target}")
        return EXIT_OK
    check_option(check_int, "--timeout", args.timeout, 1)  # run
    for path in args.notebooks:
        if not Path(path).is_file():
            raise UsageError(f"no notebook at {path}")
    for path in args.notebooks:
        exercises.run(Path(path), timeout=args.timeout)
        print(f"executed {path}")
    return EXIT_OK


def parse_fail_under(text: str) -> tuple[float, bool]:
    """``--fail-under`` as (threshold, is_percent): ``7`` points or ``70%`` of the maximum."""
    raw = text.strip()
    percent = raw.endswith("%")
    try:
        value = float(raw[:-1] if percent else raw)
    except ValueError:
        raise UsageError(
            f"--fail-under must be points (e.g. 7) or a percentage (e.g. 70%), got {text!r}"
        ) from None
    if not math.isfinite(value) or value < 0 or (percent and value > 100):
        raise UsageError(f"--fail-under must be between 0 and the maximum, got {text!r}")
    return value, percent


def cmd_grade(args: argparse.Namespace) -> int:
    """Exit codes: 0 graded, 1 graded below ``--fail-under``, 2 could not grade."""
    exercises = _exercises()
    threshold = parse_fail_under(args.fail_under) if args.fail_under is not None else None
    check_option(check_int, "--timeout", args.timeout, 1)
    root = project_root()
    report = exercises.grade(
        Path(args.notebook),
        source=Path(args.source) if args.source else None,
        timeout=args.timeout,
        roots=[root] if (root / "solutions").is_dir() else [],
    )
    if args.json:
        print(json.dumps(report.to_dict(), indent=2))
    else:
        print(report.format())
    if threshold is not None:
        value, percent = threshold
        needed = value / 100.0 * report.max_total if percent else value
        if report.total < needed:
            print(f"minimanc grade: {report.total:g}/{report.max_total:g} is below "
                  f"--fail-under {args.fail_under}", file=sys.stderr)
            return EXIT_FAILED
    return EXIT_OK


def register(subparsers: Any) -> None:
    """Add ``minimanc exercises build|convert|run`` and ``minimanc grade`` to the parser."""
    ex = subparsers.add_parser("exercises", help="build exercises/ from solutions/, convert, run")
    actions = ex.add_subparsers(dest="action", metavar="{build,convert,run}", title="actions")
    actions.required = True
    build = actions.add_parser("build", help="regenerate exercises/ from solutions/")
    build.add_argument("--check", action="store_true", help="only check, exit 1 if stale")
    convert = actions.add_parser("convert", help="percent-format script -> executed notebook")
    convert.add_argument("source", help="SOURCE.py in percent format")
    convert.add_argument("target", help="TARGET.ipynb")
    convert.add_argument("--no-execute", action="store_true", help="do not execute")
    run = actions.add_parser("run", help="execute notebooks in place")
    run.add_argument("notebooks", nargs="+", help="notebooks to execute")
    run.add_argument("--timeout", type=int, default=600, help="seconds per cell")
    ex.set_defaults(func=cmd_exercises)

    gr = subparsers.add_parser(
        "grade", help="run a notebook and print points per exercise",
        description="Grade a notebook against the tests of its solutions notebook. "
        "Exit codes: 0 graded, 1 graded below --fail-under, 2 could not grade.",
    )
    gr.add_argument("notebook")
    gr.add_argument("--json", action="store_true", help="machine-readable report")
    gr.add_argument("--source", help="solutions notebook with the authoritative grade cells "
                    "(default: solutions/<assignment>.ipynb from the notebook's metadata)")
    gr.add_argument("--timeout", type=int, default=120, help="seconds per cell")
    gr.add_argument("--fail-under", metavar="POINTS", help="exit 1 when the total is below "
                    "POINTS (or a percentage of the maximum, e.g. 70%%)")
    gr.set_defaults(func=cmd_grade)
