"""Chapter 8 — the CNN backbone every controller shares and the small layers its heads use.

:func:`backbone`: 3×3 convolutions, stride 2, zero padding 1, then the activation
(SiLU or ReLU), per layer; with the default channels ``(16, 32, 32)`` a 64×64 BEV (of any
number of planes: RGB or the binary channels) becomes 8×8×32 features (NHWC);
:func:`activate` is the configured activation. The heads' dense layers and flattening are
:func:`minimanc.layers.dense` and :func:`minimanc.layers.flatten`.
"""

from __future__ import annotations

from typing import Any

from minimanc import layers

__all__ = ["activate", "backbone"]


def backbone(params: dict, images: Any, cfg: Any, eng: Any) -> Any:
    """The shared CNN.

    Parameters
    ----------
    params : dict
        ``{"convs": [conv, ...]}`` from :func:`minimanc.models.init`.
    images : array, shape (B, H, W, C)
        BEV planes in [0, 1] (:func:`minimanc.world.encodings.to_input`), ``(H, W, C) =
        cfg.bev_shape``.
    cfg : ModelConfig
        Its ``activation`` is applied after each convolution.
    eng : Engine
        ``minimanc.engine("numpy" | "jax")``.

    Returns
    -------
    array, shape (B, h, w, C)
        ``(h, w) = cfg.feature_shape``, ``C = cfg.channels[-1]``.
    """
    act = eng.nn.silu if cfg.activation == "silu" else eng.nn.relu
    h = images
    for layer in params["convs"]:
        h = act(layers.conv(layer, h, eng.nn, stride=2, padding=1))
    return h


def activate(x: Any, cfg: Any, eng: Any) -> Any:
    """The configured activation.

    Parameters
    ----------
    x : array
    cfg : ModelConfig
        Its ``activation``: "silu" or "relu".
    eng : Engine

    Returns
    -------
    array
        Shaped like ``x``.
    """
    return eng.nn.silu(x) if cfg.activation == "silu" else eng.nn.relu(x)
