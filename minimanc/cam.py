"""Chapter 6 — the visual predicate extractor, class activation maps and per-q-state saliency.

Eq. 7 of the paper (section IV-A)::

    f^v = ConvEncoder(X)                     features, NHWC: (B, H, W, K)
    p^v = Linear(GlobalAveragePooling(f^v))  predicates, (B, M)

Because the only thing between the last convolution and the predicates is an
average and a linear map, each predicate splits exactly into a sum over
pixels — the *class activation map* of Zhou et al. (2016)::

    M_i(x, y) = Σ_k W_ki f_k(x, y)      and      p_i = mean_xy M_i(x, y) + b_i

Layouts (ours, everywhere in minimanc): images and features are channels-last
(NHWC), convolution kernels HWIO, and the linear head stores its weight as
``(K, M)`` so that ``p = gap(f) @ w + b``.  :func:`class_activation_maps`
also takes the PyTorch-style ``(M, K)`` with ``layout="MK"``.  Maps are
returned channels-first per predicate: ``(..., M, H, W)``.

Per-q-state saliency (the paper's Figures 3–4).  vAGN (chapter 5, eq. 9) turns
predicates into a q-distribution ``q = T(p) q_prev``.  We attribute q-state
``j`` to image locations by the first-order influence of each predicate::

    J_ji = ∂q_j / ∂p_i   (at the current p and q_prev)
    S_j(x, y) = Σ_i J_ji M_i(x, y)

Equivalently ``S_j(x, y) = H·W · Σ_k f_k(x, y) ∂q_j/∂f_k(x, y)`` — gradient ×
feature at the last conv layer — and ``mean_xy S_j = Σ_i J_ji (p_i − b_i)``,
the linearised change of ``q_j`` contributed by the image evidence.  Positive
``S_j`` marks where the image pushes probability *into* q-state ``j``.
Caveat: where an entry of ``W^p`` sits in ReLU's dead zone it passes no
gradient, so ``J`` (and ``S``) only see the predicates that are active.

Differentiable functions take ``xp`` (and the extractor the engine's ``nn``);
they use only the operations listed in CONTRIBUTING.md.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from minimanc import layers, vagn

__all__ = [
    "paper_cmap",
    "init_extractor",
    "predicate_extractor",
    "global_average_pool",
    "class_activation_maps",
    "upsample",
    "minmax_normalize",
    "grad_cam",
    "vagn_jacobian",
    "q_state_saliency",
    "explain",
    "peak_location",
    "blend",
    "overlay",
    "plot_q_saliency",
]


@functools.cache
def paper_cmap() -> Any:
    """The colormap of the paper's saliency figures: high → low = yellow → red → cyan
    → magenta. Built on first use, so that the math of this module (and every module
    importing it) does not import matplotlib; also available as ``cam.PAPER_CMAP``."""
    from matplotlib.colors import LinearSegmentedColormap

    # low → high: magenta → cyan → red → yellow
    return LinearSegmentedColormap.from_list(
        "manc_paper", ["#ff00ff", "#00ffff", "#ff0000", "#ffff00"], N=256
    )


def __getattr__(name: str) -> Any:
    if name == "PAPER_CMAP":  # the colormap, built on first access (see paper_cmap)
        return paper_cmap()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ---------------------------------------------------------------------------
# parameters
# ---------------------------------------------------------------------------
def init_extractor(
    rng: np.random.Generator,
    in_channels: int = 3,
    n_predicates: int = 4,
    channels: Sequence[int] = (8, 16),
    kernel_size: int = 3,
    dtype: Any = np.float64,
) -> dict:
    """Parameters of eq. 7: ``{"convs": [{"w": HWIO, "b"}, …], "head": {"w": (K, M), "b": (M,)}}``.

    ``channels`` lists the output channels of each convolution; the last one
    is ``K``, the number of feature maps that CAM combines.  Convolutions are
    He-normal and the head Glorot-uniform (:mod:`minimanc.layers`).
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator; got rng = {rng!r}")
    for name, v in (("in_channels", in_channels), ("n_predicates", n_predicates),
                    ("kernel_size", kernel_size)):
        if int(v) != v or v < 1:
            raise ValueError(f"{name} must be a positive integer; got {name} = {v!r}")
    channels = tuple(channels)
    if len(channels) == 0 or any(int(c) != c or c < 1 for c in channels):
        raise ValueError(f"channels must be a non-empty list of positive integers; got {channels}")
    k, convs, c_in = int(kernel_size), [], int(in_channels)
    for c in channels:
        convs.append(layers.init_conv(rng, k, k, c_in, int(c), dtype=dtype))
        c_in = int(c)
    return {"convs": convs, "head": layers.init_dense(rng, c_in, int(n_predicates), dtype=dtype)}


