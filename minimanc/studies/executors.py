"""Chapter 9 — where a study's jobs run: :class:`LocalExecutor` (this machine: a pool of
worker processes, or inline) or :class:`RayExecutor` (Ray tasks, on a local Ray or a
cluster), behind one interface, ``submit(fn, *args) → future`` with ``future.result()``.

The study is a grid of independent (model, setting, seed, data fraction, q-states)
trainings and closed-loop evaluations. An argument of ``submit`` may be a future of the
same executor: the job then starts once that one has finished, on its result (Ray passes
the object reference, so the cluster's scheduler orders them; the local executor waits
for it). Every job writes its result under the study's output directory (checkpoints,
rollouts, metrics), so a rerun after a lost worker, or a killed driver, resumes where it
stopped; on a cluster that directory must be on a file system every node sees.

    def power(a, b):
        return a ** b

    ex = executor("ray", workers=2)            # RAY_ADDRESS or a local ray.init(num_cpus=2)
    fut = ex.submit(power, 2, 10)              # fn: a Python function (not a builtin)
    ex.submit(power, fut, 2).result()          # 1048576: runs after fut, on its value
    ex.shutdown()

Ray is an optional dependency (``pip install 'minimanc[ray]'``).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import shutil
import threading
import warnings
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

from minimanc import dagger, diagnose, train, world
from minimanc.checks import check_int
from minimanc.errors import UsageError
from minimanc.studies.jobs import enable_jax_cache, evaluate_job, failed
from minimanc.studies.provenance import write_json
from minimanc.world.datawriter import temp_prefix

__all__ = ["EXECUTORS", "RAY_MISSING", "Done", "LocalExecutor", "RayExecutor", "RayFuture",
           "check_ray", "evaluate_trained", "executor", "is_future", "load_scenes", "train_job",
           "train_on_policy", "train_runs", "usable_cpus"]

EXECUTORS = ("local", "ray")
"""The executors :func:`executor` builds."""

RAY_MISSING = ("--executor ray needs Ray, which is not installed: pip install 'minimanc[ray]' "
               "(or pip install 'ray>=2.9')")


def usable_cpus() -> int:
    """The number of CPUs this process may run on (its affinity mask where the system has
    one, else ``os.cpu_count()``; at least 1): the default number of workers."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # macOS, Windows
        return max(os.cpu_count() or 1, 1)


def check_ray() -> None:
    """Raise :class:`~minimanc.errors.UsageError` (one line: how to install it) unless Ray
    can be imported."""
    try:
        import ray  # noqa: F401
    except ImportError as exc:
        raise UsageError(RAY_MISSING) from exc


class Done:
    """A finished future (a job run inline)."""

    def __init__(self, value: Any) -> None:
        self._value = value

    def result(self) -> Any:
        return self._value

    def done(self) -> bool:
        return True

    def add_done_callback(self, fn: Callable[[Any], None]) -> None:
        fn(self)


def is_future(a: Any) -> bool:
    """Whether ``a`` is a future of an executor (it has ``result`` and ``done``)."""
    return hasattr(a, "result") and hasattr(a, "done")


def _resolved(args: tuple) -> tuple:
    return tuple(a.result() if is_future(a) else a for a in args)


def _failed_future(exc: BaseException) -> Future:
    out: Future = Future()
    out.set_exception(exc)
    return out


