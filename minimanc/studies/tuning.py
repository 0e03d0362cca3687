"""Chapter 9 — fair tuning: :class:`Sweeps` picks each model's learning rate from the
study's sweep (:attr:`~minimanc.studies.config.StudyConfig.lrs`) by closed-loop ADE on the
tuning split, the runs at 100 % data and seed 0 evaluated by
:class:`~minimanc.studies.evaluation.Evaluations`."""

from __future__ import annotations

from collections.abc import Sequence

from minimanc.studies.config import Run, canonical_setting
from minimanc.studies.evaluation import Evaluations

__all__ = ["Sweeps"]


class Sweeps:
    """The learning-rate sweeps of a study, evaluated by ``evaluations`` under their
    primary protocol. ``chosen`` holds ``{(model, setting): lr}``, ``scores``
    ``{"model-setting": {"tune_ade": {lr: ADE}, "best_lr": lr}}`` of every sweep run."""

    def __init__(self, evaluations: Evaluations) -> None:
        self.evaluations = evaluations
        self.config = evaluations.files.config
        self.chosen: dict[tuple[str, str], float] = {}
        self.scores: dict[str, dict] = {}

    def _runs(self, model: str, setting: str) -> list[Run]:
        c = self.config
        return [Run(model, setting, c.n_states, 1.0, 0, float(lr)) for lr in c.lrs]

    def lr(self, model: str, setting: str = "paper") -> float:
        """Learning rate of ``model`` in ``setting``: best closed-loop ADE on the tuning split."""
        setting = canonical_setting(model, setting)
        key = (model, setting)
        if key in self.chosen:
            return self.chosen[key]
        c = self.config
        if len(c.lrs) == 1:
            self.chosen[key] = float(c.lrs[0])
            return self.chosen[key]
        ev = self.evaluations
        runs = self._runs(model, setting)
        futs = [ev.submit(r, "tune", ev.primary) for r in runs]
        scores = {float(r.lr): float(f.result()["ade"]) for r, f in zip(runs, futs)}
        best = min(scores, key=lambda k: (scores[k], k))
        self.scores[f"{model}-{setting}"] = {"tune_ade": {f"{k:g}": v for k, v in
                                                          scores.items()},
                                             "best_lr": best}
        self.chosen[key] = best
        return best

    def start(self, pairs: Sequence[tuple[str, str]]) -> None:
        """Queue every sweep run of the ``(model, setting)`` pairs (training, then its
        evaluation on the tuning split) first: the learning rates every other run waits
        for."""
        if len(self.config.lrs) == 1:
            return
        ev = self.evaluations
        for model, setting in pairs:
            runs = self._runs(model, canonical_setting(model, setting))
            ev.trainings.start(runs)
            for r in runs:
                ev.submit(r, "tune", ev.primary)