# ---------------------------------------------------------------------------
# eq. 7
# ---------------------------------------------------------------------------
def global_average_pool(features: Any, xp: Any = np) -> Any:
    """Global average pooling: ``(..., H, W, K) → (..., K)``, the mean over H and W."""
    return xp.mean(xp.mean(features, axis=-2), axis=-2)


def _default_strides(n_layers: int) -> tuple[int, ...]:
    return (1,) + (2,) * (n_layers - 1)


def predicate_extractor(
    params: dict,
    images: Any,
    nn: Any,
    xp: Any = np,
    return_features: bool = False,
    strides: Sequence[int] | None = None,
    padding: int | None = None,
    activation: str = "relu",
) -> Any:
    """Eq. 7: ``p^v = Linear(GAP(ConvEncoder(X)))`` as a pure function.

    ``images`` is NHWC, ``uint8`` (scaled to [0, 1]) or float; ``nn`` is an
    engine's ``nn`` namespace (``engine("numpy").nn`` / ``engine("jax").nn``)
    and ``xp`` the matching array namespace.  Every convolution is followed by
    ``activation`` ("relu" or "silu"); ``strides`` defaults to 1 for the
    first layer and 2 for the others; ``padding`` (pixels of zeros on each
    side) defaults to ``kernel_size // 2``, which keeps the size at stride 1.
    Returns ``p`` of shape ``(B, M)``, or ``(p, features)`` with ``features``
    of shape ``(B, H', W', K)`` when ``return_features`` (the input of
    :func:`class_activation_maps`).
    """
    convs = params["convs"]
    n = len(convs)
    strides = _default_strides(n) if strides is None else tuple(strides)
    if len(strides) != n:
        raise ValueError(f"strides must have one entry per conv layer ({n}); got {strides}")
    if activation not in ("relu", "silu"):
        raise ValueError(f"activation must be 'relu' or 'silu'; got activation = {activation!r}")
    shape = tuple(images.shape) if hasattr(images, "shape") else np.shape(images)
    c_in = convs[0]["w"].shape[2]
    if len(shape) != 4 or shape[-1] != c_in:
        raise ValueError(
            f"images must be NHWC with C = {c_in} channels (batch, height, width, channels); "
            f"got images with shape {shape}"
        )
    if getattr(images, "dtype", None) == np.uint8:
        images = np.asarray(images, dtype=convs[0]["w"].dtype) / 255.0
    act = nn.relu if activation == "relu" else nn.silu
    h = xp.asarray(images)
    for layer, s in zip(convs, strides):
        pad = layer["w"].shape[0] // 2 if padding is None else int(padding)
        h = act(layers.conv2d(layer, h, nn, stride=s, padding=pad))
    p = layers.dense(params["head"], global_average_pool(h, xp=xp), xp=xp)
    return (p, h) if return_features else p


# ---------------------------------------------------------------------------
# CAM and Grad-CAM
# ---------------------------------------------------------------------------
def class_activation_maps(features: Any, weights: Any, xp: Any = np, layout: str = "KM") -> Any:
    """CAM (Zhou et al. 2016): ``M_i(x, y) = Σ_k W_ki f_k(x, y)``.

    ``features`` (..., H, W, K) channels-last; ``weights`` the linear head's
    ``(K, M)`` (our layout, ``p = gap(f) @ w + b``) or ``(M, K)`` with
    ``layout="MK"``.  Returns ``(..., M, H, W)``.  The bias is not part of the
    map: ``mean_xy M_i = p_i − b_i``.
    """
    if layout not in ("KM", "MK"):
        raise ValueError(f"layout must be 'KM' or 'MK'; got layout = {layout!r}")
    fshape, wshape = tuple(features.shape), tuple(weights.shape)
    if len(fshape) < 3:
        raise ValueError(f"features must have shape (..., H, W, K); got shape {fshape}")
    if len(wshape) != 2:
        raise ValueError(f"weights must be 2-D ({layout}); got weights with shape {wshape}")
    K = fshape[-1]
    k_axis = 0 if layout == "KM" else 1
    if wshape[k_axis] != K:
        raise ValueError(
            f"weights with layout {layout!r} must have K = {K} (features.shape[-1]) on axis "
            f"{k_axis}; got weights with shape {wshape}"
        )
    w = weights if layout == "KM" else xp.transpose(weights)
    maps = xp.matmul(features, w)  # (..., H, W, M)
    nd = len(fshape)
    perm = tuple(range(nd - 3)) + (nd - 1, nd - 3, nd - 2)
    return xp.transpose(maps, perm)


