"""Chapter 1 — the core of a from-scratch reverse-mode autodiff engine.

Everything the engine needs fits in this file:

* :class:`Box` — a traced value. While :func:`grad` runs your function, every
  array that depends on the inputs is a ``Box`` that remembers *which primitive*
  produced it and *from which parents* (a tuple, never a set: the order of the
  backward sums is fixed, so gradients are bit-identical run after run).
* :func:`primitive` — turns a plain-NumPy function into a traced one: when any
  positional argument is a ``Box`` the result is a ``Box`` linked to its parents.
* :func:`defvjp` / :func:`defvjp_fwd` — register the vector-Jacobian product
  (VJP) of a primitive. Given the cotangent ``g = ∂L/∂ans`` a VJP returns
  ``∂L/∂arg = gᵀ ∂ans/∂arg`` for one argument.
* :func:`backward` — sorts the graph topologically (iteratively, so a chain of
  10,000 operations does not hit Python's recursion limit) and runs the VJPs
  from the output back to the inputs, summing the cotangents of values used
  more than once.
* :func:`grad` / :func:`value_and_grad` — JAX's API on pytrees (nested dicts,
  lists and tuples of arrays).
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
(Algorithm 1); this file is what computes them.
"""

from __future__ import annotations

import functools
import numbers
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

__all__ = [
    "Box",
    "TracerConversionError",
    "stop_gradient",
    "primitive",
    "defvjp",
    "defvjp_fwd",
    "unbroadcast",
    "backward",
    "parent_cotangents",
    "toposort",
    "grad",
    "value_and_grad",
    "tree_flatten",
    "tree_unflatten",
    "scan",
]

# The tapes of the scan steps being traced, innermost last: {id(box): box} of the boxes
# made during the step (see :func:`scan`).
_FRAMES: list[dict[int, Box]] = []
# How many calls of value_and_grad are running: scan traces its steps only inside one.
_ACTIVE = [0]


# ---------------------------------------------------------------------------
# Boxes: traced values and the graph they form
# ---------------------------------------------------------------------------
class TracerConversionError(TypeError):
    """A traced value was turned into a plain number or array, which would lose its gradient."""


def _describe(box: Box) -> str:
    value = box._value
    return f"a traced value (Box of shape {np.shape(value)}, dtype {np.result_type(value)})"


_VALUE_HINT = (
    "to use the value without its derivative on purpose (logging, a constant), write "
    "minimanc.autodiff.stop_gradient(x) or x.value"
)


def _conversion_error(box: Box, operation: str, instead: str) -> TracerConversionError:
    return TracerConversionError(
        f"{operation} on {_describe(box)} inside a function being differentiated would lose "
        f"its gradient. Instead: {instead}; {_VALUE_HINT}."
    )


_FLOAT_FIX = (
    "keep x traced: math.sin(x), math.exp(x) ... -> minimanc.autodiff.numpy.sin(x), "
    "minimanc.autodiff.numpy.exp(x) ...; build an array from traced pieces with "
    "minimanc.autodiff.numpy.stack / concatenate / where, not by assignment into a NumPy array"
)


