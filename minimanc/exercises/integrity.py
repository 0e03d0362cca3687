"""Chapter 0 — grading integrity: pristine tools for the grade cells and strict answers.

The student's cells and the grade cells share one kernel, so student code can
reach everything a grade cell relies on. :func:`grade` (``grading.py``) therefore
runs, inside the kernel:

* :func:`capture`, before any student cell: it imports what the solutions
  notebook imports and records every attribute of the watched modules
  (``builtins``, ``math``, ``cmath``, ``operator``, ``numpy.*``, ``minimanc.*``),
  the code and defaults of their Python functions, the methods of their Python
  classes and a few IPython and ``sys`` hooks (input and AST transformers,
  ``pre_run_cell`` callbacks, the custom exception handler, ``sys.displayhook``,
  ``sys.stdout``/``stderr``, trace and profile functions);
* :func:`restore`, before each grade cell: it puts back whatever student code
  replaced and prints the names (the grader reports them on the grade cell's row);
* :func:`run_grade`: it executes the grade cell in a namespace of its own, a copy
  of the student's globals in which the names the solutions notebook imports
  (``np``, ``dmp``, ...) are the captured objects, builtins are a captured copy
  and globals that hide a builtin are removed; the functions the exercise asks
  for are wrapped (:func:`strict_answer`) so that each call is followed by a
  tamper check and its value is refused unless it has an exact plain type;
* :func:`check_after`, after the grade cell: anything replaced while the tests
  ran voids the grade cell.

This is an in-process guard: it stops code that patches the tools, rebinds
names or returns values with a rigged ``__eq__``; code that rewrites this
module or later cells' text (an IPython input transformer that hides itself)
is beyond it.
"""

from __future__ import annotations

import ast
import builtins
import contextlib
import functools
import importlib
import json
import operator
import sys
import types
from collections.abc import Callable, Sequence
from dataclasses import fields, is_dataclass
from typing import Any

__all__ = [
    "WATCHED",
    "Capture",
    "RefusedAnswer",
    "TamperedDuringGrading",
    "capture",
    "check_after",
    "current",
    "defined_names",
    "imported_names",
    "plain_value",
    "read_names",
    "restore",
    "run_grade",
    "strict_answer",
]

WATCHED = ("builtins", "math", "cmath", "operator", "numpy", "minimanc")
"""Top-level packages whose module attributes are captured and restored."""

_MISSING = object()
_IS_NOT = operator.is_not
_ALWAYS = ("math", "cmath", "operator", "numpy", "numpy.linalg", "numpy.random", "numpy.testing")
_EVENTS = ("pre_run_cell", "pre_execute")  # callbacks that would see a grade cell's text
# callbacks after a cell could print a forged line after the grader's; removed without
# a word (matplotlib's inline backend registers one on its first import)
_QUIET_EVENTS = ("post_run_cell", "post_execute")
_SYS_HOOKS = ("displayhook", "stdout", "stderr")  # the kernel sets sys.excepthook per cell


class RefusedAnswer(AssertionError):
    """An answer (a value the student's function returned, or a graded value the
    solution cell binds) does not have an exact plain type."""


class TamperedDuringGrading(AssertionError):
    """Student code replaced a grading tool while a grade cell ran."""


# ----------------------------------------------------------------- what grade cells read
def read_names(source: str) -> set[str]:
    """Names a grade cell reads and never binds (empty when it is not valid Python)."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return set()
    names = [n for n in ast.walk(tree) if isinstance(n, ast.Name)]
    bound = {n.id for n in names if not isinstance(n.ctx, ast.Load)}
    bound |= {n.name for n in ast.walk(tree)
              if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))}
    return {n.id for n in names if isinstance(n.ctx, ast.Load)} - bound


def defined_names(source: str) -> tuple[list[str], list[str]]:
    """(names a cell binds at top level, classes it defines anywhere)."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return [], []
    top = []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            top.append(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            top += [n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)]
    classes = [n.name for n in ast.walk(tree) if isinstance(n, ast.ClassDef)]
    return list(dict.fromkeys(top)), classes


def imported_names(sources: Sequence[str]) -> str:
    """The top-level ``import`` statements of ``sources`` as one block of code."""
    lines = []
    for source in sources:
        try:
            tree = ast.parse(source)
        except SyntaxError:
            continue
        lines += [ast.unparse(node) for node in tree.body
                  if isinstance(node, (ast.Import, ast.ImportFrom))]
    return "\n".join(dict.fromkeys(lines))


