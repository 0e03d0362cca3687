"""Argument validators shared by all modules (used from chapter 3 on: dmp, quaternion, vagn, cam).

Every check here follows the package's rule for bad input: a ``TypeError``
when the argument is not a number at all (a string, ``None``), a
``ValueError`` when it is a number of the wrong kind (non-finite, out of
range, wrong shape), and both name the argument and its value.

Traced values — our autodiff ``Box`` inside ``grad``, JAX tracers inside
``grad``/``jit``, device arrays — are never inspected: :func:`is_concrete`
tells them apart from plain Python and NumPy values, and the ``*_if_concrete``
helpers return without looking at them.

Tolerances of internal consistency checks (a distribution summing to one, a
unit quaternion, a column-stochastic matrix) fit the precision of the values
(:func:`float_tolerance`, :func:`value_dtype`): a float32 distribution is off
by a few float32 roundings, a float64 one by a few float64 roundings, and a
single fixed tolerance is either too tight for the first or too loose for the
second.
"""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np

__all__ = [
    "TOLERANCE_FACTOR",
    "check_broadcast",
    "check_distribution",
    "check_dt",
    "check_finite",
    "check_finite_if_concrete",
    "check_float_dtype",
    "check_int",
    "check_leading_axis",
    "check_positive",
    "check_real",
    "check_rng",
    "check_stochastic_columns",
    "first_bad",
    "float_tolerance",
    "is_concrete",
    "is_traced",
    "shape_of",
    "value_dtype",
]

TOLERANCE_FACTOR: float = 8.0
"""Roundings allowed per term of a reduction: :func:`float_tolerance` is
``TOLERANCE_FACTOR · eps(dtype) · terms``.  Summing ``n`` numbers that each
carry one rounding (relative error ``eps / 2``) in floating point is off by at
most about ``n · eps`` (the sum's own ``n − 1`` roundings included); the factor
8 leaves room for the few operations that produced each term (a softmax entry,
a product ``T q``), while a genuinely wrong value (a distribution summing to
0.999) stays many orders of magnitude outside."""


# --------------------------------------------------------------------------- concreteness


def is_concrete(x: Any) -> bool:
    """True for plain Python numbers, NumPy arrays/scalars and lists/tuples of them.

    False for traced values (autodiff boxes, JAX tracers), device arrays,
    strings, ``None`` and anything else; only concrete values are inspected.
    """
    tx = type(x)
    if tx is np.ndarray or tx is float:  # the common cases first (called once per check)
        return True
    if isinstance(x, list | tuple):
        return all(is_concrete(v) for v in x)
    known = _CONCRETE_TYPES.get(tx)
    if known is None:  # the answer depends on the type alone: ask isinstance once per type
        known = _CONCRETE_TYPES[tx] = isinstance(x, bool | numbers.Number | np.ndarray
                                                 | np.generic)
    return known


_CONCRETE_TYPES: dict[type, bool] = {}
_TRACED_TYPES: dict[type, bool] = {}


def is_traced(x: Any) -> bool:
    """True for a traced or device array (it has a shape and a dtype but is not
    NumPy: an autodiff ``Box``, a JAX tracer or array), or a list/tuple holding one.

    Neither concrete nor traced (a string, ``None``, a dict) is a type error
    for every numeric argument: the ``check_*`` functions raise ``TypeError``.
    """
    tx = type(x)
    if tx is np.ndarray or tx is float:
        return False
    if isinstance(x, list | tuple):
        return any(is_traced(v) for v in x)
    known = _TRACED_TYPES.get(tx)
    if known is None:  # shape and dtype are attributes of the type (a Box's, a tracer's)
        known = hasattr(x, "shape") and hasattr(x, "dtype") and not is_concrete(x)
        if known:
            _TRACED_TYPES[tx] = True
    return known


# --------------------------------------------------------------------------- tolerances


def value_dtype(x: Any) -> np.dtype:
    """The floating-point precision the values of ``x`` carry: the dtype of a float array,
    float64 for Python floats, integers and booleans (which convert exactly)."""
    dt = np.asarray(x).dtype
    return np.dtype(dt) if np.issubdtype(dt, np.floating) else np.dtype(np.float64)


def float_tolerance(dtype: Any, terms: int = 1) -> float:
    """Tolerance of a consistency check on a reduction of ``terms`` values of ``dtype``.

    ``TOLERANCE_FACTOR · eps(dtype) · terms`` (:data:`TOLERANCE_FACTOR` = 8):
    about 1.8e-15 per term in float64 and 9.5e-7 per term in float32 (a ratio
    of 2^29 ≈ 5.4e8).  Non-float dtypes (integers, booleans) use float64's
    epsilon: they convert to it exactly.
    """
    try:
        dt = np.dtype(dtype)
    except TypeError as exc:
        raise TypeError(f"dtype must be a NumPy dtype, got dtype={dtype!r}") from exc
    if isinstance(terms, bool) or not isinstance(terms, numbers.Integral) or terms < 1:
        raise ValueError(f"terms must be an integer >= 1, got terms={terms!r}")
    eps = np.finfo(dt).eps if np.issubdtype(dt, np.floating) else np.finfo(np.float64).eps
    return float(TOLERANCE_FACTOR * eps * int(terms))


