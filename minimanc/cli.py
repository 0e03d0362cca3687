"""The ``minimanc`` command (chapter 0).

``minimanc info`` · ``minimanc exercises build|convert|run`` · ``minimanc grade NB``;
chapters add their own subcommands through a ``register(subparsers)`` function
(see ``PLUGINS``).
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import sys
from pathlib import Path

from minimanc import __version__
from minimanc.errors import EXIT_FAILED, EXIT_OK, EXIT_USAGE, UsageError

CHAPTERS = [
    ("00", "overview", "the stack, the chapter map, grading (00_warmup)"),
    ("01", "autodiff", "reverse-mode autodiff on NumPy — minimanc.autodiff"),
    ("02", "training", "layers, conv2d, Adam — minimanc.layers, minimanc.optim"),
    ("03", "dmp", "point-attractor DMP, damping ratio, stability — minimanc.dmp"),
    ("04", "quaternions", "quaternion log/exp and DMP — minimanc.quaternion"),
    ("05", "vagn", "the soft automaton — minimanc.vagn"),
    ("06", "cam", "visual predicates and CAM saliency — minimanc.cam"),
    ("07", "world", "nuScenes-style BEV world and data — minimanc.world"),
    ("08", "manc", "the assembled controller — minimanc.models"),
    ("09", "behavior_cloning", "training, closed loop, the paper's studies"),
    ("10", "highway_sandbox", "the controller in highway-env — minimanc.highway"),
]

# Modules that add subcommands; a missing one is skipped (its chapter is not built).
PLUGINS = ["minimanc.world.cli", "minimanc.studies", "minimanc.highway_cli"]

OPTIONAL = [
    ("numpy", "numpy"),
    ("jax", "jax"),
    ("matplotlib", "matplotlib"),
    ("notebook kernel", "ipykernel"),
    ("notebook runner", "nbclient"),
    ("highway-env", "highway_env"),
    ("nbval (tests)", "nbval"),
]


def project_root() -> Path:
    """The folder holding tutorials/, solutions/ and exercises/ (a source checkout)."""
    here = Path(__file__).resolve().parent.parent
    if (here / "solutions").is_dir():
        return here
    return Path.cwd()


def _version_of(module) -> str:
    return str(getattr(module, "__version__", "")) or "installed"


def cmd_info(args: argparse.Namespace) -> int:
    root = project_root()
    print(f"minimanc {__version__}")
    print("\nChapters (tutorials/ · solutions/ · exercises/):")
    for number, name, what in CHAPTERS:
        present = [
            folder[0].upper()
            for folder in ("tutorials", "solutions", "exercises")
            if list((root / folder).glob(f"{number}_*.ipynb"))
        ]
        mark = "".join(present) or "-"
        print(f"  {number} {name:<17} [{mark:<3}] {what}")
    print("  (T = tutorial, S = solutions, E = exercises present)")
    print("\nOptional pieces:")
    missing = 0
    for label, module_name in OPTIONAL:
        try:
            module = importlib.import_module(module_name)
            print(f"  ok      {label:<16} {_version_of(module)}")
        except Exception as exc:  # noqa: BLE001 - report any import failure
            missing += 1
            print(f"  MISSING {label:<16} ({type(exc).__name__}: {exc})")
    if missing:
        print(f"\n{missing} optional piece(s) missing: pip install -e '.[highway,test]'")
    return 0


def cmd_exercises(args: argparse.Namespace) -> int:
    from minimanc import exercises

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
    for path in args.notebooks:  # run
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
    from minimanc import exercises

    threshold = parse_fail_under(args.fail_under) if args.fail_under is not None else None
    if args.timeout <= 0:
        raise UsageError(f"--timeout must be a positive number of seconds, got {args.timeout}")
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="minimanc", description="minimanc: the MANC course and library."
    )
    parser.add_argument("--version", action="version", version=f"minimanc {__version__}")
    sub = parser.add_subparsers(dest="command")

    info = sub.add_parser("info", help="version, chapters and optional pieces")
    info.set_defaults(func=cmd_info)

    ex = sub.add_parser("exercises", help="build exercises/ from solutions/, convert, run")
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

    gr = sub.add_parser(
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

    for name in PLUGINS:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name and name.startswith(exc.name):
                continue  # that chapter's module is not part of this build
            raise
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except UsageError as exc:
        print(f"minimanc {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