class Box:
    """A traced array: its value plus how it was computed.

    ``parents`` is a tuple of ``(argnum, parent_box)``: the positional argument
    ``argnum`` of ``prim`` was the traced value ``parent_box``. Leaves (the
    inputs of :func:`grad`) have no parents. Operators (``+``, ``@``, ``x[i]``,
    ``.T`` …) and NumPy dispatch (``np.sum(x)``, ``ndarray * x``) are attached by
    :mod:`minimanc.autodiff.numpy`. Conversions that would drop the derivative
    (``float``, ``int``, ``complex``, ``.item()``, ``.tolist()``, ``np.asarray``)
    raise :class:`TracerConversionError`; ``bool(x)`` (control flow on the
    concrete value), ``format(x, ".3f")`` and ``repr(x)`` are allowed.
    """

    __slots__ = ("_value", "_parents", "_prim", "_args", "_kwargs", "_res")
    __array_priority__ = 1000

    def __init__(self, value, parents=(), prim=None, args=(), kwargs=None, res=None):
        self._value = value
        self._parents = parents
        self._prim = prim
        self._args = args
        self._kwargs = kwargs or {}
        self._res = res

    @property
    def value(self) -> np.ndarray:
        """The plain NumPy value inside the box (its derivative is not tracked)."""
        return self._value

    @property
    def parents(self) -> tuple:
        """``(argnum, parent_box)`` for each traced argument of the primitive that made
        this box; empty for a leaf (an input of :func:`grad`)."""
        return tuple(self._parents)

    @property
    def primitive_name(self) -> str | None:
        """The name of the primitive that made this box (``None`` for a leaf)."""
        return None if self._prim is None else _name(self._prim)

    def __repr__(self) -> str:
        return f"Box({self._value!r})"

    def __format__(self, spec: str) -> str:
        return format(self._value, spec)

    def __bool__(self) -> bool:
        return bool(self._value)

    def __float__(self) -> float:
        raise _conversion_error(
            self, "float(x) (also math.sin(x) ... or y[i] = x into a NumPy array)", _FLOAT_FIX
        )

    def __complex__(self) -> complex:
        raise _conversion_error(self, "complex(x)", _FLOAT_FIX)

    def __int__(self) -> int:
        raise _conversion_error(
            self, "int(x)",
            "a piecewise-constant function has derivative 0: say so with "
            "int(minimanc.autodiff.stop_gradient(x)), or keep x traced and use "
            "minimanc.autodiff.numpy.floor(x)",
        )

    def item(self, *args):
        raise _conversion_error(
            self, "x.item()",
            "keep x as a 0-d traced array (x * 2, minimanc.autodiff.numpy.sin(x) work as "
            "with a float)",
        )

    def tolist(self):
        raise _conversion_error(
            self, "x.tolist()",
            "index x[i] or iterate `for v in x` (each element stays traced)",
        )

    def __array__(self, dtype=None, copy=None):
        raise _conversion_error(
            self, "np.asarray(x), np.array(x), np.float64(x) or y[i] = x into a NumPy array",
            "minimanc.autodiff.numpy.asarray(x) and x.astype(np.float64) stay traced; build an "
            "array from traced pieces with minimanc.autodiff.numpy.stack / concatenate / where "
            "(never by assignment into a NumPy array)",
        )


def stop_gradient(tree):
    """The plain NumPy values of ``tree`` (a traced value or a pytree of them).

    Like ``jax.lax.stop_gradient``: what comes out is a constant to :func:`grad`.
    Use it where dropping the derivative is deliberate (logging a loss inside a
    traced function, a fixed target); plain values pass through unchanged.
    """
    if isinstance(tree, Box):
        return tree._value
    if isinstance(tree, dict | list | tuple):
        return _strip_boxes(tree)
    return tree


def _unbox(x):
    return x._value if isinstance(x, Box) else x


def _name(prim) -> str:
    return getattr(prim, "__name__", repr(prim))


# ---------------------------------------------------------------------------
# Primitives and their VJPs
# ---------------------------------------------------------------------------
def primitive(fun: Callable) -> Callable:
    """Return a traced version of the plain-NumPy function ``fun``.

    With no :class:`Box` among the positional arguments the result is simply
    ``fun(*args, **kwargs)``. Otherwise ``fun`` runs on the unboxed values and
    the result is boxed, remembering the primitive, its raw arguments and the
    boxed parents. Keyword arguments are never differentiated.
    A ``ValueError`` raised by ``fun`` is re-raised prefixed with its name, so
    shape errors say which operation failed.
    """
    name = fun.__name__

    @functools.wraps(fun)
    def traced(*args, **kwargs):
        parents = [(i, a) for i, a in enumerate(args) if isinstance(a, Box)]
        try:
            if not parents:
                return fun(*args, **kwargs)
            for key, val in kwargs.items():
                if isinstance(val, Box):
                    raise TypeError(
                        f"{name}: keyword argument {key!r} is traced; pass differentiable "
                        "values positionally"
                    )
            raw = [a._value if isinstance(a, Box) else a for a in args]
            if traced.fwd is not None:  # custom (fwd, bwd) pair, see defvjp_fwd
                ans, res = traced.fwd(*raw, **kwargs)
                box = Box(ans, tuple(parents), traced, (), None, res)
            elif traced.vjps is None:
                raise NotImplementedError(
                    f"VJP of primitive '{name}' is not defined: register one with "
                    f"defvjp({name}, ...) or defvjp_fwd({name}, fwd, bwd)"
                )
            else:
                box = Box(fun(*raw, **kwargs), tuple(parents), traced, raw, kwargs)
            if _FRAMES:  # inside a scan step: the box belongs to that step's tape
                _FRAMES[-1][id(box)] = box
            return box
        except ValueError as err:
            msg = str(err)
            if msg.startswith(f"{name}:"):
                raise
            raise ValueError(f"{name}: {msg}") from err

    traced.fun = fun
    traced.vjps = None
    traced.fwd = None
    traced.bwd = None
    return traced


