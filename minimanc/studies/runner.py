"""Chapter 9 — :class:`Study`: every study of the paper on the runs of
:class:`~minimanc.studies.runs.Runs` (Table I under both protocols of the ados, per scenario
family, sample efficiency, q-states, self-ablation, parameter counts, and whether vAGN's
q-states are driving modes), every job queued before any result is awaited."""

from __future__ import annotations

import time
from dataclasses import asdict
from typing import Any

import numpy as np
from tqdm import tqdm

from minimanc import engine, metrics, models, rollout, train
from minimanc.metrics import modes
from minimanc.studies.config import Run, canonical_setting, plan
from minimanc.studies.provenance import read_json_or_none, write_json
from minimanc.studies.recorded import MODES_OMITTED
from minimanc.studies.report import findings
from minimanc.studies.runs import THREAD_ENV, Runs, families_of

__all__ = ["THREAD_ENV", "Study", "families_of"]


class Study(Runs):
    """Runs the studies of one :class:`~minimanc.studies.config.StudyConfig` under ``out``
    (see :mod:`minimanc.studies`; the arguments are those of
    :class:`~minimanc.studies.runs.Runs`)."""

    def table1(self) -> dict:
        """``{agents: {setting: {model: aggregate}}}`` (Table I under each protocol), with
        the rows ``"human"``, ``"dmp_prior"`` (the DMP head at fixed gains) and the bounds
        (:attr:`bound_rows`: the expert, the style floor; none on recorded data) first."""
        c = self.config
        for a in self.agents:
            for s in c.settings:
                for m in c.table_models:
                    self.submit_runs(self.runs(m, s), a)
        out = {}
        for a in self.agents:
            fixed = {"human": self.human(a), "dmp_prior": self.references(a)["dmp_prior"],
                     **{b: metrics.aggregate([self.reference(b, a)]) for b in self.bound_rows}}
            out[a] = {s: {**fixed, **{m: self.aggregate(self.runs(m, s), a)
                                      for m in c.table_models}} for s in c.settings}
        return out

    def families(self) -> dict:
        """``{agents: {setting: {model: {family: aggregate}}}}``: Table I's rows per scenario
        family (:data:`minimanc.studies.jobs.SCENE_FAMILIES`; a family with no validation scene
        is left out)."""
        c = self.config
        out: dict = {}
        for a in self.agents:
            fixed = {m: families_of([self.reference(m, a)])
                     for m in ("human", "dmp_prior", *self.bound_rows)}
            out[a] = {s: {**fixed, **{m: self.aggregate_families(self.runs(m, s), a)
                                      for m in c.table_models}} for s in c.settings}
        return out

    def vagn_models(self) -> list[str]:
        """The study's models with a vAGN (their q-states are measured by :meth:`modes`)."""
        c = self.config
        names = dict.fromkeys([*c.table_models, *c.ablation_models, *c.sample_models])
        return [m for m in names if models.spec(m).family == "vagn"]

    def human_modes(self) -> Any:
        """The human's mode at each step of every validation scene
        (:func:`minimanc.metrics.modes.human_modes`, ``(S, T)``), cached next to the dataset."""
        if self.recorded:
            raise ValueError(MODES_OMITTED)
        path = self.derived_path("-val-modes.npy")
        _, _, val = self.datasets()
        if path.exists():
            try:
                labels = np.load(path, allow_pickle=False)
                if labels.shape == np.asarray(val.ego).shape[:2]:
                    return labels
            except (OSError, ValueError):
                pass
            self.discard(path, "not the validation split's mode labels")
        labels = modes.human_modes(val)
        tmp = path.with_name(path.stem + ".tmp.npy")
        np.save(tmp, labels)
        tmp.replace(path)
        return labels

    def modes(self, setting: str = "paper") -> dict:
        """Are vAGN's q-states driving modes? For each model of :meth:`vagn_models` and
        seed, the open-loop q over the validation scenes (:func:`minimanc.rollout.open_loop`:
        the model sees the human's observations) against the human's modes
        (:meth:`human_modes`) by :func:`minimanc.metrics.modes.mode_information`, aggregated over
        seeds: ``{"setting", "mode_counts", "models": {model: aggregate}}``."""
        if self.recorded:  # no human modes (minimanc.studies.recorded): nothing to measure
            return {"setting": setting, "mode_counts": {}, "models": {},
                    "omitted": MODES_OMITTED}
        labels = self.human_modes()
        counts = np.bincount(labels.ravel(), minlength=len(modes.MODES))
        out: dict = {"setting": setting,
                     "mode_counts": {m: int(n) for m, n in zip(modes.MODES, counts)},
                     "models": {}}
        _, _, val = self.datasets()
        t0 = time.perf_counter()
        for m in self.vagn_models():
            per_seed = []
            for run in self.runs(m, setting):
                path = self.cache / "modes" / f"{run.key}-val.json"
                cached = read_json_or_none(path) if path.exists() else None
                if not isinstance(cached, dict) or "mi_bits" not in cached:
                    ck = self.fit(run)
                    if self._diverged(run):
                        continue
                    fit = train.load_fit(ck)
                    q = rollout.open_loop(fit.name, fit.params, val, fit.cfg,
                                          engine(self.engine))["q"]
                    cached = modes.mode_information(q, labels)
                    write_json(path, cached)
                per_seed.append(cached)
            if per_seed:
                out["models"][m] = metrics.aggregate(per_seed)
        self.timing["modes"] = self.timing.get("modes", 0.0) + time.perf_counter() - t0
        return out

    def sample_efficiency(self, setting: str = "paper") -> dict:
        """``{"setting", "fractions", "models": {model: [aggregate per fraction]}}`` (Fig. 5a)."""
        c = self.config
        for m in c.sample_models:
            for f in c.fractions:
                self.submit_runs(self.runs(m, setting, fraction=f))
        return {"setting": setting, "agents": self.primary, "fractions": list(c.fractions),
                "models": {m: [self.aggregate(self.runs(m, setting, fraction=f))
                               for f in c.fractions] for m in c.sample_models}}

    def q_states(self, setting: str = "paper") -> dict:
        """``{"setting", "n_states", "results": [aggregate per n]}`` for MANC (Fig. 7)."""
        c = self.config
        for n in c.q_states:
            self.submit_runs(self.runs("manc", setting, n_states=n))
        return {"setting": setting, "agents": self.primary,
                "n_states": [int(n) for n in c.q_states],
                "results": [self.aggregate(self.runs("manc", setting, n_states=n))
                            for n in c.q_states]}

    def ablation(self, setting: str = "paper") -> dict:
        """``{"setting", "models": {model: aggregate}}`` (Fig. 8)."""
        c = self.config
        for m in c.ablation_models:
            self.submit_runs(self.runs(m, setting))
        return {"setting": setting, "agents": self.primary,
                "models": {m: self.aggregate(self.runs(m, setting))
                           for m in c.ablation_models}}

    def param_counts(self) -> dict:
        """``{setting: {model: number of parameters}}`` (Fig. 5b), at ``n_states``."""
        c = self.config
        out = {}
        for s in c.settings:
            cfg = models.ModelConfig(n_states=c.n_states, image_size=c.image_size, setting=s)
            out[s] = models.param_counts(cfg)
        return out

    def n_runs(self) -> int:
        """Number of closed-loop evaluations (tuning and validation, each protocol) of the
        whole study (for the progress bar; :func:`minimanc.studies.config.plan`)."""
        return sum(plan(self.config, len(self.agents))["rollouts"].values())

    def n_trainings(self) -> int:
        """Number of trainings of the whole study (:func:`minimanc.studies.config.plan`)."""
        return sum(plan(self.config, len(self.agents))["train"].values())

    def _sweep_pairs(self) -> list[tuple[str, str]]:
        c = self.config
        pairs = [(m, s) for s in c.settings for m in c.table_models]
        pairs += [(m, "paper") for m in c.ablation_models]
        pairs += [(m, "paper") for m in c.sample_models]
        seen, out = set(), []
        for m, s in pairs:
            k = (m, canonical_setting(m, s))
            if k not in seen:
                seen.add(k)
                out.append(k)
        return out

    def submit_studies(self) -> None:
        """Queue every training and evaluation of Table I and the studies before waiting for
        any (each configuration once its learning rate is tuned), so the executor's
        workers never wait for this process to ask for the next one."""
        c = self.config
        for a in self.agents:
            for s in c.settings:
                for m in c.table_models:
                    self.submit_runs(self.runs(m, s), a)
        for m in c.sample_models:
            for f in c.fractions:
                self.submit_runs(self.runs(m, "paper", fraction=f))
        for n in c.q_states:
            self.submit_runs(self.runs("manc", "paper", n_states=n))
        for m in c.ablation_models:
            self.submit_runs(self.runs(m, "paper"))

    # ----------------------------------------------------------------- everything

    def run(self) -> dict:
        """Every study; returns the ``results`` dict written to ``results.json``."""
        t0 = time.perf_counter()
        self.datasets()
        bar = train_bar = None
        if self.progress and self.pooled:
            train_bar = tqdm(total=self.n_trainings(), desc="reproduce: trainings",
                             unit="run", position=0)
            bar = tqdm(total=self.n_runs(), desc="reproduce: evaluations", unit="run",
                       position=1)
        elif self.progress:
            bar = tqdm(total=self.n_runs(), desc="reproduce: runs", unit="run")
        self._bar, self._train_bar = bar, train_bar
        try:
            self.start_sweeps(self._sweep_pairs())
            self.submit_studies()
            results = {
                "config": asdict(self.config),
                "engine": self.engine,
                "n_scenes": {"train": self.config.n_train, "tune": self.config.n_tune,
                             "val": self.config.n_val},
                "close_gap_m": metrics.CLOSE_GAP,
                "agents": list(self.agents),
                "table1": self.table1(),
                "families": self.families(),
                "sample_efficiency": self.sample_efficiency(),
                "q_states": self.q_states(),
                "ablation": self.ablation(),
                "param_counts": self.param_counts(),
                "modes": self.modes(),
            }
        finally:
            for b in (train_bar, bar):
                if b is not None:
                    b.close()
            self._bar = self._train_bar = None
        results["lr"] = {f"{m}-{s}": lr for (m, s), lr in sorted(self._lr.items())}
        results["sweeps"] = self._sweeps
        results["findings"] = findings(results)
        self.timing["total"] = time.perf_counter() - t0
        results["timing_s"] = {k: round(v, 1) for k, v in self.timing.items()}
        return results

    def explain_run(self) -> Run:
        """The run whose rollouts the explainability figures show: MANC, paper, seed 0."""
        c = self.config
        return Run("manc", "paper", c.n_states, 1.0, 0, self.lr("manc", "paper"))
