"""Chapter 1 — the gradient API: :func:`grad` and :func:`value_and_grad` (JAX's, on pytrees).
"""

from __future__ import annotations

import contextlib
import functools
import gc
import numbers
from collections.abc import Callable, Sequence

import numpy as np

from minimanc.autodiff.boxes import TRACING, Box, strip_boxes, unbox
from minimanc.autodiff.reverse import backward
from minimanc.tree import tree_flatten

__all__ = ["grad", "value_and_grad"]


@contextlib.contextmanager
def _collector_paused():
    """Pause Python's cyclic garbage collector while a gradient is traced and run back.

    A trace allocates tens of thousands of small objects (one box per operation) that
    all stay alive until the backward pass; each allocation burst would otherwise
    trigger collections that walk them (and every other live object) again, at no
    gain. Reference counting still frees the tape at the end; the collector's state
    is restored, so a nested call leaves it paused for the outer one.
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


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
        with _collector_paused():
            return _trace_and_backward(fun, args, kwargs, per_arg, has_aux, multi)

    return wrapped


def _trace_and_backward(fun: Callable, args: list, kwargs: dict, per_arg: list, has_aux: bool,
                        multi: bool) -> tuple:
    """The value and the gradient of ``fun`` at ``args`` (inputs already boxed)."""
    TRACING[0] += 1
    try:
        out = fun(*args, **kwargs)
    finally:
        TRACING[0] -= 1
    if has_aux:
        if not (isinstance(out, tuple | list) and len(out) == 2):
            raise ValueError("has_aux=True requires the function to return (value, aux)")
        out, aux = out
        aux = strip_boxes(aux)
    _check_output(out, has_aux)
    shape, dtype = np.shape(unbox(out)), np.result_type(unbox(out))
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
    value = unbox(out)
    return ((value, aux) if has_aux else value), grads


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

