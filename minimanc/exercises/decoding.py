"""Chapter 0 — decoding nodes into values, for the grader's wire (:mod:`~.wire`).

Mutable objects (lists, dicts, sets, arrays, objects) are first made as empty shells, then
filled; immutable ones (tuples, frozensets, named tuples, functions) are built on demand,
without recursion. On the tests' side decoding is strict: only the nodes of plain data
(:mod:`~.values`) are read, every field is checked, an object's class must be the
library's or one of the notebook's own cells, and nothing in a message is executed; a
malformed or refused node raises :class:`~.values.RefusedAnswer`. The notebook's side
also builds what only the tests send: modules, named objects, functions from their code,
objects from their ``__reduce_ex__`` parts.
"""

from __future__ import annotations

import builtins
import enum
import functools
import importlib
import marshal
import re
import sys
import types
from typing import Any

import numpy as np

from minimanc.exercises.values import (
    ARRAY_KINDS,
    NOT_FOUND,
    PLAIN_TYPES,
    RefusedAnswer,
    is_library,
    lookup,
    snapshot,
    update,
)

__all__ = ["Decoder"]

_MISSING = object()
_DTYPE = re.compile(r"^[<>|=]?[?biufcSUMm]\w*(\[\w+\])?$")
_SHELLS = {"obj": 0, "array": 0, "same": 0, "list": 1, "objarray": 1, "dict": 2, "set": 2, "rng": 3,
           "ref": 4}   # kind -> when it is filled (objects first: dict keys may hash them)


_IN_PLACE = frozenset({"none", "bool", "int", "float", "str"})
_LEAVES = frozenset({"none", "bool", "int", "float", "complex", "str", "bytes", "range",
                     "scalar", "jax", "handle", "enum"})   # nodes without children


def _text(value: Any) -> str:
    if type(value) is not str:
        raise RefusedAnswer("a string was expected")
    return value


@functools.cache
def _foreign_exception(name: str) -> type:
    """A stand-in class for an exception the notebook defined (only its name is kept)."""
    return type(name, (Exception,), {"__module__": "__main__"})


def _jax_from(array: np.ndarray) -> Any:
    """A JAX array of ``array`` when JAX is loaded and keeps its dtype, else ``array``."""
    jax = sys.modules.get("jax")
    if jax is None:
        return array
    if array.dtype.itemsize == 8 and array.dtype.kind in "fiuc" and \
            not jax.config.jax_enable_x64:
        return array
    return jax.numpy.asarray(array)


