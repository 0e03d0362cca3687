"""The package's import graph, read from the source (ast): no cycle, no arrow from a lower
layer to a higher one, and no minimanc module imported inside a function.

The layer order is CONTRIBUTING.md's ("Layers" section), the one list both follow: a module
may import its own layer and the layers below it. An import inside a function is allowed only
where it defers an optional dependency (:data:`OPTIONAL`; a minimanc module only in the
importers :data:`DEFERRED` names), and says why in a comment on the import's line or on a
comment line right above it. A call ``importlib.import_module("minimanc.x")`` with a literal
name counts as an import of ``minimanc.x``.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "minimanc"

OPTIONAL = {
    "matplotlib": "figures",
    "PIL": "images",
    "ray": "the [ray] extra",
    "jax": "the jax engine",
    "jaxlib": "the jax engine",
    "highway_env": "highway-env",
    "gymnasium": "highway-env",
    "nbformat": "Jupyter",
    "nbclient": "Jupyter",
    "jupyter_client": "Jupyter",
}
"""What a function may import (module or its parent), each an optional dependency."""

DEFERRED = {
    "minimanc.highway": {"minimanc.dagger.teachers": "highway-env, optional for DAgger",
                         "minimanc.cli.highway": "highway-env, reported when a command runs",
                         "minimanc.cli.dagger": "highway-env, only for --sim highway"},
    "minimanc.exercises": {"minimanc.cli.exercises": "nbformat, seconds to import"},
}
"""A minimanc module that loads an optional dependency -> the modules that may import it
inside a function (and why); everywhere else it is imported at the top like any module."""


def _layers() -> list[tuple[str, ...]]:
    text = (ROOT / "CONTRIBUTING.md").read_text(encoding="utf-8")
    block = re.search(r"## Layers\n.*?```text\n(.*?)```", text, re.S)
    assert block, "CONTRIBUTING.md has no '## Layers' section with a ```text block"
    return [tuple(name.strip() for name in line.split(",")) for line in
            block.group(1).strip().splitlines()]


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _resolve(module: str, node: ast.ImportFrom, is_package: bool) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".")[: None if is_package else -1]
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _targets(module: str, node: ast.Import | ast.ImportFrom) -> list[str]:
    """The modules ``node`` imports (a ``from P import name`` of a submodule names it)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    base = _resolve(module, node, MODULES[module].name == "__init__.py")
    return [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base for a in node.names]


def _imports(module: str, source: str | None = None
             ) -> tuple[list[tuple[str, int]], list[tuple[str, int, str]]]:
    """``(top, inner)``: module-level imports ``(target, line)`` and imports inside a function
    ``(target, line, the comments that may give its reason)``: those on the statement's lines
    and on the comment lines right above it."""
    if source is None:
        source = MODULES[module].read_text(encoding="utf-8")
    lines = source.splitlines()
    top, inner = [], []

    def walk(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import | ast.ImportFrom):
                for target in _targets(module, child):
                    if in_function:
                        inner.append((target, child.lineno, _comments(lines, child)))
                    else:
                        top.append((target, child.lineno))
            elif (dynamic := _import_module_of(child)) is not None:
                # importlib.import_module("minimanc.x") is an import like any other
                if in_function:
                    inner.append((dynamic, child.lineno, _comments(lines, child)))
                else:
                    top.append((dynamic, child.lineno))
                walk(child, in_function)
            else:
                walk(child, in_function or isinstance(
                    child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda))

    walk(ast.parse(source), False)
    return top, inner


def _import_module_of(node: ast.AST) -> str | None:
    """The module a call ``importlib.import_module("name")`` (or ``import_module``,
    ``__import__``) imports when its name is a string literal; ``None`` for any other node.
    A name computed at run time (the CLI's table of command modules) is not resolved."""
    if not isinstance(node, ast.Call) or not node.args:
        return None
    func = node.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
    arg = node.args[0]
    if name in ("import_module", "__import__") and isinstance(arg, ast.Constant) \
            and isinstance(arg.value, str):
        return arg.value
    return None


