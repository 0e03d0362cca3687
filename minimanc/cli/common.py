"""Chapter 0 — what every ``minimanc`` command shares: argument validators and the project root.

Each validator returns the checked value or raises :class:`~minimanc.errors.UsageError`
naming the option, which :func:`minimanc.cli.main` prints as one line on stderr with exit
code 2. They run before any work, so a bad argument never leaves a half-written output.
The library's own checks (a ``ValueError``/``TypeError`` naming a Python parameter) are in
:mod:`minimanc.checks`; these speak in the command line's terms (``--seeds``, ``--out``).
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

from minimanc import world
from minimanc.engine import ENGINES
from minimanc.errors import UsageError

__all__ = [
    "DEFAULT_ENGINE",
    "add_engine_option",
    "check_choices",
    "check_int",
    "check_out_dir",
    "check_out_file",
    "check_positive",
    "load_data",
    "project_root",
]


DEFAULT_ENGINE = "jax"
"""The engine the commands train and roll out with unless ``--engine`` says otherwise."""


def add_engine_option(parser: Any, what: str = "training and the closed loop") -> None:
    """Add ``--engine`` with the choices :data:`minimanc.engine.ENGINES`."""
    parser.add_argument("--engine", choices=ENGINES, default=DEFAULT_ENGINE,
                        help=f"autodiff engine for {what} (default {DEFAULT_ENGINE})")


def project_root() -> Path:
    """The folder holding tutorials/, solutions/ and exercises/ (a source checkout)."""
    here = Path(__file__).resolve().parent.parent.parent
    if (here / "solutions").is_dir():
        return here
    return Path.cwd()


def check_int(value: Any, option: str, minimum: int) -> int:
    """``value`` if it is an integer ``>= minimum``, else :class:`UsageError` naming ``option``."""
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise UsageError(f"{option} must be an integer >= {minimum}, got {value!r}")
    return value


def check_positive(value: Any, option: str) -> float:
    """``value`` if it is a finite number ``> 0``, else :class:`UsageError` naming ``option``."""
    ok = (not isinstance(value, bool) and isinstance(value, int | float)
          and math.isfinite(value) and value > 0)
    if not ok:
        raise UsageError(f"{option} must be a positive finite number, got {value!r}")
    return value


def check_choices(values: list[str], option: str, choices: tuple[str, ...],
                  what: str = "value(s)") -> list[str]:
    """``values`` if each is one of ``choices``, else :class:`UsageError` listing the unknown.

    For ``nargs="+"`` options whose choices need a library import (argparse's own
    ``choices`` would print the usage and a long list instead of one line)."""
    unknown = [v for v in values if v not in choices]
    if unknown:
        raise UsageError(f"{option}: unknown {what} {', '.join(unknown)}; choose from "
                         f"{', '.join(choices)}")
    return values


def check_out_dir(path: str | Path, option: str = "--out") -> Path:
    """Create the directory ``path`` if needed and check that a file can be written in it."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UsageError(f"{option} {out}: exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UsageError(f"{option} {out}: cannot create the directory ({e.strerror or e})") from e
    try:
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as e:
        raise UsageError(f"{option} {out}: directory is not writable ({e.strerror or e})") from e
    return out


def check_out_file(path: str | Path, option: str = "--out") -> Path:
    """Check that the file ``path`` can be written (its directory is created if needed)."""
    target = Path(path)
    if target.is_dir():
        raise UsageError(f"{option} {target}: is a directory, expected a file name")
    check_out_dir(target.parent, option=f"{option} {target}: its directory")
    return target


def load_data(path: str | Path, option: str = "--data") -> Any:
    """``world.load(path)``; a missing or unusable file is a :class:`UsageError`."""
    try:
        return world.load(path)
    except FileNotFoundError as e:
        raise UsageError(f"{option} {path}: no such file") from e
    except (world.DatasetFileError, OSError) as e:
        raise UsageError(f"{option} {e}") from e
