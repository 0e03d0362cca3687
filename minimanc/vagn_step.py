"""Chapter 5 — one vAGN update (eqs. 8–9) as one differentiable function with its own VJP.

:func:`minimanc.vagn.step` computes, for predicates ``p`` ``(..., M)``, weights ``W``
``(M, N, N)`` and the previous distribution ``q`` ``(..., N)``:

* ``A = Σ_i p_i W_i`` (eq. 8), ``R = ReLU(A)``,
* ``T = colsoftmax(R)`` (eq. 9; each column shifted by its maximum first),
* ``u = T q`` and ``q_t = u / Σ u``.

Traced by the generic tape that is about 17 operations per step. :data:`fused_step`
is the same arithmetic as **one** node (:class:`minimanc.autodiff.custom_vjp`): the
forward runs on plain NumPy arrays and keeps ``T``, ``u``, ``Σ u`` and the ReLU's
mask, and the backward is written by hand, from the output cotangent ``ḡ``:

* ``ū = (ḡ − ⟨ḡ, q_t⟩) / Σ u`` (the renormalisation),
* ``T̄_ij = ū_i q_j`` and ``q̄_j = Σ_i ū_i T_ij`` (the product),
* ``R̄_ij = T_ij (T̄_ij − Σ_k T̄_kj T_kj)`` (the column softmax; the shift by the
  column maximum cancels, also in the gradient),
* ``Ā = R̄ · w`` with ``w = 1`` where ``A > 0``, ``1/2`` where ``A = 0`` and ``0``
  elsewhere (the tie rule of the engine's ``maximum``, JAX's),
* ``W̄_i = Σ_batch p_i Ā`` and ``p̄_i = Σ_jk Ā_jk W_ijk`` (eq. 8 is a matrix product).

Cotangents are summed back over the axes along which ``q`` and ``p`` were broadcast
against each other. The NumPy engine uses it (:func:`minimanc.vagn.step` calls it when
an argument is traced by :mod:`minimanc.autodiff`); JAX differentiates the plain code.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.autodiff import custom_vjp, unbroadcast

__all__ = ["fused_step", "step_plain"]


def step_plain(q: np.ndarray, p: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Eqs. 8–9 on plain NumPy arrays: ``q_t = T(p) q / Σ T(p) q``.

    The operations of :func:`minimanc.vagn.step` with ``xp = numpy``, in the same order
    (the same values, bit for bit).

    Parameters
    ----------
    q : array, shape (..., N)
        Previous distributions.
    p : array, shape (..., M)
        Predicates; broadcasts against ``q``'s batch shape.
    W : array, shape (M, N, N)
        Transition weights.

    Returns
    -------
    q_next : array, shape (..., N)
    """
    return _forward(q, p, W)[0]


def _forward(q, p, W):
    M, N = W.shape[0], W.shape[1]
    A = np.matmul(p, np.reshape(W, (M, N * N)))
    A = np.reshape(A, tuple(p.shape[:-1]) + (N, N))
    R = np.maximum(A, 0.0)
    E = np.exp(R - np.expand_dims(np.max(R, axis=-2), -2))
    T = E / np.expand_dims(np.sum(E, axis=-2), -2)
    u = np.sum(T * np.expand_dims(q, -2), axis=-1)
    s = np.expand_dims(np.sum(u, axis=-1), -1)
    return u / s, A, T, s


def _fwd(q, p, W):
    out, A, T, s = _forward(q, p, W)
    return out, (q, p, W, A, T, s, out)


def _bwd(res: tuple, g: np.ndarray) -> tuple:
    q, p, W, A, T, s, out = res
    M, N = W.shape[0], W.shape[1]
    g_u = (g - np.sum(g * out, axis=-1, keepdims=True)) / s  # (..., N)
    g_q = np.matmul(np.expand_dims(g_u, -2), T)[..., 0, :]  # Σ_i ū_i T_ij
    g_T = np.expand_dims(g_u, -1) * np.expand_dims(q, -2)  # ū_i q_j
    g_R = T * (g_T - np.sum(g_T * T, axis=-2, keepdims=True))
    pos = A > 0
    g_A = g_R * pos
    tie = A == 0
    if tie.any():
        g_A = g_A + (0.5 * g_R) * tie
    g_A = g_A.astype(g_R.dtype, copy=False)
    batch = g_A.shape[:-2]
    ga = np.reshape(g_A, batch + (N * N,))
    g_p = np.matmul(ga, np.reshape(W, (M, N * N)).T)  # (..., M)
    pb = np.broadcast_to(p, batch + (M,)).reshape(-1, M)
    g_W = np.matmul(pb.T, ga.reshape(-1, N * N)).reshape(M, N, N)
    return (_cast(unbroadcast(q, g_q), q), _cast(unbroadcast(p, g_p), p),
            _cast(g_W, W))


def _cast(g: Any, x: Any) -> Any:
    dtype = getattr(x, "dtype", None)
    if dtype is not None and dtype.kind == "f" and g.dtype != dtype:
        return g.astype(dtype)
    return g


fused_step = custom_vjp(step_plain)
"""``fused_step(q, p, W)``: :func:`step_plain` as one node of the NumPy engine's tape,
with the VJP of the module docstring (positional arguments, shapes as there)."""
fused_step.defvjp(_fwd, _bwd)