def _comments(lines: list[str], node: ast.stmt) -> str:
    """The ``#`` comments on ``node``'s lines and on the comment-only lines right above it."""
    found = [line.split("#", 1)[1] for line in lines[node.lineno - 1:node.end_lineno]
             if "#" in line]
    above = node.lineno - 2
    while above >= 0 and lines[above].strip().startswith("#"):
        found.insert(0, lines[above].strip()[1:])
        above -= 1
    return " ".join(c.strip() for c in found)


def inner_import_errors(module: str, source: str | None = None) -> list[str]:
    """Why each import inside a function of ``module`` is not allowed (``[]``: all are)."""
    _, inner = _imports(module, source)
    path = MODULES[module].relative_to(ROOT) if module in MODULES else module
    errors = []
    for target, line, comment in inner:
        top = target.split(".")[0]
        where = f"{path}:{line}"
        if top == "minimanc":
            owner = next((k for k in DEFERRED if target == k or target.startswith(k + ".")),
                         None)
            if owner is None or module not in DEFERRED[owner]:
                errors.append(f"{where} imports {target} inside a function: import it at the "
                              "top of the module (a lower layer is passed what it needs)")
                continue
        elif top not in OPTIONAL:
            continue  # the standard library or a dependency: ruff's business, not layering
        if not comment:
            errors.append(f"{where} defers {target}: say why in a comment on that line")
    return errors


def _own(target: str) -> str | None:
    """The minimanc module a dotted import target lands in (``None``: not minimanc)."""
    while target not in MODULES:
        if "." not in target:
            return None
        target = target.rsplit(".", 1)[0]
    return target


def _graph() -> dict[str, set[str]]:
    graph = {}
    for module in MODULES:
        top, _ = _imports(module)
        graph[module] = {t for t in (_own(t) for t, _ in top) if t and t != module}
    return graph


def layer_of(module: str, layers: list[tuple[str, ...]]) -> int | None:
    """The index of ``module``'s layer: the layer naming it or its nearest parent package."""
    name = module.removeprefix("minimanc").removeprefix(".")
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):
        for i, layer in enumerate(layers):
            if ".".join(parts[:cut]) in layer:
                return i
    return None


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_import_graph_has_no_cycle():
    assert cycles(_graph()) == []


def test_cycles_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_every_module_has_a_layer_and_each_layer_names_existing_modules():
    layers = _layers()
    names = [name for layer in layers for name in layer]
    assert len(names) == len(set(names)), "a module is named in two layers"
    for name in names:
        assert f"minimanc.{name}" in MODULES, f"CONTRIBUTING's layer {name!r} is no module"
    missing = [m for m in MODULES if m != "minimanc" and layer_of(m, layers) is None]
    assert missing == [], f"modules in no layer of CONTRIBUTING.md: {missing}"


def test_no_import_points_from_a_lower_layer_to_a_higher_one():
    layers = _layers()
    upward = []
    for module, targets in _graph().items():
        if module == "minimanc":  # the package's own __init__: its version and engine switch
            continue
        for target in targets:
            low, high = layer_of(module, layers), layer_of(target, layers)
            if target == "minimanc" or low is None or high is None:
                continue  # the package itself; a module in no layer fails the test above
            if high > low:
                upward.append(f"{module} -> {target}")
    assert upward == [], f"imports from a lower layer to a higher one: {upward}"


def test_layer_of_takes_the_nearest_named_package():
    layers = [("checks",), ("world",), ("world.nuscenes", "rollout")]
    assert layer_of("minimanc.world.maps", layers) == 1
    assert layer_of("minimanc.world.nuscenes.sample", layers) == 2
    assert layer_of("minimanc.checks", layers) == 0
    assert layer_of("minimanc.nowhere", layers) is None


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_inside_functions_only_defer_an_optional_dependency(module):
    assert inner_import_errors(module) == []


def test_every_deferral_of_a_minimanc_module_is_still_there():
    for target, importers in DEFERRED.items():
        for module in importers:
            _, inner = _imports(module)
            assert any(t == target or t.startswith(target + ".") for t, _, _ in inner), (
                f"{module} no longer defers {target}: remove it from DEFERRED")


PLANTED = """
import numpy as np


def f():
    from minimanc import models
    import minimanc.highway as hw  # optional: highway-env
    import matplotlib.pyplot as plt
    # Pillow only when an image is written
    from PIL import Image
    import json
    return models, hw, plt, Image, json, np


def g():
    return importlib.import_module("minimanc.rollout")
"""