# ---------------------------------------------------------------------------- capture
def _watched_modules() -> list[types.ModuleType]:
    return [m for name, m in list(sys.modules.items())
            if isinstance(m, types.ModuleType) and name.split(".")[0] in WATCHED]


def _watched_items(module: str, namespace: dict) -> list[tuple[str, Any]]:
    """The attributes worth restoring: not dunders (but ``__import__`` and
    ``__build_class__`` of ``builtins``, whose other ``_`` names IPython sets), not
    mutable containers or arrays (data, not tools), not ``None`` (set lazily)."""
    out = []
    for k, v in namespace.items():
        if module == "builtins":
            keep = k not in _KERNEL_BUILTINS and (k in _BUILTIN_DUNDERS or not k.startswith("_"))
        else:
            keep = not (k.startswith("__") and k.endswith("__"))
        if keep and v is not None and not isinstance(v, (dict, list, set, bytearray)) \
                and not hasattr(v, "__array_interface__"):
            out.append((k, v))
    return out


_BUILTIN_DUNDERS = ("__import__", "__build_class__")
_KERNEL_BUILTINS = ("input",)  # the kernel binds a fresh input() for every cell


class Capture:
    """Pristine copies of the tools grade cells rely on; see the module docstring.

    ``preamble`` is the import block of the solutions notebook; the names it binds
    are the ones grade cells see (:attr:`preamble`). ``classes`` names the classes
    the notebook itself defines, whose instances are accepted as answers.
    """

    def __init__(self, preamble: str = "", classes: Sequence[str] = ()) -> None:
        space: dict[str, Any] = {"__builtins__": builtins}
        for module in _ALWAYS:  # numpy loads its submodules lazily: import them to watch them
            with contextlib.suppress(ImportError):
                importlib.import_module(module)
        for line in preamble.splitlines():
            # one import at a time: a missing optional package skips only its line (the
            # student's own import cell reports it)
            with contextlib.suppress(Exception):
                exec(compile(line, "<minimanc grading imports>", "exec"), space)  # noqa: S102
        del space["__builtins__"]
        self.preamble = space
        self.notebook_classes = set(classes)
        self.builtins = dict(vars(builtins))
        self.modules: list[tuple[str, dict, list[tuple[str, Any]]]] = []
        self.codes: list[tuple[str, types.FunctionType, Any, Any, Any]] = []
        self.classes: list[tuple[str, type, list[tuple[str, Any]]]] = []
        seen: set[int] = set()
        for module in _watched_modules():
            namespace = vars(module)
            items = _watched_items(module.__name__, namespace)
            self.modules.append((module.__name__, namespace, items))
            for k, v in items:
                if id(v) in seen:
                    continue
                seen.add(id(v))
                where = f"{module.__name__}.{k}"
                if isinstance(v, types.FunctionType):
                    self.codes.append((where, v, v.__code__, v.__defaults__, v.__kwdefaults__))
                elif isinstance(v, type) and not v.__flags__ & _IMMUTABLE_TYPE:
                    # like a module's attributes: not a class's data, nor one still None
                    # (set lazily: a progress bar's monitor thread on its first use)
                    members = [(n, m) for n, m in vars(v).items()
                               if n not in ("__dict__", "__weakref__", "__doc__")
                               and m is not None and not isinstance(m, (dict, list, set))]
                    self.classes.append((where, v, members))
        self.library_types = {v for name, _, items in self.modules
                              if name.split(".")[0] == "minimanc"
                              for _, v in items if isinstance(v, type)}
        numpy = sys.modules.get("numpy")
        self.numpy = numpy
        self.numpy_types = ({t for t in numpy.sctypeDict.values() if isinstance(t, type)}
                            if numpy is not None else set())
        self.hooks = _hooks()

    def replaced(self, fix: bool = True) -> list[str]:
        """Dotted names of captured objects that differ now; ``fix`` puts them back."""
        out = []
        for name, namespace, items in self.modules:
            for k, v in items:
                if namespace.get(k, _MISSING) is not v:
                    out.append(f"{name}.{k}")
                    if fix:
                        namespace[k] = v
        for where, fn, code, defaults, kwdefaults in self.codes:
            if (fn.__code__ is not code or fn.__defaults__ is not defaults
                    or fn.__kwdefaults__ is not kwdefaults):
                out.append(f"{where}.__code__")
                if fix:
                    fn.__code__, fn.__defaults__, fn.__kwdefaults__ = code, defaults, kwdefaults
        for where, cls, members in self.classes:
            namespace = vars(cls)
            for k, v in members:
                if namespace.get(k, _MISSING) is not v:
                    out.append(f"{where}.{k}")
                    if fix:
                        setattr(cls, k, v)
        out += _restore_hooks(self.hooks, fix)
        return list(dict.fromkeys(out))

    def is_plain_type(self, t: type) -> bool:
        """True for the exact types an answer may have (see :func:`plain_value`)."""
        return (t in _PLAIN or t in self.numpy_types or t in self.library_types
                or (t.__module__ == "__main__" and t.__qualname__ in self.notebook_classes)
                or _is_jax_type(t))


