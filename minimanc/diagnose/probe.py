"""Chapter 12 — what a representation holds: a linear probe.

:func:`linear_probe` asks whether a representation (a model's backbone features of each
state, or its visual predicates of eq. 7) holds a quantity (the gap to the leader, say): a
ridge regression ``y ≈ [z, 1] w`` with ``z`` the features standardised on the training
states and ``w = (ZᵀZ + λI)⁻¹ Zᵀ y`` (intercept not penalised), scored by its coefficient
of determination ``R² = 1 − Σ(y − ŷ)² / Σ(y − ȳ)²`` on held-out states. A quantity the
features hold linearly has ``R²`` near 1; one they do not, near 0 (or below).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["linear_probe"]


def _matrix(name: str, x: Any) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    a = a.reshape(len(a), -1) if a.ndim >= 1 else a
    if a.ndim != 2 or len(a) == 0 or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a finite array with a leading axis of states; got "
                         f"shape {np.shape(x)}")
    return a


def linear_probe(z_train: Any, y_train: Any, z_test: Any, y_test: Any, ridge: float = 1.0
                 ) -> dict[str, np.ndarray]:
    """The ridge read-out of a representation, fitted on some states and scored on others.

    Parameters
    ----------
    z_train : array_like, shape (N, ...)
        The representation of the training states (flattened per state).
    y_train : array_like, shape (N, K)
        The quantities to read there.
    z_test : array_like, shape (M, ...)
        The representation of the held-out states.
    y_test : array_like, shape (M, K)
        The quantities there.
    ridge : float, optional (default: 1)
        λ, the penalty on the standardised features' weights.

    Returns
    -------
    dict of str to numpy.ndarray
        ``r2 (K,)`` and ``rmse (K,)`` on the held-out states and ``std (K,)`` of
        ``y_test``.

    Raises
    ------
    ValueError
        If an array is not finite, the arrays disagree in states or columns, or ``ridge``
        is negative.
    """
    Z, Zt = _matrix("z_train", z_train), _matrix("z_test", z_test)
    Y, Yt = _matrix("y_train", y_train), _matrix("y_test", y_test)
    if Z.shape[1] != Zt.shape[1] or Y.shape[1] != Yt.shape[1] or len(Z) != len(Y) \
            or len(Zt) != len(Yt):
        raise ValueError(f"z_train {Z.shape}, y_train {Y.shape}, z_test {Zt.shape} and y_test "
                         f"{Yt.shape} must agree in states and columns")
    if not (np.isfinite(ridge) and ridge >= 0):
        raise ValueError(f"ridge must be >= 0, got {ridge!r}")
    mu, sd = Z.mean(0), Z.std(0) + 1e-8
    A = np.hstack([(Z - mu) / sd, np.ones((len(Z), 1))])
    pen = np.full(A.shape[1], float(ridge))
    pen[-1] = 0.0
    w = np.linalg.solve(A.T @ A + np.diag(pen), A.T @ Y)
    pred = np.hstack([(Zt - mu) / sd, np.ones((len(Zt), 1))]) @ w
    res = ((Yt - pred) ** 2).sum(0)
    tot = ((Yt - Yt.mean(0)) ** 2).sum(0)
    return {"r2": 1.0 - res / np.where(tot > 0, tot, 1.0),
            "rmse": np.sqrt(res / len(Yt)), "std": Yt.std(0)}