def test_inner_import_errors_finds_planted_violations():
    errors = inner_import_errors("minimanc.metrics.table", PLANTED)
    assert [e.split(" ", 1)[1] for e in errors] == [
        "imports minimanc.models inside a function: import it at the top of the module "
        "(a lower layer is passed what it needs)",
        "imports minimanc.highway inside a function: import it at the top of the module "
        "(a lower layer is passed what it needs)",
        "defers matplotlib.pyplot: say why in a comment on that line",
        "imports minimanc.rollout inside a function: import it at the top of the module "
        "(a lower layer is passed what it needs)",
    ]
    # the one module DEFERRED names may defer highway-env, with its reason
    assert inner_import_errors("minimanc.dagger.teachers", PLANTED)[1:] == [
        e.replace("minimanc/metrics/table.py", "minimanc/dagger/teachers.py")
        for e in errors[2:]]


def test_a_literal_import_module_call_is_an_import():
    source = ('import importlib\n\nSTYLE = importlib.import_module("minimanc.viz.style")\n\n\n'
              'def f(name):\n    importlib.import_module(name)  # a table\'s name: not read\n'
              '    return importlib.import_module("minimanc.highway")  # optional: highway-env\n')
    top, inner = _imports("minimanc.metrics.table", source)
    assert top == [("importlib", 1), ("minimanc.viz.style", 3)]
    assert [(t, line) for t, line, _ in inner] == [("minimanc.highway", 8)]


def reached(seeds: set[str]) -> set[str]:
    """The modules ``seeds`` import, transitively (inside functions too), with the packages
    that hold them (importing a module runs its parents' ``__init__``)."""
    seen: set[str] = set()
    stack = list(seeds)
    while stack:
        module = stack.pop()
        if module in seen or module not in MODULES:
            continue
        seen.add(module)
        parts = module.split(".")
        stack += [".".join(parts[:i]) for i in range(1, len(parts))]
        top, inner = _imports(module)
        stack += [t for t in (_own(t) for t, *_ in top + inner) if t]
        stack += [t for t in (_own(t) for t in _imports_in_sent_code(module)) if t]
    return seen


SENT_IMPORT = re.compile(r"^\s*import (minimanc[\w.]*)", re.MULTILINE)


def _imports_in_sent_code(module: str) -> list[str]:
    """The minimanc modules imported by code a module sends to another process as a string
    (the grader's cells run in the notebook's kernel): ``"import minimanc.x as y\\n..."``."""
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
    strings = [n.value for n in ast.walk(tree)
               if isinstance(n, ast.Constant) and isinstance(n.value, str)]
    return [m for text in strings for m in SENT_IMPORT.findall(text)]


def test_every_module_is_reached_from_a_notebook_or_the_command_line():
    """A module is in ``minimanc/`` because a notebook builds or uses it, or the command line
    runs it; what only ``research/`` or ``benchmarks/`` uses lives there."""
    from minimanc.cli import CORE, PLUGINS

    seeds = {"minimanc", "minimanc.__main__", "minimanc.cli", *CORE, *PLUGINS}
    for path in sorted((ROOT / "notebooks_src").glob("*.py")):
        source = path.read_text(encoding="utf-8")
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.Import | ast.ImportFrom):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                    [node.module or ""] + [f"{node.module}.{a.name}" for a in node.names]
                seeds |= {m for m in (_own(n) for n in names if n.startswith("minimanc")) if m}
    missing = sorted(set(MODULES) - reached(seeds))
    assert missing == [], f"modules no notebook and no command reaches: {missing}"


def test_reached_follows_imports_and_parent_packages():
    got = reached({"minimanc.dagger.loop"})
    assert {"minimanc", "minimanc.dagger", "minimanc.dagger.loop", "minimanc.train"} <= got
    assert "minimanc.exercises" not in got and "minimanc.cli" not in got


def test_reached_follows_imports_in_code_sent_to_a_kernel():
    assert "minimanc.exercises.serving" in _imports_in_sent_code("minimanc.exercises.checker")
    assert "minimanc.exercises.serving" in reached({"minimanc.exercises.checker"})