def defvjp(prim: Callable, *vjps: Callable | None) -> None:
    """Register one VJP per positional argument of ``prim``.

    Each ``vjp(g, ans, *args, **kwargs)`` receives the output cotangent ``g``,
    the forward result ``ans`` and the raw (unboxed) arguments, and returns the
    cotangent of *its* argument (same shape as that argument). ``None`` marks
    a non-differentiable argument (an index, an axis …).

    Example (HIPS-autograd style)::

        defvjp(multiply, lambda g, ans, x, y: unbroadcast(x, g * y),
                         lambda g, ans, x, y: unbroadcast(y, g * x))
    """
    if not hasattr(prim, "fun"):
        raise TypeError(f"defvjp: {_name(prim)} is not a primitive (wrap it with @primitive)")
    prim.vjps = tuple(vjps)


def defvjp_fwd(prim: Callable, fwd: Callable, bwd: Callable) -> None:
    """Register a JAX ``custom_vjp``-style pair for an expensive primitive.

    When traced, ``fwd(*args, **kwargs) -> (ans, residuals)`` replaces the
    forward pass and ``bwd(g, residuals)`` returns a tuple with one cotangent
    per positional argument (``None`` = not differentiable). When nothing is
    traced, the plain function runs and no residuals are kept.
    """
    if not hasattr(prim, "fun"):
        raise TypeError(f"defvjp_fwd: {_name(prim)} is not a primitive (wrap it with @primitive)")
    prim.fwd = fwd
    prim.bwd = bwd


def unbroadcast(target, g: np.ndarray) -> np.ndarray:
    """Sum the cotangent ``g`` back to the shape of ``target`` (an array or a shape).

    Broadcasting copies a value along new leading axes and along axes of size
    one; the VJP of a copy is a sum, so we sum over exactly those axes. When
    ``target`` is a floating-point array the result keeps its dtype.
    """
    if type(target) is np.ndarray and type(g) is np.ndarray:
        if g.shape == target.shape and (g.dtype == target.dtype or target.dtype.kind != "f"):
            return g  # the common case: nothing was broadcast
        shape, dtype = target.shape, target.dtype
    elif isinstance(target, tuple):
        shape, dtype = target, None
    else:
        shape, dtype = np.shape(target), np.result_type(target)
    g = np.asarray(g)
    if g.shape != shape:
        extra = g.ndim - len(shape)
        if extra > 0:
            g = g.sum(axis=tuple(range(extra)))
        axes = tuple(i for i, n in enumerate(shape) if n == 1 and g.shape[i] != 1)
        if axes:
            g = g.sum(axis=axes, keepdims=True)
        if g.shape != shape:  # target was larger than g: broadcast the cotangent
            g = np.broadcast_to(g, shape)
    if dtype is not None and dtype.kind == "f" and g.dtype != dtype:
        g = g.astype(dtype)
    return g


# ---------------------------------------------------------------------------
# The backward pass
# ---------------------------------------------------------------------------
def _box_parents(box: Box) -> list[Box]:
    return [parent for _, parent in box._parents]


def toposort(end, parents_of: Callable[[Any], Sequence] | None = None) -> list:
    """Nodes reachable from ``end``, each before its parents (iterative DFS).

    ``parents_of(node)`` lists a node's parents (default: a :class:`Box`'s). An
    explicit stack replaces recursion, so a chain of 10,000 operations is fine;
    the order depends only on the graph, never on memory addresses.
    """
    parents_of = parents_of or _box_parents
    order: list = []
    seen: dict[int, bool] = {}
    stack: list[tuple[Any, bool]] = [(end, False)]
    while stack:
        box, parents_done = stack.pop()
        if parents_done:  # all its parents are in `order`: post-order
            order.append(box)
            continue
        if id(box) in seen:
            continue
        seen[id(box)] = True
        stack.append((box, True))
        for parent in reversed(parents_of(box)):
            if id(parent) not in seen:
                stack.append((parent, False))
    order.reverse()  # post-order reversed: every box comes before its parents
    return order