def _interp_matrix(n_out: int, n_in: int, mode: str) -> np.ndarray:
    # half-pixel centres (as image resizing in PIL / jax.image.resize)
    x = (np.arange(n_out) + 0.5) * (n_in / n_out) - 0.5
    R = np.zeros((n_out, n_in))
    if mode == "nearest":
        idx = np.clip(np.floor((np.arange(n_out) + 0.5) * n_in / n_out), 0, n_in - 1)
        R[np.arange(n_out), idx.astype(int)] = 1.0
        return R
    x = np.clip(x, 0.0, n_in - 1)
    i0 = np.floor(x).astype(int)
    i1 = np.minimum(i0 + 1, n_in - 1)
    w = x - i0
    np.add.at(R, (np.arange(n_out), i0), 1.0 - w)
    np.add.at(R, (np.arange(n_out), i1), w)
    return R


def upsample(maps: Any, size: tuple[int, int] | int, mode: str = "bilinear", xp: Any = np) -> Any:
    """Resize maps ``(..., h, w)`` to ``size = (H, W)`` (bilinear or nearest).

    Implemented as ``R_h @ maps @ R_wᵀ`` with fixed interpolation matrices, so
    it is linear (an upsampled CAM is still the weighted sum of upsampled
    feature maps) and differentiable on both engines.
    """
    if mode not in ("bilinear", "nearest"):
        raise ValueError(f"mode must be 'bilinear' or 'nearest'; got mode = {mode!r}")
    if isinstance(size, int | np.integer):
        size = (int(size), int(size))
    size = tuple(int(s) for s in size)
    if len(size) != 2 or min(size) < 1:
        raise ValueError(f"size must be (H, W) with positive entries; got size = {size}")
    shape = tuple(maps.shape)
    if len(shape) < 2:
        raise ValueError(f"maps must have shape (..., h, w); got shape {shape}")
    Rh = _interp_matrix(size[0], shape[-2], mode)
    Rw = _interp_matrix(size[1], shape[-1], mode)
    return xp.matmul(xp.matmul(Rh, maps), xp.transpose(Rw))


def minmax_normalize(maps: Any, axis: tuple[int, ...] = (-2, -1), xp: Any = np) -> Any:
    """Min–max normalise each map to [0, 1] over ``axis``: ``(s − min) / (max − min)``.

    A constant map (max = min) carries no ranking and becomes all zeros
    instead of 0/0.  This is the normalisation behind every overlay.
    """
    lo, hi = maps, maps
    for a in sorted((a % maps.ndim for a in axis), reverse=True):
        lo = xp.expand_dims(xp.min(lo, axis=a), a)
        hi = xp.expand_dims(xp.max(hi, axis=a), a)
    span = hi - lo
    safe = xp.where(span > 0, span, 1.0)
    return xp.where(span > 0, (maps - lo) / safe, 0.0 * maps)


def grad_cam(features: Any, grads: Any, xp: Any = np) -> Any:
    """Grad-CAM (Selvaraju et al. 2017): ``ReLU(Σ_k α_k f_k)`` with ``α_k = mean_xy ∂y/∂f_k``.

    ``features`` and ``grads`` (the gradient of one score ``y`` with respect
    to ``features``) are ``(..., H, W, K)``; returns ``(..., H, W)``.  For
    conv → GAP → linear, ``α_k = W_k / (H W)``, so Grad-CAM equals the CAM
    after ReLU up to a positive factor — equal after min–max normalisation.
    """
    if tuple(features.shape) != tuple(grads.shape):
        raise ValueError(
            f"grads must have the shape of features {tuple(features.shape)}; "
            f"got {tuple(grads.shape)}"
        )
    alpha = global_average_pool(grads, xp=xp)  # (..., K)
    return xp.maximum(xp.sum(features * xp.expand_dims(xp.expand_dims(alpha, -2), -2), axis=-1),
                      0.0)