class LocalExecutor:
    """Jobs on this machine: ``workers`` spawned processes (``0``: inline, in the caller).

    A job whose arguments hold unfinished futures is queued once they have finished (a
    thread of the caller waits for them), so ``submit`` never blocks while a worker could
    be busy; an error of a future it waited for becomes the job's error.
    """

    name = "local"

    def __init__(self, workers: int = 1) -> None:
        self.workers = check_int("workers", workers, 0)
        self._pool: Any = None

    def submit(self, fn: Callable, *args: Any) -> Any:
        """Start ``fn(*args)``; returns a future (``result()``, ``done()``,
        ``add_done_callback``)."""
        if self.workers == 0:
            return Done(fn(*_resolved(args)))
        pool = self._ensure_pool()
        if all(a.done() for a in args if is_future(a)):
            try:
                ready = _resolved(args)
            except BaseException as exc:  # noqa: BLE001 - a failed future is the job's error
                return _failed_future(exc)
            return pool.submit(fn, *ready)
        out: Future = Future()

        def start_when_ready() -> None:
            try:
                out.set_result(pool.submit(fn, *_resolved(args)).result())
            except BaseException as exc:  # noqa: BLE001 - handed to whoever waits for `out`
                out.set_exception(exc)

        threading.Thread(target=start_when_ready, daemon=True).start()
        return out

    def _ensure_pool(self) -> Any:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(max_workers=self.workers,
                                             mp_context=mp.get_context("spawn"))
        return self._pool

    def shutdown(self) -> None:
        """Wait for the running jobs and stop the worker processes."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None


class RayFuture:
    """A Ray task's result: ``result()`` is ``ray.get`` of its object reference ``ref``."""

    def __init__(self, ref: Any) -> None:
        self.ref = ref

    def result(self) -> Any:
        import ray  # Ray is optional (the [ray] extra)

        return ray.get(self.ref)

    def done(self) -> bool:
        import ray  # Ray is optional (the [ray] extra)

        ready, _ = ray.wait([self.ref], timeout=0)
        return bool(ready)

    def add_done_callback(self, fn: Callable[[Any], None]) -> None:
        """Call ``fn(self)`` once the task has finished (in a thread of Ray's)."""
        self.ref.future().add_done_callback(lambda _: fn(self))


class RayExecutor:
    """Jobs as Ray tasks. Joins the cluster at ``address`` (or the ``RAY_ADDRESS``
    environment variable: ``"auto"`` or ``"ray://head:10001"``); with neither, starts a
    local Ray with ``workers`` CPUs. A task that loses its worker is retried
    (``max_retries``) by Ray; every job of a study resumes from its files.

    ``env`` are environment variables for the workers (e.g. the thread counts of the
    driver, so that a task computes what it would compute locally).
    """

    name = "ray"

    def __init__(self, workers: int = 2, address: str | None = None, max_retries: int = 3,
                 env: dict[str, str] | None = None) -> None:
        check_ray()
        import ray  # Ray is optional (the [ray] extra)

        self.workers = check_int("workers", workers, 1)
        self.max_retries = check_int("max_retries", max_retries, 0)
        self.address = address or os.environ.get("RAY_ADDRESS") or None
        self._started = False
        self._remote: dict[Callable, Any] = {}
        if not ray.is_initialized():
            runtime_env = {"env_vars": dict(env)} if env else None
            with warnings.catch_warnings():
                # Ray starts its processes by fork + exec, which is safe beside JAX's threads
                warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called",
                                        category=RuntimeWarning)
                if self.address:
                    ray.init(address=self.address, runtime_env=runtime_env,
                             log_to_driver=False)
                else:
                    ray.init(num_cpus=self.workers, include_dashboard=False,
                             runtime_env=runtime_env, log_to_driver=False)
                    self._started = True

    def submit(self, fn: Callable, *args: Any) -> RayFuture:
        """Start ``fn(*args)`` as a Ray task (one CPU); a :class:`RayFuture` among ``args`` is
        passed as its object reference, so the task runs after it, on its value."""
        import ray  # Ray is optional (the [ray] extra)

        task = self._remote.get(fn)
        if task is None:
            task = ray.remote(num_cpus=1, max_retries=self.max_retries)(fn)
            self._remote[fn] = task
        refs = tuple(a.ref if isinstance(a, RayFuture) else a for a in args)
        return RayFuture(task.remote(*refs))

    def shutdown(self) -> None:
        """Disconnect; a Ray this executor started is stopped."""
        import ray  # Ray is optional (the [ray] extra)

        if self._started and ray.is_initialized():
            ray.shutdown()
        self._started = False


def executor(kind: str = "local", workers: int = 1, address: str | None = None,
             env: dict[str, str] | None = None) -> LocalExecutor | RayExecutor:
    """The executor called ``kind`` (:data:`EXECUTORS`): ``"local"`` with ``workers``
    processes (0: inline), or ``"ray"`` (``address``, else ``RAY_ADDRESS``, else a local Ray
    with ``max(workers, 1)`` CPUs; ``env`` for its workers). Without Ray installed,
    ``"ray"`` raises :class:`~minimanc.errors.UsageError` saying how to install it."""
    if kind not in EXECUTORS:
        raise ValueError(f"executor must be one of {EXECUTORS}; got executor={kind!r}")
    if kind == "local":
        if address is not None:
            raise ValueError(f"ray_address is only for the ray executor; got "
                             f"ray_address={address!r} with executor='local'")
        return LocalExecutor(workers)
    return RayExecutor(max(int(check_int("workers", workers, 0)), 1), address, env=env)


