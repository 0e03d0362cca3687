"""Chapter 7 — minimanc.world.generation: worker processes that cannot start give a one-line
error that says what to do."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from minimanc.world.generation import POOL_DIED

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """\
import jax  # imported first: the worker processes are spawned, not forked

from minimanc import world

{call}
"""

CALL = "ds = world.generate(2, seed=1, raster=world.RasterConfig(size=16), workers=2)"


def run_script(tmp_path: Path, call: str) -> subprocess.CompletedProcess:
    path = tmp_path / "script.py"
    path.write_text(SCRIPT.format(call=call))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, str(path)], capture_output=True, text=True,
                          env=env, cwd=tmp_path, timeout=600)


def test_an_unguarded_script_with_jax_gets_the_one_line_error_and_the_guard_works(tmp_path):
    """A script without the ``__main__`` guard re-runs in every spawned worker, which cannot
    start processes of its own: the call stops with :data:`POOL_DIED` (not a bare
    ``BrokenProcessPool``); under the guard the same call generates the same data."""
    bare = run_script(tmp_path, CALL + "\nprint(ds.content_hash())")
    assert bare.returncode != 0
    # multiprocessing's resource tracker, a process of its own, may report the dead pool's
    # semaphores after the traceback (a UserWarning and its source line, both naming it)
    lines = [ln for ln in bare.stderr.strip().splitlines() if "resource_tracker" not in ln]
    last = lines[-1]
    assert last == f"RuntimeError: {POOL_DIED['spawn']}"
    assert "__main__" in last and "workers=1" in last
    guarded = run_script(tmp_path, 'if __name__ == "__main__":\n'
                         + textwrap.indent(CALL + "\nprint(ds.content_hash())", "    "))
    assert guarded.returncode == 0, guarded.stderr
    inline = run_script(tmp_path, CALL.replace("workers=2", "workers=1")
                        + "\nprint(ds.content_hash())")
    assert guarded.stdout.split() == inline.stdout.split() and len(inline.stdout.split()) == 1
