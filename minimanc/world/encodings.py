"""Chapter 7 — reading a stored raster: its planes, what a learner reads, a picture for people.

The rasteriser (:mod:`minimanc.world.raster`) stores a frame in its encoding's form: the RGB
image, or the binary planes of the ``"channels"`` encoding packed 8 to a byte
(:func:`minimanc.world.raster.pack`). Whatever reads a dataset's ``bev`` or a closed loop's
raster goes through this module: :func:`planes` unpacks, :func:`to_input` gives the float
planes a model reads (the one place that knows RGB is divided by 255 and channels are 0/1),
:func:`unpack` gives the same planes from the packed bytes, a JAX array's too (a training
step unpacks its batch inside the compiled function: the batch crosses to it at an eighth
of a byte per plane and pixel instead of four bytes), :func:`to_rgb` paints channels in the
devkit's colours (as l5kit's ``to_rgb`` and Roach's display image: the faded picture is for
people, the planes for the learner).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.world.history import fade
from minimanc.world.raster import (
    DRIVABLE,
    EGO,
    OPPOSITE_LANE,
    PED_CROSSING,
    ROUTE,
    SAME_LANE,
    VEHICLE,
    WALKWAY,
    RasterConfig,
)

__all__ = ["planes", "to_input", "to_rgb", "unpack"]


def _check_stored(bev: np.ndarray, cfg: RasterConfig) -> np.ndarray:
    b = np.asarray(bev)
    if b.dtype != np.uint8 or b.ndim < 3 or tuple(b.shape[-3:]) != cfg.shape:
        raise ValueError(f"bev must be uint8 (..., {', '.join(map(str, cfg.shape))}) as this "
                         f"raster stores it ({cfg.encoding}); got {b.dtype} {b.shape}")
    return b


def planes(bev: np.ndarray, cfg: RasterConfig) -> np.ndarray:
    """The planes of stored rasters ``bev (..., *cfg.shape)``: uint8 ``(..., H, W, C)``,
    ``C = len(cfg.channel_names)`` — the RGB image as it is, or the channels unpacked to
    0/1."""
    b = _check_stored(bev, cfg)
    if cfg.encoding == "rgb":
        return b
    return np.unpackbits(b, axis=-1, count=len(cfg.channel_names), bitorder="little")


def to_input(bev: np.ndarray, cfg: RasterConfig) -> np.ndarray:
    """What a learner reads: float32 ``(..., H, W, C)`` in [0, 1] — the RGB image ``/ 255``,
    or the binary planes (:func:`planes`)."""
    b = _check_stored(bev, cfg)
    if cfg.encoding == "rgb":
        return np.asarray(b, dtype=np.float32) / np.float32(255.0)
    return planes(b, cfg).astype(np.float32)


def unpack(packed: Any, count: int, dtype: Any = np.float32) -> Any:
    """The binary planes of packed bytes, for a NumPy or a JAX array (traced too): plane
    ``8k + j`` is bit ``j`` of byte ``k`` (:func:`minimanc.world.raster.pack`'s little bit
    order), so the result equals :func:`to_input` of a ``"channels"`` raster exactly, inside
    a jitted function too.

    Parameters
    ----------
    packed : array, uint8, shape (..., ceil(count / 8))
        Stored channels rasters (a dataset's ``bev`` rows); the result is of its kind.
    count : int
        The planes to keep, ``len(cfg.channel_names)``.
    dtype : dtype, optional (default: float32)
        Of the planes.

    Returns
    -------
    array, shape (..., count)
        0 and 1 in ``dtype``.
    """
    b = packed if hasattr(packed, "dtype") else np.asarray(packed)
    if b.dtype != np.uint8 or b.ndim < 1 or not 0 < count <= 8 * b.shape[-1]:
        raise ValueError(f"packed must be uint8 (..., n) with 0 < count <= 8 n, got "
                         f"{b.dtype} {tuple(b.shape)} and count={count!r}")
    bits = (b[..., None] >> np.arange(8, dtype=np.uint8)) & np.uint8(1)
    return bits.reshape(tuple(b.shape[:-1]) + (8 * b.shape[-1],))[..., :count].astype(dtype)


def to_rgb(bev: np.ndarray, cfg: RasterConfig) -> np.ndarray:
    """An RGB picture of stored rasters, uint8 ``(..., H, W, 3)``, for people: the RGB
    encoding as it is; the channels painted in the devkit's colours and order (walkway,
    drivable, crossing, lanes by direction, the route in :data:`ROUTE`, past boxes faded
    by :func:`minimanc.world.history.fade`, vehicles, ego)."""
    p = planes(bev, cfg)
    if cfg.encoding == "rgb":
        return p
    k = {name: i for i, name in enumerate(cfg.channel_names)}
    out = np.zeros(p.shape[:-1] + (3,), dtype=np.uint8)
    layers = [("walkway", WALKWAY), ("drivable", DRIVABLE), ("crossing", PED_CROSSING),
              ("lane_same", SAME_LANE), ("lane_opposite", OPPOSITE_LANE), ("route", ROUTE)]
    if cfg.history:
        shade = fade(cfg.history)
        for j in range(cfg.history, 0, -1):
            layers += [(f"vehicles_t-{j}", np.round(np.array(VEHICLE) * shade[j - 1])),
                       (f"ego_t-{j}", np.round(np.array(EGO) * shade[j - 1]))]
    layers += [("vehicles", VEHICLE), ("ego", EGO)]
    for name, colour in layers:
        if name in k:
            out[p[..., k[name]] > 0] = np.asarray(colour, dtype=np.uint8)
    return out
