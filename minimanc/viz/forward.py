"""The figure names of the math modules (chapters 5, 6 and 9), forwarded to :mod:`minimanc.viz`.

``vagn.plot_automaton``, ``cam.blend``, ``plots.plot_explain_trace``, ... keep working: the
module that used to define a figure gets a module-level ``__getattr__`` (PEP 562) that imports
the :mod:`minimanc.viz` module holding it on first access, and a ``__dir__`` that lists it.
The math module itself never imports a plotting library.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["forwarder"]


def forwarder(
    module: str, namespace: Mapping[str, Any], targets: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``module``, forwarding ``targets`` lazily.

    Parameters
    ----------
    module : str
        Name of the forwarding module (its ``__name__``), used in error messages.
    namespace : mapping
        The forwarding module's ``globals()``: what ``__dir__`` lists beside the targets.
    targets : mapping of str to str
        ``{attribute: module that defines it}``, e.g.
        ``{"blend": "minimanc.viz.saliency"}``.  The value is read from that module on
        every access (not cached), so a value it computes when asked stays current.

    Returns
    -------
    getattr_ : callable
        The module's ``__getattr__``: raises ``AttributeError`` for a name not in
        ``targets``.
    dir_ : callable
        The module's ``__dir__``.

    Raises
    ------
    AttributeError
        From ``getattr_``, for a name that is not in ``targets``.
    """
    targets = dict(targets)

    def __getattr__(name: str) -> Any:
        where = targets.get(name)
        if where is None:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        return getattr(importlib.import_module(where), name)

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(targets))

    return __getattr__, __dir__
