"""Chapter 9 — a study's closed-loop evaluations: :class:`Evaluations` drives each trained
:class:`~minimanc.studies.config.Run` on a split under a protocol of the ados once (its
training first, :class:`~minimanc.studies.training.Trainings`), scores it
(:func:`minimanc.studies.jobs.score`) and keeps both in the
:class:`~minimanc.studies.cache.StudyFiles`; :func:`families_of` aggregates the scores per
scenario family."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

from minimanc import metrics, rollout
from minimanc.studies.cache import StudyFiles
from minimanc.studies.config import Run
from minimanc.studies.executors import Done, evaluate_trained
from minimanc.studies.jobs import SCENE_FAMILIES, failed
from minimanc.studies.submission import Submitter
from minimanc.studies.training import Trainings

__all__ = ["Evaluations", "families_of"]


class Evaluations:
    """The closed-loop evaluations of a study: ``trainings`` give the checkpoints,
    ``files`` the cache, ``submitter`` runs the jobs, ``engine`` drives; ``primary`` is the
    protocol used when none is named; ``timing`` gets the seconds of inline rollouts
    (``"rollout"``); ``bar``, when set, a tqdm bar advanced by each finished evaluation."""

    def __init__(self, trainings: Trainings, files: StudyFiles, submitter: Submitter,
                 engine: str, primary: str, timing: dict[str, float] | None = None) -> None:
        self.trainings = trainings
        self.files = files
        self.submitter = submitter
        self.engine = engine
        self.primary = primary
        self.timing = {} if timing is None else timing
        self.bar: Any = None
        self.futures: dict[str, Any] = {}

    def submit(self, run: Run, split: str = "val", agents: str | None = None) -> Any:
        """Train ``run`` if needed and start its closed-loop evaluation on ``split`` under
        the protocol ``agents`` (default :attr:`primary`).

        Returns a future-like object whose ``result()`` is the metrics dict
        (:func:`minimanc.studies.jobs.score`).
        """
        agents = self.primary if agents is None else agents
        key = f"{run.key}-{split}-{agents}"
        if key in self.futures:
            return self.futures[key]
        cached = self.files.cached_scores(run, split, agents)
        if cached is not None:
            fut: Any = Done(cached)
        else:
            trained, k = self.trainings.start([run])[run.key]
            self.files.datasets()
            lo, hi = self.files.rows(split)
            roll_path, met_path = self.files.rollout_paths(run, split, agents)
            job = {"data": str(self.files.data_path), "lo": lo, "hi": hi,
                   "engine": self.engine, "rollout": str(roll_path), "metrics": str(met_path),
                   "jax_cache": str(self.files.jax_dir), "agents": agents}
            if self.submitter.pooled:  # runs once its training job has finished
                fut = self.submitter.submit(evaluate_trained, trained, k, job)
            elif self.files.diverged(run):
                fut = Done(failed("training diverged"))
            else:
                t0 = time.perf_counter()
                fut = Done(evaluate_trained(trained.result(), k, job))
                self.timing["rollout"] = (self.timing.get("rollout", 0.0)
                                          + time.perf_counter() - t0)
        self.futures[key] = fut
        fut.add_done_callback(self._tick)
        return fut

    def result(self, run: Run, split: str = "val", agents: str | None = None) -> dict:
        """Metrics of ``run`` on ``split`` under ``agents`` (trains and evaluates if needed;
        waits)."""
        return self.submit(run, split, agents).result()

    def rollout(self, run: Run, split: str = "val", agents: str | None = None
                ) -> rollout.Rollout:
        """The saved :class:`minimanc.rollout.Rollout` of ``run`` on ``split`` under
        ``agents`` (default :attr:`primary`)."""
        agents = self.primary if agents is None else agents
        self.result(run, split, agents)
        return rollout.Rollout.load(self.files.rollout_paths(run, split, agents)[0])

    def aggregate(self, runs: Sequence[Run], agents: str | None = None) -> dict:
        """:func:`minimanc.metrics.aggregate` of the seeds ``runs`` on the validation split."""
        futs = [self.submit(r, agents=agents) for r in runs]
        return metrics.aggregate([f.result() for f in futs])

    def aggregate_families(self, runs: Sequence[Run], agents: str | None = None) -> dict:
        """:func:`families_of` the seeds ``runs`` on the validation split."""
        return families_of([self.submit(r, agents=agents).result() for r in runs])

    def submit_runs(self, runs: Sequence[Run], agents: str | None = None) -> None:
        """Queue the trainings of ``runs``, then their evaluations on the validation split."""
        self.trainings.start(runs)
        for r in runs:
            self.submit(r, agents=agents)

    def _tick(self, _future: Any = None) -> None:
        """One evaluation finished: advance its progress bar."""
        if self.bar is not None:
            self.bar.update(1)


def families_of(per_seed: Sequence[dict]) -> dict:
    """``{family: aggregate}`` over the seeds' :func:`minimanc.studies.jobs.score` dicts (the
    families every seed has, in the order of :data:`minimanc.studies.jobs.SCENE_FAMILIES`)."""
    return {f: metrics.aggregate([r["families"][f] for r in per_seed]) for f in SCENE_FAMILIES
            if all(f in r.get("families", {}) for r in per_seed)}
