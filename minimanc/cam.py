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

The display helpers (:func:`~minimanc.viz.saliency.paper_cmap`, ``blend``, ``overlay`` and
``plot_q_saliency``) are figures, in :mod:`minimanc.viz.saliency`; this module imports no
plotting code.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from minimanc import layers, vagn
from minimanc.checks import check_int

__all__ = [
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
]


# ------------------------------------------------------------------ parameters
def init_extractor(
    rng: np.random.Generator,
    in_channels: int = 3,
    n_predicates: int = 4,
    channels: Sequence[int] = (8, 16),
    kernel_size: int = 3,
    dtype: Any = np.float64,
) -> dict:
    """Parameters of the predicate extractor of eq. 7.

    Convolutions are He-normal and the head Glorot-uniform
    (:mod:`minimanc.layers`).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    in_channels : int, optional (default: 3)
        Channels ``C`` of the input images, ≥ 1.
    n_predicates : int, optional (default: 4)
        Number of predicates ``M``, ≥ 1.
    channels : sequence of int, optional (default: (8, 16))
        Output channels of each convolution (at least one); the last one is
        ``K``, the number of feature maps that CAM combines.
    kernel_size : int, optional (default: 3)
        Height and width of every kernel, ≥ 1.
    dtype : NumPy float dtype, optional (default: float64)
        Precision of the parameters.

    Returns
    -------
    params : dict
        ``{"convs": [{"w": (k, k, c_in, c_out) HWIO, "b": (c_out,)}, ...],
        "head": {"w": (K, M), "b": (M,)}}``.

    Raises
    ------
    ValueError
        If ``rng`` is not a ``numpy.random.Generator``, a size is not an integer
        ≥ 1, ``channels`` is empty, or ``dtype`` is not a float type.
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator; got rng = {rng!r}")
    c_in = check_int("in_channels", in_channels, 1)
    n_predicates = check_int("n_predicates", n_predicates, 1)
    k = check_int("kernel_size", kernel_size, 1)
    channels = tuple(channels)
    if len(channels) == 0:
        raise ValueError(f"channels must list at least one convolution; got channels={channels}")
    channels = tuple(check_int(f"channels[{i}]", c, 1) for i, c in enumerate(channels))
    convs = []
    for c in channels:
        convs.append(layers.init_conv(rng, k, k, c_in, c, dtype=dtype))
        c_in = c
    return {"convs": convs, "head": layers.init_dense(rng, c_in, n_predicates, dtype=dtype)}


# ----------------------------------------------------------------------- eq. 7
def global_average_pool(features: Any, xp: Any = np) -> Any:
    """Global average pooling of eq. 7: the mean over the two spatial axes.

    Parameters
    ----------
    features : array-like, shape (..., H, W, K)
        Feature maps, channels-last.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    pooled : array, shape (..., K)
        One average per feature map.
    """
    return xp.mean(xp.mean(features, axis=-2), axis=-2)


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

    Every convolution is followed by ``activation``.

    Parameters
    ----------
    params : dict
        Parameters from :func:`init_extractor` (plain or traced arrays).
    images : array-like, shape (B, H, W, C)
        NHWC images, ``uint8`` (scaled to [0, 1]) or float.
    nn : namespace
        An engine's neural-net primitives (``engine("numpy").nn`` /
        ``engine("jax").nn``).
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.
    return_features : bool, optional (default: False)
        Also return the last convolution's features (the input of
        :func:`class_activation_maps`).
    strides : sequence of int, optional (default: None)
        One stride per convolution; None is 1 for the first layer and 2 for the
        others.
    padding : int, optional (default: None)
        Pixels of zeros on each side; None is ``kernel_size // 2``, which keeps
        the size at stride 1.
    activation : {"relu", "silu"}, optional (default: "relu")
        Nonlinearity after each convolution.

    Returns
    -------
    p : array, shape (B, M)
        Predicates ``p^v``.
    features : array, shape (B, H', W', K)
        Returned as ``(p, features)`` only when ``return_features``.

    Raises
    ------
    ValueError
        If ``strides`` does not have one entry per convolution, ``activation``
        is unknown, or ``images`` is not NHWC with the first kernel's ``C``.
    """
    convs = params["convs"]
    n = len(convs)
    strides = (1,) + (2,) * (n - 1) if strides is None else tuple(strides)
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
        h = act(layers.conv(layer, h, nn, stride=s, padding=pad))
    p = layers.dense(params["head"], global_average_pool(h, xp=xp), xp=xp)
    return (p, h) if return_features else p