# --------------------------------------------------------------------------- scalars and arrays


def first_bad(values: np.ndarray, bad: np.ndarray) -> Any:
    """The first offending entry of ``values`` where ``bad`` is true, for error messages."""
    values = np.asarray(values)
    return float(values[bad].flat[0] if values.ndim else values.item())


def check_real(name: str, value: Any) -> np.ndarray:
    """``value`` as a float64 array; TypeError naming ``name`` unless it is real numbers.

    Strings, bytes, ``None``, complex numbers and other objects raise
    ``TypeError``; non-finite values pass (see :func:`check_finite`).
    """
    if value is None or isinstance(value, str | bytes):
        raise TypeError(f"{name} must be a real number or array, got {name}={value!r}")
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError) as exc:  # ragged nested lists
        raise TypeError(f"{name} must be a real number or array, got {name}={value!r}") from exc
    if raw.dtype.kind not in "biuf":  # bool, signed, unsigned, float (not complex, str, object)
        raise TypeError(
            f"{name} must be a real number or array, got {name}={value!r} (dtype {raw.dtype})"
        )
    return raw if raw.dtype == np.float64 else raw.astype(np.float64)


def check_finite(name: str, value: Any) -> np.ndarray:
    """:func:`check_real`, then ValueError naming ``name`` if any entry is NaN or ±inf."""
    arr = check_real(name, value)
    bad = ~np.isfinite(arr)
    if bad.any():
        raise ValueError(f"{name} must be finite, got {name}={first_bad(arr, bad)!r}")
    return arr


def check_finite_if_concrete(name: str, value: Any) -> None:
    """:func:`check_finite` on concrete values; traced values pass unseen.

    Anything that is neither concrete nor an array (a string, ``None``, a dict)
    raises the TypeError of :func:`check_real`.
    """
    if is_traced(value):
        return
    check_finite(name, value)


def check_positive(name: str, value: Any) -> np.ndarray:
    """:func:`check_finite`, then ValueError naming ``name`` unless every entry is > 0."""
    arr = check_finite(name, value)
    bad = arr <= 0
    if bad.any():
        raise ValueError(f"{name} must be > 0, got {name}={first_bad(arr, bad)!r}")
    return arr


def check_int(name: str, value: Any, minimum: int, maximum: int | None = None) -> int:
    """An integer ``>= minimum`` (and ``<= maximum`` if given) or ValueError naming it.

    Python and NumPy integers pass and are returned as ``int``; bools, floats
    (even 2.0), strings and ``None`` do not.
    """
    if maximum is not None and maximum < minimum:
        raise ValueError(f"check_int({name!r}): maximum {maximum} < minimum {minimum}")
    ok = not isinstance(value, bool) and isinstance(value, numbers.Integral) and value >= minimum
    if maximum is None:
        if not ok:
            raise ValueError(f"{name} must be an integer >= {minimum}, got {name}={value!r}")
    elif not (ok and value <= maximum):
        raise ValueError(f"{name} must be an integer in [{minimum}, {maximum}], "
                         f"got {name}={value!r}")
    return int(value)


def check_dt(dt: Any) -> Any:
    """A time step ``dt`` in seconds: a concrete one as a ``float``, a traced one unseen.

    A concrete ``dt`` must be a finite scalar > 0 (ValueError naming it and its value);
    a value that is no real number raises the TypeError of :func:`check_real`. Every
    integrator (the DMP's Euler steps of eqs. 10–11, the quaternion DMP) and every metric
    of a time series (jerk, time to collision) takes its ``dt`` through this check.
    """
    if type(dt) is float and 0.0 < dt < float("inf"):  # the common case, checked at once
        return dt
    if is_traced(dt):
        return dt
    arr = check_real("dt", dt)
    if arr.ndim:
        raise ValueError(f"dt must be a scalar, got dt with shape {arr.shape}")
    if not (np.isfinite(arr) and arr > 0):
        raise ValueError(f"dt must be a positive finite number, got dt={dt!r}")
    return float(arr)


def check_leading_axis(name: str, value: Any, length: int, why: str) -> Any:
    """``value`` whose first axis has ``length`` (ValueError naming it otherwise).

    Lists become NumPy arrays (so that ``value[k]`` works); arrays are
    returned unchanged, dtype included.  ``why`` completes the message:
    ``f"{name} {why}, so its leading axis must have length ..."`` (e.g.
    ``"is listed in per_step"``).
    """
    if isinstance(value, list | tuple) and not is_traced(value):
        check_real(name, value)
        value = np.asarray(value)
    shape = shape_of(value)
    if len(shape) == 0 or shape[0] != length:
        raise ValueError(
            f"{name} {why}, so its leading axis must have length {length}; "
            f"got {name} with shape {shape}"
        )
    return value


# --------------------------------------------------------------------------- shapes


def shape_of(x: Any) -> tuple[int, ...]:
    """The shape of any array-like (NumPy, traced, nested lists, scalars)."""
    shape = getattr(x, "shape", None)
    return tuple(shape) if shape is not None else tuple(np.shape(x))


