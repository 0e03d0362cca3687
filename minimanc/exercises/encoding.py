"""Chapter 0 — encoding values as nodes, for the grader's wire (:mod:`~.wire`).

A value becomes a list of nodes (JSON-ready lists whose first item names the kind) and a
list of byte buffers (array data). Objects are visited iteratively, each given an index
the first time it is met, so shared objects stay shared, cycles close and a chain of
40,000 objects needs no recursion. The tests' side sends anything (functions by code,
objects by their own ``__reduce_ex__``); the notebook's side sends only what the tests
read (:mod:`~.values`) and raises :class:`~.values.RefusedAnswer` for anything else.
"""

from __future__ import annotations

import enum
import functools
import hashlib
import marshal
import sys
import types
from typing import Any

import numpy as np

from minimanc.autodiff import Box
from minimanc.exercises.values import (
    ARRAY_KINDS,
    PLAIN_TYPES,
    RefusedAnswer,
    class_name,
    contents,
    is_jax_array,
    is_library,
    is_numpy_scalar,
    is_tracer,
    lookup,
    name_of,
    refusal,
    state_of,
)

__all__ = ["Encoder"]

_NAMED = (type, types.ModuleType)   # sent by name, never by state
_FUNCTIONS = (types.FunctionType, types.BuiltinFunctionType, types.MethodType,
              functools.partial, np.ufunc, type)


def _code_names(code: types.CodeType) -> set[str]:
    """The global names ``code`` and the functions inside it read."""
    names, todo = set(), [code]
    while todo:
        c = todo.pop()
        names.update(c.co_names)
        todo += [k for k in c.co_consts if isinstance(k, types.CodeType)]
    return names