_DATA: dict[str, Any] = {}


def load_scenes(data: str, lo: int, hi: int) -> Any:
    """Scenes ``lo:hi`` of the dataset file ``data`` (loaded once per worker process)."""
    if data not in _DATA:
        _DATA.clear()
        _DATA[data] = world.load(data)
    key = f"{data}[{lo}:{hi}]"
    if key not in _DATA:
        _DATA[key] = _DATA[data].subset(slice(lo, hi))
    return _DATA[key]


def train_job(job: dict) -> list[str]:
    """:func:`train_runs` on the training scenes ``job["lo"]:job["hi"]`` of the dataset file
    ``job["data"]`` (what a worker runs)."""
    return train_runs(load_scenes(job["data"], job["lo"], job["hi"]), job)


def train_runs(ds: Any, job: dict) -> list[str]:
    """Train the runs of one configuration of a study on ``ds`` together
    (:func:`minimanc.train.fit_many`, each resuming its own checkpoint) and return their
    checkpoint paths; a diverged run leaves ``diverged.json`` beside its checkpoint.

    ``job``: ``{"model", "cfg"`` (:class:`~minimanc.models.ModelConfig`), ``"train_cfgs"``
    (one :class:`~minimanc.train.TrainConfig` per run, differing in ``seed`` and ``lr``),
    ``"checkpoints"`` (one path per run), ``"engine", "jax_cache"}`` and optionally
    ``"progress"`` and ``"perception"``, the file of the perception targets of ``ds``
    (:func:`minimanc.train.save_targets`; with ``perception_weight`` > 0): then
    each run trains on its own with the auxiliary loss (:func:`minimanc.train.fit`'s
    ``perception``; :func:`~minimanc.train.fit_many` trains without it); and/or
    ``"dagger_rounds"`` (≥ 1), ``"round_epochs"`` and ``"beta"``: each run trains on its
    own on-policy (:func:`train_on_policy`, with the auxiliary loss if the job names
    targets; its checkpoint, written last, marks it done);
    for :func:`train_job` also ``"data", "lo", "hi"``.
    """
    if job["engine"] == "jax" and job.get("jax_cache"):
        enable_jax_cache(job["jax_cache"])
    paths = [Path(p) for p in job["checkpoints"]]
    on_policy = job.get("dagger_rounds", 0) > 0
    todo = []
    for k, (path, tc) in enumerate(zip(paths, job["train_cfgs"])):
        if (path.parent / "diverged.json").exists():
            continue
        if path.exists():
            try:
                epoch = train.load_checkpoint(path)["epoch"]
                if on_policy or epoch >= tc.epochs:  # on-policy: written when done
                    continue
            except train.CheckpointError:
                path.unlink(missing_ok=True)  # derived data: train it again
        todo.append(k)
    if todo:
        tcs, dirs = [job["train_cfgs"][k] for k in todo], [paths[k].parent for k in todo]
        if on_policy:
            out = [_result_or_diverged(train_on_policy, ds, job, tc, paths[k])
                   for k, tc in zip(todo, tcs)]
        elif job.get("perception"):
            targets = train.load_targets(job["perception"])
            out = [_fit_or_diverged(ds, job, tc, d, targets) for tc, d in zip(tcs, dirs)]
        else:
            out = train.fit_many(job["model"], ds, job["cfg"], tcs, engine=job["engine"],
                                 checkpoint_dirs=dirs, resume=True,
                                 progress=job.get("progress", False), errors="return")
        for k, res in zip(todo, out):
            if isinstance(res, train.TrainingDiverged):
                write_json(paths[k].parent / "diverged.json", {"error": str(res)})
    return [str(p) for p in paths]


