"""Chapter 9 — :class:`Study`: every study of the paper on one
:class:`~minimanc.studies.config.StudyConfig` (Table I under both protocols of the ados, per
scenario family, sample efficiency, q-states, self-ablation, parameter counts, and whether
vAGN's q-states are driving modes), every job queued before any result is awaited.

A study is made of parts, one job each: its files (:class:`~minimanc.studies.cache.StudyFiles`:
the data and the cache of every run), where its jobs run
(:class:`~minimanc.studies.submission.Submitter`), its trainings
(:class:`~minimanc.studies.training.Trainings`), its closed-loop evaluations
(:class:`~minimanc.studies.evaluation.Evaluations`), its learning-rate sweeps
(:class:`~minimanc.studies.tuning.Sweeps`) and the rows no training makes
(:class:`~minimanc.studies.references.References`)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from minimanc import metrics, models, rollout, train
from minimanc.engine import ENGINES
from minimanc.metrics import modes
from minimanc.rollout import check_agents
from minimanc.studies.cache import StudyFiles
from minimanc.studies.config import Run, StudyConfig, canonical_setting, plan
from minimanc.studies.evaluation import Evaluations, families_of
from minimanc.studies.executors import usable_cpus
from minimanc.studies.jobs import enable_jax_cache
from minimanc.studies.provenance import read_json_or_none, write_json
from minimanc.studies.recorded import (
    MODES_OMITTED,
    PERCEPTION_REFUSAL,
    REACTIVE_REFUSAL,
    is_recorded,
)
from minimanc.studies.references import References
from minimanc.studies.report import findings
from minimanc.studies.submission import Submitter
from minimanc.studies.training import Trainings
from minimanc.studies.tuning import Sweeps

__all__ = ["Study"]


class Study:
    """The studies of one :class:`StudyConfig` under ``out``: trained, evaluated and cached.

    ``engine`` trains and drives ("jax" or "numpy"); ``workers`` processes run the
    trainings and closed-loop evaluations, every job queued as soon as what it needs is
    known (0: everything inline in this process, one after the other; ``None``: one per
    CPU this process may use, :func:`minimanc.studies.executors.usable_cpus`);
    ``progress`` shows tqdm bars; ``log`` receives one line per event.
    ``agents`` are the protocols of the ados Table I is reported under
    (:data:`minimanc.rollout.AGENTS`, default both); the first one also tunes the
    learning rates and scores the other studies.
    ``executor``: ``"local"`` (this machine's ``workers`` processes) or ``"ray"``
    (trainings and rollouts as Ray tasks: the cluster at ``ray_address`` or
    ``RAY_ADDRESS``, else a local Ray with ``workers`` CPUs; the output directory must be
    on a file system every node sees). ``seeds_together``:
    train the runs of one configuration in one vmapped step
    (:func:`minimanc.train.fit_many`; results equal to training them one by one, to
    float32 rounding). Off by default: on XLA's CPU backend a convolution vmapped over
    per-run kernels becomes a grouped convolution, slower than the separate ones
    (``benchmarks/bench_study.py --seeds-together``).

    Its parts: ``files`` (:class:`~minimanc.studies.cache.StudyFiles`), ``submitter``,
    ``trainings``, ``evaluations``, ``sweeps``, ``references``; ``timing`` holds the
    seconds spent per stage.
    """

    def __init__(self, config: StudyConfig, out: str | Path, engine: str = "jax",
                 workers: int | None = None, progress: bool = True,
                 log: Callable[[str], None] | None = None,
                 agents: Sequence[str] = ("replay", "reactive"),
                 executor: str = "local", ray_address: str | None = None,
                 seeds_together: bool = False) -> None:
        if not isinstance(config, StudyConfig):
            raise ValueError(f"config must be a StudyConfig; got config={config!r}")
        if engine not in ENGINES:
            raise ValueError(f"engine must be one of {ENGINES}; got engine={engine!r}")
        self.submitter = Submitter(executor, usable_cpus() if workers is None else workers,
                                   ray_address)
        if isinstance(agents, str) or len(agents) == 0 or len(set(agents)) != len(agents):
            raise ValueError("agents must be a non-empty sequence of distinct protocols; got "
                             f"agents={agents!r}")
        self.agents = tuple(check_agents(a) for a in agents)
        if is_recorded(config) and "reactive" in self.agents:
            raise ValueError(REACTIVE_REFUSAL)
        if is_recorded(config) and config.training.perception_weight > 0:
            raise ValueError(PERCEPTION_REFUSAL)
        self.config = config
        self.engine = engine
        self.progress = progress
        self.log = log or (lambda msg: None)
        self.timing: dict[str, float] = {}
        self.files = StudyFiles(config, out, engine, self.log, progress, self.timing)
        if engine == "jax":
            enable_jax_cache(self.files.jax_dir)
        self.trainings = Trainings(self.files, self.submitter, engine, seeds_together,
                                   self.log, progress, self.timing)
        self.evaluations = Evaluations(self.trainings, self.files, self.submitter, engine,
                                       self.agents[0], self.timing)
        self.sweeps = Sweeps(self.evaluations)
        self.references = References(self.files, self.timing)

    # ----------------------------------------------------------------- the parts' main calls

    @property
    def primary(self) -> str:
        """The protocol that tunes the learning rates and scores the other studies."""
        return self.agents[0]

    @property
    def recorded(self) -> bool:
        """Whether the study runs on recorded data (:mod:`minimanc.studies.recorded`)."""
        return is_recorded(self.config)

    def datasets(self) -> tuple[Any, Any, Any]:
        """``(train, tune, val)`` (:meth:`StudyFiles.datasets`)."""
        return self.files.datasets()

    def checkpoint(self, run: Run) -> Path:
        """The checkpoint of ``run`` (:meth:`StudyFiles.checkpoint`)."""
        return self.files.checkpoint(run)

    def model_config(self, run: Run) -> models.ModelConfig:
        """The run's model configuration (:meth:`Trainings.model_config`)."""
        return self.trainings.model_config(run)

    def train_config(self, run: Run) -> train.TrainConfig:
        """The run's training configuration (:meth:`Trainings.train_config`)."""
        return self.trainings.train_config(run)

    def fit(self, run: Run) -> Path:
        """Train ``run`` (or reuse its checkpoint) and wait (:meth:`Trainings.fit`)."""
        return self.trainings.fit(run)

    def result(self, run: Run, split: str = "val", agents: str | None = None) -> dict:
        """Metrics of ``run`` on ``split`` under ``agents`` (:meth:`Evaluations.result`)."""
        return self.evaluations.result(run, split, agents)

    def rollout(self, run: Run, split: str = "val", agents: str | None = None
                ) -> rollout.Rollout:
        """The saved rollout of ``run`` (:meth:`Evaluations.rollout`)."""
        return self.evaluations.rollout(run, split, agents)

    def close(self) -> None:
        """Shut the worker processes down (:meth:`Submitter.close`)."""
        self.submitter.close()

    # ----------------------------------------------------------------- studies

    def runs(self, model: str, setting: str = "paper", n_states: int | None = None,
             fraction: float = 1.0) -> list[Run]:
        """One :class:`Run` per seed, at ``model``'s tuned learning rate (on-policy when the
        study trains so, :attr:`StudyConfig.on_policy`)."""
        setting = canonical_setting(model, setting)
        n = self.config.n_states if n_states is None else int(n_states)
        lr = self.sweeps.lr(model, setting)
        return [Run(model, setting, n, float(fraction), s, lr, self.config.on_policy)
                for s in self.config.seeds]

    def table1(self) -> dict:
        """``{agents: {setting: {model: aggregate}}}`` (Table I under each protocol), with
        the rows ``"human"``, ``"dmp_prior"`` (the DMP head at fixed gains) and the bounds
        (:attr:`References.bound_rows`: the expert, the style floor, the privileged learner
        over the training seeds; none on recorded data) first."""
        c = self.config
        for a in self.agents:
            for s in c.settings:
                for m in c.table_models:
                    self.evaluations.submit_runs(self.runs(m, s), a)
        out = {}
        ev, refs = self.evaluations, self.references
        for a in self.agents:
            fixed = {r: refs.aggregate(r, a) for r in ("human", "dmp_prior", *refs.bound_rows)}
            out[a] = {s: {**fixed, **{m: ev.aggregate(self.runs(m, s), a)
                                      for m in c.table_models}} for s in c.settings}
        return out

    def families(self) -> dict:
        """``{agents: {setting: {model: {family: aggregate}}}}``: Table I's rows per scenario
        family (:data:`minimanc.studies.jobs.SCENE_FAMILIES`; a family with no validation scene
        is left out)."""
        c = self.config
        out: dict = {}
        for a in self.agents:
            fixed = {m: families_of(self.references.runs(m, a))
                     for m in ("human", "dmp_prior", *self.references.bound_rows)}
            out[a] = {s: {**fixed, **{m: self.evaluations.aggregate_families(self.runs(m, s), a)
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
        path = self.files.derived_path("-val-modes.npy")
        _, _, val = self.datasets()
        if path.exists():
            try:
                labels = np.load(path, allow_pickle=False)
                if labels.shape == np.asarray(val.ego).shape[:2]:
                    return labels
            except (OSError, ValueError):
                pass
            self.files.discard(path, "not the validation split's mode labels")
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
                path = self.files.dir / "modes" / f"{run.key}-val.json"
                cached = read_json_or_none(path) if path.exists() else None
                if not isinstance(cached, dict) or "mi_bits" not in cached:
                    ck = self.fit(run)
                    if self.files.diverged(run):
                        continue
                    fit = train.load_fit(ck)
                    q = rollout.open_loop(fit, val, engine=self.engine)["q"]
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
                self.evaluations.submit_runs(self.runs(m, setting, fraction=f))
        return {"setting": setting, "agents": self.primary, "fractions": list(c.fractions),
                "models": {m: [self.evaluations.aggregate(self.runs(m, setting, fraction=f))
                               for f in c.fractions] for m in c.sample_models}}

    def q_states(self, setting: str = "paper") -> dict:
        """``{"setting", "n_states", "results": [aggregate per n]}`` for MANC (Fig. 7)."""
        c = self.config
        for n in c.q_states:
            self.evaluations.submit_runs(self.runs("manc", setting, n_states=n))
        return {"setting": setting, "agents": self.primary,
                "n_states": [int(n) for n in c.q_states],
                "results": [self.evaluations.aggregate(self.runs("manc", setting, n_states=n))
                            for n in c.q_states]}

    def ablation(self, setting: str = "paper") -> dict:
        """``{"setting", "models": {model: aggregate}}`` (Fig. 8)."""
        c = self.config
        for m in c.ablation_models:
            self.evaluations.submit_runs(self.runs(m, setting))
        return {"setting": setting, "agents": self.primary,
                "models": {m: self.evaluations.aggregate(self.runs(m, setting))
                           for m in c.ablation_models}}

    def param_counts(self) -> dict:
        """``{setting: {model: number of parameters}}`` (Fig. 5b), at ``n_states``."""
        c = self.config
        out = {}
        for s in c.settings:
            cfg = replace(c.model_config(c.n_states, s), input_shape=c.raster.input_shape)
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
                    self.evaluations.submit_runs(self.runs(m, s), a)
        for m in c.sample_models:
            for f in c.fractions:
                self.evaluations.submit_runs(self.runs(m, "paper", fraction=f))
        for n in c.q_states:
            self.evaluations.submit_runs(self.runs("manc", "paper", n_states=n))
        for m in c.ablation_models:
            self.evaluations.submit_runs(self.runs(m, "paper"))

    # ----------------------------------------------------------------- everything

    def run(self) -> dict:
        """Every study; returns the ``results`` dict written to ``results.json``."""
        t0 = time.perf_counter()
        self.datasets()
        bar = train_bar = None
        if self.progress and self.submitter.pooled:
            train_bar = tqdm(total=self.n_trainings(), desc="reproduce: trainings",
                             unit="run", position=0)
            bar = tqdm(total=self.n_runs(), desc="reproduce: evaluations", unit="run",
                       position=1)
        elif self.progress:
            bar = tqdm(total=self.n_runs(), desc="reproduce: runs", unit="run")
        self.evaluations.bar, self.trainings.bar = bar, train_bar
        try:
            self.sweeps.start(self._sweep_pairs())
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
            self.evaluations.bar = self.trainings.bar = None
        results["lr"] = {f"{m}-{s}": lr for (m, s), lr in sorted(self.sweeps.chosen.items())}
        results["sweeps"] = self.sweeps.scores
        results["findings"] = findings(results)
        self.timing["total"] = time.perf_counter() - t0
        results["timing_s"] = {k: round(v, 1) for k, v in self.timing.items()}
        return results

    def explain_run(self) -> Run:
        """The run whose rollouts the explainability figures show: MANC, paper, seed 0."""
        c = self.config
        return Run("manc", "paper", c.n_states, 1.0, 0, self.sweeps.lr("manc", "paper"),
                   c.on_policy)