def _raw_cotangents(box: Box, g: np.ndarray) -> list:
    """``(argnum, parent, cotangent)`` for each traced parent of ``box``."""
    prim = box._prim
    if prim.bwd is not None:
        cts = prim.bwd(g, box._res)
        if not isinstance(cts, tuple | list):
            cts = (cts,)
        out = []
        for argnum, parent in box._parents:
            ct = cts[argnum] if argnum < len(cts) else None
            if ct is None:
                raise NotImplementedError(
                    f"{_name(prim)}: argument {argnum} is not differentiable")
            out.append((argnum, parent, ct))
        return out
    vjps, out = prim.vjps, []
    for argnum, parent in box._parents:
        vjp = vjps[argnum] if argnum < len(vjps) else None
        if vjp is None:
            raise NotImplementedError(
                f"VJP of primitive '{_name(prim)}' with respect to argument {argnum} is not "
                "defined"
            )
        out.append((argnum, parent, vjp(g, box._value, *box._args, **box._kwargs)))
    return out


def parent_cotangents(box: Box, g: np.ndarray) -> list:
    """``(argnum, parent, cotangent)`` for each traced parent of ``box``, given the
    cotangent ``g`` of ``box``: one application of the chain rule (a VJP), its shape
    checked and its dtype that of the parent (float32 stays float32)."""
    out = _raw_cotangents(box, g)
    for k, (argnum, parent, ct) in enumerate(out):
        pval = parent._value
        if isinstance(pval, _Outputs):  # a scan's outputs: one cotangent (or None) each
            continue
        if type(ct) is not np.ndarray:
            ct = np.asarray(ct)
        if type(pval) is np.ndarray:
            pshape, pdtype = pval.shape, pval.dtype
        else:
            pshape, pdtype = np.shape(pval), np.result_type(pval)
        if ct.shape != pshape:
            raise ValueError(
                f"VJP of '{_name(box._prim)}' returned a cotangent of shape {ct.shape} "
                f"for an argument of shape {pshape}"
            )
        if ct.dtype != pdtype and pdtype.kind == "f":
            ct = ct.astype(pdtype)
        out[k] = (argnum, parent, ct)
    return out


def backward(end: Box, g: np.ndarray,
             on_edge: Callable[[Box, int, Box, np.ndarray], None] | None = None
             ) -> dict[int, np.ndarray]:
    """Run every VJP from ``end`` (with cotangent ``g``) back to the leaves.

    Returns ``{id(leaf): cotangent}`` for the leaves (boxes without parents).
    A value used several times receives the *sum* of its cotangents.
    ``on_edge(box, argnum, parent, cotangent)``, if given, sees every edge's
    cotangent as it is computed (:func:`minimanc.autodiff.graph.computation_graph`).
    """
    cotangents: dict[int, Any] = {id(end): g}
    leaves: dict[int, np.ndarray] = {}
    for box in toposort(end):
        g = cotangents.pop(id(box))
        if not box._parents:
            leaves[id(box)] = g
            continue
        for argnum, parent, ct in parent_cotangents(box, g):
            if on_edge is not None:
                on_edge(box, argnum, parent, ct)
            key = id(parent)
            cotangents[key] = ct if key not in cotangents else _add(cotangents[key], ct)
    return leaves


def _add(a, b):
    """Sum two cotangents; those of a scan's outputs are tuples with ``None`` for zero."""
    if isinstance(a, tuple):
        return tuple(y if x is None else x if y is None else x + y for x, y in zip(a, b))
    return a + b


# ---------------------------------------------------------------------------
# Pytrees: nested dicts, lists and tuples (None is an empty subtree)
# ---------------------------------------------------------------------------
def _dict_keys(d: dict) -> list:
    try:
        return sorted(d)
    except TypeError:
        return list(d)