class Decoder:
    """Nodes → values: mutable objects first as empty shells, the rest on demand."""

    def __init__(self, wire, nodes: list, buffers: list[bytes]) -> None:
        if not isinstance(nodes, list):
            raise RefusedAnswer("a message without nodes")
        self.wire, self.nodes, self.buffers = wire, nodes, buffers
        self.objs: list = [_MISSING] * len(nodes)
        self.late: list[tuple[Any, Any]] = []
        self.classes: dict[tuple | None, type] = {}

    def run(self, root: Any) -> Any:
        if not self.wire.tests:   # the mirrors of this message only
            self.wire.fresh, self.wire.changed, self.wire.mirrors = [], set(), {}
        shells = []
        for index, node in enumerate(self.nodes):
            if not isinstance(node, list) or not node or not isinstance(node[0], str):
                raise RefusedAnswer(f"node {index} is not a node")
            if node[0] in _SHELLS:
                self.objs[index] = self.shell(node)
                shells.append(index)
            elif node[0] in _LEAVES:
                self.objs[index] = self.build(node)
        for index in sorted(shells, key=lambda i: _SHELLS[self.nodes[i][0]]):
            self.fill(index)
        value = self.get(root)
        for obj, state in self.late:   # reduced objects (the tests' only)
            if hasattr(obj, "__setstate__"):
                obj.__setstate__(state)
            else:
                slots = state[1] if isinstance(state, tuple) else {}
                obj.__dict__.update(state[0] if isinstance(state, tuple) else state)
                for key, item in (slots or {}).items():
                    setattr(obj, key, item)
        return value

    def index(self, i: Any) -> int:
        if type(i) is not int or not 0 <= i < len(self.nodes):
            raise RefusedAnswer(f"a reference to node {i!r}")
        return i

    def buffer(self, i: Any) -> bytes:
        if type(i) is not int or not 0 <= i < len(self.buffers):
            raise RefusedAnswer(f"a reference to buffer {i!r}")
        return self.buffers[i]

    def get(self, i: Any) -> Any:
        if type(i) is int and 0 <= i < len(self.objs) and self.objs[i] is not _MISSING:
            return self.objs[i]
        if type(i) is list:   # a value written in place
            if not i or i[0] not in _IN_PLACE:
                raise RefusedAnswer(f"a value written in place of kind {i[:1]!r}")
            return self.build(i)
        i = self.index(i)
        stack, visiting = [i], set()
        while stack:
            j = stack[-1]
            if self.objs[j] is not _MISSING:
                stack.pop()
                continue
            pending = [c for c in self.children(self.nodes[j]) if self.objs[c] is _MISSING]
            if pending:
                if j in visiting:
                    raise RefusedAnswer("a cycle through immutable values")
                visiting.add(j)
                stack += pending
                continue
            self.objs[j] = self.build(self.nodes[j])
            stack.pop()
        return self.objs[i]

    def children(self, node: list) -> list[int]:
        """The nodes an immutable node is built from (values written in place aside)."""
        kind = node[0]
        if kind in ("tuple", "frozenset"):
            refs = node[1]
        elif kind == "ntuple":
            refs = node[3]
        elif kind == "slice":
            refs = node[1:4]
        elif kind == "exception":
            refs = node[3:4]
        elif self.wire.tests:
            return []
        elif kind == "function":
            refs = node[3:4] + node[6:9]
        elif kind == "method":
            refs = node[1:2]
        elif kind == "reduce":
            refs = [c for c in node[1:6] if c != -1]
        else:
            return []
        return [self.index(c) for c in refs if type(c) is not list]

    def build(self, node: list) -> Any:
        kind = node[0]
        if kind == "none":
            return None
        if kind in ("bool", "int"):
            if type(node[1]) is not (bool if kind == "bool" else int):
                raise RefusedAnswer(f"a bad {kind}")
            return node[1]
        if kind == "float":
            return float(_text(node[1]))
        if kind == "complex":
            return complex(float(_text(node[1])), float(_text(node[2])))
        if kind == "str":
            return _text(node[1])
        if kind == "bytes":
            return self.buffer(node[1])
        if kind == "tuple":
            return tuple(self.get(c) for c in node[1])
        if kind == "frozenset":
            return frozenset(self.get(c) for c in node[1])
        if kind == "slice":
            return slice(*(self.get(c) for c in node[1:4]))
        if kind == "range":
            if len(node) != 4 or not all(type(v) is int for v in node[1:4]):
                raise RefusedAnswer("a bad range")
            return range(*node[1:4])
        if kind == "scalar":
            return self.array(["array", node[1], [], node[2]])[()]
        if kind == "jax":
            return _jax_from(self.array(node).copy())
        if kind == "handle":
            return self.handle(node[1])
        if kind == "ntuple":
            return self.cls(node[1], node[2], tuple)._make(self.get(c) for c in node[3])
        if kind == "enum":
            return self.cls(node[1], node[2], enum.Enum)[_text(node[3])]
        if kind == "exception":
            return self.exception(node)
        if self.wire.tests:
            raise RefusedAnswer(f"a value of kind {kind!r}")
        return self.build_argument(node)

    def build_argument(self, node: list) -> Any:
        """What only the tests send: modules, names, functions by code, reduced objects."""
        kind = node[0]
        if kind == "module":
            return importlib.import_module(node[1])
        if kind == "global":
            importlib.import_module(node[1])
            found = lookup(node[1], node[2])
            if found is NOT_FOUND:
                raise ImportError(f"cannot find {node[1]}.{node[2]} in the notebook")
            return found
        if kind == "main":
            if node[1] not in self.wire.namespace:
                raise NameError(f"name {node[1]!r} is not defined in the notebook")
            return self.wire.namespace[node[1]]
        if kind == "method":
            return getattr(self.get(node[1]), node[2])
        if kind == "function":
            if tuple(node[1]) != tuple(sys.version_info[:2]):
                raise RuntimeError(f"the tests run Python {node[1]}, the notebook "
                                   f"{list(sys.version_info[:2])}: use one interpreter")
            scope = self.get(node[3])
            if isinstance(scope, str):
                scope = vars(importlib.import_module(scope))
            else:
                scope.setdefault("__builtins__", builtins)
            cells = tuple(types.CellType(v) for v in self.get(node[8]))
            fn = types.FunctionType(marshal.loads(self.buffer(node[2])), scope, node[4],
                                    self.get(node[6]), cells or None)
            fn.__qualname__, fn.__kwdefaults__ = node[5], self.get(node[7])
            return fn
        if kind == "reduce":
            obj = self.get(node[1])(*self.get(node[2]))
            if node[3] != -1:
                self.late.append((obj, self.get(node[3])))
            if node[4] != -1:
                obj.extend(self.get(node[4]))
            for key, item in (self.get(node[5]) if node[5] != -1 else {}).items():
                obj[key] = item
            return obj
        raise RuntimeError(f"unknown node {kind!r}")

    def array(self, node: list) -> np.ndarray:
        dtype, shape = _text(node[1]), node[2]
        if not _DTYPE.match(dtype) or not isinstance(shape, list) or \
                not all(type(n) is int and n >= 0 for n in shape):
            raise RefusedAnswer(f"an array of dtype {dtype!r} and shape {shape!r}")
        dtype = np.dtype(dtype)
        if dtype.kind not in ARRAY_KINDS or dtype.fields is not None or dtype.subdtype is not None:
            raise RefusedAnswer(f"an array of dtype {dtype}")
        return np.frombuffer(self.buffer(node[3]), dtype=dtype).reshape(shape)

    def handle(self, hid: Any) -> Any:
        if type(hid) is not int:
            raise RefusedAnswer("a bad function handle")
        if not self.wire.tests:
            return self.wire.callables[hid]
        if hid not in self.wire.proxies:
            self.wire.proxies[hid] = self.wire.proxy(self.wire, hid)
        return self.wire.proxies[hid]

    def cls(self, module: Any, qualname: Any, base: type | None = None) -> type:
        key = (module, qualname, base) if type(module) is type(qualname) is str else None
        found = self.classes.get(key)
        if found is None:
            found = self.classes[key] = self.resolve(module, qualname, base)
        return found

    def resolve(self, module: Any, qualname: Any, base: type | None) -> type:
        module, qualname = _text(module), _text(qualname)
        if not self.wire.tests:
            if module == "__main__":
                return self.build_argument(["main", qualname])
            return self.build_argument(["global", module, qualname])
        cls = self.wire.classes.get(qualname, NOT_FOUND) if module == "__main__" else \
            lookup(module, qualname) if is_library(module) else NOT_FOUND
        if not isinstance(cls, type) or cls.__module__ != module or \
                (base is not None and not issubclass(cls, base)):
            raise RefusedAnswer(f"an object of class {qualname}, which the tests do not know "
                                "(they read the library's classes and those of the "
                                "notebook's own cells)")
        if base is None and (issubclass(cls, (BaseException, tuple, enum.Enum)) or any(
                b in PLAIN_TYPES or b is np.ndarray for b in cls.__mro__[1:-1])):
            raise RefusedAnswer(f"an object of class {qualname} sent by its attributes")
        return cls

    def exception(self, node: list) -> BaseException:
        module, qualname = _text(node[1]), _text(node[2])
        cls = getattr(builtins, qualname, None) if module == "builtins" else \
            lookup(module, qualname) if is_library(module) else None
        if not (isinstance(cls, type) and issubclass(cls, BaseException)):
            cls = _foreign_exception(qualname.rsplit(".", 1)[-1])
        exc = cls.__new__(cls)
        exc.args = tuple(self.get(node[3]))
        return exc

    def shell(self, node: list) -> Any:
        kind = node[0]
        if kind == "ref":
            if not self.wire.tests or type(node[1]) is not int or \
                    node[1] not in self.wire.originals:
                raise RefusedAnswer("a reference to an object the tests did not send")
            return self.wire.originals[node[1]]
        if kind == "same":   # an array the notebook was sent before, unchanged since
            if self.wire.tests or node[1] not in self.wire.kept:
                raise RefusedAnswer("a reference to an array never sent")
            obj = self.wire.kept[node[1]]
        elif kind == "array":
            obj = self.array(node).copy()
            if not self.wire.tests and node[-1] is not None:
                self.wire.kept[node[-1]] = obj
        elif kind == "objarray":
            shape = node[1]
            if not isinstance(shape, list) or not all(type(n) is int and n >= 0 for n in shape):
                raise RefusedAnswer("an object array of a bad shape")
            obj = np.empty(shape, dtype=object)
        elif kind == "obj":
            cls = self.cls(node[1], node[2])
            obj = object.__new__(cls) if cls.__new__ is object.__new__ else cls.__new__(cls)
        elif kind == "rng":
            if self.wire.tests:
                raise RefusedAnswer("a random generator")
            obj = np.random.Generator(self.cls(node[1], node[2])())
        else:
            obj = {"list": list, "dict": dict, "set": set}[kind]()
        if not self.wire.tests and node[-1] is not None:
            self.wire.mirrors[id(obj)] = (node[-1], obj)
        return obj

    def fill(self, index: int) -> None:
        node, obj = self.nodes[index], self.objs[index]
        kind = node[0]
        if kind == "list":
            obj.extend(self.get(c) for c in node[1])
        elif kind == "set":
            obj.update(self.get(c) for c in node[1])
        elif kind == "dict":
            items = node[1]
            if len(items) % 2:
                raise RefusedAnswer("a dict with a key and no value")
            for k, v in zip(items[::2], items[1::2]):
                obj[self.get(k)] = self.get(v)
        elif kind == "objarray":
            flat = [self.get(c) for c in node[2]]
            if len(flat) != obj.size:
                raise RefusedAnswer("an object array of the wrong size")
            for k, item in enumerate(flat):
                obj.reshape(-1)[k] = item
        elif kind == "obj":
            pairs = node[3]
            if len(pairs) % 2 or not all(type(k) is str for k in pairs[::2]) or \
                    (self.wire.tests and any(k.startswith("__") for k in pairs[::2])):
                raise RefusedAnswer(f"the attributes of a {type(obj).__qualname__}")
            for key, value in zip(pairs[::2], pairs[1::2]):
                object.__setattr__(obj, key, self.get(value))
        elif kind == "rng":
            obj.bit_generator.state = self.get(node[3])
        elif kind == "ref" and len(node) > 2:
            update(obj, self.get(node[2]))
            self.wire.digests.pop(node[1], None)   # send it in full next time
        if not self.wire.tests and kind != "ref" and node[-1] is not None:
            self.wire.fresh.append((obj, snapshot(obj)))

