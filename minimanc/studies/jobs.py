"""Chapter 9 — the jobs of a study that run outside :class:`~minimanc.studies.runner.Study`:
the closed-loop rollout and metrics of one trained run (:func:`evaluate_job`, in a worker
process or inline), the persistent JAX compilation cache, and the cache's JSON files
(written atomically, read as ``None`` when broken)."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from minimanc import metrics

_WORKER_DATA: dict[str, Any] = {}


def _load_split(data_path: str, lo: int, hi: int) -> Any:
    from minimanc import world

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
    import jax

    if jax.config.jax_compilation_cache_dir:
        return
    Path(directory).mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(directory))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


def evaluate_job(job: dict) -> dict:
    """Closed-loop rollout + metrics of one trained run (runs in a worker or inline)."""
    from minimanc import engine, rollout, train

    if job["engine"] == "jax" and job.get("jax_cache"):
        enable_jax_cache(job["jax_cache"])
    ds = _load_split(job["data"], job["lo"], job["hi"])
    fit = train.load(job["checkpoint"])
    try:
        traj = rollout.closed_loop(fit.name, fit.params, ds, fit.cfg, engine(job["engine"]),
                                   progress=False)
    except rollout.BadControls as exc:  # a model whose closed loop blows up scores inf
        res = {k: float("inf") for k in metrics.METRICS}
        res["error"] = str(exc)
        write_json(job["metrics"], res)
        np.savez(job["rollout"], error=np.array(str(exc)))
        return res
    traj.save(job["rollout"])
    res = metrics.evaluate(traj, ds)
    write_json(job["metrics"], res)
    return res


def write_json(path: str | Path, obj: Any) -> None:
    """Write ``obj`` as JSON atomically (temporary file in the same directory, removed on
    failure, then :func:`os.replace`)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(obj, indent=1, sort_keys=True)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def read_json(path: Path) -> Any:
    """The JSON in ``path``, or ``None`` if it is missing or unreadable (a broken cache entry)."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None


class Done:
    """A finished future (inline evaluation)."""

    def __init__(self, value: Any) -> None:
        self._value = value

    def result(self) -> Any:
        return self._value

    def done(self) -> bool:
        return True
