"""Chapter 0 — what every ``minimanc`` command shares: argument validators and the project root.

Each validator returns the checked value or raises :class:`~minimanc.errors.UsageError`
naming the option, which :func:`minimanc.cli.main` prints as one line on stderr with exit
code 2. They run before any work, so a bad argument never leaves a half-written output.
A number is checked by the library's own check (:mod:`minimanc.checks`) through
:func:`check_option`, which names the option (``--seeds``) and raises a UsageError; the
validators here are the command line's own (choices, output paths, the dataset file).
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from minimanc import world
from minimanc.engine import ENGINES
from minimanc.errors import UsageError

__all__ = [
    "DEFAULT_ENGINE",
    "add_engine_option",
    "check_choices",
    "check_option",
    "check_out_dir",
    "check_out_file",
    "load_data",
    "project_root",
]


T = TypeVar("T")

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


def check_option(check: Callable[..., T], option: str, value: Any, *args: Any) -> T:
    """``check(option, value, *args)`` on a command-line option, its error as a UsageError.

    ``check`` is a validator of :mod:`minimanc.checks` (``check_int``, ``check_positive``
    ...): the command line checks its numbers with the library's checks and changes only
    the kind of error, ``ValueError``/``TypeError`` → :class:`UsageError` with the same
    message, which names the option (``check_option(check_int, "--seed", args.seed, 0)``).
    Returns what ``check`` returns.
    """
    try:
        return check(option, value, *args)
    except (TypeError, ValueError) as exc:
        raise UsageError(str(exc)) from None


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
