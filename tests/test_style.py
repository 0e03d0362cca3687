"""Project hygiene: ruff-clean code, the README's two commands, CI wiring."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_ruff_clean():
    ruff = shutil.which("ruff")
    if ruff is None:
        pytest.fail("ruff is not installed: pip install -e '.[test]'")
    out = subprocess.run([ruff, "check", "."], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_readme_has_exactly_two_commands_and_ci_runs_the_second():
    main = subprocess.run([sys.executable, ".ci/readme_command.py", "main"], cwd=ROOT,
                          capture_output=True, text=True, check=True).stdout.strip()
    test = subprocess.run([sys.executable, ".ci/readme_command.py", "test"], cwd=ROOT,
                          capture_output=True, text=True, check=True).stdout.strip()
    assert main.startswith("pip install") and "minimanc" in main
    assert test.startswith("pip install") and "pytest" in test
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