# ------------------------------------------------------------ CAM and Grad-CAM
def class_activation_maps(features: Any, weights: Any, xp: Any = np, layout: str = "KM") -> Any:
    """CAM (Zhou et al. 2016) of eq. 7's head: ``M_i(x, y) = Σ_k W_ki f_k(x, y)``.

    The bias is not part of the map: ``mean_xy M_i = p_i − b_i``.

    Parameters
    ----------
    features : array-like, shape (..., H, W, K)
        Last convolution's features, channels-last.
    weights : array-like, shape (K, M), or (M, K) with ``layout="MK"``
        The linear head's weight (ours: ``p = gap(f) @ w + b``).
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.
    layout : {"KM", "MK"}, optional (default: "KM")
        Axis order of ``weights``; "MK" is PyTorch's ``Linear.weight``.

    Returns
    -------
    maps : array, shape (..., M, H, W)
        One map per predicate, channels-first.

    Raises
    ------
    ValueError
        If ``layout`` is unknown, ``features`` has fewer than 3 axes, ``weights``
        is not 2-D, or the ``K`` of ``weights`` and ``features`` differ.
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
    """Resize maps to ``size`` by bilinear or nearest interpolation (half-pixel centres).

    Implemented as ``R_h @ maps @ R_wᵀ`` with fixed interpolation matrices, so
    it is linear (an upsampled CAM is still the weighted sum of upsampled
    feature maps) and differentiable on both engines.

    Parameters
    ----------
    maps : array-like, shape (..., h, w)
        Maps to resize.
    size : int or (int, int)
        Output ``(H, W)``; an int is used for both.
    mode : {"bilinear", "nearest"}, optional (default: "bilinear")
        Interpolation.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    resized : array, shape (..., H, W)
        The resized maps.

    Raises
    ------
    ValueError
        If ``mode`` is unknown, ``size`` is not two positive integers, or
        ``maps`` has fewer than 2 axes.
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
    """Min–max normalise each map to [0, 1]: ``(s − min) / (max − min)`` over ``axis``.

    A constant map (max = min) carries no ranking and becomes all zeros instead
    of 0/0.  This is the normalisation behind every overlay.

    Parameters
    ----------
    maps : array-like, shape (..., H, W)
        Maps to normalise.
    axis : tuple of int, optional (default: (-2, -1))
        Axes over which each map's minimum and maximum are taken.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    normalised : array, shape (..., H, W)
        Maps in [0, 1], the shape of ``maps``.
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

    For conv → GAP → linear (eq. 7), ``α_k = W_k / (H W)``, so Grad-CAM equals
    the CAM after ReLU up to a positive factor — equal after min–max
    normalisation.

    Parameters
    ----------
    features : array-like, shape (..., H, W, K)
        Last convolution's features.
    grads : array-like, shape (..., H, W, K)
        Gradient of one score ``y`` with respect to ``features``.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    cam : array, shape (..., H, W)
        Non-negative class activation map.

    Raises
    ------
    ValueError
        If ``grads`` and ``features`` differ in shape.
    """
    if tuple(features.shape) != tuple(grads.shape):
        raise ValueError(
            f"grads must have the shape of features {tuple(features.shape)}; "
            f"got {tuple(grads.shape)}"
        )
    alpha = global_average_pool(grads, xp=xp)  # (..., K)
    return xp.maximum(xp.sum(features * xp.expand_dims(xp.expand_dims(alpha, -2), -2), axis=-1),
                      0.0)


