"""What the closed-loop benchmarks share: one drive's scores and a table row's cells (mean,
or mean ± std over seeds). Imported by the benchmark scripts next to it."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc import metrics


def scores(traj: Any, ds: Any) -> dict[str, float]:
    """:func:`minimanc.metrics.evaluate` of a closed loop on ``ds``, with the mean |along-| and
    |cross-track| displacement from the human (``along_track``, ``cross_track``)."""
    m = metrics.evaluate(traj, ds)
    along, cross = metrics.along_cross_track(traj.ego, np.asarray(ds.ego, dtype=np.float64))
    m["along_track"] = float(np.abs(along).mean())
    m["cross_track"] = float(np.abs(cross).mean())
    return m


def cells(runs: list[dict], keys: Sequence[str]) -> str:
    """The ``keys`` of ``runs`` (one dict per seed) as markdown cells: the value for one run,
    ``mean ± std`` for several."""
    out = []
    for k in keys:
        v = np.array([r[k] for r in runs])
        out.append(f"{v.mean():.2f}" if len(v) == 1 else f"{v.mean():.2f} ± {v.std():.2f}")
    return " | ".join(out)
