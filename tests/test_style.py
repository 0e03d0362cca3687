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