def train_on_policy(ds: Any, job: dict, tc: train.TrainConfig, checkpoint: Path) -> Path:
    """Train one run of ``job`` on-policy: DAgger (:func:`minimanc.dagger.dagger`) with the
    world's expert among reactive ados (:class:`minimanc.dagger.WorldTeacher`), the last
    round's checkpoint copied to ``checkpoint`` (atomically: the file marks the run done).

    Parameters
    ----------
    ds : minimanc.world.Dataset
        The study's training split. The pool is the scenes :func:`minimanc.train.fit`
        would train on (``tc.subset`` of them, :func:`minimanc.train.subset_scenes`).
    job : dict
        ``"model"``, ``"cfg"`` (the :class:`~minimanc.models.ModelConfig`), ``"engine"``,
        ``"dagger_rounds"`` (rounds after the demonstrations), ``"round_epochs"`` (the
        epochs of each later round, continuing from the previous one), ``"beta"`` (``p``
        of ``β_i = p^i``) and optionally ``"progress"`` and ``"perception"`` (the file of the
        perception targets of ``ds``: every round then trains with the auxiliary loss, on
        the demonstrations' targets and on what the expert perceives in the collected
        states, :func:`minimanc.diagnose.state_targets` for the data's raster).
    tc : minimanc.train.TrainConfig
        The run's: round 0 trains with it on its demonstrations (every scene it is given:
        ``subset`` 1), its ``seed`` is also DAgger's (scene order, mixture coins).
    checkpoint : Path
        The run's checkpoint; DAgger's rounds live in ``<its folder>/dagger/round_<i>``,
        so a killed run resumes after its last finished round.

    Returns
    -------
    Path
        ``checkpoint``.

    Raises
    ------
    minimanc.train.TrainingDiverged
        When a round's training diverges.
    """
    rounds = check_int("dagger_rounds", job["dagger_rounds"], 1)
    scenes = train.subset_scenes(len(ds), tc.subset, tc.seed)
    pool = ds.subset(scenes)
    tc = replace(tc, subset=1.0)
    cfg = train.config_for_data(job["cfg"], pool, "pool")
    targets = None
    perceive = None
    if job.get("perception"):
        targets = train.load_targets(job["perception"]).subset(scenes)
        perceive = partial(diagnose.state_targets, view=pool.raster)
    teacher = dagger.WorldTeacher(pool, agents="reactive", perceive=perceive)
    budget = dagger.plan_budget(len(pool) * pool.n_steps, pool.n_steps, rounds)
    out = Path(checkpoint).parent / "dagger"
    dagger.dagger(job["model"], teacher, budget, rounds=rounds,
                  beta=job["beta"], cfg=cfg, train_cfg=tc, engine=job["engine"], out=out,
                  seed=tc.seed, progress=job.get("progress", False), evaluate=False,
                  round_cfg=replace(tc, epochs=check_int("round_epochs", job["round_epochs"],
                                                         1)),
                  perception=targets)
    tmp = Path(checkpoint).with_name(temp_prefix(checkpoint) + "tmp")
    shutil.copyfile(dagger.round_dir(out, rounds) / train.CHECKPOINT_NAME, tmp)
    os.replace(tmp, checkpoint)
    return Path(checkpoint)


def _result_or_diverged(fn: Callable, *args: Any) -> Any:
    """``fn(*args)``, or the :class:`~minimanc.train.TrainingDiverged` it raised."""
    try:
        return fn(*args)
    except train.TrainingDiverged as exc:
        return exc


def _fit_or_diverged(ds: Any, job: dict, tc: train.TrainConfig, directory: Path,
                     targets: train.PerceptionTargets) -> Any:
    """One run of ``job`` by :func:`minimanc.train.fit` with the perception ``targets``
    (resuming its checkpoint in ``directory``): its result, or its
    :class:`~minimanc.train.TrainingDiverged`."""
    try:
        return train.fit(job["model"], ds, job["cfg"], tc, engine=job["engine"],
                         checkpoint_dir=directory, resume=True,
                         progress=job.get("progress", False), perception=targets)
    except train.TrainingDiverged as exc:
        return exc


def evaluate_trained(checkpoints: list[str], index: int, job: dict) -> dict:
    """:func:`minimanc.studies.jobs.evaluate_job` of ``job`` with the checkpoint
    ``checkpoints[index]`` (the result of :func:`train_job`); a diverged run scores
    :func:`minimanc.studies.jobs.failed`."""
    checkpoint = checkpoints[index]
    if (Path(checkpoint).parent / "diverged.json").exists():
        return failed("training diverged")
    return evaluate_job({**job, "checkpoint": checkpoint})
