"""research/seeing_the_leader: every script answers ``--help`` from the repository's root, as
a fresh clone runs it (the scripts import their sibling modules by path, and no script reads
the study's data before parsing its arguments), and the folder imports minimanc's public API
only (the check of ``tests/test_research_why_it_crashes.py``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_research_why_it_crashes import unpublished

ROOT = Path(__file__).resolve().parents[1]
HERE = ROOT / "research" / "seeing_the_leader"
SCRIPTS = sorted(p for p in HERE.glob("*.py") if 'if __name__ == "__main__":' in p.read_text())
"""The folder's scripts (its other files are modules they import)."""


def test_every_script_answers_help_from_the_repository_root(tmp_path):
    assert {p.stem for p in SCRIPTS} >= {"cost", "leader_data", "perception", "reach"}
    env = {"PATH": "/usr/bin:/bin", "SEEING_DATA": str(tmp_path / "absent")}
    env.update({k: v for k, v in os.environ.items()
                if k in ("PYTHONPATH", "HOME", "XLA_FLAGS")})
    runs = {p.name: subprocess.Popen([sys.executable, str(p.relative_to(ROOT)), "--help"],
                                     cwd=ROOT, env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True) for p in SCRIPTS}
    for name, proc in runs.items():
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0 and out.startswith("usage: "), f"{name}: {err[-2000:]}"
    assert not (tmp_path / "absent").exists(), "--help wrote into the study's data directory"


@pytest.mark.parametrize("path", sorted(HERE.glob("*.py")), ids=lambda p: p.name)
def test_the_folder_uses_minimanc_s_public_api_only(path):
    bad = unpublished(path.read_text(encoding="utf-8"))
    assert bad == [], f"{path.name} imports names minimanc does not publish: {bad}"
