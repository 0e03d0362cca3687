"""Project hygiene: ruff-clean code, the README's two commands, CI wiring."""

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_ruff_clean():
    # the ruff of the running environment, also when its bin/ is not on PATH (.venv/bin/python)
    if importlib.util.find_spec("ruff") is not None:
        cmd = [sys.executable, "-m", "ruff"]
    elif shutil.which("ruff"):
        cmd = [shutil.which("ruff")]
    else:
        pytest.fail("ruff is not installed: pip install -e '.[test]'")
    out = subprocess.run([*cmd, "check", "."], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_readme_has_exactly_two_commands_and_ci_runs_the_second():
    main = subprocess.run([sys.executable, ".ci/readme_command.py", "main"], cwd=ROOT,
                          capture_output=True, text=True, check=True).stdout.strip()
    test = subprocess.run([sys.executable, ".ci/readme_command.py", "test"], cwd=ROOT,
                          capture_output=True, text=True, check=True).stdout.strip()
    for line in (main, test):  # each creates and uses its own virtual environment (PEP 668)
        assert line.startswith("python3 -m venv .venv && .venv/bin/pip install -e "), line
    assert main.endswith(".venv/bin/minimanc reproduce --quick"), main
    assert test.endswith(".venv/bin/python -m pytest"), test
    assert "readme_command.py test" in (ROOT / ".ci" / "run").read_text()


def test_every_module_docstring_names_its_chapter():
    import ast

    missing = []
    for path in sorted((ROOT / "minimanc").rglob("*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text())) or ""
        if path.name != "__main__.py" and "chapter" not in doc.lower():
            missing.append(str(path.relative_to(ROOT)))
    assert not missing, f"module docstrings without their chapter: {missing}"


def test_every_notebook_names_the_module_it_builds():
    import nbformat

    missing = []
    for folder in ("tutorials", "solutions"):
        for path in sorted((ROOT / folder).glob("*.ipynb")):
            nb = nbformat.read(path, as_version=4)
            first = next((c.source for c in nb.cells if c.cell_type == "markdown"), "")
            if "minimanc." not in first:
                missing.append(f"{folder}/{path.name}")
    assert not missing, f"first markdown cell does not name a minimanc module: {missing}"


def test_no_warnings_leak_into_notebook_outputs():
    import nbformat

    leaks = []
    for folder in ("tutorials", "solutions"):
        for path in sorted((ROOT / folder).glob("*.ipynb")):
            nb = nbformat.read(path, as_version=4)
            for index, cell in enumerate(nb.cells):
                for out in cell.get("outputs", []):
                    if out.get("name") == "stderr" and "Warning" in out.get("text", ""):
                        leaks.append(f"{folder}/{path.name}: cell {index}")
    assert not leaks, leaks


def _code_cells(folders=("tutorials", "solutions")):
    import nbformat

    for folder in folders:
        for path in sorted((ROOT / folder).glob("*.ipynb")):
            nb = nbformat.read(path, as_version=4)
            for index, cell in enumerate(nb.cells):
                if cell.cell_type == "code":
                    yield f"{folder}/{path.name} cell {index}", cell


def test_nbval_tags_are_ones_nbval_reads():
    """nbval 0.11 reads lower-case metadata tags; an upper-case tag is silently ignored."""
    wrong = [where for where, cell in _code_cells(("tutorials", "solutions", "exercises"))
             for tag in cell.metadata.get("tags", [])
             if tag.upper().replace("-", "_").startswith("NBVAL") and tag != tag.lower()]
    assert not wrong, f"upper-case nbval tags (write e.g. nbval-ignore-output): {wrong}"


def test_every_output_nbval_ignores_is_checked_by_an_assert():
    """A cell whose output is not compared (machine-dependent numbers) must check itself."""
    unchecked = []
    for where, cell in _code_cells():
        ignored = ("nbval-ignore-output" in cell.metadata.get("tags", [])
                   or "NBVAL_IGNORE_OUTPUT" in cell.source)
        if ignored and "assert " not in cell.source:
            unchecked.append(where)
    assert not unchecked, f"nbval-ignore-output cells without an assert: {unchecked}"


def test_model_code_imports_no_matplotlib():
    """Plotting is imported where a figure is drawn, never by the math and model modules."""
    code = ("import sys, minimanc.models, minimanc.train, minimanc.rollout; "
            "print('matplotlib' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", "importing the model code imported matplotlib"


def _private_reach_ins(path: Path) -> list[str]:
    """``module._name`` uses and ``from module import _name`` of another minimanc module."""
    import ast
    import importlib.util

    def is_module(dotted: str) -> bool:
        try:
            return importlib.util.find_spec(dotted) is not None
        except (ImportError, ValueError):
            return False

    tree = ast.parse(path.read_text())
    own = ".".join(path.relative_to(ROOT).with_suffix("").parts)
    aliases, found = {}, []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("minimanc") and a.asname:
                    aliases[a.asname] = a.name
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("minimanc"):
            for a in node.names:
                dotted = f"{node.module}.{a.name}"
                if a.name.startswith("_") and not a.name.startswith("__"):
                    found.append(f"from {node.module} import {a.name}")
                elif is_module(dotted):
                    aliases[a.asname or a.name] = dotted
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in aliases and node.attr.startswith("_")
                and not node.attr.startswith("__") and aliases[node.value.id] != own):
            found.append(f"{node.value.id}.{node.attr} (line {node.lineno})")
    return found


def test_no_module_reaches_into_another_modules_private_names():
    """What two modules share is public and lives once (library, benchmarks, research,
    notebooks)."""
    files = [*(ROOT / "minimanc").rglob("*.py"), *(ROOT / "benchmarks").glob("*.py"),
             *(ROOT / "research").rglob("*.py"),
             *(ROOT / "notebooks_src").glob("*.py")]
    bad = {str(p.relative_to(ROOT)): r for p in sorted(files) if (r := _private_reach_ins(p))}
    assert not bad, f"private names used across modules: {bad}"


MAX_LINES = 600


def test_no_tracked_python_file_is_over_600_lines():
    """Every tracked ``.py`` file of minimanc/, tests/, research/, benchmarks/ and .ci/ has at
    most 600 lines, so that a module holds one concept (split a longer one by concept, tests
    included). Notebook sources (notebooks_src/) are exempt: a chapter's notebook is one file."""
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout: the tracked files are unknown")
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--", "minimanc", "tests", "research", "benchmarks", ".ci"],
        cwd=ROOT, capture_output=True, text=True, check=True).stdout.split("\0")
    tracked = [ROOT / name for name in listed if name.endswith(".py")]
    assert any(p.name == "test_style.py" for p in tracked), "git ls-files listed no test file"
    too_long = {str(p.relative_to(ROOT)): n for p in tracked
                if p.is_file() and (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not too_long, f"files over {MAX_LINES} lines (split them by concept): {too_long}"
