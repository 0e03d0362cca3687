"""Chapter 1 — ``minimanc.autodiff``: reverse-mode automatic differentiation from scratch.

* the engine's core, one module per concept (``boxes``, ``primitives``, ``reverse``,
  ``api``, ``loops``, ``custom``), toured below and gathered here: boxes,
  :func:`primitive`, :func:`defvjp`, the backward pass, :func:`grad` and
  :func:`value_and_grad` (JAX semantics, on the pytrees of :mod:`minimanc.tree`),
  :func:`scan` and :class:`custom_vjp`;
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

**The core, a tour.** The engine in one import; each concept lives in its own module:

* :class:`Box` (:mod:`~minimanc.autodiff.boxes`) — a traced value. While
  :func:`grad` runs your function, every array that depends on the inputs is a
  ``Box`` that remembers *which primitive* produced it and *from which parents*
  (a tuple, never a set: the order of the backward sums is fixed, so gradients
  are bit-identical run after run).
* :func:`primitive` (:mod:`~minimanc.autodiff.primitives`) — turns a plain-NumPy
  function into a traced one: when any positional argument is a ``Box`` the
  result is a ``Box`` linked to its parents.
* :func:`defvjp` / :func:`defvjp_fwd` — register the vector-Jacobian product
  (VJP) of a primitive. Given the cotangent ``g = ∂L/∂ans`` a VJP returns
  ``∂L/∂arg = gᵀ ∂ans/∂arg`` for one argument.
* :func:`backward` (:mod:`~minimanc.autodiff.reverse`) — sorts the graph
  topologically (iteratively, so a chain of 10,000 operations does not hit
  Python's recursion limit) and runs the VJPs from the output back to the
  inputs, summing the cotangents of values used more than once.
* :func:`grad` / :func:`value_and_grad` (:mod:`~minimanc.autodiff.api`) — JAX's API
  on pytrees (nested dicts, lists and tuples of arrays, :mod:`minimanc.tree`).
* :func:`scan` (:mod:`~minimanc.autodiff.loops`) — ``jax.lax.scan``, one tape node per loop;
  :func:`custom_vjp` (:mod:`~minimanc.autodiff.custom`) — ``jax.custom_vjp``, a function
  with a hand-written VJP.
* :func:`stop_gradient` — the plain value of a traced one, for the places where
  dropping the derivative is deliberate (logging a loss, a constant target).

A gradient is never dropped silently: turning a ``Box`` into a Python or NumPy
number or array (``float(x)``, ``x.item()``, ``np.asarray(x)``, ``math.sin(x)``,
``y[i] = x`` into a NumPy array) raises :class:`TracerConversionError` saying
what to write instead. ``bool(x)`` and comparisons stay allowed: the value is
concrete, so Python control flow (``if x > 0:``) picks a branch and the
gradient of that branch is exact, as under ``jax.grad`` without ``jit``.

The primitives themselves (``add``, ``matmul``, ``sum``, …), each with its VJP
beside it, live in :mod:`minimanc.autodiff.numpy`. The engine computes
first-order derivatives only: VJPs are plain NumPy, so ``grad(grad(f))`` is not
supported (it raises a clear error). The paper (``manc.tex``) trains every
model of section IV (eqs. 7–11) with gradients of a behaviour-cloning loss
(Algorithm 1); these modules compute them.
"""

from minimanc.autodiff import (
    dispatch,  # noqa: F401 - installs the operators of Box
    numpy,
)
from minimanc.autodiff.api import grad, value_and_grad
from minimanc.autodiff.boxes import Box, TracerConversionError, stop_gradient
from minimanc.autodiff.check import check_grads
from minimanc.autodiff.custom import custom_vjp
from minimanc.autodiff.graph import Graph, computation_graph
from minimanc.autodiff.loops import scan
from minimanc.autodiff.primitives import (
    defvjp,
    defvjp_fwd,
    primitive,
    through_max,
    unbroadcast,
)
from minimanc.autodiff.reverse import backward, parent_cotangents, toposort
from minimanc.tree import tree_flatten, tree_unflatten

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
    "parent_cotangents",
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
