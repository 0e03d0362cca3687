"""Chapter 1 — traced values: :class:`Box`, the error that keeps a gradient from being dropped,
:func:`stop_gradient`, and the tape state shared by the tracer.

While :func:`~minimanc.autodiff.api.grad` runs a function, every array that
depends on its inputs is a ``Box`` that remembers *which primitive* produced it
and *from which parents* (a tuple, never a set: the order of the backward sums is
fixed, so gradients are bit-identical run after run).
"""

from __future__ import annotations

import numpy as np

from minimanc.tree import tree_flatten

__all__ = [
    "FRAMES",
    "TRACING",
    "Box",
    "TracerConversionError",
    "prim_name",
    "stop_gradient",
    "strip_boxes",
    "unbox",
]

FRAMES: list[dict[int, Box]] = []
"""The tapes of the scan steps being traced, innermost last: ``{id(box): box}`` of the
boxes made during the step (:func:`~minimanc.autodiff.loops.scan` pushes and pops them)."""

TRACING = [0]
"""How many calls of ``value_and_grad`` are running: ``scan`` traces its steps only inside one."""


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
        self._kwargs = kwargs
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
        return None if self._prim is None else prim_name(self._prim)

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
        return strip_boxes(tree)
    return tree



def unbox(x):
    """The plain value of a traced ``x``; anything else unchanged."""
    return x._value if isinstance(x, Box) else x


def prim_name(prim) -> str:
    """A primitive's name, for messages."""
    return getattr(prim, "__name__", repr(prim))


def strip_boxes(tree):
    """The pytree ``tree`` with every traced leaf replaced by its plain value."""
    leaves, _, rebuild = tree_flatten(tree)
    return rebuild([unbox(leaf) for leaf in leaves])
