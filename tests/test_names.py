"""Names that say one thing: no public function, class or constant is defined in two modules of
``minimanc/`` (read from the source with ``ast``).

A name defined twice is either one concept written twice (keep one definition, import it where
it is needed) or two things sharing a name (rename one so the name says what it does). The one
exception is a protocol, CONTRIBUTING.md's "Names" section: :data:`PROTOCOLS` lists each
protocol name with exactly the modules that implement it, and such a name is always called
through its module (``dmp.step``, ``importlib.import_module(name).register``), never imported
bare from another package.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

from minimanc.cli import CORE, PLUGINS

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "minimanc"

PROTOCOLS: dict[str, frozenset[str]] = {
    # every command module of the CLI table adds its commands with register(subparsers)
    "register": frozenset((*CORE, *PLUGINS)),
    # a dynamical system's one update (the paper's equation) and its unrolling over time
    "step": frozenset(("minimanc.dmp.integrate", "minimanc.vagn.automaton",
                       "minimanc.models.forward")),
    "rollout": frozenset(("minimanc.dmp.integrate", "minimanc.vagn.automaton")),
}
"""Protocol name -> the modules that define it (and no others)."""


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def public_defs(source: str) -> list[str]:
    """The public functions, classes and constants (``UPPER_CASE = ...`` assignments; a
    documented re-export, ``from m import X as X``, is no definition) a module defines at
    its top level."""
    out = []
    for node in ast.parse(source).body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            out.append(node.name)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            out += [t.id for t in targets if isinstance(t, ast.Name) and t.id.isupper()]
    return [name for name in out if not name.startswith("_")]


def definitions(sources: dict[str, str]) -> dict[str, list[str]]:
    """Name -> the modules (sorted) that define it, for ``{module: source}``."""
    out: dict[str, list[str]] = defaultdict(list)
    for module, source in sorted(sources.items()):
        for name in public_defs(source):
            out[name].append(module)
    return dict(out)


def duplicates(sources: dict[str, str],
               protocols: dict[str, frozenset[str]]) -> dict[str, list[str]]:
    """The names defined in more than one module, except a protocol name defined in exactly
    its own modules (a protocol defined elsewhere, or missing from one, is reported)."""
    return {name: where for name, where in definitions(sources).items()
            if len(where) > 1 and set(where) != protocols.get(name)}


def bare_imports(sources: dict[str, str], protocols: dict[str, frozenset[str]]) -> list[str]:
    """``module imports name from package`` for every protocol name imported bare outside the
    package that defines it (its ``__init__`` may gather it from its own modules)."""
    out = []
    for module, source in sorted(sources.items()):
        for node in ast.walk(ast.parse(source)):
            if not isinstance(node, ast.ImportFrom) or not node.module:
                continue
            for alias in node.names:
                if f"{node.module}.{alias.name}" in sources:
                    continue  # a module (``from minimanc import rollout``, the package)
                owners = protocols.get(alias.name, ())
                if any(node.module == o or o.startswith(node.module + ".") for o in owners):
                    if not any(o.startswith(module + ".") for o in owners):
                        out.append(f"{module} imports {alias.name} from {node.module}")
    return out


SOURCES = {module_name(p): p.read_text(encoding="utf-8") for p in sorted(PACKAGE.rglob("*.py"))}


def test_no_public_name_is_defined_in_two_modules():
    found = duplicates(SOURCES, PROTOCOLS)
    listed = "; ".join(f"{name}: {', '.join(where)}" for name, where in sorted(found.items()))
    assert found == {}, f"public names defined in two or more modules: {listed}"


def test_every_protocol_module_exists_and_defines_its_name():
    defs = definitions(SOURCES)
    for name, modules in PROTOCOLS.items():
        assert set(defs.get(name, ())) == modules, (name, defs.get(name))


def test_protocol_names_are_called_through_their_module():
    assert bare_imports(SOURCES, PROTOCOLS) == []


def test_duplicates_names_a_planted_second_definition_and_spares_a_protocol():
    sources = {
        "minimanc.a": "def load(path):\n    pass\n\nclass Box:\n    pass\n",
        "minimanc.b": "import json\n\ndef load(path, what):\n    pass\n\ndef _hid():\n    pass\n",
        "minimanc.z": "def _hid():\n    pass\n",
        "minimanc.c": "def step(x):\n    pass\n\ndef helper():\n    def load():\n        pass\n",
        "minimanc.d": "def step(x):\n    pass\n",
    }
    protocols = {"step": frozenset(("minimanc.c", "minimanc.d"))}
    assert duplicates(sources, protocols) == {"load": ["minimanc.a", "minimanc.b"]}
    # a protocol name defined outside its modules is a duplicate again
    sources["minimanc.e"] = "class step:\n    pass\n"
    assert duplicates(sources, protocols) == {
        "load": ["minimanc.a", "minimanc.b"],
        "step": ["minimanc.c", "minimanc.d", "minimanc.e"]}


def test_bare_imports_finds_a_protocol_name_imported_from_another_package():
    protocols = {"step": frozenset(("minimanc.dmp.integrate",))}
    sources = {
        "minimanc.dmp": "from minimanc.dmp.integrate import step\n",
        "minimanc.quaternion.dmp": "from minimanc import dmp\n\ndmp.step\n",
        "minimanc.models.forward": "def f():\n    from minimanc.dmp import step\n",
        "minimanc.step": "",
        "minimanc.cli": "from minimanc import step\n",
    }
    assert bare_imports(sources, protocols) == [
        "minimanc.models.forward imports step from minimanc.dmp"]


def test_duplicates_names_a_constant_defined_twice_and_spares_a_re_export():
    sources = {
        "minimanc.a": "DT = 0.5\nrate: float = 2.0\n",
        "minimanc.b": "DT: float = 0.5\nKEYS = ('x',)\n",
        "minimanc.c": "from minimanc.a import DT as DT\nKEYS2 = ('y',)\nrate = 3.0\n",
    }
    assert duplicates(sources, {}) == {"DT": ["minimanc.a", "minimanc.b"]}
