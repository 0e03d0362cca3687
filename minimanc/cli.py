"""The ``minimanc`` command (chapter 0).

``minimanc info`` · ``minimanc exercises build|convert|run`` · ``minimanc grade NB``;
chapters add their own subcommands through a ``register(subparsers)`` function
(see ``PLUGINS``).
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from pathlib import Path

from minimanc import __version__
from minimanc.errors import EXIT_USAGE, UsageError

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
        except exercises.NotebookFormatError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        if args.check:
            if changed:
                print("exercises/ is out of date for: " + ", ".join(changed), file=sys.stderr)
                print("run: minimanc exercises build", file=sys.stderr)
                return 1
            print("exercises/ is in sync with solutions/")
            return 0
        names = (": " + ", ".join(changed)) if changed else ""
        print(f"wrote {len(changed)} exercise notebook(s){names}")
        return 0
    if args.action == "convert":
        if len(args.paths) != 2:
            print("usage: minimanc exercises convert SOURCE.py TARGET.ipynb", file=sys.stderr)
            return 2
        exercises.convert(Path(args.paths[0]), Path(args.paths[1]), execute=not args.no_execute)
        print(f"wrote {args.paths[1]}")
        return 0
    for path in args.paths:  # run
        exercises.run(Path(path), timeout=args.timeout)
        print(f"executed {path}")
    return 0


def cmd_grade(args: argparse.Namespace) -> int:
    from minimanc import exercises

    report = exercises.grade(
        Path(args.notebook), source=Path(args.source) if args.source else None, timeout=args.timeout
    )
    if args.json:
        print(json.dumps(report.to_dict(), indent=2))
    else:
        print(report.format())
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="minimanc", description="minimanc: the MANC course and library."
    )
    parser.add_argument("--version", action="version", version=f"minimanc {__version__}")
    sub = parser.add_subparsers(dest="command")

    info = sub.add_parser("info", help="version, chapters and optional pieces")
    info.set_defaults(func=cmd_info)

    ex = sub.add_parser("exercises", help="build exercises/ from solutions/, convert, run")
    ex.add_argument("action", choices=["build", "convert", "run"])
    ex.add_argument("paths", nargs="*", help="convert: SOURCE.py TARGET.ipynb; run: notebooks")
    ex.add_argument("--check", action="store_true", help="build: only check, exit 1 if stale")
    ex.add_argument("--no-execute", action="store_true", help="convert: do not execute")
    ex.add_argument("--timeout", type=int, default=600, help="run: seconds per cell")
    ex.set_defaults(func=cmd_exercises)

    gr = sub.add_parser("grade", help="run a notebook and print points per exercise")
    gr.add_argument("notebook")
    gr.add_argument("--json", action="store_true", help="machine-readable report")
    gr.add_argument("--source", help="solutions notebook with the authoritative grade cells")
    gr.add_argument("--timeout", type=int, default=120, help="seconds per cell")
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
