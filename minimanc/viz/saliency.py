"""Chapter 6 — saliency in the paper's colours: the colormap, overlays, the per-q-state panel.

Display helpers for the maps of :mod:`minimanc.cam` (CAMs of eq. 7, per-q-state saliency
``S_j``): :func:`paper_cmap` (high → low = yellow → red → cyan → magenta), :func:`blend`
(the overlay as data), :func:`overlay` (drawn on an axes) and :func:`plot_q_saliency` (the
paper's Figures 3–4 panel).  Every map is min–max normalised
(:func:`minimanc.cam.minmax_normalize`) before it is coloured.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc.cam import minmax_normalize, upsample
from minimanc.viz.style import clear_ticks, pyplot, state_labels

__all__ = ["paper_cmap", "blend", "overlay", "plot_q_saliency"]


@functools.cache
def paper_cmap() -> Any:
    """The colormap of the paper's saliency figures: high → low = yellow → red → cyan → magenta.

    Built on first use (and cached), so that importing this module does not import
    matplotlib.

    Returns
    -------
    cmap : matplotlib.colors.LinearSegmentedColormap
        256 colours, low → high: magenta, cyan, red, yellow.
    """
    from matplotlib.colors import LinearSegmentedColormap  # matplotlib only when a figure is drawn

    # low → high: magenta → cyan → red → yellow
    return LinearSegmentedColormap.from_list(
        "manc_paper", ["#ff00ff", "#00ffff", "#ff0000", "#ffff00"], N=256
    )


def _as_rgb_float(image: Any) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=-1)
    if img.ndim != 3 or img.shape[-1] not in (1, 3):
        raise ValueError(f"image must be (H, W), (H, W, 1) or (H, W, 3); got shape {img.shape}")
    if img.shape[-1] == 1:
        img = np.repeat(img, 3, axis=-1)
    if img.dtype == np.uint8:
        return img.astype(float) / 255.0
    return np.clip(img.astype(float), 0.0, 1.0)


def blend(image: Any, saliency: Any, alpha: float = 0.5, cmap: Any = None) -> np.ndarray:
    """The overlay as data: ``(1 − α)·image + α·cmap(minmax(saliency))``.

    ``saliency`` is min–max normalised and, if its size differs from the
    image's, bilinearly resized to it first.

    Parameters
    ----------
    image : array-like, shape (H, W), (H, W, 1) or (H, W, 3)
        ``uint8`` or float image in [0, 1].
    saliency : array-like, shape (h, w)
        Saliency map.
    alpha : float, optional (default: 0.5)
        Weight of the colours, in [0, 1].
    cmap : matplotlib colormap, optional (default: None)
        None is :func:`paper_cmap`.

    Returns
    -------
    rgb : array, shape (H, W, 3)
        RGB floats in [0, 1].

    Raises
    ------
    ValueError
        If ``alpha`` is outside [0, 1], or ``image`` or ``saliency`` has the
        wrong shape.
    """
    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"alpha must be in [0, 1]; got alpha = {alpha!r}")
    img = _as_rgb_float(image)
    s = np.asarray(saliency, dtype=float)
    if s.ndim != 2:
        raise ValueError(f"saliency must have shape (h, w); got shape {s.shape}")
    if s.shape != img.shape[:2]:
        s = upsample(s, img.shape[:2])
    s = minmax_normalize(s)
    colours = np.asarray((cmap or paper_cmap())(s))[..., :3]
    return (1.0 - alpha) * img + alpha * colours


def overlay(
    image: Any,
    saliency: Any,
    ax: Any = None,
    alpha: float = 0.5,
    cmap: Any = None,
    title: str | None = None,
) -> Any:
    """Draw :func:`blend` on ``ax``: the BEV image with its saliency in the paper's colours.

    Parameters
    ----------
    image : array-like, shape (H, W), (H, W, 1) or (H, W, 3)
        ``uint8`` or float image in [0, 1].
    saliency : array-like, shape (h, w)
        Saliency map (min–max normalised here).
    ax : matplotlib Axes, optional (default: None)
        Axes to draw on; a new figure when None.
    alpha : float, optional (default: 0.5)
        Weight of the colours, in [0, 1].
    cmap : matplotlib colormap, optional (default: None)
        None is :func:`paper_cmap` (high → low: yellow, red, cyan, magenta).
    title : str, optional (default: None)
        Axes title.

    Returns
    -------
    ax : matplotlib Axes
        ``ax`` (or the new axes) showing the blend, without ticks.

    Raises
    ------
    ValueError
        As :func:`blend`.
    """
    rgb = blend(image, saliency, alpha=alpha, cmap=cmap)
    if ax is None:
        _, ax = pyplot().subplots(figsize=(3, 3))
    ax.imshow(rgb, interpolation="nearest")
    if title is not None:
        ax.set_title(title)
    return clear_ticks(ax)


def plot_q_saliency(
    image: Any,
    saliency: Any,
    q: Any,
    axes: Any = None,
    alpha: float = 0.5,
    labels: Sequence[str] | None = None,
) -> Any:
    """Figures 3–4 style panel: the BEV image, then one overlay per q-state.

    Each overlay is titled with its q-state's name and probability.

    Parameters
    ----------
    image : array-like, shape (H, W), (H, W, 1) or (H, W, 3)
        The BEV input.
    saliency : array-like, shape (N, H, W)
        Per-q-state saliency (e.g. ``explain(...)["saliency"][b]``).
    q : array-like, shape (N,)
        q-distribution shown in the titles.
    axes : sequence of matplotlib Axes, optional (default: None)
        ``N + 1`` axes; a new row of them when None.
    alpha : float, optional (default: 0.5)
        Weight of the colours, in [0, 1].
    labels : sequence of str, optional (default: None)
        ``N`` q-state names; ``q_0 … q_{N-1}`` when None.

    Returns
    -------
    axes : array of matplotlib Axes, shape (N + 1,)
        The axes drawn on.

    Raises
    ------
    ValueError
        If ``saliency`` is not ``(N, H, W)``, ``q`` not ``(N,)``, or ``labels``
        does not have ``N`` entries.
    """
    saliency = np.asarray(saliency, dtype=float)
    q = np.asarray(q, dtype=float)
    if saliency.ndim != 3 or q.shape != (saliency.shape[0],):
        raise ValueError(
            f"saliency must be (N, H, W) and q (N,); got saliency {saliency.shape}, q {q.shape}"
        )
    N = saliency.shape[0]
    labels = state_labels(labels, N)
    if axes is None:
        _, axes = pyplot().subplots(1, N + 1, figsize=(2.4 * (N + 1), 2.6))
    axes = np.ravel(axes)
    axes[0].imshow(_as_rgb_float(image), interpolation="nearest")
    axes[0].set_title("BEV input")
    clear_ticks(axes[0])
    for j in range(N):
        overlay(image, saliency[j], ax=axes[j + 1], alpha=alpha,
                title=f"{labels[j]}: P = {q[j]:.2f}")
    return axes
