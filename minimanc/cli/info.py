"""Chapter 0 — ``minimanc info``: the version, the chapter map and the optional pieces."""

from __future__ import annotations

import argparse
import importlib
from typing import Any

from minimanc import __version__
from minimanc.cli.common import project_root
from minimanc.errors import EXIT_OK

__all__ = ["CHAPTERS", "OPTIONAL", "cmd_info", "register"]

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
    ("11", "dagger", "behaviour cloning's drift and DAgger — minimanc.dagger"),
]
"""(number, name, what it builds) of every chapter, in order."""

OPTIONAL = [
    ("numpy", "numpy"),
    ("jax", "jax"),
    ("matplotlib", "matplotlib"),
    ("notebook kernel", "ipykernel"),
    ("notebook runner", "nbclient"),
    ("highway-env", "highway_env"),
    ("nbval (tests)", "nbval"),
]
"""(label, module) of the pieces ``minimanc info`` reports as present or missing."""


def _version_of(module: Any) -> str:
    return str(getattr(module, "__version__", "")) or "installed"


def cmd_info(args: argparse.Namespace) -> int:
    """Print the version, which chapters' notebooks are present, and the optional pieces."""
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
    return EXIT_OK


def register(subparsers: Any) -> None:
    """Add ``minimanc info`` to the ``minimanc`` parser."""
    info = subparsers.add_parser("info", help="version, chapters and optional pieces")
    info.set_defaults(func=cmd_info)
