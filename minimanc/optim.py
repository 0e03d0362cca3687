"""Chapter 2 — optimisers as pure functions on pytrees: SGD with momentum and Adam.

Algorithm 1 of the paper trains the controller by gradient descent on the
behaviour-cloning loss with learning rate γ. Following optax, an optimiser is
a pair of pure functions::

    state = adam_init(params)
    params, state = adam_update(grads, state, params, lr=1e-3)

``params``, ``grads`` and the state are pytrees (nested dicts / lists /
tuples of arrays, see :mod:`minimanc.tree`). The updates
use arithmetic only, so they run unchanged on NumPy arrays, on JAX arrays and
inside ``jax.jit``; float32 parameters stay float32 (the hyper-parameters are
Python floats, which never promote an array).
"""

from __future__ import annotations

from collections.abc import Callable
from numbers import Integral, Real
from typing import Any

import numpy as np

from minimanc.tree import map as tree_map

__all__ = [
    "sgd_init",
    "sgd_update",
    "adam_init",
    "adam_update",
]


def _zeros_like(xp: Any) -> Callable:
    return lambda p: xp.zeros_like(p)


def _check_positive(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, Real) or not value > 0:
        raise ValueError(f"{name} must be a positive number, got {name}={value!r}")


def _check_lr(lr: Any) -> None:
    """A positive number, or a scalar array (e.g. traced under ``jit``, unchecked there)."""
    if isinstance(lr, Real) and not isinstance(lr, bool):
        _check_positive("lr", lr)
    elif not (hasattr(lr, "dtype") and getattr(lr, "shape", None) == ()):
        raise ValueError(f"lr must be a positive number or a scalar array, got lr={lr!r}")
    elif isinstance(lr, np.ndarray) and not lr > 0:
        raise ValueError(f"lr must be positive, got lr={lr!r}")


def _check_unit(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, Real) or not 0 <= value < 1:
        raise ValueError(f"{name} must be in [0, 1), got {name}={value!r}")


def _check_state(state: Any, keys: tuple[str, ...], fn: str) -> None:
    if not isinstance(state, dict) or set(state) != set(keys):
        got = sorted(state) if isinstance(state, dict) else type(state).__name__
        raise ValueError(
            f"state must be the dict returned by {fn} with keys {list(keys)}, got state={got}"
        )


def _plain_scalar(v: Any) -> Any:
    """NumPy scalars/0-d arrays → Python float (so float32 arrays stay float32)."""
    return float(v) if isinstance(v, np.ndarray | np.generic) else v


# ---------------------------------------------------------------------------
# SGD with momentum
# ---------------------------------------------------------------------------
def sgd_init(params: Any, xp: Any = np) -> dict:
    """State of :func:`sgd_update`: ``{"velocity": zeros like params}``."""
    return {"velocity": tree_map(_zeros_like(xp), params)}


def sgd_update(grads: Any, state: dict, params: Any, lr: float = 1e-2, momentum: float = 0.9,
               nesterov: bool = False) -> tuple[Any, dict]:
    """One step of SGD with (heavy-ball or Nesterov) momentum, as optax.sgd:

    ``v ← momentum v + g``;  ``θ ← θ − lr v`` (Nesterov: ``θ ← θ − lr (g + momentum v)``).
    ``momentum=0`` is plain gradient descent ``θ ← θ − lr g``. Returns
    ``(new_params, new_state)``.
    """
    _check_positive("lr", lr)
    _check_unit("momentum", momentum)
    _check_state(state, ("velocity",), "sgd_init")
    velocity = tree_map(lambda v, g: momentum * v + g, state["velocity"], grads)
    if nesterov:
        new_params = tree_map(lambda p, g, v: p - lr * (g + momentum * v), params, grads,
                              velocity)
    else:
        new_params = tree_map(lambda p, v: p - lr * v, params, velocity)
    return new_params, {"velocity": velocity}


# ---------------------------------------------------------------------------
# Adam
# ---------------------------------------------------------------------------
def adam_init(params: Any, xp: Any = np) -> dict:
    """State of :func:`adam_update`: ``{"step": 0, "m": zeros, "v": zeros}`` (like params)."""
    zeros = _zeros_like(xp)
    return {"step": 0, "m": tree_map(zeros, params), "v": tree_map(zeros, params)}


def adam_update(grads: Any, state: dict, params: Any, lr: float = 1e-3, b1: float = 0.9,
                b2: float = 0.999, eps: float = 1e-8) -> tuple[Any, dict]:
    """One Adam step (Kingma & Ba 2015), with the same conventions as optax.adam:

    ``m ← b1 m + (1 − b1) g``, ``v ← b2 v + (1 − b2) g²``, ``t ← t + 1``,
    ``θ ← θ − lr m̂ / (sqrt(v̂) + eps)`` with the bias corrections
    ``m̂ = m / (1 − b1^t)``, ``v̂ = v / (1 − b2^t)``. Returns ``(new_params, new_state)``.
    ``lr`` may be a scalar array, so that a jitted training step takes it as an
    argument (one compilation serves every learning rate).
    """
    _check_lr(lr)
    _check_unit("b1", b1)
    _check_unit("b2", b2)
    _check_positive("eps", eps)
    _check_state(state, ("step", "m", "v"), "adam_init")
    step = state["step"]
    if isinstance(step, bool) or (isinstance(step, Real) and not isinstance(step, Integral)):
        raise ValueError(f"state['step'] must be an integer count, got step={step!r}")
    if isinstance(step, Integral) or (
        isinstance(step, np.ndarray) and step.ndim == 0 and np.issubdtype(step.dtype, np.integer)
    ):
        step = int(step)  # a plain Python int outside jit: exact, never promotes float32
    t = step + 1
    c1 = _plain_scalar(1 - b1 ** t)
    c2 = _plain_scalar(1 - b2 ** t)
    m = tree_map(lambda m_, g: b1 * m_ + (1 - b1) * g, state["m"], grads)
    v = tree_map(lambda v_, g: b2 * v_ + (1 - b2) * (g * g), state["v"], grads)
    new_params = tree_map(
        lambda p, m_, v_: p - lr * (m_ / c1) / ((v_ / c2) ** 0.5 + eps), params, m, v
    )
    return new_params, {"step": t, "m": m, "v": v}