class Encoder:
    """Values → nodes, iteratively: each object gets an index the first time it is met."""

    def __init__(self, wire) -> None:
        self.wire = wire
        self.nodes: list = []
        self.buffers: list[bytes] = []
        self.memo: dict[int, int] = {}
        self.keep: list = []
        self.todo: list = []
        self.scopes: dict[tuple[int, int], dict] = {}
        self.parts: set[int] = set()   # ids of the encoder's own containers: never mirrored

    def ref(self, obj: Any) -> int | list:
        """The index of ``obj``'s node; a float, int, bool, str or ``None`` is written in
        place instead (most of a message's values: no node, no index)."""
        t = type(obj)
        if t is float:
            return ["float", repr(obj)]
        if t is int or t is bool:
            return [t.__name__, obj]
        if t is str:
            return ["str", obj]
        if obj is None:
            return ["none"]
        index = self.memo.get(id(obj))
        if index is None:
            index = self.memo[id(obj)] = len(self.nodes)
            self.keep.append(obj)
            self.nodes.append(None)
            self.todo.append((index, obj))
        return index

    def part(self, obj: Any) -> int:
        """``ref`` of a container the encoder made (a function's globals, a generator's
        state): sent without an id, so the notebook does not mirror it."""
        self.parts.add(id(obj))
        return self.ref(obj)

    def buffer(self, data: bytes) -> int:
        self.buffers.append(bytes(data))
        return len(self.buffers) - 1

    def run(self, root: Any) -> int:
        top = self.ref(root)
        while self.todo:
            index, obj = self.todo.pop()
            self.nodes[index] = self.node(obj)
        return top

    def node(self, obj: Any) -> list:
        t, wire = type(obj), self.wire
        if not wire.tests and id(obj) in wire.mirrors:
            cid, _ = wire.mirrors[id(obj)]
            if id(obj) in wire.changed:
                return ["ref", cid, self.ref(contents(obj))]
            return ["ref", cid]
        if obj is None:
            return ["none"]
        if t is bool or t is int:
            return [t.__name__, obj]
        if t is float:
            return ["float", repr(obj)]
        if t is complex:
            return ["complex", repr(obj.real), repr(obj.imag)]
        if t is str:
            return ["str", obj]
        if t is bytes:
            return ["bytes", self.buffer(obj)]
        if t is slice:
            return ["slice", self.ref(obj.start), self.ref(obj.stop), self.ref(obj.step)]
        if t is range:
            return ["range", obj.start, obj.stop, obj.step]
        if t is tuple or t is frozenset:
            return [t.__name__, [self.ref(x) for x in obj]]
        if t in (list, set, dict, np.ndarray, np.random.Generator):
            mirrored = wire.tests and id(obj) not in self.parts
            return self.mutable(obj, wire.register(obj) if mirrored else None)
        if is_numpy_scalar(t):
            return ["scalar", obj.dtype.str, self.buffer(obj.tobytes())]
        if is_jax_array(obj) and not is_tracer(obj):
            array = np.asarray(obj)
            return ["jax", array.dtype.str, list(array.shape), self.buffer(array.tobytes())]
        if isinstance(obj, BaseException):
            args = obj.args if all(type(a) in (str, int, float, bool, type(None))
                                   for a in obj.args) else (str(obj),)
            return ["exception", t.__module__, t.__qualname__, self.ref(tuple(args))]
        return self.answer(obj) if not wire.tests else self.argument(obj)

    def mutable(self, obj: Any, cid: int | None) -> list:
        t = type(obj)
        if t is np.ndarray:
            if obj.dtype.hasobject:
                return ["objarray", list(obj.shape), [self.ref(x) for x in obj.reshape(-1)], cid]
            if obj.dtype.kind not in ARRAY_KINDS or obj.dtype.fields is not None:
                raise RefusedAnswer(f"an array of dtype {obj.dtype}, which cannot be sent")
            data = np.ascontiguousarray(obj)
            if cid is not None:   # the notebook still holds this array as it was last sent?
                digest = hashlib.blake2b(data.reshape(-1).view(np.uint8), digest_size=16)
                key = (obj.shape, obj.dtype.str, digest.digest())
                if self.wire.digests.get(cid) == key:
                    return ["same", cid]
                self.wire.digests[cid] = key
            return ["array", obj.dtype.str, list(obj.shape), self.buffer(data.tobytes()), cid]
        if t is np.random.Generator:
            bits = type(obj.bit_generator)
            return ["rng", bits.__module__, bits.__qualname__,
                    self.part(obj.bit_generator.state), cid]
        if t is dict:
            return ["dict", [self.ref(x) for kv in obj.items() for x in kv], cid]
        return [t.__name__, [self.ref(x) for x in obj], cid]

    def answer(self, obj: Any) -> list:
        """The notebook's side: a function becomes a handle, a library or notebook object
        goes by state, anything else is refused."""
        t = type(obj)
        module = t.__module__
        known = module == "__main__" or is_library(module)
        if isinstance(obj, _FUNCTIONS) or (callable(obj) and not known):
            name = getattr(obj, "__name__", "a function")
            return ["handle", self.wire.offer(obj, f"the function {name} it returned")]
        if not known or any(b in PLAIN_TYPES or b is np.ndarray for b in t.__mro__[1:-1]
                            if not (b is tuple and hasattr(t, "_fields"))):
            raise RefusedAnswer(refusal(obj))
        return self.instance(obj, None)

    def argument(self, obj: Any) -> list:
        """The tests' side: modules, classes and functions by name or by code; objects by
        state, or by their own ``__reduce_ex__``."""
        t = type(obj)
        if t.__reduce_ex__ is object.__reduce_ex__ and t.__reduce__ is object.__reduce__ \
                and not isinstance(obj, _NAMED) and not callable(obj):   # a plain object
            if isinstance(obj, Box):
                raise TypeError("a traced value cannot be sent to the notebook")
            return self.instance(obj, self.wire.register(obj))
        if self.wire.proxy is not None and isinstance(obj, self.wire.proxy):
            return ["handle", obj.hid]
        if isinstance(obj, types.ModuleType):
            return ["module", obj.__name__]
        named = name_of(obj)
        if named is not None:
            return ["global", *named]
        if isinstance(obj, type) and obj.__module__ == "__main__":
            return ["main", obj.__qualname__]
        if isinstance(obj, types.FunctionType):
            return self.function(obj)
        if isinstance(obj, (types.MethodType, types.BuiltinMethodType)) and \
                not isinstance(obj.__self__, types.ModuleType):
            return ["method", self.ref(obj.__self__), obj.__name__]
        if is_tracer(obj):
            raise TypeError(f"a traced value ({class_name(t)}) cannot be sent to the notebook")
        if t.__reduce_ex__ is object.__reduce_ex__ and t.__reduce__ is object.__reduce__:
            return self.instance(obj, self.wire.register(obj))
        parts = obj.__reduce_ex__(4)
        if isinstance(parts, str):
            module = getattr(obj, "__module__", None)
            if isinstance(module, str) and lookup(module, parts) is obj:
                return ["global", module, parts]
            raise TypeError(f"cannot send a {class_name(t)} to the notebook")
        parts = tuple(parts) + (None,) * (5 - len(parts))
        listed = self.part(list(parts[3])) if parts[3] is not None else -1
        mapped = self.part(dict(parts[4])) if parts[4] is not None else -1
        state = self.ref(parts[2]) if parts[2] is not None else -1
        return ["reduce", self.ref(parts[0]), self.ref(tuple(parts[1])), state, listed, mapped]

    def instance(self, obj: Any, cid: int | None) -> list:
        t = type(obj)
        if isinstance(obj, enum.Enum):
            return ["enum", t.__module__, t.__qualname__, obj.name]
        if isinstance(obj, tuple):
            return ["ntuple", t.__module__, t.__qualname__, [self.ref(x) for x in obj]]
        pairs = [x for k, v in state_of(obj).items() for x in (k, self.ref(v))]
        return ["obj", t.__module__, t.__qualname__, pairs, cid]

    def function(self, fn: types.FunctionType) -> list:
        """A function by code: a cell's with copies of the globals it reads, a library
        closure's with its module's globals (the notebook's own module)."""
        code = fn.__code__
        if fn.__module__ == "__main__" or fn.__module__ not in sys.modules:
            key = (id(fn.__globals__), id(code))
            if key not in self.scopes:
                self.scopes[key] = {k: fn.__globals__[k] for k in sorted(_code_names(code))
                                    if k in fn.__globals__ and k != "__builtins__"}
            where = self.part(self.scopes[key])
        else:
            where = self.ref(fn.__module__)
        cells = tuple(c.cell_contents for c in fn.__closure__ or ())
        return ["function", list(sys.version_info[:2]), self.buffer(marshal.dumps(code)),
                where, fn.__name__, fn.__qualname__, self.ref(fn.__defaults__),
                self.ref(fn.__kwdefaults__), self.ref(cells)]

