"""Chapter 0 — what crosses between the tests' process and a student's notebook.

The tests of a notebook run in a process of their own (:mod:`~minimanc.exercises.checker`);
the student's functions stay in the notebook's kernel (:mod:`~minimanc.exercises.serving`).
Values travel between them as graphs of nodes (:mod:`~minimanc.exercises.wire`):

* **to the notebook** (the tests' arguments) anything the tests hold goes across: data,
  library objects (by class and state), modules, classes and library functions (by
  name), the tests' own functions (by code, with the globals they read) and random
  generators (by state). The notebook's copies of the tests' lists, dicts, sets, arrays,
  objects and generators are *mirrors*: when a call changed one, the reply carries its
  new state and the tests' original is changed the same way (:func:`update`); a mirror
  the notebook returns comes back as the original itself.
* **to the tests** (the notebook's answers) only data is read: ``None``, ``bool``, ``int``,
  ``float``, ``complex``, ``str``, ``bytes``, ``tuple``, ``list``, ``dict``, ``set``,
  ``frozenset``, ``slice``, ``range``, NumPy arrays (numeric, bool, string or date dtypes;
  object arrays element by element) and NumPy scalars (``np.float64`` and the other types
  NumPy defines), JAX arrays, instances of the library's classes and of the classes the
  notebook's own (non-exercise) cells define (by state, built as the tests' class),
  exceptions (by class name and arguments) and functions, which stay in the notebook (a
  call goes back to it). The tests build each value as its exact type and execute nothing
  the notebook sends. A subclass of any of these (``class Rigged(float)``) or an object of
  another class is refused (:class:`RefusedAnswer`).

This module holds the rules both ends share: the plain types, an object's state, and how
a mirror is compared and copied back.
"""

from __future__ import annotations

import functools
import sys
from typing import Any

import numpy as np

__all__ = [
    "ARRAY_KINDS",
    "NOT_FOUND",
    "PLAIN_TYPES",
    "RefusedAnswer",
    "changed",
    "class_name",
    "contents",
    "is_jax_array",
    "is_library",
    "is_numpy_scalar",
    "is_tracer",
    "lookup",
    "name_of",
    "refusal",
    "shared_state",
    "snapshot",
    "state_of",
    "update",
]

NOT_FOUND = object()
"""What :func:`lookup` returns for a name that does not resolve."""
PLAIN_TYPES = frozenset({type(None), bool, int, float, complex, str, bytes, tuple, list, dict,
                         set, frozenset, slice, range})
"""The Python types an answer may have (exactly: not a subclass)."""
ARRAY_KINDS = frozenset("biufcSUMm")
"""The dtype kinds of an array that crosses as bytes (object arrays go element by element)."""


class RefusedAnswer(AssertionError):
    """A value from the notebook that the tests do not read: not one of the plain types
    (see the module docstring), or a message that is not well formed."""


def class_name(t: type) -> str:
    """``t``'s name as a student wrote it (``Rigged``, ``numpy.matrix``)."""
    return t.__qualname__ if t.__module__ in ("builtins", "__main__") else \
        f"{t.__module__}.{t.__qualname__}"


def refusal(value: Any) -> str:
    """What a value of a type the tests do not read is, and what to return instead."""
    t = type(value)
    hint = ("not a plain type; return a float, int, bool, str, tuple, list, dict, a numpy "
            "array or scalar, or a library object")
    for base in t.__mro__[1:]:
        if base in PLAIN_TYPES:
            article = "an" if base.__qualname__[0] in "aeiou" else "a"
            hint = f"{article} {base.__qualname__} subclass; return a plain {base.__qualname__}"
            break
        if base is np.ndarray:
            hint = "an ndarray subclass; return a plain numpy.ndarray (np.asarray)"
            break
    name = class_name(t)
    return f"{'an' if name[0] in 'AEIOUaeiou' else 'a'} {name}, {hint}"


def is_numpy_scalar(t: type) -> bool:
    """A scalar type NumPy itself defines (``np.float64``, ``np.int32``, ``np.bool_``...)."""
    return issubclass(t, np.generic) and t.__module__ == "numpy" and \
        not issubclass(t, (np.void, np.object_))


def is_jax_array(value: Any) -> bool:
    """A JAX array (or tracer), when JAX is loaded."""
    jax = sys.modules.get("jax")
    return jax is not None and isinstance(value, jax.Array)


def is_tracer(value: Any) -> bool:
    """A value JAX is tracing (``jax.grad``, ``jax.jit``...)."""
    core = getattr(sys.modules.get("jax"), "core", None)
    return core is not None and isinstance(value, core.Tracer)


