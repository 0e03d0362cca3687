"""Tests for minimanc.studies.executors: the local and Ray executors behind one interface,
the clear error without Ray, and a small study (:data:`SMALL`) on a local Ray giving the
local executor's ``results.json`` (and resuming from its cache)."""

from __future__ import annotations

import json
import os
import shutil
import sys
import time
import types
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from minimanc.errors import UsageError
from minimanc.studies import PRESETS, executors
from minimanc.studies.config import plan
from minimanc.studies.report import json_safe
from minimanc.studies.runner import Study
from minimanc.studies.submission import THREAD_ENV

try:
    import ray  # noqa: F401

    HAVE_RAY = True
except ImportError:
    HAVE_RAY = False
needs_ray = pytest.mark.skipif(not HAVE_RAY, reason="ray is not installed: "
                               "pip install 'minimanc[ray]' (CI installs it)")


SMALL = replace(PRESETS["tiny"], table_models=("cnn", "manc"), ablation_models=(),
                sample_models=(), settings=("paper",))
"""The ``tiny`` preset with Table I of CNN and MANC in one setting and its q-states study:
three trainings and their rollouts, enough to queue jobs on jobs in every executor."""


def add(a, b):
    return a + b


def sleep_then(seconds: float, value: int) -> int:
    time.sleep(seconds)
    return value


def die_once(marker: str, value: int) -> int:
    """Kills its worker process the first time (a lost worker), returns ``value`` after."""
    if not os.path.exists(marker):
        Path(marker).write_text("died")
        os._exit(1)
    return value


def test_local_executor_inline_and_pool():
    for workers in (0, 1):
        ex = executors.executor("local", workers)
        try:
            first = ex.submit(add, 2, 3)
            # a future among the arguments is the job's input, once finished
            assert ex.submit(add, first, 10).result() == 15
        finally:
            ex.shutdown()


def test_bad_arguments():
    with pytest.raises(ValueError, match="executor must be one of .*'dask'"):
        executors.executor("dask")
    with pytest.raises(ValueError, match="ray_address is only for the ray executor"):
        executors.executor("local", 1, address="auto")
    with pytest.raises(ValueError, match="workers"):
        executors.executor("local", -1)
    with pytest.raises(ValueError, match="executor must be one of"):
        Study(PRESETS["tiny"], "unused", executor="slurm")
    with pytest.raises(ValueError, match="ray_address is only for executor='ray'"):
        Study(PRESETS["tiny"], "unused", ray_address="auto")