def tree_flatten(tree) -> tuple[list, list[str], Callable[[Sequence], Any]]:
    """Return ``(leaves, paths, rebuild)`` where ``rebuild(new_leaves)`` rebuilds the tree.

    ``paths`` are readable locations such as ``"['layers'][1]['w']"``.
    """
    leaves: list = []
    paths: list[str] = []

    def build(node, path):
        if node is None:
            return lambda it: None
        if isinstance(node, dict):
            keys = _dict_keys(node)
            subs = [build(node[k], f"{path}[{k!r}]") for k in keys]
            return lambda it: type(node)(zip(keys, [s(it) for s in subs]))
        if isinstance(node, list | tuple):
            subs = [build(c, f"{path}[{i}]") for i, c in enumerate(node)]
            if hasattr(node, "_fields"):  # namedtuple
                return lambda it: type(node)(*[s(it) for s in subs])
            return lambda it: type(node)([s(it) for s in subs])
        leaves.append(node)
        paths.append(path)
        return lambda it: next(it)

    rebuilder = build(tree, "")
    return leaves, paths, lambda new: rebuilder(iter(new))


def tree_unflatten(rebuild: Callable[[Sequence], Any], leaves: Sequence):
    """Inverse of :func:`tree_flatten`: ``tree_unflatten(rebuild, leaves)``."""
    return rebuild(leaves)


# ---------------------------------------------------------------------------
# grad and value_and_grad
# ---------------------------------------------------------------------------
def _check_leaf(leaf, argnum: int, path: str) -> np.ndarray:
    if isinstance(leaf, Box):
        raise NotImplementedError(
            "grad of a function that is itself being differentiated: higher-order "
            "derivatives are not supported by minimanc.autodiff (use the jax engine)"
        )
    if isinstance(leaf, bool | int):
        dtype_name = type(leaf).__name__
    else:
        arr = np.asarray(leaf)
        if np.issubdtype(arr.dtype, np.floating):
            return arr
        dtype_name = str(arr.dtype)
    where = f"argument {argnum}" + (f" at {path}" if path else "")
    raise TypeError(f"grad requires real floating-point inputs, got {dtype_name} for {where}")


def _check_output(out, has_aux: bool) -> None:
    """Refuse outputs that are not a scalar array (None, a tuple, a dict ...)."""
    if isinstance(out, Box | np.ndarray | np.generic | numbers.Number) and not isinstance(
        out, bool
    ):
        return
    if out is None:
        raise TypeError(
            "grad requires a scalar output (shape ()), but the function returned None "
            "(a missing `return`?)"
        )
    if isinstance(out, tuple | list):
        hint = ("with has_aux=True the function returns (scalar, aux)" if has_aux
                else "to return extra values use has_aux=True and return (scalar, aux)")
        raise TypeError(
            f"grad requires a scalar output (shape ()), got a {type(out).__name__} of "
            f"{len(out)} values; {hint}"
        )
    raise TypeError(
        f"grad requires a scalar output (shape ()), got {type(out).__name__}"
        + (": a Python bool has no derivative" if isinstance(out, bool) else "")
    )