_IMMUTABLE_TYPE = 1 << 8  # Py_TPFLAGS_IMMUTABLETYPE: built-in and static types
_PLAIN = frozenset({type(None), bool, int, float, complex, str, bytes, range, slice,
                    type(Ellipsis), tuple, list, dict, set, frozenset})
_CALLABLE = (types.FunctionType, types.BuiltinFunctionType, types.MethodType,
             functools.partial)


def _is_jax_type(t: type) -> bool:
    """JAX arrays and tracers: a class that JAX's own modules define (one merely
    claiming a ``jax`` ``__module__`` is not found there)."""
    jax = sys.modules.get("jax")
    if jax is None or not t.__module__.startswith(("jax", "jaxlib")):
        return False
    home = sys.modules.get(t.__module__)
    if home is None or getattr(home, t.__name__, None) is not t:
        return False
    core = sys.modules.get("jax._src.core")
    tracer = getattr(core, "Tracer", None)
    return issubclass(t, (jax.Array, tracer) if tracer is not None else jax.Array)


def _hooks() -> dict[str, Any]:
    hooks: dict[str, Any] = {f"sys.{h}": getattr(sys, h, None) for h in _SYS_HOOKS}
    hooks["sys.gettrace"], hooks["sys.getprofile"] = sys.gettrace(), sys.getprofile()
    ip = _ipython()
    if ip is not None:
        for attr in _TRANSFORMERS:
            hooks[f"IPython.{attr}"] = list(getattr(ip, attr, []))
        callbacks = ip.events.callbacks
        for event in _EVENTS + _QUIET_EVENTS:
            hooks[f"IPython.events.{event}"] = list(callbacks.get(event, []))
        hooks["IPython.custom_exceptions"] = ip.custom_exceptions
        hooks["IPython.CustomTB"] = ip.CustomTB
    return hooks


_TRANSFORMERS = ("input_transformers_cleanup", "input_transformers_post", "ast_transformers")


def _ipython():
    get = getattr(sys.modules.get("IPython"), "get_ipython", None)
    return get() if get else None


def _same_list(current: list, kept: list) -> bool:
    return len(current) == len(kept) and all(a is b for a, b in zip(current, kept))


def _restore_hooks(hooks: dict[str, Any], fix: bool) -> list[str]:
    out = []
    for attr in _SYS_HOOKS:
        if getattr(sys, attr, None) is not hooks[f"sys.{attr}"]:
            out.append(f"sys.{attr}")
            if fix:
                setattr(sys, attr, hooks[f"sys.{attr}"])
    for get, set_, key in ((sys.gettrace, sys.settrace, "sys.gettrace"),
                           (sys.getprofile, sys.setprofile, "sys.getprofile")):
        if get() is not hooks[key]:
            out.append(key.replace("get", "set"))
            if fix:
                set_(hooks[key])
    ip = _ipython()
    if ip is None or "IPython.CustomTB" not in hooks:
        return out
    for attr in _TRANSFORMERS:
        current = getattr(ip, attr)
        if not _same_list(current, hooks[f"IPython.{attr}"]):
            out.append(f"IPython.{attr}")
            if fix:
                current[:] = hooks[f"IPython.{attr}"]
    for event in _EVENTS + _QUIET_EVENTS:
        current = ip.events.callbacks.setdefault(event, [])
        if not _same_list(current, hooks[f"IPython.events.{event}"]):
            if event in _EVENTS:
                out.append(f"IPython.events.{event}")
            if fix:
                current[:] = hooks[f"IPython.events.{event}"]
    if (ip.custom_exceptions is not hooks["IPython.custom_exceptions"]
            or ip.CustomTB is not hooks["IPython.CustomTB"]):
        out.append("IPython.set_custom_exc")
        if fix:
            ip.custom_exceptions = hooks["IPython.custom_exceptions"]
            ip.CustomTB = hooks["IPython.CustomTB"]
    return out