def is_library(module: str) -> bool:
    """``module`` is ``minimanc`` or one of its modules."""
    return module == "minimanc" or module.startswith("minimanc.")


@functools.cache
def _slots(t: type) -> tuple[str, ...]:
    names = []
    for cls in t.__mro__:
        slots = cls.__dict__.get("__slots__", ())
        names += [s for s in ((slots,) if isinstance(slots, str) else slots)
                  if s not in ("__dict__", "__weakref__")]
    return tuple(names)


def state_of(obj: Any) -> dict:
    """An object's attributes: its ``__dict__`` and its slots."""
    out = dict(getattr(obj, "__dict__", ()))
    for slot in _slots(type(obj)):
        if hasattr(obj, slot):
            out[slot] = getattr(obj, slot)
    return out


def shared_state(obj: Any) -> dict:
    """The attributes a mirror shares with its original: all of them for a class of the
    notebook's cells, the public ones for a library object (its ``_private`` ones are
    caches, such as a module loaded on first use, and stay as the tests have them)."""
    state = state_of(obj)
    if is_library(type(obj).__module__):
        return {k: v for k, v in state.items() if not k.startswith("_")}
    return state


def contents(obj: Any) -> Any:
    """A mirror's state as a new value: what the tests' original becomes."""
    if isinstance(obj, np.ndarray):
        return obj.copy()
    if isinstance(obj, np.random.Generator):
        return obj.bit_generator.state
    if isinstance(obj, (list, set, dict)):
        return type(obj)(obj)
    return shared_state(obj)


def snapshot(obj: Any) -> Any:
    """What :func:`changed` compares a mirror with after a call (shallow)."""
    if isinstance(obj, (np.ndarray, np.random.Generator)):
        return contents(obj)
    return list(obj.items() if isinstance(obj, dict) else obj if isinstance(obj, (list, set))
                else shared_state(obj).items())


def changed(obj: Any, before: Any) -> bool:
    """Whether ``obj`` differs from its :func:`snapshot` ``before`` (contents replaced,
    added or removed; array bytes; generator state)."""
    if isinstance(obj, np.ndarray):
        return obj.shape != before.shape or obj.dtype != before.dtype or \
            obj.tobytes() != before.tobytes()
    if isinstance(obj, np.random.Generator):
        return obj.bit_generator.state != before
    now = snapshot(obj)
    if isinstance(obj, set):
        return {id(x) for x in now} != {id(x) for x in before}
    if isinstance(obj, list):
        return len(now) != len(before) or any(a is not b for a, b in zip(now, before))
    return len(now) != len(before) or any(a[0] != b[0] or a[1] is not b[1]
                                          for a, b in zip(now, before))


def update(original: Any, state: Any) -> None:
    """Give the tests' ``original`` the ``state`` its mirror has in the notebook (an array
    of another shape, or a read-only one, is left as it is)."""
    if isinstance(original, np.ndarray):
        if isinstance(state, np.ndarray) and state.shape == original.shape and \
                original.flags.writeable:
            original[...] = state
    elif isinstance(original, np.random.Generator):
        original.bit_generator.state = state
    elif isinstance(original, list):
        original[:] = state
    elif isinstance(original, (dict, set)):
        original.clear()
        original.update(state)
    else:
        for key in set(shared_state(original)) - set(state):
            delattr(original, key)
        for key, value in state.items():
            object.__setattr__(original, key, value)


def lookup(module: str, qualname: str) -> Any:
    """``module.qualname`` if ``module`` is imported and the chain of names resolves, else
    :data:`NOT_FOUND`."""
    owner = sys.modules.get(module)
    if owner is None or "<" in qualname:
        return NOT_FOUND
    for part in qualname.split("."):
        owner = getattr(owner, part, NOT_FOUND)
        if owner is NOT_FOUND:
            return NOT_FOUND
    return owner


def name_of(obj: Any) -> tuple[str, str] | None:
    """(module, qualname) naming ``obj`` itself, for an object a module defines."""
    if isinstance(obj, np.ufunc):
        module, qualname = "numpy", obj.__name__
    else:
        module = getattr(obj, "__module__", None)
        qualname = getattr(obj, "__qualname__", None) or getattr(obj, "__name__", None)
    if not isinstance(module, str) or not isinstance(qualname, str) or module == "__main__":
        return None
    return (module, qualname) if lookup(module, qualname) is obj else None