# ---------------------------------------------------------------------------
# per-q-state saliency (Figures 3-4)
# ---------------------------------------------------------------------------
def vagn_jacobian(
    q_prev: Any, p: Any, W: Any, grad: Callable | None = None, xp: Any = np
) -> Any:
    """``J[..., j, i] = ∂q_j/∂p_i`` for one vAGN step ``q = T(p) q_prev`` (eq. 9).

    With ``grad=None`` the closed form (NumPy) is used: with ``A = Σ p_i W_i``,
    ``T = colsoftmax(ReLU(A))`` and ``G_i = 1[A > 0] ⊙ W_i``,
    ``J_ji = Σ_c q_prev[c] T_jc (G_i[j, c] − Σ_r T_rc G_i[r, c])``.
    Given an engine's ``grad`` (and its ``xp``) the Jacobian is instead
    computed by reverse mode, one pass per q-state: batch rows are
    independent, so the gradient of ``Σ_batch q_j`` gives every row's
    ``∂q_j/∂p`` at once.  Returns shape ``(..., N, M)``.
    """
    M, N = vagn.check_weights(W)
    if grad is not None:
        rows = []
        for j in range(N):
            def qj(pp: Any, j: int = j) -> Any:
                return xp.sum(vagn.step(q_prev, pp, W, xp=xp)[..., j])

            rows.append(grad(qj)(p))
        return xp.stack(rows, axis=-2)
    p = np.asarray(p, dtype=float)
    q_prev = np.asarray(q_prev, dtype=float)
    W = np.asarray(W, dtype=float)
    vagn.check_state(q_prev, N, name="q_prev")
    A = vagn.combined_weights(p, W)
    T = vagn.transition_matrix(p, W)
    G = (A > 0)[..., None, :, :] * W  # (..., M, N, N)
    colmean = np.einsum("...rc,...irc->...ic", T, G)  # (..., M, N)
    qb = np.broadcast_to(q_prev, T.shape[:-2] + (N,))
    return np.einsum("...c,...jc,...ijc->...ji", qb, T, G) - np.einsum(
        "...c,...jc,...ic->...ji", qb, T, colmean
    )


def q_state_saliency(cams: Any, jacobian: Any, xp: Any = np) -> Any:
    """Per-q-state saliency ``S_j(x, y) = Σ_i J_ji M_i(x, y)``.

    ``cams`` (..., M, H, W) and ``jacobian`` (..., N, M) give (..., N, H, W).

    See the module docstring for why this is the gradient × feature
    attribution of ``q_j`` at the last conv layer (scaled by H·W).
    """
    cshape, jshape = tuple(cams.shape), tuple(jacobian.shape)
    if len(cshape) < 3 or len(jshape) < 2 or jshape[-1] != cshape[-3]:
        raise ValueError(
            f"cams (..., M, H, W) and jacobian (..., N, M) must agree on M; "
            f"got cams {cshape}, jacobian {jshape}"
        )
    h, w = cshape[-2], cshape[-1]
    flat = xp.reshape(cams, cshape[:-2] + (h * w,))  # (..., M, HW)
    out = xp.matmul(jacobian, flat)  # (..., N, HW)
    return xp.reshape(out, tuple(out.shape[:-1]) + (h, w))