# ------------------------------------------------------------------- strict answers
def _type_name(t: type) -> str:
    return t.__qualname__ if t.__module__ in ("builtins", "__main__") else \
        f"{t.__module__}.{t.__qualname__}"


def _expected(t: type, capture: Capture) -> str:
    """What a refused type should have been: its first plain base, or a hint."""
    for base in t.__mro__[1:]:
        if base in _PLAIN or base in capture.numpy_types:
            article = "an" if base.__qualname__[0] in "aeiou" else "a"
            return f"{article} {base.__qualname__} subclass; return a plain {base.__qualname__}"
        if capture.numpy is not None and base is capture.numpy.ndarray:
            return "an ndarray subclass; return a plain numpy.ndarray (np.asarray)"
    return ("not a plain type; return a float, int, bool, str, tuple, list, dict, "
            "a numpy array or scalar, or a library object")


def plain_value(value: Any, where: str, capture: Capture, depth: int = 0,
                verb: str = "returned") -> None:
    """Refuse ``value`` unless it and everything it holds has an exact plain type.

    Plain: ``None``, ``bool``, ``int``, ``float``, ``complex``, ``str``, ``bytes``,
    ``tuple``/``list``/``dict``/``set`` of plain values, ``numpy.ndarray`` (exact type,
    a numeric dtype; object arrays element by element), NumPy scalars, instances of
    ``minimanc`` classes and of the classes the notebook defines, JAX arrays and
    tracers, functions (the grade cell wraps them). A subclass of any of these is
    refused: it could override ``__eq__`` or ``__array_function__``.
    """
    t = type(value)
    if depth > 20:
        return
    if isinstance(value, _CALLABLE) and t in _CALLABLE:
        return
    if capture.numpy is not None and t is capture.numpy.ndarray:
        if value.dtype.hasobject:
            for item in value.reshape(-1)[:10_000]:
                plain_value(item, where, capture, depth + 1, verb)
        return
    if not capture.is_plain_type(t):
        raise RefusedAnswer(f"{where} {verb} a {_type_name(t)}, {_expected(t, capture)}")
    if t in (tuple, list, set, frozenset) or (isinstance(value, tuple) and t is not tuple):
        for item in value:
            plain_value(item, where, capture, depth + 1, verb)
    elif t is dict:
        for k, v in value.items():
            plain_value(k, where, capture, depth + 1, verb)
            plain_value(v, where, capture, depth + 1, verb)
    elif t in capture.library_types and is_dataclass(value):
        for f in fields(value):
            plain_value(getattr(value, f.name), where, capture, depth + 1, verb)


def strict_answer(name: str, fn: Callable, capture: Capture) -> Callable:
    """``fn`` as a grade cell sees it: after each call, anything the call replaced is
    restored and the call fails (:class:`TamperedDuringGrading`); a value that is not
    plain (:func:`plain_value`) fails (:class:`RefusedAnswer`). Returned functions
    are wrapped the same way."""

    @functools.wraps(fn)
    def answer(*args, **kwargs):
        baseline = _active_baseline()
        try:
            value = fn(*args, **kwargs)
        finally:
            tampered = baseline.replaced() if baseline is not None else []
        if tampered:
            raise TamperedDuringGrading(
                f"{name} replaced {', '.join(tampered[:5])} while the tests ran")
        plain_value(value, name, capture)
        if isinstance(value, _CALLABLE):
            return strict_answer(f"the function returned by {name}", value, capture)
        return value

    return answer


# ----------------------------------------------------------------- the kernel side
_STATE: dict[str, Any] = {}


def capture(preamble: str = "", classes: Sequence[str] = ()) -> Capture:
    """Record the pristine tools (call before any student cell); see :class:`Capture`."""
    _STATE["capture"] = Capture(preamble, classes)
    _STATE.pop("baseline", None)
    return _STATE["capture"]


