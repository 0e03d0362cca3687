"""Chapter 0 — the ``minimanc`` command: one module per command group.

* :mod:`~minimanc.cli.info` — ``minimanc info`` (the chapter map of :mod:`minimanc.chapters`
  and the pieces the README uses);
* :mod:`~minimanc.cli.exercises` — ``minimanc exercises build|convert|run`` and ``grade``;
* :mod:`~minimanc.cli.data` — ``minimanc data generate|show`` (chapter 7);
* :mod:`~minimanc.cli.reproduce` — ``minimanc reproduce`` (chapter 9);
* :mod:`~minimanc.cli.highway` — ``minimanc highway collect|train|eval|render`` (chapter 10);
* :mod:`~minimanc.cli.dagger` — ``minimanc dagger`` (chapter 11);
* :mod:`~minimanc.cli.results` — ``minimanc results check|update`` (the README's quoted
  results, chapter 9);
* :mod:`~minimanc.cli.common` — the argument validators and the project root they share.

Each module has ``register(subparsers)``; choices come from the library's registries
(:data:`minimanc.engine.ENGINES`, :data:`minimanc.inputs.SETTINGS`,
:func:`minimanc.models.names`), never retyped. A command raises
:class:`~minimanc.errors.UsageError` for bad input, which :func:`main` prints as one line
on stderr with exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys

from minimanc import __version__
from minimanc.errors import EXIT_USAGE, UsageError

__all__ = ["CORE", "PLUGINS", "build_parser", "main"]

CORE = ("minimanc.cli.info", "minimanc.cli.exercises")
"""Command modules of chapter 0, always registered."""

PLUGINS = {
    "minimanc.cli.data": "minimanc.world",
    "minimanc.cli.reproduce": "minimanc.studies",
    "minimanc.cli.highway": "minimanc.highway",
    "minimanc.cli.results": "minimanc.studies.provenance",
    "minimanc.cli.dagger": "minimanc.dagger",
}
"""Command module -> the chapter package it drives. A command is registered only when its
chapter's package is part of this build (found without importing it, so a missing optional
dependency such as highway-env is reported when the command runs, not here)."""


def _chapter_present(package: str) -> bool:
    try:
        return importlib.util.find_spec(package) is not None
    except ModuleNotFoundError:  # a parent package is missing
        return False


def build_parser() -> argparse.ArgumentParser:
    """The ``minimanc`` parser with every available command group registered."""
    parser = argparse.ArgumentParser(
        prog="minimanc", description="minimanc: the MANC course and library."
    )
    parser.add_argument("--version", action="version", version=f"minimanc {__version__}")
    sub = parser.add_subparsers(dest="command")
    chapters = [name for name, package in PLUGINS.items() if _chapter_present(package)]
    for name in (*CORE, *chapters):
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``minimanc argv``; returns the exit code (2 for a :class:`UsageError`)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.command_line = ["minimanc", *(sys.argv[1:] if argv is None else argv)]
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except UsageError as exc:
        print(f"minimanc {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:  # `minimanc info | head`: the reader left, nothing to report
        sys.stdout = open(os.devnull, "w")  # no flush error at exit
        return 0


if __name__ == "__main__":
    sys.exit(main())
