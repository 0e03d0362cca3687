"""What the closed-loop benchmarks share: one drive's scores and a table row's cells (mean,
or mean ± std over seeds). Imported by the benchmark scripts next to it."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from minimanc.studies import jobs


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
