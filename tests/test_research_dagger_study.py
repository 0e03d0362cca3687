"""research/dagger_study: chapter 11's study of behaviour cloning against DAgger at equal
labels answers ``--help`` from the repository's root (its ``REPORT.md``'s quotes are checked
by ``tests/test_provenance.py``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_study_answers_help_from_the_repository_root():
    out = subprocess.run([sys.executable, "research/dagger_study/dagger_study.py", "--help"],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.startswith("usage: "), out.stderr[-2000:]
    assert "--seeds" in out.stdout and "--work" in out.stdout
