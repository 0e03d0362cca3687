"""What the closed-loop benchmarks share: one drive's scores, a table row's cells (mean,
or mean ± std over seeds), the columns of a closed-loop table and a timed log line.
Imported by the benchmark scripts next to it."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc.studies import jobs

N_TRAIN, N_TUNE, N_VAL = 650, 40, 200
"""The paper preset's split of data seed 0: training, tuning and validation scenes."""
SHOW = ("ade", "along_track", "cross_track", "collision_rate", "at_fault_collision_rate",
        "off_road_rate")
"""The metrics of a closed-loop table's columns, with their headers :data:`HEAD`."""
HEAD = ("ADE m", "along m", "cross m", "coll. %", "at fault %", "off road %")
LABEL = {"cnn": "CNN", "manc": "MANC", "cnn_lstm": "CNN-LSTM", "rvs_g": "RvS-G"}
"""A model's name in a table."""


def log(msg: str, t0: float) -> None:
    """Print ``msg`` with the seconds since ``t0`` (:func:`time.perf_counter`)."""
    print(f"[{time.perf_counter() - t0:7.1f} s] {msg}", flush=True)


def scores(traj: Any, ds: Any) -> dict[str, float]:
    """:func:`minimanc.studies.jobs.score` of a closed loop on ``ds`` without its scene
    families: :func:`minimanc.metrics.evaluate`'s metrics, the mean |along-| and |cross-track|
    displacement from the human (``along_track``, ``cross_track``) and the collisions by kind
    with the speeds at the at-fault contacts (keys ``contacts_*``)."""
    return {k: v for k, v in jobs.score(traj, ds).items() if k != "families"}


def cells(runs: list[dict], keys: Sequence[str]) -> str:
    """The ``keys`` of ``runs`` (one dict per seed) as markdown cells: the value for one run,
    ``mean ± std`` for several."""
    out = []
    for k in keys:
        v = np.array([r[k] for r in runs])
        out.append(f"{v.mean():.2f}" if len(v) == 1 else f"{v.mean():.2f} ± {v.std():.2f}")
    return " | ".join(out)