def value_and_grad(
    fun: Callable, argnums: int | Sequence[int] = 0, has_aux: bool = False
) -> Callable:
    """Return ``f(*args) -> (value, gradient)`` like ``jax.value_and_grad``.

    ``fun`` must return a scalar (shape ``()``); with ``has_aux=True`` it returns
    ``(scalar, aux)`` and the value is ``(scalar, aux)``. The gradient has the
    pytree structure of ``args[argnums]`` (a tuple of those when ``argnums`` is
    a tuple) and the dtype of each input leaf.
    """
    multi = not isinstance(argnums, int)
    nums = tuple(argnums) if multi else (argnums,)
    if not all(isinstance(n, int) for n in nums) or not nums:
        raise ValueError(f"argnums must be an int or a non-empty tuple of ints, got {argnums!r}")

    @functools.wraps(fun)
    def wrapped(*args, **kwargs):
        if not all(-len(args) <= n < len(args) for n in nums):
            raise ValueError(
                f"argnums={argnums!r} but the function was called with {len(args)} "
                "positional arguments"
            )
        if len({n % len(args) for n in nums}) != len(nums):
            raise ValueError(f"argnums={argnums!r} names the same argument twice")
        args = list(args)
        per_arg = []  # (leaf boxes, rebuild, original leaves) for each argnum
        for n in nums:
            leaves, paths, rebuild = tree_flatten(args[n])
            arrays = [_check_leaf(leaf, n, p) for leaf, p in zip(leaves, paths)]
            boxes = [Box(a) for a in arrays]
            per_arg.append((boxes, rebuild, leaves))
            args[n] = rebuild(boxes)
        _ACTIVE[0] += 1
        try:
            out = fun(*args, **kwargs)
        finally:
            _ACTIVE[0] -= 1
        if has_aux:
            if not (isinstance(out, tuple | list) and len(out) == 2):
                raise ValueError("has_aux=True requires the function to return (value, aux)")
            out, aux = out
            aux = _strip_boxes(aux)
        _check_output(out, has_aux)
        shape, dtype = np.shape(_unbox(out)), np.result_type(_unbox(out))
        if shape != ():
            raise TypeError(
                f"grad requires a scalar output (shape ()), got shape {shape}; reduce it "
                "first, e.g. with .sum() or .mean()"
            )
        if not np.issubdtype(dtype, np.floating):
            raise TypeError(f"grad requires a real floating-point output, got {dtype}")
        cts = backward(out, np.ones((), dtype=dtype)) if isinstance(out, Box) else {}
        grads = []
        for boxes, rebuild, leaves in per_arg:
            gl = []
            for box, leaf in zip(boxes, leaves):
                g = cts.get(id(box))
                val = box._value
                if g is None:
                    g = np.zeros_like(val)
                g = np.asarray(g, dtype=val.dtype)
                if not g.flags.writeable:
                    g = g.copy()
                gl.append(float(g) if isinstance(leaf, float) else g)
            grads.append(rebuild(gl))
        grads = tuple(grads) if multi else grads[0]
        value = _unbox(out)
        return ((value, aux) if has_aux else value), grads

    return wrapped


def grad(fun: Callable, argnums: int | Sequence[int] = 0, has_aux: bool = False) -> Callable:
    """Return the gradient function of the scalar function ``fun`` (like ``jax.grad``).

    >>> import minimanc.autodiff.numpy as anp
    >>> float(grad(lambda x: anp.sum(x ** 2))(anp.asarray([1.0, 2.0]))[1])
    4.0
    """
    vg = value_and_grad(fun, argnums, has_aux)

    @functools.wraps(fun)
    def wrapped(*args, **kwargs):
        value, g = vg(*args, **kwargs)
        return (g, value[1]) if has_aux else g

    return wrapped


def _strip_boxes(tree):
    leaves, _, rebuild = tree_flatten(tree)
    return rebuild([_unbox(leaf) for leaf in leaves])


# ---------------------------------------------------------------------------
# scan: a loop that is one node of the tape
# ---------------------------------------------------------------------------
class _Outputs(tuple):
    """The value of a scan node: its output leaves (final carry leaves, then stacked ys)."""


@primitive
def _select(outs, k):
    """Output ``k`` of a scan node."""
    return outs[k]


def _select_fwd(outs, k):
    return outs[k], (k, len(outs))


def _select_bwd(g, res):
    k, n = res
    return tuple(g if j == k else None for j in range(n)), None


defvjp_fwd(_select, _select_fwd, _select_bwd)


@primitive
def _scan_node(*args):
    """The tape node of one :func:`scan` (built by :func:`scan`, never called)."""
    raise NotImplementedError("_scan_node is built by scan")  # pragma: no cover


def _is_float(value) -> bool:
    return np.issubdtype(np.result_type(value), np.floating)


def _scan_length(xs_vals: list, xs_paths: list[str], length: int | None) -> int:
    lengths = {}
    for v, p in zip(xs_vals, xs_paths):
        if np.ndim(v) == 0:
            raise ValueError(f"scan: every leaf of xs needs a leading (time) axis; xs{p} is "
                             f"a scalar of shape {np.shape(v)}")
        lengths[p] = np.shape(v)[0]
    if len(set(lengths.values())) > 1:
        raise ValueError(f"scan: the leaves of xs have different leading lengths {lengths}")
    if length is not None and (not isinstance(length, numbers.Integral)
                               or isinstance(length, bool) or length < 1):
        raise ValueError(f"scan: length must be a positive integer, got length={length!r}")
    if lengths:
        n = next(iter(lengths.values()))
        if length is not None and length != n:
            raise ValueError(f"scan: length={length} but xs has leading length {n}")
        if n < 1:
            raise ValueError("scan: xs has leading length 0; scan needs at least one step")
        return n
    if length is None:
        raise ValueError("scan: xs has no arrays, so pass length=<number of steps>")
    return int(length)


