"""docs/library.md's examples run: every ```python block of the page, in order, in a fresh
process (as a reader pastes them), and the two marked examples (``<!-- example: NAME -->``
right above the block: the data → training → closed loop → metrics path and the registration
of a MANC variant) each on its own, since a reader copies those alone.

What they produce is checked: the trained models drive the validation scenes, the metrics
have every key of :data:`minimanc.metrics.ALL_METRICS` with finite values, and the
registered variant is a vAGN model with a DMP head whose q stays a distribution.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from minimanc import metrics

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "library.md"
BLOCK = re.compile(r"(?:<!-- example: ([\w-]+) -->\n)?```python\n(.*?)```", re.S)
MARK = "JSON-SUMMARY "


def blocks() -> list[tuple[str | None, str]]:
    """``(name or None, code)`` of every ```python block of the page, in order."""
    return BLOCK.findall(PAGE.read_text(encoding="utf-8"))


def example(name: str) -> str:
    found = [code for n, code in blocks() if n == name]
    assert len(found) == 1, f"docs/library.md has {len(found)} blocks marked example: {name}"
    return found[0]


def run(code: str, summary: str, tmp_path: Path) -> dict:
    """Run ``code`` and then ``summary`` (which prints the dict to check) in a new process."""
    script = tmp_path / "example.py"
    script.write_text(code + "\n\nimport json as _json\nprint(" + repr(MARK) +
                      " + _json.dumps(" + summary.strip() + "))\n", encoding="utf-8")
    env = {**os.environ, "MPLBACKEND": "Agg",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, f"the example failed:\n{out.stderr[-3000:]}"
    lines = [line for line in out.stdout.splitlines() if line.startswith(MARK)]
    assert len(lines) == 1, out.stdout[-2000:]
    return json.loads(lines[0][len(MARK):])


END_TO_END = """{
    "metrics": {k: float(v) for k, v in scores.items()},
    "name": fit.name, "steps": fit.steps, "history": [float(h) for h in fit.history],
    "ego": list(traj.ego.shape), "val": list(val_ds.ego.shape),
    "moved": float(abs(traj.ego[:, -1, :2] - traj.ego[:, 0, :2]).sum()),
}"""

REGISTER = """{
    "names": list(models.names()), "vagn": list(models.vagn_models()),
    "dmp": list(models.dmp_models()),
    "name": qp_fit.name, "steps": qp_fit.steps, "history": [float(h) for h in qp_fit.history],
    "gains": list(qp_fit.params["gains"]["w"].shape), "n": qp_fit.cfg.n_states,
    "m": qp_fit.cfg.n_predicates, "aux": sorted(qp_traj.aux), "agents": qp_traj.agents,
    "q_sum": [float(qp_traj.aux["q"].sum(-1).min()), float(qp_traj.aux["q"].sum(-1).max())],
    "ego": list(qp_traj.ego.shape), "val": list(val_ds.ego.shape),
    "ade": float(metrics.evaluate(qp_traj, val_ds)["ade"]),
}"""


def check_end_to_end(got: dict) -> None:
    assert set(got["metrics"]) == set(metrics.ALL_METRICS)
    assert all(v == v and abs(v) != float("inf") for v in got["metrics"].values()), got
    assert got["name"] == "manc" and got["steps"] > 0 and len(got["history"]) == 2
    assert all(h == h and abs(h) != float("inf") for h in got["history"])
    assert got["ego"] == got["val"] and got["moved"] > 0   # it drove every validation scene


def check_register(got: dict) -> None:
    assert got["names"][-1] == "manc_qp" and "manc_qp" in got["vagn"] and "manc_qp" in got["dmp"]
    assert got["name"] == "manc_qp" and got["steps"] > 0
    assert all(h == h and abs(h) != float("inf") for h in got["history"])
    assert got["gains"] == [got["n"] + got["m"], 4]            # FC(q ⊕ p): N + M inputs
    assert got["aux"] == ["alpha", "beta", "predicates", "q"] and got["agents"] == "reactive"
    assert abs(got["q_sum"][0] - 1) < 1e-5 and abs(got["q_sum"][1] - 1) < 1e-5
    assert got["ego"] == got["val"] and got["ade"] == got["ade"] and got["ade"] >= 0


def test_the_page_has_its_examples():
    named = [n for n, _ in blocks() if n]
    assert named == ["end-to-end", "register"], named
    assert len(blocks()) >= 12, "docs/library.md has lost its per-layer examples"


def test_the_end_to_end_example_runs_alone(tmp_path):
    check_end_to_end(run(example("end-to-end"), END_TO_END, tmp_path))


def test_the_registration_example_runs_alone(tmp_path):
    check_register(run(example("register"), REGISTER, tmp_path))


def test_every_example_of_the_page_runs_in_order(tmp_path):
    pytest.importorskip("highway_env")   # the highway section needs the [highway] extra
    code = "\n\n".join(code for _, code in blocks())
    got = run(code, "{'end_to_end': " + END_TO_END + ", 'register': " + REGISTER +
              ", 'highway': sorted(on_highway.metrics), 'expert': list(expert.ego.shape)}",
              tmp_path)
    check_end_to_end(got["end_to_end"])
    check_register(got["register"])
    assert {"collision_rate", "off_road_rate", "ade"} <= set(got["highway"])
    assert got["expert"] == got["register"]["val"]
