"""Chapter 9 — the runs of a study: :class:`Runs` trains each :class:`~minimanc.studies.config.Run`
once (or reuses its checkpoint), drives it closed loop on a split under a protocol of the
ados, keeps both in the cache under the output directory, tunes the learning rates on the
tuning split, and hands the trainings and evaluations to an executor
(:mod:`minimanc.studies.executors`: a pool of worker processes on this machine, or Ray
tasks); optionally the seeds (and a sweep's learning rates) of one configuration train
together (:func:`minimanc.train.fit_many`). :class:`minimanc.studies.runner.Study` builds
the paper's studies on it."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from minimanc import metrics, models, rollout, train, world
from minimanc.checks import check_int
from minimanc.diagnose import bounds
from minimanc.engine import ENGINES
from minimanc.rollout import check_agents
from minimanc.studies.config import Run, StudyConfig, canonical_setting
from minimanc.studies.executors import (
    EXECUTORS,
    Done,
    check_ray,
    evaluate_trained,
    executor,
    train_job,
    train_runs,
    usable_cpus,
)
from minimanc.studies.jobs import (
    SCENE_FAMILIES,
    STUDY_METRICS,
    enable_jax_cache,
    failed,
    score,
)
from minimanc.studies.provenance import read_json_or_none
from minimanc.studies.recorded import REACTIVE_REFUSAL, is_recorded

__all__ = ["THREAD_ENV", "Runs", "families_of"]

THREAD_ENV: tuple[str, ...] = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                               "MINIMANC_XLA_THREADS", "XLA_FLAGS", "JAX_PLATFORMS")
"""Environment variables a Ray worker inherits from the driver (so that a task computes as
a local job would)."""


class Runs:
    """The runs of one :class:`StudyConfig` under ``out``: trained, evaluated and cached.

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
        workers = usable_cpus() if workers is None else check_int("workers", workers, 0)
        if executor not in EXECUTORS:
            raise ValueError(f"executor must be one of {EXECUTORS}; got executor={executor!r}")
        if executor == "ray":
            check_ray()  # before any work: the one-line UsageError saying how to install it
        if ray_address is not None and executor != "ray":
            raise ValueError(f"ray_address is only for executor='ray'; got "
                             f"ray_address={ray_address!r} with executor={executor!r}")
        if isinstance(agents, str) or len(agents) == 0 or len(set(agents)) != len(agents):
            raise ValueError("agents must be a non-empty sequence of distinct protocols; got "
                             f"agents={agents!r}")
        self.agents = tuple(check_agents(a) for a in agents)
        if is_recorded(config) and "reactive" in self.agents:
            raise ValueError(REACTIVE_REFUSAL)
        self.config = config
        self.out = Path(out)
        self.engine = engine
        self.workers = workers
        self.progress = progress
        self.log = log or (lambda msg: None)
        self.cache = self.out / "cache" / f"{config.fingerprint()}-{engine}"
        self.jax_cache = self.out / "cache" / "jax"
        if engine == "jax":
            enable_jax_cache(self.jax_cache)
        self._data: tuple[Any, Any, Any] | None = None
        self.executor = executor
        self.ray_address = ray_address
        self.seeds_together = bool(seeds_together)
        self._pool: Any = None
        self._trained: dict[str, tuple[Any, int]] = {}
        self._futures: dict[str, Any] = {}
        self._lr: dict[tuple[str, str], float] = {}
        self._sweeps: dict[str, dict] = {}
        self.timing: dict[str, float] = {}
        self._bar: Any = None
        self._train_bar: Any = None
        self._references: dict[str, dict] = {}

    # ----------------------------------------------------------------- data

    @property
    def data_path(self) -> Path:
        """The dataset file: the given one (``config.data_file``), else the one generated
        under ``data/``."""
        c = self.config
        if c.data_file:
            return Path(c.data_file)
        n = c.n_train + c.n_tune + c.n_val
        return self.out / "data" / f"world-{n}x{c.data_seed}-{c.image_size}px.npz"

    def derived_path(self, suffix: str) -> Path:
        """Where data derived from the dataset file is cached: next to a generated file,
        under ``data/`` (named by the content hash) for a given one."""
        c = self.config
        if not c.data_file:
            return self.data_path.with_name(self.data_path.stem + suffix)
        folder = self.out / "data"
        folder.mkdir(parents=True, exist_ok=True)
        return folder / f"{self.data_path.stem}-{c.data_hash[:12]}{suffix}"

    @property
    def recorded(self) -> bool:
        """Whether the study runs on recorded data (:mod:`minimanc.studies.recorded`)."""
        return is_recorded(self.config)

    @property
    def bound_rows(self) -> tuple[str, ...]:
        """The bound rows of Table I (:data:`minimanc.diagnose.bounds.BOUND_ROWS`); none on
        recorded data (:mod:`minimanc.studies.recorded`)."""
        return () if self.recorded else bounds.BOUND_ROWS

    def datasets(self) -> tuple[Any, Any, Any]:
        """``(train, tune, val)``: the given file's scenes, or generated once (saved under
        ``data/``), then loaded."""
        if self._data is not None:
            return self._data
        c = self.config
        n = c.n_train + c.n_tune + c.n_val
        t0 = time.perf_counter()
        ds = None
        if c.data_file:
            ds = world.load(self.data_path)
            if ds.content_hash() != c.data_hash:
                raise ValueError(f"{self.data_path}: the file changed since its study "
                                 "configuration was made (another content hash); make the "
                                 "configuration again (minimanc.studies.recorded.data_config)")
            self.log(f"data: loaded {len(ds)} scenes from {self.data_path}")
        elif self.data_path.exists():
            try:
                ds = world.load(self.data_path)
                self.log(f"data: loaded {n} scenes from {self.data_path}")
            except world.DatasetFileError as exc:  # older format, truncated, altered: remake
                self.discard(self.data_path, str(exc))
        if ds is None:
            self.log(f"data: generating {n} scenes ({c.image_size}x{c.image_size} BEV)")
            ds = world.generate(n, seed=c.data_seed,
                                raster=world.RasterConfig(size=c.image_size),
                                progress=self.progress)
            world.save(ds, self.data_path)
        self.timing["data"] = time.perf_counter() - t0
        a, b = c.n_train, c.n_train + c.n_tune
        self._data = (ds.subset(slice(0, a)), ds.subset(slice(a, b)), ds.subset(slice(b, n)))
        return self._data

    def _bounds(self, split: str) -> tuple[int, int]:
        c = self.config
        a, b = c.n_train, c.n_train + c.n_tune
        return {"tune": (a, b), "val": (b, b + c.n_val)}[split]

    # ----------------------------------------------------------------- training

    def model_config(self, run: Run) -> Any:
        return models.ModelConfig(n_states=run.n_states, image_size=self.config.image_size,
                                  setting=run.setting)

    def train_config(self, run: Run) -> Any:
        """The run's :class:`~minimanc.train.TrainConfig` (:meth:`StudyConfig.train_config`)."""
        return self.config.train_config(run.model, run.lr, run.seed, run.fraction)

    def checkpoint(self, run: Run) -> Path:
        return self.cache / "models" / run.key / train.CHECKPOINT_NAME

    def fit(self, run: Run) -> Path:
        """Train ``run`` (or resume / reuse its checkpoint) and wait for it. Returns the
        checkpoint path."""
        fut, k = self.train_group([run])[run.key]
        return Path(fut.result()[k])

    def _complete(self, run: Run) -> bool:
        """Whether ``run``'s checkpoint holds every epoch (or the run diverged)."""
        path = self.checkpoint(run)
        if self._diverged(run):
            return True  # scored as inf; delete diverged.json to train it again
        if not path.exists():
            return False
        try:
            return train.load_checkpoint(path)["epoch"] >= self.config.epochs
        except train.CheckpointError as exc:
            # the cache is derived data: drop the broken entry and train the run again
            self.discard(path, str(exc))
            return False

    def train_group(self, runs: Sequence[Run]) -> dict[str, tuple[Any, int]]:
        """Start training ``runs``: those of one configuration (model, setting, q-states,
        fraction) that are not trained yet train together (one job per configuration, or
        per run without ``seeds_together``). Returns ``{run.key: (future, index)}``: the
        job's ``result()[index]`` is the run's checkpoint path."""
        groups: dict[tuple, list[Run]] = {}
        for r in runs:
            if r.key in self._trained:
                continue
            if self._complete(r):
                self._trained[r.key] = (Done([str(self.checkpoint(r))]), 0)
                continue
            g = (r.model, r.setting, r.n_states, r.fraction)
            groups.setdefault(g if self.seeds_together else (r.key,), []).append(r)
        train_ds = self.datasets()[0] if groups else None
        for group in groups.values():
            first = group[0]
            job = {"model": first.model, "data": str(self.data_path), "lo": 0,
                   "hi": self.config.n_train, "cfg": self.model_config(first),
                   "train_cfgs": [self.train_config(r) for r in group],
                   "checkpoints": [str(self.checkpoint(r)) for r in group],
                   "engine": self.engine, "jax_cache": str(self.jax_cache)}
            keys = ", ".join(r.key for r in group)
            if self.pooled:
                fut = self._executor().submit(train_job, job)
                self.log(f"train: {keys} submitted")
            else:
                t0 = time.perf_counter()
                fut = Done(train_runs(train_ds, {**job, "progress": self.progress}))
                dt = time.perf_counter() - t0
                self.timing["train"] = self.timing.get("train", 0.0) + dt
                self.log(f"train: {keys} in {dt:.1f} s")
                for r in group:
                    if self._diverged(r):
                        self.log(f"train: {r.key} diverged; scored as inf")
            for k, r in enumerate(group):
                self._trained[r.key] = (fut, k)
            n_runs = len(group)
            fut.add_done_callback(lambda _, n=n_runs: self._tick_training(n))
        return {r.key: self._trained[r.key] for r in runs}

    def _diverged(self, run: Run) -> bool:
        return (self.checkpoint(run).parent / "diverged.json").exists()

    def discard(self, path: Path, why: str) -> None:
        """Delete the unreadable cache entry ``path`` (it is recomputed), saying so on stderr."""
        print(f"minimanc reproduce: discarding the unreadable cache entry {path} ({why}); "
              "recomputing it", file=sys.stderr)
        self.log(f"cache: discarded {path}")
        path.unlink(missing_ok=True)

    # ----------------------------------------------------------------- evaluation

    @property
    def primary(self) -> str:
        """The protocol that tunes the learning rates and scores the other studies."""
        return self.agents[0]

    def _paths(self, run: Run, split: str, agents: str = "replay") -> tuple[Path, Path]:
        base = self.cache / "rollouts"
        tail = "" if agents == "replay" else f"-{agents}"
        return (base / f"{run.key}-{split}{tail}.npz",
                base / f"{run.key}-{split}{tail}.json")

    def submit(self, run: Run, split: str = "val", agents: str | None = None) -> Any:
        """Train ``run`` if needed and start its closed-loop evaluation on ``split`` under
        the protocol ``agents`` (default :attr:`primary`).

        Returns a future-like object whose ``result()`` is the metrics dict
        (:func:`minimanc.studies.jobs.score`).
        """
        agents = self.primary if agents is None else agents
        key = f"{run.key}-{split}-{agents}"
        if key in self._futures:
            return self._futures[key]
        roll_path, met_path = self._paths(run, split, agents)
        cached = read_json_or_none(met_path) if met_path.exists() and roll_path.exists() else None
        if met_path.exists() and roll_path.exists() and not isinstance(cached, dict):
            self.discard(met_path, "not a JSON object")
        if isinstance(cached, dict) and not (
                "families" in cached and all(k in cached for k in STUDY_METRICS)):
            cached = None  # scored by an older version: evaluate again
        if isinstance(cached, dict):
            fut: Any = Done(cached)
        else:
            trained, k = self.train_group([run])[run.key]
            self.datasets()
            lo, hi = self._bounds(split)
            job = {"data": str(self.data_path), "lo": lo, "hi": hi, "engine": self.engine,
                   "rollout": str(roll_path), "metrics": str(met_path),
                   "jax_cache": str(self.jax_cache), "agents": agents}
            if self.pooled:  # runs once its training job has finished
                fut = self._executor().submit(evaluate_trained, trained, k, job)
            elif self._diverged(run):
                fut = Done(failed("training diverged"))
            else:
                t0 = time.perf_counter()
                fut = Done(evaluate_trained(trained.result(), k, job))
                self.timing["rollout"] = (self.timing.get("rollout", 0.0)
                                          + time.perf_counter() - t0)
        self._futures[key] = fut
        fut.add_done_callback(self._tick)
        return fut

    def _executor(self) -> Any:
        """The :mod:`~minimanc.studies.executors` executor of the jobs (made on first use)."""
        if self._pool is None:
            env = {k: os.environ[k] for k in THREAD_ENV if k in os.environ}
            self._pool = executor(self.executor, self.workers, self.ray_address, env=env)
        return self._pool

    def result(self, run: Run, split: str = "val", agents: str | None = None) -> dict:
        """Metrics of ``run`` on ``split`` under ``agents`` (trains and evaluates if needed;
        waits)."""
        return self.submit(run, split, agents).result()

    def rollout(self, run: Run, split: str = "val", agents: str | None = None) -> Any:
        """The saved :class:`minimanc.rollout.Rollout` of ``run`` on ``split`` under
        ``agents`` (default :attr:`primary`)."""
        agents = self.primary if agents is None else agents
        self.result(run, split, agents)
        return rollout.Rollout.load(self._paths(run, split, agents)[0])

    def close(self) -> None:
        """Shut the worker processes down (and a local Ray this study started)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    # ----------------------------------------------------------------- tuning

    def lr(self, model: str, setting: str = "paper") -> float:
        """Learning rate of ``model`` in ``setting``: best closed-loop ADE on the tuning split."""
        setting = canonical_setting(model, setting)
        key = (model, setting)
        if key in self._lr:
            return self._lr[key]
        c = self.config
        if len(c.lrs) == 1:
            self._lr[key] = float(c.lrs[0])
            return self._lr[key]
        runs = [Run(model, setting, c.n_states, 1.0, 0, float(lr)) for lr in c.lrs]
        futs = [self.submit(r, "tune", self.primary) for r in runs]
        scores = {float(r.lr): float(f.result()["ade"]) for r, f in zip(runs, futs)}
        best = min(scores, key=lambda k: (scores[k], k))
        self._sweeps[f"{model}-{setting}"] = {"tune_ade": {f"{k:g}": v for k, v in
                                                           scores.items()},
                                              "best_lr": best}
        self._lr[key] = best
        return best

    def start_sweeps(self, pairs: Sequence[tuple[str, str]]) -> None:
        """Queue every sweep run (training, then its evaluation on the tuning split) first:
        the learning rates every other run waits for."""
        c = self.config
        if len(c.lrs) == 1:
            return
        for model, setting in pairs:
            setting = canonical_setting(model, setting)
            runs = [Run(model, setting, c.n_states, 1.0, 0, float(lr)) for lr in c.lrs]
            self.train_group(runs)
            for r in runs:
                self.submit(r, "tune", self.primary)

    # ----------------------------------------------------------------- studies

    def runs(self, model: str, setting: str = "paper", n_states: int | None = None,
             fraction: float = 1.0) -> list[Run]:
        """One :class:`Run` per seed, at ``model``'s tuned learning rate."""
        setting = canonical_setting(model, setting)
        n = self.config.n_states if n_states is None else int(n_states)
        lr = self.lr(model, setting)
        return [Run(model, setting, n, float(fraction), s, lr) for s in self.config.seeds]

    def aggregate(self, runs: list[Run], agents: str | None = None) -> dict:
        futs = [self.submit(r, agents=agents) for r in runs]
        return metrics.aggregate([f.result() for f in futs])

    def aggregate_families(self, runs: list[Run], agents: str | None = None) -> dict:
        res = [self.submit(r, agents=agents).result() for r in runs]
        return families_of(res)

    def submit_runs(self, runs: list[Run], agents: str | None = None) -> None:
        self.train_group(runs)
        for r in runs:
            self.submit(r, agents=agents)

    def _tick(self, _future: Any = None) -> None:
        """One evaluation finished: advance its progress bar."""
        if self._bar is not None:
            self._bar.update(1)

    def _tick_training(self, n: int) -> None:
        """``n`` trainings finished: advance their progress bar."""
        if self._train_bar is not None:
            self._train_bar.update(n)

    @property
    def pooled(self) -> bool:
        """Whether trainings and evaluations run as jobs of the executor (Ray, or a local
        pool of ``workers`` processes) rather than in this process."""
        return self.executor == "ray" or self.workers > 0

    def reference(self, name: str, agents: str) -> dict:
        """The scores of a driver without learning on the validation split (cached in memory):
        ``"human"``, ``"dmp_prior"`` or a bound (:data:`minimanc.diagnose.bounds.BOUND_ROWS`)."""
        key = f"{name}-val-{agents}"
        if key not in self._references:
            _, _, val = self.datasets()
            t0 = time.perf_counter()
            if name == "human":
                traj = rollout.human(val, agents=agents)
            elif name == "expert":
                traj = bounds.expert_rollout(val, agents=agents)
            elif name == "style_floor":  # one drive, ados reacting, scored under either protocol
                if "style_floor" not in self._references:
                    self._references["style_floor"] = bounds.floor_rollout(
                        val, bounds.median_style())
                traj = self._references["style_floor"]
            else:
                cfg = models.ModelConfig(n_states=self.config.n_states,
                                         image_size=self.config.image_size)
                traj = rollout.fixed_gains(val, cfg=cfg, agents=agents)
            self._references[key] = score(traj, val)
            self.timing["references"] = (self.timing.get("references", 0.0)
                                         + time.perf_counter() - t0)
        return self._references[key]

    def human(self, agents: str | None = None) -> dict:
        """Metrics of the logged human on the validation split (the "Human" row) under
        ``agents`` (default :attr:`primary`): the log itself, or the human's logged controls
        among reactive ados."""
        return metrics.aggregate([self.reference("human", agents or self.primary)])

    def references(self, agents: str | None = None) -> dict:
        """``{"dmp_prior": aggregate}``: policies without learning, on the validation split.

        ``dmp_prior`` is MANC's DMP head at its initial constant gains
        (:func:`minimanc.rollout.fixed_gains`): what the structure alone does,
        the bar the learned gains must clear.
        """
        return {"dmp_prior": metrics.aggregate([self.reference("dmp_prior",
                                                                agents or self.primary)])}


def families_of(per_seed: Sequence[dict]) -> dict:
    """``{family: aggregate}`` over the seeds' :func:`minimanc.studies.jobs.score` dicts (the
    families every seed has, in the order of :data:`minimanc.studies.jobs.SCENE_FAMILIES`)."""
    return {f: metrics.aggregate([r["families"][f] for r in per_seed]) for f in SCENE_FAMILIES
            if all(f in r.get("families", {}) for r in per_seed)}
