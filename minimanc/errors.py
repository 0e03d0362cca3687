"""Errors shared by the command line and the library (chapter 0).

:class:`UsageError` is what a command raises for input a user typed: the
``minimanc`` command prints its message as one line on stderr and exits with
code 2, never with a traceback.
"""

from __future__ import annotations

__all__ = ["UsageError", "EXIT_OK", "EXIT_FAILED", "EXIT_USAGE"]

EXIT_OK = 0
"""The command did what was asked."""
EXIT_FAILED = 1
"""The command ran but its result is a failure (e.g. a grade below ``--fail-under``)."""
EXIT_USAGE = 2
"""The command could not run: bad arguments, a missing or unreadable file."""


class UsageError(ValueError):
    """An argument or input file given on the command line is invalid."""