def _check_carry(new, paths: list[str], new_paths: list[str], ref: list) -> None:
    if new_paths != paths:
        raise TypeError(f"scan: f must return a carry with the structure of init: init has "
                        f"leaves {paths}, f returned {new_paths}")
    for p, a, b in zip(paths, ref, new):
        vb = _unbox(b)
        if np.shape(a) != np.shape(vb) or np.result_type(a) != np.result_type(vb):
            raise TypeError(
                f"scan: the carry must keep its shape and dtype; at init{p} it has shape "
                f"{np.shape(a)} and dtype {np.result_type(a)} but f returned shape "
                f"{np.shape(vb)} and dtype {np.result_type(vb)} (cast it with .astype)")


def _split_step_output(out) -> tuple:
    if not (isinstance(out, tuple | list) and len(out) == 2):
        raise TypeError(f"scan: f(carry, x) must return a pair (new_carry, y), got "
                        f"{type(out).__name__}")
    return out


def _stack_ys(per_step: list[list]) -> list:
    return [np.stack([np.asarray(step[j]) for step in per_step])
            for j in range(len(per_step[0]))]


def scan(f: Callable, init, xs, length: int | None = None) -> tuple:
    """``jax.lax.scan`` for this engine: ``(carry, ys)`` of the loop ::

        carry = init
        for i in range(L):
            carry, y_i = f(carry, xs[i])      # xs[i]: every leaf of xs at index i
        ys = stack of the y_i along a new leading axis

    ``init``, ``xs`` and ``y`` are pytrees; the carry keeps its structure, shapes
    and dtypes (a ``TypeError`` otherwise), and ``L`` is the leading length of
    ``xs``' leaves (or ``length`` when ``xs`` is ``None``). Inside
    :func:`grad` the loop is **one node** of the tape: each step runs on a small
    tape of its own whose inputs are fresh leaves for the carry and ``x``; the
    node's VJP runs the steps' tapes in reverse order, passing the carry's
    cotangent from step to step, and sums what each step sends to traced
    values that ``f`` closes over (parameters). Derivatives with respect to
    ``init``, ``xs`` and closed-over values are those of the unrolled loop.
    """
    init_leaves, init_paths, init_rebuild = tree_flatten(init)
    xs_leaves, xs_paths, xs_rebuild = tree_flatten(xs)
    init_vals = [np.asarray(_unbox(v)) for v in init_leaves]
    xs_vals = [np.asarray(_unbox(v)) for v in xs_leaves]
    n = _scan_length(xs_vals, xs_paths, length)
    traced = _ACTIVE[0] > 0 or any(isinstance(v, Box) for v in init_leaves + xs_leaves)
    if not traced:
        return _scan_plain(f, init_rebuild, init_paths, init_vals, xs_rebuild, xs_vals, n)
    carry_vals = init_vals
    steps, ys_steps, y_rebuild = [], [], None
    for i in range(n):
        c_in = [Box(v) if _is_float(v) else v for v in carry_vals]
        x_in = [Box(v[i]) if _is_float(v) else v[i] for v in xs_vals]
        frame: dict[int, Box] = {}
        _FRAMES.append(frame)
        try:
            c_out, y = _split_step_output(f(init_rebuild(c_in), xs_rebuild(x_in)))
        finally:
            _FRAMES.pop()
        c_leaves, c_paths, _ = tree_flatten(c_out)
        _check_carry(c_leaves, init_paths, c_paths, init_vals)
        y_leaves, _, y_rebuild = tree_flatten(y)
        steps.append((frame, c_in, x_in, c_leaves, y_leaves))
        carry_vals = [np.asarray(_unbox(v)) for v in c_leaves]
        ys_steps.append([_unbox(v) for v in y_leaves])
    ys_vals = _stack_ys(ys_steps)
    step_leaves = {id(b) for s in steps for b in s[1] + s[2] if isinstance(b, Box)}
    parents = [(j, b) for j, b in enumerate(init_leaves) if isinstance(b, Box)]
    parents += [(len(init_leaves) + j, b) for j, b in enumerate(xs_leaves) if isinstance(b, Box)]
    outer: dict[int, Box] = {}  # traced values made outside the loop that f uses
    for frame, _, _, c_leaves, y_leaves in steps:
        used = [p for b in frame.values() for _, p in b._parents]
        for b in used + [b for b in c_leaves + y_leaves if isinstance(b, Box)]:
            if id(b) not in frame and id(b) not in step_leaves:
                outer.setdefault(id(b), b)
    base = len(init_leaves) + len(xs_leaves)
    parents += [(base + k, b) for k, b in enumerate(outer.values())]
    out_vals = carry_vals + ys_vals
    if not parents:  # nothing traced reaches the loop
        return init_rebuild(carry_vals), y_rebuild(ys_vals)
    res = (steps, len(carry_vals), init_vals, xs_vals, [b._value for b in outer.values()],
           list(outer), len(init_leaves), len(xs_leaves))
    node = Box(_Outputs(out_vals), tuple(parents), _scan_node, (), None, res)
    if _FRAMES:
        _FRAMES[-1][id(node)] = node
    outs = [_select(node, k) if _is_float(v) else v for k, v in enumerate(out_vals)]
    nc = len(carry_vals)
    return init_rebuild(outs[:nc]), y_rebuild(outs[nc:])


