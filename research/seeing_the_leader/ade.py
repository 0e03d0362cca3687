"""Where the image drivers' ADE comes from: along the human's path (speed) or across it (lane).

Issue 41 asks for a learned ADE ≤ 1.5× the style floor's; every image driver of
``end_to_end.py`` is near 12 m, the privileged MLP 4.7 m, the floor 5.05 m. This script
re-drives trained checkpoints of ``end_to_end.py`` (and the style floor) on the same
validation scenes, reactive ados, and splits each step's displacement from the logged human
with :func:`minimanc.metrics.along_cross_track`: ``along`` (ahead of or behind the human on
its path: the speed profile) and ``cross`` (beside it: the lane). It reports, over the 200
scenes, the ADE, the mean |along| and |cross|, the mean signed ``along`` at the last step
(a driver that is too fast on average is ahead), its spread over scenes, and the mean
speed error ``(path length − human path length) / horizon``.

    cd research/seeing_the_leader && PYTHONPATH=../..:. python ade.py \
        --work /work/data/seeing/end_to_end --rows cnn_dagger_s0 cnn_channels0_s0 ...

A row is ``MODEL_FORM_sSEED`` of ``end_to_end.py`` (its checkpoint must exist) or ``floor``.
Each row's numbers are cached as JSON under ``--work/ade``; ``--report`` writes
``results/ade.md`` from the cache.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import end_to_end as E
import leader_data as L
import numpy as np

from minimanc import diagnose, metrics, rollout, train
from minimanc.world.geometry import DT

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"


def decompose(ego: np.ndarray, human: np.ndarray) -> dict[str, float]:
    """The displacement's parts over scenes (see the module docstring)."""
    along, cross = metrics.along_cross_track(ego, human)
    horizon = (ego.shape[1] - 1) * DT
    length = np.linalg.norm(np.diff(ego[..., :2], axis=1), axis=-1).sum(axis=1)
    human_length = np.linalg.norm(np.diff(human[..., :2], axis=1), axis=-1).sum(axis=1)
    dv = (length - human_length) / horizon
    return {"ade": float(metrics.ade(ego, human).mean()),
            "along_abs": float(np.abs(along).mean()), "cross_abs": float(np.abs(cross).mean()),
            "along_end": float(along[:, -1].mean()), "along_end_sd": float(along[:, -1].std()),
            "speed_error": float(dv.mean()), "speed_error_abs": float(np.abs(dv).mean()),
            "scenes": int(ego.shape[0])}


def trajectories(row: str, work: Path) -> tuple[np.ndarray, np.ndarray]:
    """The row's poses and the human's on the validation scenes, reactive ados."""
    if row == "floor":
        val = E.draw("rgb", work).subset(list(E.VALIDATE))
        traj = diagnose.floor_rollout(val, diagnose.median_style(), agents="reactive")
    else:
        stem, seed = row.rsplit("_s", 1)
        model = next(m for m in sorted(E.MODELS, key=len, reverse=True)
                     if stem.startswith(m + "_"))
        form = stem[len(model) + 1:]
        path = E.checkpoint_of(model, form, int(seed), work)
        if path is None:
            raise SystemExit(f"no checkpoint for {row}: train it with end_to_end.py first")
        val = E.draw(form, work).subset(list(E.VALIDATE))
        traj = rollout.closed_loop(train.load_fit(path), val, agents="reactive",
                                   progress=False)
    return np.asarray(traj.ego), np.asarray(val.ego)


def run(row: str, work: Path) -> dict:
    path = work / "ade" / f"{row}.json"
    if path.exists():
        return json.loads(path.read_text())
    ego, human = trajectories(row, work)
    out = {"row": row, **decompose(ego, human)}
    E.write_json(path, out)
    return out


def report(work: Path) -> str:
    rows = sorted((json.loads(p.read_text()) for p in (work / "ade").glob("*.json")),
                  key=lambda r: (r["row"] != "floor", r["row"]))
    lines = ["# Where the ADE comes from: along the human's path or across it\n",
             "Validation scenes 600–799, reactive ados; `ade.py` (module docstring: the "
             "quantities). along/cross: mean |displacement| along and across the human's "
             "heading; end: the signed along-track offset at the last step, mean ± sd over "
             "scenes (positive = ahead of the human); speed error: (path length − the "
             "human's) / horizon, mean and mean |·|.\n",
             "| row | ADE m | along m | cross m | end m | speed error m/s "
             "| \\|speed error\\| m/s |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['row']} | {r['ade']:.2f} | {r['along_abs']:.2f} | "
                     f"{r['cross_abs']:.2f} | {r['along_end']:+.1f} ± {r['along_end_sd']:.1f} | "
                     f"{r['speed_error']:+.2f} | {r['speed_error_abs']:.2f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, default=L.DATA_DIR / "end_to_end")
    ap.add_argument("--rows", nargs="*", default=[])
    ap.add_argument("--report", action="store_true")
    a = ap.parse_args()
    for row in a.rows:
        print(json.dumps(run(row, a.work)), flush=True)
    if a.report:
        (RESULTS / "ade.md").write_text(report(a.work))


if __name__ == "__main__":
    main()