# ------------------------------------------ per-q-state saliency (Figures 3-4)
def vagn_jacobian(
    q_prev: Any, p: Any, W: Any, grad: Callable | None = None, xp: Any = np
) -> Any:
    """Jacobian ``J[..., j, i] = ∂q_j/∂p_i`` of one vAGN step ``q = T(p) q_prev`` (eqs. 8–9).

    With ``grad=None`` the closed form (NumPy) is used: with ``A = Σ p_i W_i``,
    ``T = colsoftmax(ReLU(A))`` and ``G_i = 1[A > 0] ⊙ W_i``,
    ``J_ji = Σ_c q_prev[c] T_jc (G_i[j, c] − Σ_r T_rc G_i[r, c])``.  Given an
    engine's ``grad`` (and its ``xp``) the Jacobian is instead computed by
    reverse mode, one pass per q-state: batch rows are independent, so the
    gradient of ``Σ_batch q_j`` gives every row's ``∂q_j/∂p`` at once.

    Parameters
    ----------
    q_prev : array-like, shape (..., N)
        Previous q-distributions.
    p : array-like, shape (..., M)
        Predicates.
    W : array-like, shape (M, N, N)
        vAGN transition weights.
    grad : callable, optional (default: None)
        An engine's ``grad``; None uses the closed form.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    J : array, shape (..., N, M)
        ``∂q_j/∂p_i`` at ``(q_prev, p)``.

    Raises
    ------
    ValueError
        If ``W`` is not of shape ``(M, N, N)``, or (closed form) ``q_prev`` is
        not a distribution over ``N`` states.
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
    """Per-q-state saliency ``S_j(x, y) = Σ_i J_ji M_i(x, y)`` (Figures 3–4).

    See the module docstring for why this is the gradient × feature attribution
    of ``q_j`` at the last conv layer (scaled by H·W).

    Parameters
    ----------
    cams : array-like, shape (..., M, H, W)
        Class activation maps from :func:`class_activation_maps`.
    jacobian : array-like, shape (..., N, M)
        ``∂q/∂p`` from :func:`vagn_jacobian`.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    saliency : array, shape (..., N, H, W)
        One map per q-state.

    Raises
    ------
    ValueError
        If the shapes are wrong or disagree on ``M``.
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

    Runs eq. 7 and one vAGN step (eq. 9) and forms CAMs, the vAGN Jacobian and
    the per-q-state saliency.  CAMs are only defined up to a map that is the
    same in every image: adding ``B_i(x, y)`` to ``M_i`` and ``−mean(B_i)`` to
    ``b_i`` gives the same predictor.  Objects present in every image (the ego
    vehicle of a BEV) can therefore carry arbitrary CAM mass; a data-set
    baseline (``baseline_cams``) removes it.

    Parameters
    ----------
    params : dict
        Plain (not traced) extractor parameters from :func:`init_extractor`.
    images : array-like, shape (B, H, W, C)
        NHWC images.
    q_prev : array-like, shape (N,) or (B, N)
        Previous q-distributions.
    W : array-like, shape (M, N, N)
        vAGN transition weights.
    nn : namespace
        An engine's neural-net primitives.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.
    strides : sequence of int, optional (default: None)
        As in :func:`predicate_extractor`.
    activation : {"relu", "silu"}, optional (default: "relu")
        As in :func:`predicate_extractor`.
    upsample_to_input : bool, optional (default: True)
        Upsample ``cams`` and ``saliency`` to ``(H, W)``; else they stay at
        feature resolution ``(h, w)``.
    baseline_cams : array-like, shape (M, h, w), optional (default: None)
        Subtracted from the CAMs before the saliency is formed, e.g. the mean
        CAM over the training images.

    Returns
    -------
    frame : dict
        ``p`` (B, M), ``q`` (B, N), ``cams`` (B, M, H, W), ``jacobian``
        (B, N, M) and ``saliency`` (B, N, H, W).

    Raises
    ------
    ValueError
        If ``baseline_cams`` does not have shape ``(M, h, w)``, or any input is
        refused by :func:`predicate_extractor` or :func:`minimanc.vagn.step`.
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
    """Row and column of the maximum of each map.

    Parameters
    ----------
    maps : array-like, shape (..., H, W)
        Maps.

    Returns
    -------
    peaks : array of int, shape (..., 2)
        ``(row, column)`` of each map's first maximum.

    Raises
    ------
    ValueError
        If ``maps`` has fewer than 2 axes.
    """
    maps = np.asarray(maps)
    if maps.ndim < 2:
        raise ValueError(f"maps must have shape (..., H, W); got shape {maps.shape}")
    flat = maps.reshape(maps.shape[:-2] + (-1,)).argmax(axis=-1)
    return np.stack(np.unravel_index(flat, maps.shape[-2:]), axis=-1)