def test_ray_missing_is_one_clear_line(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray → ImportError
    with pytest.raises(UsageError) as info:
        executors.executor("ray", 2)
    msg = str(info.value)
    with pytest.raises(UsageError, match="--executor ray needs Ray"):
        Study(PRESETS["tiny"], "unused", executor="ray")  # before any work
    assert "\n" not in msg and "--executor ray" in msg and "minimanc[ray]" in msg


def test_ray_address_from_argument_or_environment(monkeypatch):
    """``address`` wins, then ``RAY_ADDRESS``; with neither a local Ray of ``workers`` CPUs."""
    calls = []
    fake = types.SimpleNamespace(is_initialized=lambda: False,
                                 init=lambda **kw: calls.append(kw), shutdown=lambda: None)
    monkeypatch.setitem(sys.modules, "ray", fake)
    monkeypatch.setenv("RAY_ADDRESS", "ray://head:10001")
    executors.executor("ray", 2, address="auto")
    executors.executor("ray", 2)
    monkeypatch.delenv("RAY_ADDRESS")
    executors.executor("ray", 3, env={"OMP_NUM_THREADS": "1"})
    assert calls[0]["address"] == "auto"
    assert calls[1]["address"] == "ray://head:10001"
    assert "address" not in calls[2] and calls[2]["num_cpus"] == 3
    assert calls[2]["runtime_env"] == {"env_vars": {"OMP_NUM_THREADS": "1"}}


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray of 2 CPUs for the module's Ray tests, with the thread variables a study
    gives its workers: an executor that finds Ray running uses it and leaves it running, so
    Ray starts once (about 25 s on 2 cores) instead of once per executor."""
    env = {k: os.environ[k] for k in THREAD_ENV if k in os.environ}
    ex = executors.executor("ray", 2, env=env)
    yield
    ex.shutdown()


@needs_ray
def test_ray_futures_chain_and_a_lost_worker_is_retried(tmp_path, local_ray):
    import ray.cloudpickle

    # the workers cannot import this test module: ship its functions by value
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    ex = executors.executor("ray", 2)
    try:
        first = ex.submit(add, 2, 3)
        assert ex.submit(add, first, 10).result() == 15  # runs after `first`, on its value
        assert ex.submit(die_once, str(tmp_path / "marker"), 7).result() == 7
        assert (tmp_path / "marker").exists()
    finally:
        ex.shutdown()


def run_small(out: Path, executor: str, log: list | None = None, workers: int = 2) -> dict:
    """The :data:`SMALL` study under ``out``; its results.json content without the wall
    times."""
    study = Study(SMALL, out, workers=workers, progress=False,
                  executor=executor, log=None if log is None else log.append)
    try:
        res = study.run()
    finally:
        study.close()
    res.pop("timing_s")
    return json.loads(json.dumps(json_safe(res), sort_keys=True))


def assert_same_results(got: object, want: object, where: str = "results") -> None:
    """``got`` equals ``want`` key for key, item for item and in every string and integer;
    their floats agree to 12 significant digits. The trainings and rollouts are the same
    float32 computation in every process (a different training would move a metric in its
    7th digit); the float64 means and spreads of the metrics may round their last bit
    another way in another process, where NumPy's vector loops take another path."""
    assert type(got) is type(want), f"{where}: {type(got).__name__} != {type(want).__name__}"
    if isinstance(want, dict):
        assert sorted(got) == sorted(want), f"{where}: keys {sorted(got)} != {sorted(want)}"
        for key in want:
            assert_same_results(got[key], want[key], f"{where}[{key!r}]")
    elif isinstance(want, list):
        assert len(got) == len(want), f"{where}: {len(got)} items != {len(want)}"
        for i, (g, w) in enumerate(zip(got, want)):
            assert_same_results(g, w, f"{where}[{i}]")
    elif isinstance(want, float):
        assert np.isclose(got, want, rtol=1e-12, atol=1e-12, equal_nan=True), \
            f"{where}: {got!r} != {want!r}"
    else:
        assert got == want, f"{where}: {got!r} != {want!r}"


def test_same_results_tells_a_training_apart_from_a_rounding():
    """The comparison behind the executor tests: the last bit of a float64 mean passes;
    the 7th digit a different float32 training moves, a key, a count or a string fails."""
    want = {"ade": [1.249437979746095, 2.0], "n": 1, "form": "learner"}
    assert_same_results({"ade": [1.2494379797460948, 2.0], "n": 1, "form": "learner"}, want)
    for wrong in ({"ade": [1.249438979746095, 2.0], "n": 1, "form": "learner"},
                  {"ade": [1.249437979746095, 2.0], "n": 2, "form": "learner"},
                  {"ade": [1.249437979746095, 2.0], "n": 1.0, "form": "learner"},
                  {"ade": [1.249437979746095], "n": 1, "form": "learner"},
                  {"ade": [1.249437979746095, 2.0], "n": 1, "form": "paper"},
                  {"ade": [1.249437979746095, 2.0], "n": 1}):
        with pytest.raises(AssertionError):
            assert_same_results(wrong, want)


@pytest.fixture(scope="module")
def pool_run(tmp_path_factory) -> tuple[dict, Path, list]:
    """The small study on the local executor's two worker processes, run once for the tests
    that compare other executors with it: ``(results text, its directory, its log)``."""
    out = tmp_path_factory.mktemp("pool")
    log: list[str] = []
    return run_small(out, "local", log, workers=2), out, log


@pytest.mark.whole_run
def test_small_study_in_worker_processes_equals_inline(tmp_path, pool_run):
    """Trainings and evaluations as jobs of two worker processes (queued as soon as their
    inputs are known) give the inline run's results.json (:func:`assert_same_results`)."""
    pooled, pool_dir, log = pool_run
    shutil.copytree(pool_dir / "data", tmp_path / "inline" / "data")  # same scenes
    assert_same_results(run_small(tmp_path / "inline", "local", workers=0), pooled)
    assert sum(line.startswith("train:") and line.endswith("submitted") for line in log) == \
        sum(plan(SMALL)["train"].values())


def test_local_executor_waits_for_futures_without_blocking(tmp_path):
    """A job on an unfinished future is queued once that one finishes; ``submit`` returns at
    once, and the error of the future it waits for is the job's error, whether that future
    failed before or after the job was submitted."""
    ex = executors.executor("local", 2)
    try:
        slow = ex.submit(sleep_then, 1.0, 3)
        t0 = time.perf_counter()
        chained = ex.submit(add, slow, 4)
        assert time.perf_counter() - t0 < 0.5 and not chained.done()
        assert chained.result() == 7
        bad = ex.submit(add, ex.submit(add, "a", 1), 2)
        with pytest.raises(TypeError):
            bad.result()
        # a future that has already failed when the job is submitted: ``submit`` still
        # returns, and the error comes out of the job's own future (both orders are
        # checked, since which one the line above took depends on timing)
        failed_first = ex.submit(add, "a", 1)
        with pytest.raises(TypeError):
            failed_first.result()
        late = ex.submit(add, failed_first, 2)
        with pytest.raises(TypeError):
            late.result()
    finally:
        ex.shutdown()


@pytest.mark.whole_run
@needs_ray
def test_small_study_on_ray_equals_local(tmp_path, pool_run, local_ray):
    """Same results.json (:func:`assert_same_results`) on a local Ray (2 CPUs) as on the
    local executor;
    a rerun after lost results recomputes only those and gives the same file again."""
    local, pool_dir, _ = pool_run
    shutil.copytree(pool_dir / "data", tmp_path / "ray" / "data")  # same scenes
    on_ray = run_small(tmp_path / "ray", "ray")
    assert_same_results(on_ray, local)
    # lose one run's checkpoint and its validation metrics: the rerun trains and evaluates
    # that run only, from the cache of everything else
    cache = next((tmp_path / "ray" / "cache").glob("*-jax"))
    lost = sorted((cache / "models").iterdir())[0]
    shutil.rmtree(lost)
    for f in (cache / "rollouts").glob(f"{lost.name}-*"):
        f.unlink()
    log: list[str] = []
    assert_same_results(run_small(tmp_path / "ray", "ray", log), local)
    trained = [line for line in log if line.startswith("train:")]
    assert trained == [f"train: {lost.name} submitted"]
