"""Public functions of the math modules document their model in numpydoc style.

For every function listed in a module's ``__all__``:

* a function with parameters has a ``Parameters`` section naming each of them;
* a function that returns a value (its return annotation is not ``None``) has a
  ``Returns`` section;
* a function whose own body raises an exception has a ``Raises`` section naming
  that exception class.

Each module's docstring names its chapter ("Chapter N — ...").  The modules are
a parameter (:data:`MODULES`): add a module name to check it too.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import re
import textwrap
from collections.abc import Callable
from types import ModuleType

import pytest

MODULES: tuple[str, ...] = (
    "minimanc.quaternion",
    "minimanc.vagn",
    "minimanc.cam",
    "minimanc.layers",
    "minimanc.dmp",
    "minimanc.metrics",
    "minimanc.tree",
    "minimanc.viz.automaton",
    "minimanc.viz.saliency",
    "minimanc.models.dmp_head",
    "minimanc.models.readout",
    "minimanc.chapters",
    "minimanc.diagnose",
)
"""Modules whose public functions must carry numpydoc sections."""

_HEADER = re.compile(r"^(?P<title>[A-Z][A-Za-z ]*)\n-{3,}[ \t]*$", re.MULTILINE)


# --------------------------------------------------------------------------- docstring parsing


def sections(doc: str) -> dict[str, str]:
    """The numpydoc sections of a (cleaned) docstring: title -> body text."""
    heads = list(_HEADER.finditer(doc))
    out = {}
    for k, m in enumerate(heads):
        end = heads[k + 1].start() if k + 1 < len(heads) else len(doc)
        out[m.group("title").strip()] = doc[m.end():end]
    return out


def documented_names(body: str) -> set[str]:
    """Names declared at the section's left margin: ``name : type`` or ``a, b : type``."""
    names: set[str] = set()
    for line in body.splitlines():
        if not line.strip() or line[0].isspace():
            continue
        head = line.split(" : ")[0] if " : " in line else line
        for part in head.split(","):
            names.add(part.strip().lstrip("*"))
    return names


def public_functions(module: ModuleType) -> list[tuple[str, Callable]]:
    """``(name, function)`` for every function in ``module.__all__`` (wrappers unwrapped)."""
    found = []
    for name in module.__all__:
        obj = inspect.unwrap(getattr(module, name))
        if inspect.isfunction(obj):
            found.append((name, obj))
    return found


def _returns_value(fn: Callable) -> bool:
    """False for ``-> None``; unannotated, whether its body returns a value."""
    ann = inspect.signature(fn).return_annotation
    if ann is not inspect.Signature.empty:
        return ann not in (None, "None")
    tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    return any(
        isinstance(node, ast.Return) and node.value is not None or isinstance(node, ast.Yield)
        for node in ast.walk(tree)
    )


def _raised_here(fn: Callable) -> set[str]:
    """Exception classes raised by ``raise Name(...)`` in the function's own body."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Raise) and node.exc is not None:
            exc = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            if isinstance(exc, ast.Name):
                names.add(exc.id)
    return names


def problems(module: ModuleType) -> list[str]:
    """Every missing section or undocumented parameter among the module's public functions."""
    found = []
    for name, fn in public_functions(module):
        where = f"{module.__name__}.{name}"
        doc = inspect.getdoc(fn) or ""
        secs = sections(doc)
        params = [p for p in inspect.signature(fn).parameters]
        if params:
            if "Parameters" not in secs:
                found.append(f"{where}: no Parameters section")
            else:
                missing = [p for p in params if p not in documented_names(secs["Parameters"])]
                if missing:
                    found.append(f"{where}: Parameters does not document {missing}")
        if _returns_value(fn) and "Returns" not in secs:
            found.append(f"{where}: no Returns section")
        raised = _raised_here(fn)
        if raised:
            if "Raises" not in secs:
                found.append(f"{where}: raises {sorted(raised)} but has no Raises section")
            else:
                missing = sorted(raised - documented_names(secs["Raises"]))
                if missing:
                    found.append(f"{where}: Raises does not name {missing}")
    return found


# --------------------------------------------------------------------------- the checks


@pytest.mark.parametrize("module_name", MODULES)
def test_public_functions_have_numpydoc_sections(module_name: str) -> None:
    module = importlib.import_module(module_name)
    assert public_functions(module), f"{module_name} lists no public function in __all__"
    found = problems(module)
    assert not found, "\n".join(found)


@pytest.mark.parametrize("module_name", MODULES)
def test_module_docstring_names_its_chapter(module_name: str) -> None:
    doc = importlib.import_module(module_name).__doc__ or ""
    assert re.match(r"Chapter \d+ — ", doc), f"{module_name}'s docstring must open with its chapter"


# --------------------------------------------------------------------------- the checker itself


def _documented(x: int, xp: object = None) -> int:
    """Add one.

    Parameters
    ----------
    x : int
        A number.
    xp : module, optional (default: None)
        Unused.

    Returns
    -------
    y : int
        ``x + 1``.

    Raises
    ------
    ValueError
        If ``x`` is negative.
    """
    if x < 0:
        raise ValueError(f"x must be >= 0, got x={x!r}")
    return x + 1


def _undocumented(x: int, xp: object = None) -> int:
    """Add one; ``x`` must be non-negative."""
    if x < 0:
        raise ValueError(f"x must be >= 0, got x={x!r}")
    return x + 1


def _half_documented(x: int, xp: object = None) -> None:
    """Check ``x``.

    Parameters
    ----------
    x : int
        A number.
    """


def _fake_module(*functions: Callable) -> ModuleType:
    mod = ModuleType("fake")
    for f in functions:
        setattr(mod, f.__name__, f)
    mod.__all__ = [f.__name__ for f in functions]
    return mod


def test_checker_accepts_a_documented_function() -> None:
    assert problems(_fake_module(_documented)) == []


def test_checker_reports_each_missing_section() -> None:
    found = problems(_fake_module(_undocumented, _half_documented))
    assert found == [
        "fake._undocumented: no Parameters section",
        "fake._undocumented: no Returns section",
        "fake._undocumented: raises ['ValueError'] but has no Raises section",
        "fake._half_documented: Parameters does not document ['xp']",
    ]


def test_sections_split_on_numpydoc_headers() -> None:
    doc = inspect.getdoc(_documented) or ""
    secs = sections(doc)
    assert list(secs) == ["Parameters", "Returns", "Raises"]
    assert documented_names(secs["Parameters"]) == {"x", "xp"}
    assert documented_names(secs["Raises"]) == {"ValueError"}