def check_broadcast(*named: tuple[str, Any, int]) -> tuple[int, ...]:
    """The common batch shape of several arguments, or ValueError naming them all.

    Each entry is ``(name, value, core)`` where ``core`` is the number of
    trailing axes that are not batch axes (1 for a quaternion ``(..., 4)``, 0
    for an angle ``(...)``).  Works on traced values (only shapes are read).
    """
    batches = []
    for name, value, core in named:
        shape = shape_of(value)
        batches.append((name, shape, shape[: len(shape) - core] if core else shape))
    try:
        return tuple(np.broadcast_shapes(*(b for _, _, b in batches)))
    except ValueError:
        listed = ", ".join(f"{n} with shape {s}" for n, s, _ in batches)
        batch = ", ".join(f"{n}: {b}" for n, _, b in batches)
        raise ValueError(
            f"the batch shapes do not broadcast: {listed} (batch shapes {batch})"
        ) from None


# --------------------------------------------------------------------------- distributions


def check_distribution(name: str, q: Any, n: int, what: str = "states") -> None:
    """``q`` of shape ``(..., n)``: probability distributions along the last axis.

    The shape is checked on every value (also traced ones); concrete values
    must also be finite, have no entry below ``−tol`` and sum to one within
    ``tol = float_tolerance(value_dtype(q), n)`` — the tolerance of ``q``'s own
    precision, taken before any conversion.  ValueError names ``name``.
    """
    shape = shape_of(q)
    if len(shape) == 0 or shape[-1] != n:
        raise ValueError(
            f"{name} must have shape (..., N) with N = {n} {what}; got {name} with shape {shape}"
        )
    if is_traced(q):
        return
    tol = float_tolerance(value_dtype(q), n)
    qa = check_real(name, q)
    if not np.all(np.isfinite(qa)):
        raise ValueError(f"{name} must be finite; got {name} = {qa!r}")
    if np.any(qa < -tol):
        raise ValueError(
            f"{name} must be a probability distribution: it has a negative entry "
            f"(min {qa.min():.3g}); got {name} = {qa!r}"
        )
    off = np.abs(qa.sum(axis=-1) - 1.0)
    if np.any(off > tol):
        worst = float(qa.sum(axis=-1).reshape(-1)[np.argmax(off.reshape(-1))])
        hint = ""
        if qa.dtype == np.float64 and np.all(off <= float_tolerance(np.float32, n)):
            hint = (f" — within float32 precision: if {name} holds float32 values converted "
                    f"to float64, pass them as float32 or renormalise ({name} / "
                    f"{name}.sum(-1, keepdims=True))")
        raise ValueError(
            f"{name} must be a probability distribution: entries sum to {worst!r}, "
            f"not 1 (|sum - 1| = {float(off.max()):.3g} > tolerance {tol:.3g}){hint}; "
            f"got {name} = {qa!r}"
        )


def check_stochastic_columns(name: str, T: Any) -> np.ndarray:
    """A concrete ``(..., N, N)`` column-stochastic matrix, returned as float64.

    Finite (ValueError otherwise, before any linear algebra), non-negative and
    every column summing to one within ``float_tolerance(value_dtype(T), N)``.
    """
    tol_dtype = value_dtype(T)
    Ta = check_real(name, T)
    if Ta.ndim < 2 or Ta.shape[-1] != Ta.shape[-2]:
        raise ValueError(f"{name} must have shape (..., N, N); got {name} with shape {Ta.shape}")
    bad = ~np.isfinite(Ta)
    if bad.any():
        raise ValueError(
            f"{name} must be finite; got {name} with {int(bad.sum())} non-finite "
            f"entr{'y' if bad.sum() == 1 else 'ies'} (first {first_bad(Ta, bad)!r})"
        )
    tol = float_tolerance(tol_dtype, Ta.shape[-1])
    sums = Ta.sum(axis=-2)
    if np.any(Ta < -tol) or np.any(np.abs(sums - 1.0) > tol):
        raise ValueError(
            f"{name} must be column-stochastic (non-negative, every column summing to 1 "
            f"within {tol:.3g}); got column sums {np.round(sums, 6)} and minimum entry "
            f"{float(Ta.min()):.3g}"
        )
    return Ta


# --------------------------------------------------------------------------- other arguments


def check_rng(name: str, rng: Any) -> np.random.Generator:
    """``rng`` if it is a ``numpy.random.Generator`` (``default_rng(seed)``), else ValueError
    naming it: a seed or the legacy ``RandomState`` would draw other numbers silently."""
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"{name} must be a numpy.random.Generator, got {name}={rng!r}")
    return rng


def check_float_dtype(name: str, dtype: Any) -> np.dtype:
    """``numpy.dtype(dtype)`` if it is a floating-point type, else ValueError naming it
    (``TypeError`` from NumPy when ``dtype`` is no dtype at all)."""
    dt = np.dtype(dtype)
    if not np.issubdtype(dt, np.floating):
        raise ValueError(f"{name} must be a floating-point type, got {name}={dtype!r}")
    return dt