def _scan_plain(f, init_rebuild, init_paths, init_vals, xs_rebuild, xs_vals, n) -> tuple:
    """The loop of :func:`scan` on plain values (nothing traced)."""
    carry, ys_steps, y_rebuild = init_rebuild(init_vals), [], None
    for i in range(n):
        carry, y = _split_step_output(f(carry, xs_rebuild([v[i] for v in xs_vals])))
        c_leaves, c_paths, _ = tree_flatten(carry)
        _check_carry(c_leaves, init_paths, c_paths, init_vals)
        y_leaves, _, y_rebuild = tree_flatten(y)
        ys_steps.append(y_leaves)
    return carry, y_rebuild(_stack_ys(ys_steps))


def _accumulate(cts: dict, key: int, ct) -> None:
    cts[key] = ct if key not in cts else cts[key] + ct


def _scan_bwd(g: tuple, res: tuple) -> tuple:
    """VJP of a scan node: the steps' tapes in reverse, the carry's cotangent passed back."""
    steps, nc, init_vals, xs_vals, outer_vals, outer_ids, n_init, n_xs = res
    g_carry = list(g[:nc])
    g_ys = g[nc:]
    x_cts = [None] * n_xs
    outer_cts: dict[int, np.ndarray] = {}
    outer_set = set(outer_ids)
    for i in range(len(steps) - 1, -1, -1):
        frame, c_in, x_in, c_out, y_out = steps[i]
        # cts: boxes of this step's tape; boundary: its fresh inputs and closed-over values
        cts: dict[int, Any] = {}
        boundary: dict[int, Any] = {}
        for b, ct in zip(c_out + y_out, g_carry + [None if gy is None else gy[i]
                                                   for gy in g_ys]):
            if isinstance(b, Box) and ct is not None:
                _accumulate(cts if id(b) in frame else boundary, id(b), ct)
        # the order the boxes were made in is topological: walk it backwards
        for box in reversed(list(frame.values())):
            ct = cts.pop(id(box), None)
            if ct is None:
                continue
            for _, parent, pct in parent_cotangents(box, ct):
                key = id(parent)
                into = cts if key in frame else boundary
                into[key] = pct if key not in into else _add(into[key], pct)
        g_carry = [boundary.get(id(b)) if isinstance(b, Box) else None for b in c_in]
        for j, b in enumerate(x_in):
            if isinstance(b, Box) and id(b) in boundary:
                if x_cts[j] is None:
                    x_cts[j] = np.zeros_like(xs_vals[j])
                x_cts[j][i] += boundary[id(b)]
        for key, ct in boundary.items():
            if key in outer_set:
                _accumulate(outer_cts, key, ct)
    cts_init = [np.zeros_like(v) if ct is None else ct for v, ct in zip(init_vals, g_carry)]
    cts_xs = [np.zeros_like(v) if ct is None else ct for v, ct in zip(xs_vals, x_cts)]
    cts_outer = [outer_cts.get(k, None) for k in outer_ids]
    cts_outer = [np.zeros_like(v) if ct is None else ct for v, ct in zip(outer_vals, cts_outer)]
    return tuple(cts_init + cts_xs + cts_outer)


defvjp_fwd(_scan_node, lambda *args: (None, None), _scan_bwd)
