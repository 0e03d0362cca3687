"""Chapter 8 — eq. 7's read-out: what the predicate layer reads of the backbone's features, and
the maps its logits split into (the CAMs of chapter 6).

Eq. 7 writes the predicates as ``p = Linear(GAP(f))`` over the features ``f`` ``(B, h, w, C)``
(then the sigmoid of :attr:`ModelConfig.predicate_activation`).
:attr:`ModelConfig.predicate_readout` chooses what the linear layer reads:

* ``"gap"`` — eq. 7 as the paper writes it: the global average ``GAP(f)`` ``(B, C)``. Each
  logit splits into a class activation map ``M_i(y, x) = Σ_c w_ci f_c(y, x)`` with
  ``mean_yx M_i = z_i − b_i`` (:func:`minimanc.cam.class_activation_maps`).
* ``"flatten"`` — ``flatten(f)`` ``(B, h·w·C)``: each predicate is a weighted sum over every
  position and channel, a weight map ``W_i(y, x, c)`` instead of one weight per channel, so
  the predicates keep *where* a feature fires. It is still linear in ``f``, so each logit
  still splits exactly over positions: ``M_i(y, x) = Σ_c W_i(y, x, c) f_c(y, x)`` with
  ``sum_yx M_i = z_i − b_i`` (a sum: the weights already carry the ``1/(h·w)`` of the mean).

:func:`readout_input` is the layer's input, :func:`predicate_logits` eq. 7's logits and
:func:`logit_maps` their maps. Every function takes the array namespace ``xp`` and uses only the
operations listed in CONTRIBUTING.md, so it runs on both engines.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc import cam, layers

__all__ = ["PREDICATE_READOUTS", "check_readout", "logit_maps", "predicate_logits",
           "readout_input"]

PREDICATE_READOUTS: tuple[str, ...] = ("gap", "flatten")
"""What eq. 7's predicate layer reads of the features (:attr:`ModelConfig.predicate_readout`):
their global average (the paper's form) or all of them."""


def check_readout(readout: str) -> str:
    """``readout`` if it is one of :data:`PREDICATE_READOUTS`.

    Parameters
    ----------
    readout : str

    Returns
    -------
    str
        ``readout``.

    Raises
    ------
    ValueError
        If it is not "gap" or "flatten".
    """
    if readout not in PREDICATE_READOUTS:
        raise ValueError(f"predicate_readout must be one of {PREDICATE_READOUTS}, got "
                         f"predicate_readout={readout!r}")
    return readout


def readout_input(features: Any, readout: str, xp: Any = np) -> Any:
    """What eq. 7's linear layer reads of the features.

    Parameters
    ----------
    features : array, shape (B, h, w, C)
        The backbone's features (:func:`minimanc.models.backbone`).
    readout : {"gap", "flatten"}
        :attr:`ModelConfig.predicate_readout`.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    array, shape (B, C) or (B, h·w·C)
        ``GAP(f)`` (the mean over the two spatial axes) or ``flatten(f)`` in the stored (row,
        column, channel) order.

    Raises
    ------
    ValueError
        If ``readout`` is unknown.
    """
    if check_readout(readout) == "gap":
        return xp.mean(xp.mean(features, axis=1), axis=1)  # GAP of eq. 7
    return layers.flatten(features, xp)


def predicate_logits(params: dict, features: Any, readout: str, xp: Any = np) -> Any:
    """Eq. 7's logits ``z = Linear(readout(f))``, before :attr:`ModelConfig.predicate_activation`.

    Parameters
    ----------
    params : dict
        The predicate layer (:func:`minimanc.models.zoo.predicate_layer`): ``w`` ``(C, M)``
        for "gap", ``(h·w·C, M)`` for "flatten"; ``b`` ``(M,)``.
    features : array, shape (B, h, w, C)
    readout : {"gap", "flatten"}
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    array, shape (B, M)

    Raises
    ------
    ValueError
        If ``readout`` is unknown.
    """
    return layers.dense(params, readout_input(features, readout, xp), xp)


def logit_maps(features: Any, weights: Any, readout: str, xp: Any = np) -> Any:
    """Each predicate's logit split over positions: the CAM of eq. 7 (chapter 6).

    "gap": ``M_i(y, x) = Σ_c w_ci f_c(y, x)`` and ``mean_yx M_i = z_i − b_i``
    (:func:`minimanc.cam.class_activation_maps`). "flatten": the weights as a map
    ``W (h, w, C, M)``, ``M_i(y, x) = Σ_c W[y, x, c, i] f_c(y, x)`` and ``sum_yx M_i = z_i − b_i``.

    Parameters
    ----------
    features : array, shape (..., h, w, C)
        The backbone's features.
    weights : array, shape (C, M) or (h·w·C, M)
        The predicate layer's ``w``.
    readout : {"gap", "flatten"}
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    array, shape (..., M, h, w)
        One map per predicate, channels-first.

    Raises
    ------
    ValueError
        If ``readout`` is unknown, or ``weights`` does not have the read-out's number of rows.
    """
    if check_readout(readout) == "gap":
        return cam.class_activation_maps(features, weights, xp=xp)
    fshape, wshape = tuple(features.shape), tuple(weights.shape)
    if len(fshape) < 3 or len(wshape) != 2 or wshape[0] != int(np.prod(fshape[-3:])):
        raise ValueError(f"the flatten read-out needs features (..., h, w, C) and weights "
                         f"(h·w·C, M); got features {fshape} and weights {wshape}")
    h, w, c = fshape[-3:]
    grid = xp.reshape(weights, (h, w, c, wshape[1]))
    maps = xp.sum(xp.expand_dims(features, -1) * grid, axis=-2)  # (..., h, w, M)
    nd = len(fshape)
    return xp.transpose(maps, tuple(range(nd - 3)) + (nd - 1, nd - 3, nd - 2))
