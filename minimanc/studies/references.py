"""Chapter 9 — the rows of Table I that no training makes: :class:`References` drives the
logged human, MANC's DMP head at constant gains (the "DMP prior") and the bounds
(:data:`minimanc.diagnose.bounds.BOUND_ROWS`: the expert, the style floor, the privileged
learner, one per training seed) on a study's
validation split, and keeps their scores in the study's cache (a run that resumes does not
drive them again)."""

from __future__ import annotations

import time
from typing import Any

from minimanc import metrics, models, rollout
from minimanc.diagnose import bounds
from minimanc.studies.cache import StudyFiles
from minimanc.studies.jobs import score
from minimanc.studies.provenance import write_json
from minimanc.studies.recorded import is_recorded

__all__ = ["References"]


class References:
    """The drivers without learning of a study whose data are ``files``; ``timing`` gets the
    seconds spent driving them (``"references"``)."""

    def __init__(self, files: StudyFiles, timing: dict[str, float] | None = None) -> None:
        self.files = files
        self.config = files.config
        self.timing = {} if timing is None else timing
        self._scores: dict[str, dict] = {}
        self._floor: Any = None
        self._privileged: dict[int, Any] = {}

    @property
    def bound_rows(self) -> tuple[str, ...]:
        """The bound rows of Table I (:data:`minimanc.diagnose.bounds.BOUND_ROWS`); none on
        recorded data (:mod:`minimanc.studies.recorded`)."""
        return () if is_recorded(self.config) else bounds.BOUND_ROWS

    def score(self, name: str, agents: str, seed: int = 0) -> dict:
        """The scores (:func:`minimanc.studies.jobs.score`) of a driver without learning on
        the validation split under ``agents``: ``"human"`` (the log, or the human's logged
        controls among reactive ados), ``"dmp_prior"`` (MANC's DMP head as the library builds
        it, the paper's goal rule, at its initial constant gains,
        :func:`minimanc.rollout.fixed_gains`: what the structure alone does, the bar the
        learned gains must clear; the same bar whatever the study's ``model``, under whose
        goal rule the default gains may mean another pace) or a bound of
        :attr:`bound_rows` (``"privileged"``: the learner of training seed ``seed``)."""
        key = f"{name}-val-{agents}" + (f"-s{seed}" if name == "privileged" else "")
        if key not in self._scores:
            cached = self.files.cached_reference(key)
            self._scores[key] = self._drive(name, agents, seed, key) if cached is None else cached
        return self._scores[key]

    def _drive(self, name: str, agents: str, seed: int, key: str) -> dict:
        """:meth:`score` of a row the cache does not hold: driven, scored and saved."""
        _, _, val = self.files.datasets()
        t0 = time.perf_counter()
        if name == "human":
            traj = rollout.human(val, agents=agents)
        elif name == "expert":
            traj = bounds.expert_rollout(val, agents=agents)
        elif name == "privileged":
            traj = bounds.privileged_rollout(self.privileged(seed), val, agents=agents)
        elif name == "style_floor":  # one drive, ados reacting, scored under either protocol
            if self._floor is None:
                self._floor = bounds.floor_rollout(val, bounds.median_style())
            traj = self._floor
        else:
            cfg = models.ModelConfig(n_states=self.config.n_states)
            traj = rollout.fixed_gains(val, cfg=cfg, agents=agents)
        res = score(traj, val)
        write_json(self.files.reference_path(key), res)
        self.timing["references"] = (self.timing.get("references", 0.0)
                                      + time.perf_counter() - t0)
        return res

    def runs(self, name: str, agents: str) -> list[dict]:
        """The scores of row ``name`` under ``agents``, one per run: one per training seed for
        ``"privileged"`` (a learner), one for the others."""
        seeds = self.config.seeds if name == "privileged" else (0,)
        return [self.score(name, agents, seed) for seed in seeds]

    def aggregate(self, name: str, agents: str) -> dict:
        """:meth:`runs` as a Table I row (:func:`minimanc.metrics.aggregate`)."""
        return metrics.aggregate(self.runs(name, agents))

    def privileged(self, seed: int) -> Any:
        """The privileged learner of training seed ``seed``
        (:func:`minimanc.diagnose.bounds.privileged_learner` on the training split; kept). A
        study that caps its training (``training.max_steps_per_epoch``) caps it too, at
        ``epochs × max_steps_per_epoch`` steps."""
        if seed not in self._privileged:
            train_ds, _, _ = self.files.datasets()
            tc = self.config.training
            steps = None if tc.max_steps_per_epoch is None else \
                tc.epochs * tc.max_steps_per_epoch
            self._privileged[seed] = bounds.privileged_learner(train_ds, seed, steps)
        return self._privileged[seed]
