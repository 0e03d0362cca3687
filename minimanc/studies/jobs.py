"""Chapter 9 — the jobs of a study that run outside :class:`~minimanc.studies.runner.Study`:
the closed-loop rollout and metrics of one trained run (:func:`evaluate_job`, in a worker
process or inline) under either protocol of the ados, the scoring of a rollout with the
along-/cross-track split and per scenario family (:func:`score`), the persistent JAX
compilation cache, and the cache's JSON files (written atomically, read as ``None`` when
broken)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from minimanc import metrics, rollout, train, world
from minimanc.diagnose.collisions import collision_taxonomy
from minimanc.studies.provenance import write_json

_WORKER_DATA: dict[str, Any] = {}

TRACK_METRICS: tuple[str, ...] = ("along_track", "cross_track", "along_bias")
"""ADE split by :func:`minimanc.metrics.along_cross_track`: ``along_track`` = mean over
scenes and steps of ``|along|`` (m; speed and timing), ``cross_track`` = mean of ``|cross|``
(m; steering), ``along_bias`` = mean of the signed ``along`` (m; < 0: behind the human)."""

STUDY_METRICS: tuple[str, ...] = metrics.ALL_METRICS + TRACK_METRICS
CONTACT_PREFIX: str = "contacts_"
"""Prefix of the collision-taxonomy keys of :func:`score`."""
"""Every metric a study reports for a rollout (a failed run has them all ``inf``)."""

SCENE_FAMILIES: tuple[str, ...] = ("free", "junction", "roundabout", "cut_in")
"""Scenario families, from the world's scene tags: ``free`` = a straight or curved road
without a cut-in, ``junction`` = an intersection, ``roundabout``, ``cut_in`` = a scene with
a cut-in (on any map, so it overlaps the others)."""


def scene_families(ds: Any) -> dict[str, np.ndarray]:
    """``{family: (S,) bool}``: which scenes of ``ds`` belong to each of :data:`SCENE_FAMILIES`
    (from ``ds.tags``; ValueError when the dataset has none)."""
    tags = getattr(ds, "tags", None)
    if tags is None or len(tags) != len(ds.ego):
        raise ValueError("ds must be a minimanc.world dataset with one tag dict per scene")
    kind = np.array([t["kind"] for t in tags])
    cut = np.array([bool(t["has_cut_in"]) for t in tags])
    return {"free": np.isin(kind, ("straight", "curved")) & ~cut,
            "junction": kind == "intersection", "roundabout": kind == "roundabout",
            "cut_in": cut}


def failed(error: str | None = None) -> dict:
    """The scores of a run that could not be evaluated: every :data:`STUDY_METRICS` ``inf``
    (also per family, so that :func:`minimanc.metrics.aggregate` keeps every key)."""
    res: dict[str, Any] = {k: float("inf") for k in STUDY_METRICS}
    res["families"] = {f: {k: float("inf") for k in STUDY_METRICS} for f in SCENE_FAMILIES}
    if error is not None:
        res["error"] = error
    return res


def scene_scores(traj: Any, ds: Any) -> dict[str, np.ndarray]:
    """Every metric of :data:`STUDY_METRICS` per scene, ``{metric: (S,)}``, in the units of
    :func:`minimanc.metrics.evaluate` (whose values are their means over the scenes): the
    per-scene functions of :mod:`minimanc.metrics`, on the rollout's own ados when it has
    them (the reactive protocol), else on the dataset's log."""
    ego = np.asarray(traj.ego, dtype=np.float64)
    human = np.asarray(ds.ego, dtype=np.float64)
    if ego.shape != human.shape:
        raise ValueError(f"traj.ego must have the dataset's shape {human.shape}; got {ego.shape}")
    ado, valid = ds.ado, ds.ado_valid
    if getattr(traj, "ado", None) is not None:
        ado, valid = traj.ado, traj.ado_valid
    along, cross = metrics.along_cross_track(ego, human)
    return {
        "close_encounters": 100.0 * metrics.close_encounters(ego, ado, valid, metrics.CLOSE_GAP),
        "max_acceleration": metrics.max_acceleration(ego),
        "ade": metrics.ade(ego, human),
        "goal_distance": metrics.goal_distance(ego, human[:, -1]),
        "collision_rate": 100.0 * metrics.collisions(ego, ado, valid),
        "off_road_rate": 100.0 * metrics.off_road(ego, ds.maps),
        "at_fault_collision_rate": 100.0 * metrics.at_fault_collisions(ego, ado, valid, ds.maps),
        "ttc_rate": 100.0 * metrics.ttc_rate(ego, ado, valid),
        "route_progress": metrics.route_progress(ego, human, ds.maps),
        "along_track": np.abs(along).mean(axis=1),
        "cross_track": np.abs(cross).mean(axis=1),
        "along_bias": along.mean(axis=1),
    }


