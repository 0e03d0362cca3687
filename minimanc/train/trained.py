"""Chapter 8 — a trained model, given whole or in parts: every function that runs a trained
model takes either its :class:`~minimanc.train.FitResult` (what :func:`~minimanc.train.fit`
and :func:`~minimanc.train.load_fit` return) or its parts, the model's ``name``, its
``params`` and its ``cfg`` (a researcher's own parameters). :func:`accepts_fit` gives a
function written with the parts the first form (``@accepts_fit()``), the same rule for all
of them (:func:`minimanc.rollout.closed_loop`, :func:`~minimanc.rollout.open_loop`,
:func:`~minimanc.rollout.replay`, :class:`~minimanc.rollout.ModelPolicy`,
:func:`minimanc.train.open_loop_loss`, :func:`minimanc.train.save_checkpoint`)::

    rollout.closed_loop(fit, ds, agents="reactive")             # the training result
    rollout.closed_loop("manc", params, ds, cfg, agents="reactive")   # its parts
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

from minimanc.train.config import FitResult

__all__ = ["CHECKPOINT_DEFAULTS", "FIT_PARTS", "STD_DEFAULT", "accepts_fit"]

FIT_PARTS: tuple[str, ...] = ("params", "cfg")
"""The parameters a :class:`FitResult` given as ``name`` fills (and which are then left out
of the call): its ``params`` and its ``cfg``."""

STD_DEFAULT: dict[str, Callable[[FitResult], Any]] = {"std": lambda fit: fit.control_std}
"""The loss normalisation a result was trained with, the default of a loss's ``std``."""

CHECKPOINT_DEFAULTS: dict[str, Callable[[FitResult], Any]] = {
    **STD_DEFAULT,
    "train_cfg": lambda fit: fit.train_cfg,
    "history": lambda fit: fit.history,
    "val_history": lambda fit: fit.val_history,
    "steps": lambda fit: fit.steps,
    "epoch": lambda fit: len(fit.history),
    "raster": lambda fit: fit.raster,
}
"""What a checkpoint records of a result besides its parts: its configuration, loss
histories, optimiser steps, normalisation, ``epoch`` (the number of epochs trained) and the
raster of its training data."""

F = TypeVar("F", bound=Callable[..., Any])


def accepts_fit(defaults: Mapping[str, Callable[[FitResult], Any]] | None = None
                ) -> Callable[[F], F]:
    """A decorator: the function ``fn``, which takes a trained model as its parts
    ``name, params, ..., cfg``, also called with the :class:`FitResult` that holds them in
    the place of ``name`` (``@accepts_fit()``).

    With a :class:`FitResult` first, the parameters of :data:`FIT_PARTS` are left out and
    come from the result, as does ``name``: the positional arguments after the result are
    those that stood between ``name`` and ``cfg`` (the data: ``closed_loop(fit, ds)``,
    ``replay(fit, ds, scene)``), every parameter after ``cfg`` is given by keyword
    (``closed_loop(fit, ds, engine="numpy")``), so that a call that gives the parts again
    is refused. The parameters named in ``defaults`` that the call does not give come from
    the result too (:data:`STD_DEFAULT`, :data:`CHECKPOINT_DEFAULTS`). With a name first,
    ``fn`` is called as written.

    Parameters
    ----------
    defaults : mapping of str to callable, optional
        ``{parameter: result -> value}``: the defaults a result gives ``fn``'s parameters.

    Returns
    -------
    callable
        The decorator: ``fn`` (a function, or an ``__init__``, with the parameters ``name``,
        ``params`` and ``cfg``) taking either form, with ``fn``'s signature and docstring.

    Raises
    ------
    TypeError
        When ``fn`` lacks ``name``, ``params``, ``cfg`` or a parameter of ``defaults`` (at
        decoration), or a call gives a :class:`FitResult` together with ``params`` or
        ``cfg``.
    """
    def decorate(fn: F) -> F:
        sig = inspect.signature(fn)
        names = list(sig.parameters)
        missing = [p for p in ("name", *FIT_PARTS, *(defaults or {})) if p not in names]
        if missing:
            raise TypeError(f"accepts_fit needs a function with the parameters name, params, "
                            f"cfg and those of its defaults; {fn.__qualname__} lacks {missing}")
        slot = names.index("name")
        after = names.index("cfg")
        given_fit = sig.replace(parameters=[
            p.replace(kind=inspect.Parameter.KEYWORD_ONLY) if k > after else p
            for k, (n, p) in enumerate(sig.parameters.items()) if n not in FIT_PARTS])
        given = dict(defaults or {})

        @functools.wraps(fn)
        def call(*args: Any, **kwargs: Any) -> Any:
            first = args[slot] if len(args) > slot else kwargs.get("name")
            if not isinstance(first, FitResult):
                return fn(*args, **kwargs)
            try:
                bound = given_fit.bind(*args, **kwargs)
            except TypeError as exc:
                raise TypeError(f"{fn.__qualname__}: given a FitResult, leave out "
                                f"{' and '.join(FIT_PARTS)} (they are the result's) and give the "
                                f"options after them by keyword ({exc})") from None
            arguments = dict(bound.arguments)
            arguments.update(name=first.name, params=first.params, cfg=first.cfg)
            for n, get in given.items():
                if n not in arguments:
                    arguments[n] = get(first)
            return fn(**arguments)

        return call  # type: ignore[return-value]

    return decorate
