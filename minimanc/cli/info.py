"""Chapter 0 — ``minimanc info``: the version, the chapter map and the pieces the README uses.

The chapter map is :data:`minimanc.chapters.CHAPTERS`. The pieces are what the README tells a
student to install and run: the core dependencies, JupyterLab (``jupyter lab``, the ``lab``
extra), the test tools (``pytest`` with nbval, the ``test`` extra), highway-env (chapter 10,
the ``highway`` extra) and Ray (``minimanc reproduce --executor ray``, the ``ray`` extra).
Each missing piece is reported with the ``pip install`` line that installs it.
"""

from __future__ import annotations

import argparse
import importlib
import shutil
from dataclasses import dataclass
from typing import Any

from minimanc import __version__
from minimanc.chapters import CHAPTERS, markdown_table
from minimanc.cli.common import project_root
from minimanc.errors import EXIT_OK

__all__ = ["COMMANDS", "PIECES", "Piece", "cmd_info", "install_line", "register"]


@dataclass(frozen=True)
class Piece:
    """A package the README relies on: its label, import name and the extra installing it."""

    label: str
    module: str
    extra: str | None
    """The ``pyproject.toml`` extra that installs it; ``None`` for a core dependency."""


PIECES: tuple[Piece, ...] = (
    Piece("numpy", "numpy", None),
    Piece("jax", "jax", None),
    Piece("matplotlib", "matplotlib", None),
    Piece("pillow", "PIL", None),
    Piece("tqdm", "tqdm", None),
    Piece("notebook format", "nbformat", None),
    Piece("notebook runner", "nbclient", None),
    Piece("notebook kernel", "ipykernel", None),
    Piece("JupyterLab", "jupyterlab", "lab"),
    Piece("pytest", "pytest", "test"),
    Piece("pytest-xdist", "xdist", "test"),
    Piece("nbval", "nbval", "test"),
    Piece("hypothesis", "hypothesis", "test"),
    Piece("highway-env", "highway_env", "highway"),
    Piece("gymnasium", "gymnasium", "highway"),
    Piece("ray", "ray", "ray"),
)
"""Every piece ``minimanc info`` checks, in the order it prints them."""

COMMANDS: tuple[tuple[str, str], ...] = (
    ("jupyter", "python -m jupyterlab"),
    ("minimanc", "python -m minimanc"),
    ("pytest", "python -m pytest"),
)
"""(command, the same run through the interpreter) of each command the README runs."""


def install_line(extras: set[str | None]) -> str:
    """The ``pip install`` line (from a clone) that installs the pieces of ``extras``.

    Parameters
    ----------
    extras : set of str or None
        The extras to install; ``None`` stands for the core dependencies.

    Returns
    -------
    str
        ``pip install -e .`` for the core alone, else ``pip install -e '.[a,b]'``.
    """
    named = sorted(extra for extra in extras if extra is not None)
    return f"pip install -e '.[{','.join(named)}]'" if named else "pip install -e ."


def _version_of(module: Any) -> str:
    return str(getattr(module, "__version__", "")) or "installed"


def _hint(piece: Piece) -> str:
    return install_line({piece.extra})


def cmd_info(args: argparse.Namespace) -> int:
    """Print the version, the chapter map with the notebooks present, and the pieces."""
    if args.readme_table:
        print(markdown_table(), end="")
        return EXIT_OK
    root = project_root()
    print(f"minimanc {__version__}")
    print("\nChapters (tutorials/ · solutions/ · exercises/):")
    for chapter in CHAPTERS:
        present = [
            folder[0].upper()
            for folder in ("tutorials", "solutions", "exercises")
            if (root / folder / f"{chapter.notebook}.ipynb").is_file()
        ]
        mark = "".join(present) or "-"
        modules = ", ".join(chapter.shown)
        print(f"  {chapter.code} {chapter.name:<17} [{mark:<3}] {chapter.title} — {modules}")
        print(f"  {'':<26} exercises: {chapter.exercises}")
    print("  (T = tutorial, S = solutions, E = exercises present)")
    print("\nPieces the README uses:")
    missing: set[str | None] = set()
    for piece in PIECES:
        try:
            module = importlib.import_module(piece.module)
            print(f"  ok      {piece.label:<16} {_version_of(module)}")
        except Exception as exc:  # noqa: BLE001 - report any import failure
            missing.add(piece.extra)
            print(f"  MISSING {piece.label:<16} ({type(exc).__name__}: {exc}); "
                  f"install: {_hint(piece)}")
    print("\nCommands the README runs:")
    for command, fallback in COMMANDS:
        where = shutil.which(command)
        if where:
            print(f"  ok      {command}")
        else:
            print(f"  absent  {command:<16} not on PATH: activate the environment "
                  f"(source .venv/bin/activate) or run `{fallback}`")
    if missing:
        print(f"\nSome pieces are missing; to install them: {install_line(missing)}")
    return EXIT_OK


def register(subparsers: Any) -> None:
    """Add ``minimanc info`` to the ``minimanc`` parser."""
    info = subparsers.add_parser("info", help="version, chapters and the pieces the README uses")
    info.add_argument("--readme-table", action="store_true",
                      help="print the README's '## Chapters' table from minimanc.chapters")
    info.set_defaults(func=cmd_info)