def current() -> Capture:
    """The active capture (raises when :func:`capture` has not run in this process)."""
    if "capture" not in _STATE:
        raise RuntimeError("minimanc grading: no capture in this kernel")
    return _STATE["capture"]


def _active_baseline() -> _Baseline | None:
    return _STATE.get("baseline")


def restore(token: str, user: dict | None = None, read: Sequence[str] = (),
            answers: Sequence[str] = ()) -> list[str]:
    """Put back every captured object student code replaced and print ``token`` and
    what was found as one JSON line (read by :func:`minimanc.exercises.grade`).

    With the student's globals ``user`` and the names the next grade cell ``read``s,
    it also names the globals that the grade cell will not use as they are: an
    import of the solutions notebook bound to something else, a global hiding a
    builtin (the grade cell gets the captured ones, see :func:`run_grade`).
    """
    cap = current()
    names = cap.replaced(fix=True)
    for name in read if user is not None else ():
        if name not in user or name in answers:
            continue
        if name in cap.preamble and user[name] is not cap.preamble[name]:
            names.append(f"the name {name} (rebound)")
        elif name not in cap.preamble and name in cap.builtins and \
                user[name] is not cap.builtins[name]:
            names.append(f"the builtin {name} (hidden by a global)")
    print(f"{token}:{json.dumps(names)}")
    return names


def check_after(token: str) -> list[str]:
    """Like :func:`restore`, after a grade cell: what changed while it ran."""
    _STATE.pop("baseline", None)
    return restore(token)


def run_grade(source: str, user: dict, answers: Sequence[str] = (),
              filename: str = "<grade cell>") -> None:
    """Execute a grade cell's ``source`` against the student's globals ``user``.

    The cell runs in a copy of ``user`` where the solutions notebook's imports are
    the captured objects, ``__builtins__`` is the captured builtins (a global that
    hides a builtin the cell reads is dropped), each function (or callable object
    of no known class) in ``answers`` is wrapped by :func:`strict_answer` and each
    other value in ``answers`` must be plain (:func:`plain_value`). Names the cell
    binds are copied back to ``user`` afterwards, so later cells see them.
    """
    cap = current()
    read = read_names(source)
    namespace = dict(user)
    injected: dict[str, Any] = {"__builtins__": dict(cap.builtins)}
    for name in sorted(read):
        if name in answers and name in user:
            value = user[name]
            if isinstance(value, type):
                pass
            elif type(value) in _CALLABLE or (callable(value) and not cap.is_plain_type(
                    type(value))):   # a function, or a callable object of no known class
                injected[name] = strict_answer(name, value, cap)
            else:                    # data, or an object of a library or notebook class
                plain_value(value, name, cap, verb="is")
        elif name in cap.preamble:
            injected[name] = cap.preamble[name]
        elif name in cap.builtins and name in user:
            namespace.pop(name)
    namespace.update(injected)
    before = dict(namespace)
    # the state at the start of the cell (with the forbidden functions shadowed): a
    # call of a student function must leave it as it is
    _STATE["baseline"] = _Baseline(cap)
    try:
        exec(compile(source, filename, "exec"), namespace)  # noqa: S102 - the grade cell
    finally:
        _STATE.pop("baseline", None)
        for k, v in namespace.items():
            if k != "__builtins__" and before.get(k, _MISSING) is not v:
                user[k] = v


class _Baseline:
    """The attributes of the watched public modules (``numpy``, ``numpy.testing``,
    ``math``, ``minimanc.dmp``, ..., no ``_private`` module: those are compared at
    the end of the cell) as they are at the start of one grade cell, compared after
    every call of a student function (at C speed: ``map``)."""

    def __init__(self, cap: Capture) -> None:
        self.modules = []
        for name, namespace, _ in cap.modules:
            if any(part.startswith("_") for part in name.split(".")):
                continue
            items = _watched_items(name, namespace)
            self.modules.append((name, namespace, tuple(k for k, _ in items),
                                 tuple(v for _, v in items)))

    def replaced(self) -> list[str]:
        """Names that differ from the baseline, put back."""
        out = []
        for name, namespace, keys, values in self.modules:
            if not any(map(_IS_NOT, map(namespace.get, keys), values)):
                continue
            for k, v in zip(keys, values):
                if namespace.get(k, _MISSING) is not v:
                    out.append(f"{name}.{k}")
                    namespace[k] = v
        return out
