"""Chapter 5 — the vAGN soft automaton: eqs. 8–9, one step, a rollout, what it shows.

The planner of the paper (section IV-B) is a probabilistic automaton with ``N``
hidden states ("q-states").  Its state is a distribution ``q_t`` over the
q-states and its transitions are *generated* from the visual predicates
``p ∈ R^M`` produced by the predicate extractor of chapter 6 (eq. 7):

* eq. 8:  ``W^p = Σ_i p_i W_i``  (``W`` has shape ``(M, N, N)``; :func:`combined_weights`)
* eq. 9:  ``q_t = colsoftmax(ReLU(W^p)) · q_{t-1}``  (:func:`transition_matrix`,
  :func:`step`, :func:`rollout`)

Conventions used throughout this module
---------------------------------------
* ``T[i, j] = P(q_t = i | q_{t-1} = j)``: column ``j`` holds the transitions
  *out of* state ``j`` and sums to one ("softmax along column"), and one step
  is the matrix–vector product ``q_t = T q_{t-1}``.
* Leading axes are batch axes: ``p`` of shape ``(..., M)`` gives ``T`` of
  shape ``(..., N, N)`` and ``q`` of shape ``(..., N)``.
* Sequences are time-major: ``ps`` of shape ``(T, ..., M)``.

Every differentiable function takes the array namespace ``xp`` (plain NumPy by
default, ``engine("numpy").xp`` or ``engine("jax").xp`` for gradients) and uses
only the operations listed in CONTRIBUTING.md.  Input checks run only on
concrete NumPy inputs (never on traced values); distributions and stochastic
matrices are checked with a tolerance that fits their own dtype
(:func:`minimanc.checks.float_tolerance`), and the distributions this module
produces are renormalised rather than trusted to stay on the simplex.

A property worth knowing (the tutorial shows it): ReLU sets negative entries
of ``W^p`` to zero, but a zero still becomes ``e^0 = 1`` inside the softmax, so
**no transition ever has probability exactly zero**.  The smallest possible
entry of a column is ``1 / (1 + Σ_{r≠i} e^{R_rj})`` with ``R = ReLU(W^p)``;
the automaton graph is always complete and "impossible" transitions can only
be read off by thresholding (see :func:`minimanc.viz.automaton.plot_automaton`'s ``min_prob``).  (In
float64 an entry underflows to 0.0 only when its column's logits differ by
more than ``−ln`` of the smallest subnormal, ≈ 745.)

The figures (``plot_automaton``, ``plot_q_heatmap``) are in :mod:`minimanc.viz.automaton`;
this module imports no plotting code.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from minimanc.checks import (
    check_distribution,
    check_int,
    check_real,
    check_stochastic_columns,
    is_concrete,
)
from minimanc.engine import fused_kernel
from minimanc.vagn.fused import fused_step

__all__ = [
    "check_weights",
    "check_state",
    "init_vagn",
    "combined_weights",
    "transition_matrix",
    "step",
    "rollout",
    "uniform_state",
    "random_state",
    "stationary_distribution",
    "most_likely_states",
    "most_likely_path",
    "min_transition_probability",
]

# ---------------------------------------------------------------------------
# input checks (concrete NumPy values only)
# ---------------------------------------------------------------------------
def check_weights(W: Any) -> tuple[int, int]:
    """Validate transition weights ``W`` (eq. 8) and return ``(M, N)``.

    The shape is checked on every value (also traced ones); concrete ``W`` must
    also be finite.  Shared with :mod:`minimanc.cam`.

    Parameters
    ----------
    W : array-like, shape (M, N, N)
        One ``N × N`` weight matrix ``W_i`` per predicate.

    Returns
    -------
    M : int
        Number of predicates.
    N : int
        Number of q-states.

    Raises
    ------
    TypeError
        If concrete ``W`` is not real numbers.
    ValueError
        If ``W`` is not of shape ``(M, N, N)``, or concrete ``W`` is not finite.
    """
    shape = tuple(np.shape(W)) if is_concrete(W) else tuple(W.shape)
    if len(shape) != 3 or shape[1] != shape[2]:
        raise ValueError(f"W must have shape (M, N, N); got W with shape {shape}")
    if is_concrete(W) and not np.all(np.isfinite(check_real("W", W))):
        raise ValueError("W must be finite; got W with non-finite entries")
    return shape[0], shape[1]


def check_state(q: Any, n_states: int, name: str = "q") -> None:
    """Validate ``q``: distributions over the ``N`` q-states along the last axis.

    The shape is checked on every value; concrete ``q`` must also be finite,
    non-negative and sum to one within ``float_tolerance(value_dtype(q), N)``
    (:func:`minimanc.checks.float_tolerance`: ``TOLERANCE_FACTOR · eps · N`` of
    ``q``'s own precision).  See :func:`minimanc.checks.check_distribution`.

    Parameters
    ----------
    q : array-like, shape (..., N)
        Distributions to check.
    n_states : int
        Number of q-states ``N``.
    name : str, optional (default: "q")
        Name of the argument in error messages.

    Raises
    ------
    TypeError
        If concrete ``q`` is not real numbers.
    ValueError
        If the last axis is not ``N``, or concrete ``q`` is not a distribution.
    """
    check_distribution(name, q, n_states, what="q-states")


def _check_p(p: Any, M: int) -> None:
    shape = tuple(np.shape(p)) if is_concrete(p) else tuple(p.shape)
    if len(shape) == 0 or shape[-1] != M:
        raise ValueError(
            f"p must have shape (..., M) with M = {M} predicates (W.shape[0]); "
            f"got p with shape {shape}"
        )
    if is_concrete(p) and not np.all(np.isfinite(check_real("p", p))):
        raise ValueError(f"p must be finite; got p = {np.asarray(p)!r}")


def _check_T(T: Any, name: str = "T") -> np.ndarray:
    """Concrete column-stochastic ``T`` as float64 (tolerance of its own precision)."""
    return check_stochastic_columns(name, T)


def _renormalise(q: Any, xp: Any) -> Any:
    """``q / Σ q`` along the last axis, in the array namespace ``xp``."""
    return q / xp.expand_dims(xp.sum(q, axis=-1), -1)


# ---------------------------------------------------------------------------
# parameters and initial states
# ---------------------------------------------------------------------------
def init_vagn(
    rng: np.random.Generator,
    n_predicates: int,
    n_states: int,
    scale: float = 0.5,
    mean: float = 0.0,
) -> np.ndarray:
    """Transition weights ``W`` of eq. 8, entries drawn from ``N(mean, scale²)``.

    With ``mean = 0`` about half of every ``W^p`` starts in ReLU's dead zone,
    where it receives no gradient.  When the predicates are non-negative a small
    positive ``mean`` (e.g. 0.5 with ``scale`` 0.1) starts every entry active and
    lets training decide which transitions to switch off; chapter 5's tutorial
    shows the difference.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    n_predicates : int
        Number of predicates ``M`` ≥ 1.
    n_states : int
        Number of q-states ``N`` ≥ 1.
    scale : float, optional (default: 0.5)
        Standard deviation of the entries, ≥ 0.
    mean : float, optional (default: 0.0)
        Mean of the entries.

    Returns
    -------
    W : array, shape (M, N, N)
        Transition weights, float64.

    Raises
    ------
    ValueError
        If ``rng`` is not a ``numpy.random.Generator``, ``n_predicates`` or
        ``n_states`` is not an integer ≥ 1, ``scale`` is negative or not finite,
        or ``mean`` is not finite.
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator; got rng = {rng!r}")
    M = check_int("n_predicates", n_predicates, 1)
    N = check_int("n_states", n_states, 1)
    if not np.isfinite(scale) or scale < 0:
        raise ValueError(f"scale must be finite and >= 0; got scale = {scale!r}")
    if not np.isfinite(mean):
        raise ValueError(f"mean must be finite; got mean = {mean!r}")
    return mean + scale * rng.standard_normal((M, N, N))


def uniform_state(n_states: int) -> np.ndarray:
    """Algorithm 1's ``UniformInit()``: ``q' = (1/N, …, 1/N)``.

    Parameters
    ----------
    n_states : int
        Number of q-states ``N`` ≥ 1.

    Returns
    -------
    q : array, shape (N,)
        The uniform distribution.

    Raises
    ------
    ValueError
        If ``n_states`` is not an integer ≥ 1.
    """
    n_states = check_int("n_states", n_states, 1)
    return np.full(n_states, 1.0 / n_states)


def random_state(
    rng: np.random.Generator, n_states: int, size: int | tuple[int, ...] | None = None
) -> np.ndarray:
    """Algorithm 1's ``RandomInit()``: ``q'`` uniform on the simplex (a flat Dirichlet).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    n_states : int
        Number of q-states ``N`` ≥ 1.
    size : int or tuple of int, optional (default: None)
        Batch shape; ``None`` draws one distribution.

    Returns
    -------
    q : array, shape (*size, N)
        Distributions over the q-states.

    Raises
    ------
    ValueError
        If ``rng`` is not a ``numpy.random.Generator`` or ``n_states`` is not an
        integer ≥ 1.
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator; got rng = {rng!r}")
    n_states = check_int("n_states", n_states, 1)
    return rng.dirichlet(np.ones(n_states), size=size)


# ---------------------------------------------------------------------------
# the model (eqs. 8-9)
# ---------------------------------------------------------------------------
def combined_weights(p: Any, W: Any, xp: Any = np) -> Any:
    """Eq. 8: the predicate-weighted sum ``W^p = Σ_i p_i W_i``.

    Parameters
    ----------
    p : array-like, shape (..., M)
        Predicates.
    W : array-like, shape (M, N, N)
        Transition weights.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    Wp : array, shape (..., N, N)
        Combined weights, before the ReLU and the softmax of eq. 9.

    Raises
    ------
    TypeError
        If concrete ``p`` or ``W`` is not real numbers.
    ValueError
        If a shape is wrong (``p``'s last axis must be ``M = W.shape[0]``) or a
        concrete value is not finite.
    """
    M, N = check_weights(W)
    _check_p(p, M)
    p = xp.asarray(p)
    W = xp.asarray(W)
    flat = xp.matmul(p, xp.reshape(W, (M, N * N)))  # (..., N*N)
    return xp.reshape(flat, tuple(p.shape[:-1]) + (N, N))


def transition_matrix(p: Any, W: Any, xp: Any = np) -> Any:
    """Eqs. 8–9: ``T = colsoftmax(ReLU(Σ_i p_i W_i))``.

    Every column sums to one: ``T[..., i, j] = P(next = i | current = j)``.  The
    softmax subtracts the column maximum first, so it never overflows (the shift
    cancels, also in the gradient).

    Parameters
    ----------
    p : array-like, shape (..., M)
        Predicates.
    W : array-like, shape (M, N, N)
        Transition weights.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    T : array, shape (..., N, N)
        Column-stochastic transition matrices with strictly positive entries.

    Raises
    ------
    TypeError
        If concrete ``p`` or ``W`` is not real numbers.
    ValueError
        If a shape is wrong or a concrete value is not finite.
    """
    A = combined_weights(p, W, xp=xp)  # eq. 8
    R = xp.maximum(A, 0.0)  # ReLU
    shifted = R - xp.expand_dims(xp.max(R, axis=-2), -2)
    E = xp.exp(shifted)
    return E / xp.expand_dims(xp.sum(E, axis=-2), -2)  # softmax along each column


def step(q: Any, p: Any, W: Any, xp: Any = np) -> Any:
    """Eq. 9: one vAGN update ``q_t = T(p) q_{t-1}``, renormalised.

    The result is divided by its sum.  In exact arithmetic this is the identity
    (every column of ``T`` sums to one, so ``Σ q_t = Σ q_{t-1} = 1``) and it
    changes no gradient with respect to ``p`` or ``W``; in floating point it
    removes the rounding drift of the sum, so ``q`` fed back step after step
    stays a distribution to the precision of its dtype.  Traced by the NumPy
    engine the whole update is one tape node (:data:`minimanc.vagn.fused.fused_step`).

    Parameters
    ----------
    q : array-like, shape (..., N)
        Previous distributions ``q_{t-1}`` (checked with :func:`check_state`).
    p : array-like, shape (..., M)
        Predicates; the batch shapes of ``q`` and ``p`` broadcast.
    W : array-like, shape (M, N, N)
        Transition weights.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    q_next : array, shape (..., N)
        Distributions ``q_t``.

    Raises
    ------
    TypeError
        If a concrete argument is not real numbers.
    ValueError
        If a shape is wrong, a concrete value is not finite, or concrete ``q``
        is not a distribution.
    """
    M, N = check_weights(W)
    check_state(q, N)
    if fused_kernel(xp, q, p, W) is not None:
        _check_p(p, M)  # traced by the NumPy engine: one tape node (minimanc.vagn.fused)
        return fused_step(xp.asarray(q), xp.asarray(p), xp.asarray(W))
    T = transition_matrix(p, W, xp=xp)
    q = xp.asarray(q)
    return _renormalise(xp.sum(T * xp.expand_dims(q, -2), axis=-1), xp)


def rollout(q0: Any, ps: Any, W: Any, xp: Any = np) -> Any:
    """Run eq. 9 over a predicate sequence (time-major).

    Each step is renormalised as in :func:`step`.

    Parameters
    ----------
    q0 : array-like, shape (..., N)
        Initial distributions.
    ps : array-like, shape (T, ..., M)
        Predicates of each step.
    W : array-like, shape (M, N, N)
        Transition weights.
    xp : module, optional (default: numpy)
        Array namespace: ``numpy``, or an engine's ``xp`` to differentiate.

    Returns
    -------
    qs : array, shape (T + 1, ..., N)
        ``qs[0]`` is ``q0`` (broadcast to the batch shape), ``qs[t]`` the
        distribution after consuming ``ps[t - 1]``.

    Raises
    ------
    TypeError
        If a concrete argument is not real numbers.
    ValueError
        If ``ps`` is not of shape ``(T, ..., M)``, another shape is wrong, a
        concrete value is not finite, or ``q0`` is not a distribution.
    """
    M, N = check_weights(W)
    check_state(q0, N, name="q0")
    shape = tuple(np.shape(ps)) if is_concrete(ps) else tuple(ps.shape)
    if len(shape) < 2 or shape[-1] != M:
        raise ValueError(
            f"ps must have shape (T, ..., M) with M = {M}; got ps with shape {shape}"
        )
    _check_p(ps, M)
    ps = xp.asarray(ps)
    q = xp.asarray(q0)
    qs = [q]
    for t in range(shape[0]):
        T = transition_matrix(ps[t], W, xp=xp)
        q = _renormalise(xp.sum(T * xp.expand_dims(q, -2), axis=-1), xp)
        qs.append(q)
    if len(qs) > 1:  # broadcast q0 against the batch shape of the sequence
        qs[0] = qs[0] + xp.zeros_like(qs[1])
    return xp.stack(qs, axis=0)


# ---------------------------------------------------------------------------
# analysis (plain NumPy, no gradients)
# ---------------------------------------------------------------------------
def min_transition_probability(p: Any, W: Any) -> float:
    """The smallest entry of ``T(p)``: always > 0, since a ReLU zero becomes ``e^0 = 1``.

    Parameters
    ----------
    p : array-like, shape (..., M)
        Predicates.
    W : array-like, shape (M, N, N)
        Transition weights.

    Returns
    -------
    p_min : float
        ``min T(p)`` over every batch entry, row and column.

    Raises
    ------
    ValueError
        If a shape is wrong or a value is not finite.
    """
    return float(np.min(transition_matrix(np.asarray(p, float), np.asarray(W, float))))


def stationary_distribution(T: Any) -> np.ndarray:
    """The distribution ``π`` with ``T π = π`` for a column-stochastic ``T``.

    vAGN matrices have strictly positive entries, so by Perron–Frobenius ``π``
    is unique, strictly positive, and ``T^k q → π`` for every start ``q``: it is
    what the automaton settles to while the predicates stay constant.  Solved as
    the least-squares system ``[T − I; 1ᵀ] π = [0; 1]``.

    Parameters
    ----------
    T : array-like, shape (N, N)
        Column-stochastic transition matrix (e.g. from :func:`transition_matrix`).

    Returns
    -------
    pi : array, shape (N,)
        The stationary distribution.

    Raises
    ------
    TypeError
        If ``T`` is not real numbers.
    ValueError
        If ``T`` is not of shape ``(N, N)``, has NaN or ±inf entries, or is not
        column-stochastic (checked before any linear algebra runs).
    """
    T = _check_T(T)
    if T.ndim != 2:
        raise ValueError(f"T must have shape (N, N); got T with shape {T.shape}")
    N = T.shape[0]
    A = np.vstack([T - np.eye(N), np.ones((1, N))])
    b = np.zeros(N + 1)
    b[-1] = 1.0
    pi, *_ = np.linalg.lstsq(A, b, rcond=None)
    pi = np.clip(pi, 0.0, None)
    return pi / pi.sum()


def most_likely_states(qs: Any) -> np.ndarray:
    """Per-step most probable q-state: ``argmax_i q_t[i]``.

    Parameters
    ----------
    qs : array-like, shape (..., N)
        Distributions over the q-states (e.g. from :func:`rollout`).

    Returns
    -------
    states : array of int, shape (...)
        Index of the most probable q-state of each distribution.

    Raises
    ------
    ValueError
        If ``qs`` is a scalar.
    """
    qs = np.asarray(qs, dtype=float)
    if qs.ndim < 1:
        raise ValueError(f"qs must have shape (..., N); got qs with shape {qs.shape}")
    return np.argmax(qs, axis=-1)


def most_likely_path(q0: Any, Ts: Any) -> tuple[np.ndarray, float]:
    """Viterbi: the single most probable state *sequence* ``s_0 … s_T``.

    Maximises ``log q0[s_0] + Σ_t log Ts[t-1][s_t, s_{t-1}]`` over paths.  The
    per-step argmax of the marginals (:func:`most_likely_states`) need not be a
    likely path — compare both.

    Parameters
    ----------
    q0 : array-like, shape (N,)
        Initial distribution.
    Ts : array-like, shape (T, N, N)
        Column-stochastic transition matrices, e.g. ``transition_matrix(ps, W)``.

    Returns
    -------
    path : array of int, shape (T + 1,)
        The most probable q-state at each time.
    logp : float
        Its log probability.

    Raises
    ------
    TypeError
        If ``q0`` or ``Ts`` is not real numbers.
    ValueError
        If ``Ts`` is not of shape ``(T, N, N)``, not finite or not
        column-stochastic, or ``q0`` is not a distribution of shape ``(N,)`` (so
        a NaN never yields a path with ``log p = nan``).
    """
    Ts = _check_T(Ts, name="Ts")
    if Ts.ndim != 3:
        raise ValueError(f"Ts must have shape (T, N, N); got Ts with shape {Ts.shape}")
    N = Ts.shape[-1]
    check_state(q0, N, name="q0")
    q0 = np.asarray(q0, dtype=float)
    if q0.ndim != 1:
        raise ValueError(f"q0 must have shape (N,); got q0 with shape {q0.shape}")
    with np.errstate(divide="ignore"):
        delta = np.log(q0)
        logT = np.log(Ts)
    back = np.zeros((Ts.shape[0], N), dtype=int)
    for t in range(Ts.shape[0]):
        scores = logT[t] + delta[None, :]  # scores[i, j]: arrive in i from j
        back[t] = np.argmax(scores, axis=1)
        delta = scores[np.arange(N), back[t]]
    path = [int(np.argmax(delta))]
    logp = float(delta[path[0]])
    for t in range(Ts.shape[0] - 1, -1, -1):
        path.append(int(back[t, path[-1]]))
    return np.array(path[::-1]), logp
