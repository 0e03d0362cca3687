"""Chapter 0 — running a student's function for a figure: :func:`attempt` returns its value,
or names its error, so that a stub or a bug shows in a panel's title and the notebook runs
to the end."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["attempt"]


def attempt(fn: Callable[..., Any], *args: Any) -> tuple[Any, str]:
    """``(fn(*args), "")``, or ``(None, "ErrorName: message")`` when ``fn`` raises.

    Parameters
    ----------
    fn : callable
        A student's function (or anything that may raise).
    *args
        Its arguments.

    Returns
    -------
    value, error : tuple
        The value (None on an error) and the error as one line ("" when none).
    """
    try:
        return fn(*args), ""
    except Exception as exc:  # noqa: BLE001 - the figure names any error of the student's
        text = " ".join(str(exc).split())
        return None, f"{type(exc).__name__}: {text[:80]}" if text else type(exc).__name__
