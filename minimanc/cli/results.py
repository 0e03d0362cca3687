"""Chapter 9 — ``minimanc results check|update [README.md]``: the README's quoted results
(:mod:`minimanc.studies.provenance`) against the files that measured them."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from minimanc.errors import EXIT_OK, UsageError
from minimanc.studies import provenance

__all__ = ["cmd_results", "register"]

EXIT_DIFFERS = 1
"""``check`` found a quote that differs from its file, or a typed number."""


def cmd_results(args: argparse.Namespace) -> int:
    """Check (or update, then check) the quotes of ``args.readme``; one line per problem."""
    try:
        if args.results_command == "update":
            changed = provenance.update_readme(args.readme)
            print(f"{args.readme}: {'updated' if changed else 'already up to date'}")
        problems = provenance.check_readme(args.readme)
    except (OSError, KeyError, ValueError) as exc:
        raise UsageError(f"{args.readme}: {exc}") from exc
    for p in problems:
        print(f"{args.readme}: {p}", file=sys.stderr)
    if not problems and args.results_command == "check":
        print(f"{args.readme}: every quoted result matches its file")
    return EXIT_DIFFERS if problems else EXIT_OK


def register(subparsers: Any) -> None:
    """Add ``results check`` and ``results update`` to an argparse sub-parser collection."""
    p = subparsers.add_parser("results", help="check the README's quoted results against "
                                              "the files that measured them")
    sub = p.add_subparsers(dest="results_command", required=True)
    for name, what in (("check", "exit 1 when a quote differs from its file or a number "
                                 "is typed outside a quote"),
                       ("update", "rewrite every quote from its file, then check")):
        c = sub.add_parser(name, help=what)
        c.add_argument("readme", nargs="?", default="README.md", help="default ./README.md")
        c.set_defaults(func=cmd_results)
