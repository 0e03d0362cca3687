"""Chapter 8 — the CNN backbone every controller shares and the small layers its heads use.

:func:`backbone`: 3×3 convolutions, stride 2, zero padding 1, then the activation
(SiLU or ReLU), per layer; with the default channels ``(16, 32, 32)`` a 64×64 BEV
becomes 8×8×32 features (NHWC).
"""

from __future__ import annotations

from typing import Any

from minimanc import layers

__all__ = ["activate", "backbone", "dense", "flatten"]


def backbone(params: dict, images: Any, cfg: Any, eng: Any) -> Any:
    """The shared CNN.

    Parameters
    ----------
    params : dict
        ``{"convs": [conv, ...]}`` from :func:`minimanc.models.init`.
    images : array, shape (B, H, W, 3)
        BEV rasters in [0, 1].
    cfg : ModelConfig
        Its ``activation`` is applied after each convolution.
    eng : Engine
        ``minimanc.engine("numpy" | "jax")``.

    Returns
    -------
    array, shape (B, h, w, C)
        ``h = w = cfg.feature_size``, ``C = cfg.channels[-1]``.
    """
    act = eng.nn.silu if cfg.activation == "silu" else eng.nn.relu
    h = images
    for layer in params["convs"]:
        h = act(layers.conv2d(layer, h, eng.nn, stride=2, padding=1))
    return h


def dense(p: dict, x: Any, eng: Any) -> Any:
    """A dense layer on ``eng``'s namespace.

    Parameters
    ----------
    p : dict
        ``w`` ``(n_in, n_out)``, ``b`` ``(n_out,)``.
    x : array, shape (B, n_in)
    eng : Engine

    Returns
    -------
    array, shape (B, n_out)
        ``x @ w + b``.
    """
    return layers.dense(p, x, xp=eng.xp)


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


def flatten(f: Any, xp: Any) -> Any:
    """Flatten all but the batch axis.

    Parameters
    ----------
    f : array, shape (B, ...)
    xp : module
        The engine's array namespace.

    Returns
    -------
    array, shape (B, F)
    """
    return xp.reshape(f, (f.shape[0], -1))
