"""Chapter 1 — ``minimanc.autodiff``: reverse-mode automatic differentiation from scratch.

* :mod:`minimanc.autodiff.core` — boxes, :func:`primitive`, :func:`defvjp`, the
  backward pass, :func:`grad` and :func:`value_and_grad` (JAX semantics, pytrees),
  :func:`scan` and :class:`custom_vjp`, gathered from one module per concept
  (``boxes``, ``primitives``, ``reverse``, ``pytrees``, ``api``, ``loops``, ``custom``);
* :mod:`minimanc.autodiff.numpy` — the NumPy-like namespace (``anp``, the ``xp``
  of ``engine("numpy")``), each primitive with its VJP beside it (``elementwise``,
  ``reductions``, ``arrays``; ``dispatch`` makes traced values behave like arrays);
* :mod:`minimanc.autodiff.check` — central-difference gradient checks;
* :mod:`minimanc.autodiff.graph` — :func:`computation_graph`, the traced graph of a
  function at a point with the cotangent on each edge (drawn by
  :func:`minimanc.viz.graph.plot_graph`);
* :mod:`minimanc.autodiff.nn` — neural-net primitives (activations, conv2d).

Converting a traced value to a plain number or array (``float(x)``, ``x.item()``,
``np.asarray(x)``, ``math.sin(x)``) raises :class:`TracerConversionError` instead
of dropping its gradient; :func:`stop_gradient` does it on purpose. NumPy's own
functions (``np.sum``, ``np.exp``, ``ndarray @ x``) dispatch to the primitives of
:mod:`minimanc.autodiff.numpy`, and those without one raise a ``TypeError``.

First-order derivatives only (no ``grad(grad(f))``): use the ``jax`` engine for
higher orders.
"""

from minimanc.autodiff import (
    dispatch,  # noqa: F401 - installs the operators of Box
    numpy,
)
from minimanc.autodiff.check import check_grads
from minimanc.autodiff.core import (
    Box,
    TracerConversionError,
    backward,
    custom_vjp,
    defvjp,
    defvjp_fwd,
    grad,
    primitive,
    scan,
    stop_gradient,
    through_max,
    toposort,
    tree_flatten,
    tree_unflatten,
    unbroadcast,
    value_and_grad,
)
from minimanc.autodiff.graph import Graph, computation_graph

__all__ = [
    "Box",
    "Graph",
    "TracerConversionError",
    "backward",
    "check_grads",
    "computation_graph",
    "custom_vjp",
    "defvjp",
    "defvjp_fwd",
    "grad",
    "numpy",
    "primitive",
    "scan",
    "stop_gradient",
    "through_max",
    "toposort",
    "tree_flatten",
    "tree_unflatten",
    "unbroadcast",
    "value_and_grad",
]
