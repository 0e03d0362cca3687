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

Both passes hold the batch axis last (matrices of shape ``(N, N, B)``), so each sum and
maximum over the q-states is a reduction over an outer axis. Cotangents are summed back
over the axes along which ``q`` and ``p`` were broadcast against each other.

The NumPy engine uses it (:func:`minimanc.vagn.step` calls it when an argument is traced
by :mod:`minimanc.autodiff`); JAX differentiates the plain code.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.autodiff import custom_vjp, through_max, unbroadcast

__all__ = ["fused_step", "step_plain"]


def step_plain(q: np.ndarray, p: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Eqs. 8–9 on plain NumPy arrays: ``q_t = T(p) q / Σ T(p) q``.

    The arithmetic of :func:`minimanc.vagn.step` (equal to it up to float rounding:
    the sums over the q-states may be taken in another order).

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
    return _forward(np.asarray(q), np.asarray(p), np.asarray(W))[0]


def _flat(q, p, N, M):
    """``q`` and ``p`` broadcast to one batch and flattened: ``(B, N)``, ``(B, M)``."""
    batch = np.broadcast_shapes(q.shape[:-1], p.shape[:-1])
    if q.shape[:-1] != batch:
        q = np.broadcast_to(q, batch + (N,))
    if p.shape[:-1] != batch:
        p = np.broadcast_to(p, batch + (M,))
    return q.reshape(-1, N), p.reshape(-1, M), batch


def _forward(q, p, W):
    """The update with the batch axis last: ``(N, N, B)`` matrices, so every sum and
    maximum over the q-states runs over an outer axis (long inner loops on small ``N``)."""
    M, N = W.shape[0], W.shape[1]
    qf, pf, batch = _flat(q, p, N, M)
    A = np.matmul(np.reshape(W, (M, N * N)).T, pf.T).reshape(N, N, -1)  # eq. 8: A[i, j, b]
    R = np.maximum(A, 0.0)
    E = np.exp(R - R.max(axis=0))  # shifted by each column's maximum
    T = E / E.sum(axis=0)  # column softmax of eq. 9
    qt = qf.T  # (N, B)
    u = (T * qt).sum(axis=1)  # u_i = Σ_j T_ij q_j
    s = u.sum(axis=0)
    out = u / s
    q_next = np.ascontiguousarray(out.T).reshape(batch + (N,))
    return q_next, (qf, pf, batch, A, T, qt, s, out)


def _fwd(q, p, W):
    q_next, res = _forward(q, p, W)
    return q_next, (q, p, W) + res


def _bwd(res: tuple, g: np.ndarray) -> tuple:
    q, p, W, qf, pf, batch, A, T, qt, s, out = res
    M, N = W.shape[0], W.shape[1]
    if g.shape != batch + (N,):
        g = np.broadcast_to(g, batch + (N,))
    gt = g.reshape(-1, N).T  # (N, B)
    g_u = (gt - (gt * out).sum(axis=0)) / s
    g_q = (T * g_u[:, None, :]).sum(axis=0)  # Σ_i ū_i T_ij
    g_T = g_u[:, None, :] * qt  # ū_i q_j
    g_R = T * (g_T - (g_T * T).sum(axis=0))
    g_A = through_max(g_R, A, 0.0).reshape(N * N, -1)  # the ReLU; (N², B)
    Wf = np.reshape(W, (M, N * N))
    g_p = np.matmul(Wf, g_A).T.reshape(batch + (M,))
    g_W = np.matmul(g_A, pf).T.reshape(M, N, N)
    g_q = g_q.T.reshape(batch + (N,))
    return (_cast(unbroadcast(q, g_q), q), _cast(unbroadcast(p, g_p), p), _cast(g_W, W))


def _cast(g: Any, x: Any) -> Any:
    dtype = getattr(x, "dtype", None)
    if dtype is not None and dtype.kind == "f" and g.dtype != dtype:
        return g.astype(dtype)
    return g


fused_step = custom_vjp(step_plain)
"""``fused_step(q, p, W)``: :func:`step_plain` as one node of the NumPy engine's tape,
with the VJP of the module docstring (positional arguments, shapes as there)."""
fused_step.defvjp(_fwd, _bwd)
