"""Chapter 1 — ``minimanc.autodiff``: reverse-mode automatic differentiation from scratch.

* :mod:`minimanc.autodiff.core` — boxes, :func:`primitive`, :func:`defvjp`, the
  backward pass, :func:`grad` and :func:`value_and_grad` (JAX semantics, pytrees);
* :mod:`minimanc.autodiff.numpy` — the NumPy-like namespace (``anp``, the ``xp``
  of ``engine("numpy")``), each primitive with its VJP beside it;
* :mod:`minimanc.autodiff.check` — central-difference gradient checks;
* :mod:`minimanc.autodiff.nn` — neural-net primitives (activations, conv2d).

First-order derivatives only (no ``grad(grad(f))``): use the ``jax`` engine for
higher orders.
"""

from minimanc.autodiff import numpy
from minimanc.autodiff.check import check_grads
from minimanc.autodiff.core import (
    Box,
    backward,
    defvjp,
    defvjp_fwd,
    grad,
    primitive,
    toposort,
    tree_flatten,
    tree_unflatten,
    unbroadcast,
    value_and_grad,
)

__all__ = [
    "Box",
    "backward",
    "check_grads",
    "defvjp",
    "defvjp_fwd",
    "grad",
    "numpy",
    "primitive",
    "toposort",
    "tree_flatten",
    "tree_unflatten",
    "unbroadcast",
    "value_and_grad",
]
