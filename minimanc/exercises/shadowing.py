"""Chapter 0 — library shadowing: the functions an exercise asks for raise while it is graded.
"""

from __future__ import annotations

import builtins
import importlib
import types
from collections.abc import Sequence
from typing import Any

__all__ = [
    "ForbiddenFunctionError",
    "Shadow",
    "resolve",
    "shadow",
]

# ------------------------------------------------------------------ library shadowing
class ForbiddenFunctionError(RuntimeError):
    """A library function an exercise asks the student to write was called while grading."""


def resolve(dotted: str) -> tuple[Any, str, Any]:
    """(owner module or object, attribute name, value) of ``pkg.module.attr``."""
    parts = dotted.split(".")
    for cut in range(len(parts) - 1, 0, -1):
        try:
            owner = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:-1]:
            owner = getattr(owner, name)
        return owner, parts[-1], getattr(owner, parts[-1])
    raise ImportError(f"cannot import {dotted!r}")


def _blocker_code(message: str, n_free: int) -> types.CodeType:
    """Code of ``lambda *a, **k: raise ForbiddenFunctionError(message)`` with
    ``n_free`` free variables, so it can replace the code of a closure too."""
    names = [f"_free{i}" for i in range(n_free)]
    assign = "".join(f"    {n} = None\n" for n in names)
    touch = "".join(f"        {n}\n" for n in names)
    text = (
        "def _outer():\n" + assign +
        "    def blocked(*args, **kwargs):\n" + touch +
        "        raise __import__('minimanc.exercises', fromlist=['x'])"
        f".ForbiddenFunctionError({message!r})\n"
        "    return blocked\n"
    )
    scope: dict = {}
    exec(compile(text, "<minimanc grading>", "exec"), scope)  # noqa: S102 - fixed template
    return scope["_outer"]().__code__


class Shadow:
    """Library functions disabled while an exercise's grade cells run; see :func:`shadow`."""

    def __init__(self) -> None:
        self._codes: list[tuple[types.FunctionType, types.CodeType]] = []
        self._attrs: list[tuple[Any, str, Any]] = []

    def restore(self) -> None:
        """Put every disabled function back (idempotent)."""
        for fn, code in reversed(self._codes):
            fn.__code__ = code
        for owner, name, value in reversed(self._attrs):
            if isinstance(owner, dict):
                owner[name] = value
            else:
                setattr(owner, name, value)
        self._codes, self._attrs = [], []


def shadow(targets: Sequence[str], exercise: str, namespace: dict | None = None) -> Shadow:
    """Make each library function in ``targets`` raise :class:`ForbiddenFunctionError`.

    A Python function has its code replaced, so every reference to it fails: the
    module attribute, a name bound earlier (``from minimanc.dmp import classify``,
    ``classify = dmp.classify``), a wrapper calling it, and copies of it found in
    ``namespace`` (the student's globals). Other callables are replaced in their
    module and wherever ``namespace`` binds them. Call ``restore()`` afterwards.
    Targets that cannot be imported are skipped.
    """
    guard = Shadow()
    namespace = namespace if namespace is not None else {}
    for dotted in targets:
        try:
            owner, attr, value = resolve(dotted)
        except (ImportError, AttributeError):
            continue
        message = (f"Exercise {exercise}: write {attr} yourself; {dotted} is disabled "
                   "while grading")
        if isinstance(value, types.FunctionType):
            original = value.__code__
            same = [value] + [
                v for v in namespace.values()
                if isinstance(v, types.FunctionType) and v is not value and v.__code__ is original
            ]
            for fn in same:
                guard._codes.append((fn, fn.__code__))
                fn.__code__ = _blocker_code(message, len(fn.__code__.co_freevars))
            continue
        blocker = types.FunctionType(_blocker_code(message, 0), {"__builtins__": builtins})
        guard._attrs.append((owner, attr, value))
        setattr(owner, attr, blocker)
        for name, bound in list(namespace.items()):
            if bound is value:
                guard._attrs.append((namespace, name, bound))
                namespace[name] = blocker
    return guard