def explain(
    params: dict,
    images: Any,
    q_prev: Any,
    W: Any,
    nn: Any,
    xp: Any = np,
    strides: Sequence[int] | None = None,
    activation: str = "relu",
    upsample_to_input: bool = True,
    baseline_cams: Any = None,
) -> dict:
    """Everything behind one frame of the paper's execution traces, as NumPy arrays.

    Runs eq. 7 and one vAGN step (eq. 9) on ``images`` (B, H, W, C) with
    plain (not traced) ``params``, ``q_prev`` (N,) or (B, N) and ``W``, and
    returns a dict with ``p`` (B, M), ``q`` (B, N), ``cams`` (B, M, H, W),
    ``jacobian`` (B, N, M) and ``saliency`` (B, N, H, W); maps are upsampled
    to the input size unless ``upsample_to_input`` is False.

    ``baseline_cams`` (M, h, w) at feature resolution, e.g. the mean CAM over
    the training images, is subtracted from the CAMs before the saliency is
    formed.  CAMs are only defined up to a map that is the same in every
    image: adding ``B_i(x, y)`` to ``M_i`` and ``−mean(B_i)`` to ``b_i`` gives
    the same predictor.  Objects present in every image (the ego vehicle of a
    BEV) can therefore carry arbitrary CAM mass; a data-set baseline removes it.
    """
    p, f = predicate_extractor(params, images, nn, xp=xp, return_features=True,
                               strides=strides, activation=activation)
    p, f = np.asarray(p), np.asarray(f)
    cams = class_activation_maps(f, np.asarray(params["head"]["w"]))
    if baseline_cams is not None:
        baseline_cams = np.asarray(baseline_cams, dtype=float)
        if baseline_cams.shape != cams.shape[1:]:
            raise ValueError(
                f"baseline_cams must have shape {cams.shape[1:]} (M, h, w at feature "
                f"resolution); got baseline_cams with shape {baseline_cams.shape}"
            )
        cams = cams - baseline_cams
    q = vagn.step(q_prev, p, W)
    J = vagn_jacobian(q_prev, p, W)
    S = q_state_saliency(cams, J)
    if upsample_to_input:
        size = tuple(images.shape[1:3])
        cams, S = upsample(cams, size), upsample(S, size)
    return {"p": p, "q": q, "cams": cams, "jacobian": J, "saliency": S}


def peak_location(maps: Any) -> np.ndarray:
    """Row and column of the maximum of each map: (..., H, W) → (..., 2) integers."""
    maps = np.asarray(maps)
    if maps.ndim < 2:
        raise ValueError(f"maps must have shape (..., H, W); got shape {maps.shape}")
    flat = maps.reshape(maps.shape[:-2] + (-1,)).argmax(axis=-1)
    return np.stack(np.unravel_index(flat, maps.shape[-2:]), axis=-1)


# ---------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------
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
    """The overlay as data: ``(1 − α)·image + α·cmap(minmax(saliency))``, RGB floats (H, W, 3).

    ``saliency`` (h, w) is min–max normalised and, if smaller than the image,
    bilinearly upsampled to it first.
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
    """Draw :func:`blend` on ``ax``: the BEV image with its min–max-normalised
    saliency in the paper's colours (high → low: yellow, red, cyan, magenta)."""
    import matplotlib.pyplot as plt

    rgb = blend(image, saliency, alpha=alpha, cmap=cmap)
    if ax is None:
        _, ax = plt.subplots(figsize=(3, 3))
    ax.imshow(rgb, interpolation="nearest")
    if title is not None:
        ax.set_title(title)
    ax.set_xticks([])
    ax.set_yticks([])
    return ax


def plot_q_saliency(
    image: Any,
    saliency: Any,
    q: Any,
    axes: Any = None,
    alpha: float = 0.5,
    labels: Sequence[str] | None = None,
) -> Any:
    """Figures 3–4 style panel: the BEV image, then one overlay per q-state
    titled with its name (``labels``, default ``q_j``) and probability.
    ``saliency`` (N, H, W), ``q`` (N,).  Returns the axes."""
    import matplotlib.pyplot as plt

    saliency = np.asarray(saliency, dtype=float)
    q = np.asarray(q, dtype=float)
    if saliency.ndim != 3 or q.shape != (saliency.shape[0],):
        raise ValueError(
            f"saliency must be (N, H, W) and q (N,); got saliency {saliency.shape}, q {q.shape}"
        )
    N = saliency.shape[0]
    if labels is None:
        labels = [f"$q_{{{j}}}$" for j in range(N)]
    if len(labels) != N:
        raise ValueError(f"labels must have N = {N} entries; got {len(labels)}")
    if axes is None:
        _, axes = plt.subplots(1, N + 1, figsize=(2.4 * (N + 1), 2.6))
    axes = np.ravel(axes)
    axes[0].imshow(_as_rgb_float(image), interpolation="nearest")
    axes[0].set_title("BEV input")
    axes[0].set_xticks([])
    axes[0].set_yticks([])
    for j in range(N):
        overlay(image, saliency[j], ax=axes[j + 1], alpha=alpha,
                title=f"{labels[j]}: P = {q[j]:.2f}")
    return axes