def score(traj: Any, ds: Any) -> dict:
    """Every metric of the rollout ``traj`` on ``ds`` (its rows are ``ds``'s scenes in
    order), averaged over the scenes (:func:`scene_scores`; the same numbers as
    :func:`minimanc.metrics.evaluate`, and :data:`TRACK_METRICS`), the collisions by kind
    (:func:`minimanc.diagnose.collision_taxonomy`, keys prefixed
    :data:`CONTACT_PREFIX`), and ``"families"``:
    the same averages over the scenes of each of :data:`SCENE_FAMILIES` present (with
    ``n_scenes``)."""
    per = scene_scores(traj, ds)
    res: dict[str, Any] = {k: float(v.mean()) for k, v in per.items()}
    ado, valid = ds.ado, ds.ado_valid
    if getattr(traj, "ado", None) is not None:
        ado, valid = traj.ado, traj.ado_valid
    kinds = collision_taxonomy(traj.ego, ado, valid, ds.ego, ds.maps)
    res.update({f"{CONTACT_PREFIX}{k}": v for k, v in kinds.items()})
    fams = {}
    for fam, mask in scene_families(ds).items():
        if mask.any():
            fams[fam] = {**{k: float(v[mask].mean()) for k, v in per.items()},
                         "n_scenes": int(mask.sum())}
    res["families"] = fams
    return res


def _load_split(data_path: str, lo: int, hi: int) -> Any:
    ds = _WORKER_DATA.get(data_path)
    if ds is None:
        ds = world.load(data_path)
        _WORKER_DATA.clear()
        _WORKER_DATA[data_path] = ds
    key = (data_path, lo, hi)
    sub = _WORKER_DATA.get(key)
    if sub is None:
        sub = ds.subset(slice(lo, hi))
        _WORKER_DATA[key] = sub
    return sub


def enable_jax_cache(directory: str | Path) -> None:
    """Persist JAX compilations under ``directory`` (unless the user set a cache already):
    runs that differ only by their seed, learning rate or data fraction then compile once
    (:func:`minimanc.train.fit` passes the last two to its jitted step as arguments)."""
    import jax  # JAX only for the jax engine

    if jax.config.jax_compilation_cache_dir:
        return
    Path(directory).mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(directory))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


def evaluate_job(job: dict) -> dict:
    """Closed-loop rollout + :func:`score` of one trained run (runs in a worker or inline).

    ``job``: ``data`` (the dataset file), ``lo``/``hi`` (the split's rows), ``checkpoint``,
    ``engine``, ``rollout`` and ``metrics`` (the files written), optionally ``agents``
    (the protocol, default ``"replay"``) and ``jax_cache``."""
    if job["engine"] == "jax" and job.get("jax_cache"):
        enable_jax_cache(job["jax_cache"])
    ds = _load_split(job["data"], job["lo"], job["hi"])
    fit = train.load_fit(job["checkpoint"])
    try:
        traj = rollout.closed_loop(fit, ds, engine=job["engine"], progress=False,
                                   agents=job.get("agents", "replay"))
    except rollout.BadControls as exc:  # a model whose closed loop blows up scores inf
        res = failed(str(exc))
        write_json(job["metrics"], res)
        np.savez(job["rollout"], error=np.array(str(exc)))
        return res
    traj.save(job["rollout"])
    res = score(traj, ds)
    write_json(job["metrics"], res)
    return res
