"""Chapter 9 — a study's trainings: :class:`Trainings` trains each
:class:`~minimanc.studies.config.Run` once (or reuses its checkpoint in the
:class:`~minimanc.studies.cache.StudyFiles`), inline or as a job of the
:class:`~minimanc.studies.submission.Submitter`; optionally the seeds (and a sweep's
learning rates) of one configuration train together (:func:`minimanc.train.fit_many`).
An on-policy run (:attr:`~minimanc.studies.config.Run.on_policy`) trains on its own by
DAgger (:func:`minimanc.studies.executors.train_on_policy`)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from minimanc import models, train
from minimanc.studies.cache import StudyFiles
from minimanc.studies.config import Run
from minimanc.studies.executors import Done, train_job, train_runs
from minimanc.studies.recorded import is_recorded
from minimanc.studies.submission import Submitter

__all__ = ["DAGGER_BETA", "DAGGER_REFUSAL", "Trainings"]

DAGGER_BETA: float = 0.5
"""``p`` of DAgger's mixing schedule ``β_i = p^i`` (:func:`minimanc.dagger.beta_schedule`)
for a study's on-policy runs."""

DAGGER_REFUSAL: str = (
    "on-policy training (dagger_rounds > 0) is not available on recorded data: DAgger asks "
    "the world's driver in the states the policy visits, and a recorded scene has none")
"""Why a study on recorded data trains by behaviour cloning only (one line)."""


class Trainings:
    """The trainings of a study: ``files`` (where checkpoints are), ``submitter`` (where
    jobs run), ``engine``; ``seeds_together`` trains the runs of one configuration in one
    vmapped step (:func:`minimanc.train.fit_many`); ``log`` gets one line per event,
    ``timing`` the seconds of inline trainings (``"train"``); ``bar``, when set, a tqdm bar
    advanced by each finished training. A study on recorded data with
    ``dagger_rounds`` > 0 is refused (:data:`DAGGER_REFUSAL`)."""

    def __init__(self, files: StudyFiles, submitter: Submitter, engine: str,
                 seeds_together: bool, log: Callable[[str], None], progress: bool = True,
                 timing: dict[str, float] | None = None) -> None:
        if files.config.on_policy and is_recorded(files.config):
            raise ValueError(DAGGER_REFUSAL)
        self.files = files
        self.config = files.config
        self.submitter = submitter
        self.engine = engine
        self.seeds_together = bool(seeds_together)
        self.log = log
        self.progress = progress
        self.timing = {} if timing is None else timing
        self.bar: Any = None
        self._started: dict[str, tuple[Any, int]] = {}

    def model_config(self, run: Run) -> models.ModelConfig:
        """The run's :class:`~minimanc.models.ModelConfig`: the study's
        (:meth:`~minimanc.studies.config.StudyConfig.model_config`) with its q-states and
        setting."""
        return self.config.model_config(run.n_states, run.setting)

    def train_config(self, run: Run) -> train.TrainConfig:
        """The run's :class:`~minimanc.train.TrainConfig` (:meth:`StudyConfig.train_config`)."""
        return self.config.train_config(run.model, run.lr, run.seed, run.fraction)

    def fit(self, run: Run) -> Path:
        """Train ``run`` (or resume / reuse its checkpoint) and wait for it. Returns the
        checkpoint path."""
        fut, k = self.start([run])[run.key]
        return Path(fut.result()[k])

    def start(self, runs: Sequence[Run]) -> dict[str, tuple[Any, int]]:
        """Start training ``runs``: those of one configuration (model, setting, q-states,
        fraction) that are not trained yet train together (one job per configuration, or
        per run without ``seeds_together``; an on-policy run always alone, its job holding
        DAgger's ``dagger_rounds``, ``round_epochs`` and ``beta``). With
        ``perception_weight`` > 0 the job names the file of the training split's perception
        targets (:meth:`StudyFiles.perception_targets`, computed here once). Returns
        ``{run.key: (future, index)}``: the job's ``result()[index]`` is the run's
        checkpoint path."""
        files = self.files
        groups: dict[tuple, list[Run]] = {}
        for r in runs:
            if r.key in self._started:
                continue
            if files.complete(r):
                self._started[r.key] = (Done([str(files.checkpoint(r))]), 0)
                continue
            g = (r.model, r.setting, r.n_states, r.fraction)
            alone = r.on_policy or not self.seeds_together
            groups.setdefault((r.key,) if alone else g, []).append(r)
        train_ds = files.datasets()[0] if groups else None
        perception = ""
        if groups and self.config.training.perception_weight > 0:
            perception = str(files.perception_targets())
        for group in groups.values():
            first = group[0]
            job = {"model": first.model, "data": str(files.data_path), "lo": 0,
                   "hi": self.config.n_train, "cfg": self.model_config(first),
                   "train_cfgs": [self.train_config(r) for r in group],
                   "checkpoints": [str(files.checkpoint(r)) for r in group],
                   "engine": self.engine, "jax_cache": str(files.jax_dir),
                   "perception": perception}
            if first.on_policy:
                job.update(dagger_rounds=self.config.dagger_rounds,
                           round_epochs=self.config.round_epochs, beta=DAGGER_BETA)
            keys = ", ".join(r.key for r in group)
            if self.submitter.pooled:
                fut = self.submitter.submit(train_job, job)
                self.log(f"train: {keys} submitted")
            else:
                t0 = time.perf_counter()
                fut = Done(train_runs(train_ds, {**job, "progress": self.progress}))
                dt = time.perf_counter() - t0
                self.timing["train"] = self.timing.get("train", 0.0) + dt
                self.log(f"train: {keys} in {dt:.1f} s")
                for r in group:
                    if files.diverged(r):
                        self.log(f"train: {r.key} diverged; scored as inf")
            for k, r in enumerate(group):
                self._started[r.key] = (fut, k)
            n_runs = len(group)
            fut.add_done_callback(lambda _, n=n_runs: self._tick(n))
        return {r.key: self._started[r.key] for r in runs}

    def _tick(self, n: int) -> None:
        """``n`` trainings finished: advance their progress bar."""
        if self.bar is not None:
            self.bar.update(n)
