"""Chapter 8 — several runs of one configuration trained together: :func:`fit_many` (runs
that differ only in their ``seed`` and ``lr``) and :func:`fit_seeds`.

On JAX the runs' parameters, optimiser states, batches and hyper-parameters are stacked
along a leading axis and one jitted ``jax.vmap`` of the training step advances all of
them: one compilation and one dispatch per step instead of one per run, and one larger
batch for XLA. Each run still sees exactly its own data order, initialisation, ``q'``
draws, normalisation and checkpoints, so every :class:`~minimanc.train.FitResult` equals
the one :func:`~minimanc.train.fit` gives alone, to float32 rounding (XLA may order the
batched sums differently; ``tests/test_train_many.py``). A run whose epoch has fewer
minibatches (windows tile each scene from a random offset) is masked for the remaining
steps: its state is left unchanged. On the NumPy engine the runs are trained one after
the other.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from minimanc import models
from minimanc.train.batches import dataset_shape, subset_scenes
from minimanc.train.config import FitResult, TrainConfig, TrainingDiverged
from minimanc.train.fit import (
    RunState,
    as_engine,
    check_fit_args,
    diverged_loss,
    end_epoch,
    epoch_plan,
    fit,
    result_of,
    start_run,
    step_batch,
)
from minimanc.train.step import hyper_args, train_step_fn
from minimanc.tree import map as tree_map

__all__ = ["fit_many", "fit_seeds"]

ERRORS = ("raise", "return")


def _check_together(tcs: Sequence[TrainConfig]) -> None:
    """Runs train together only when they differ in nothing but ``seed`` and ``lr``."""
    if not tcs:
        raise ValueError("train_cfgs must hold at least one TrainConfig, got none")
    for i, tc in enumerate(tcs):
        if not isinstance(tc, TrainConfig):
            raise ValueError(f"train_cfgs[{i}] must be a train.TrainConfig, got {tc!r}")
        if replace(tc, seed=tcs[0].seed, lr=tcs[0].lr) != tcs[0]:
            raise ValueError(f"train_cfgs must differ only in seed and lr; train_cfgs[{i}]={tc} "
                             f"differs from train_cfgs[0]={tcs[0]} in more")


def _stack(trees: Sequence[Any]) -> Any:
    return tree_map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *trees)


def _unstack(tree: Any, k: int) -> Any:
    return tree_map(lambda x: np.array(x[k]), tree)


def _many_step(name: str, cfg: models.ModelConfig, tc: TrainConfig, eng: Any) -> Any:
    """``(params, opt, batch, hyper, active) → (params, opt, loss)``, all stacked along axis 0;
    runs with ``active`` false keep their parameters and optimiser state."""
    import jax  # JAX only for the jax engine
    import jax.numpy as jnp  # JAX only for the jax engine

    step = jax.vmap(train_step_fn(name, cfg, tc, eng))

    def many(params, opt, batch, hyper, active):
        new_p, new_o, loss = step(params, opt, batch, hyper)

        def keep(new, old):
            mask = jnp.reshape(active, (-1,) + (1,) * (jnp.ndim(new) - 1))
            return jnp.where(mask, new, old)

        return tree_map(keep, new_p, params), tree_map(keep, new_o, opt), loss

    return jax.jit(many)


def fit_many(
    name: str,
    train_ds: Any,
    cfg: models.ModelConfig | None,
    train_cfgs: Sequence[TrainConfig],
    engine: Any = "jax",
    checkpoint_dirs: Sequence[str | Path] | None = None,
    resume: bool = False,
    progress: bool = True,
    errors: str = "raise",
) -> list[FitResult | TrainingDiverged]:
    """Train model ``name`` once per :class:`TrainConfig` of ``train_cfgs`` (which may differ
    only in ``seed`` and ``lr``), all together; the same results as one :func:`fit` each.

    ``checkpoint_dirs``: one directory per run (its ``checkpoint.npz`` every epoch, as
    :func:`fit`); ``resume``: each run continues from its own checkpoint (runs at
    different epochs are fine). ``errors="raise"`` raises the first run's
    :class:`TrainingDiverged`; ``"return"`` puts it in that run's place in the returned
    list and trains the others to the end (a diverged run keeps its last good
    checkpoint, as with :func:`fit`).
    """
    if errors not in ERRORS:
        raise ValueError(f"errors must be one of {ERRORS}, got errors={errors!r}")
    tcs = list(train_cfgs)
    _check_together(tcs)
    name, cfg, _ = check_fit_args(name, train_ds, cfg, tcs[0])
    if checkpoint_dirs is not None and len(checkpoint_dirs) != len(tcs):
        raise ValueError(f"checkpoint_dirs must hold one directory per run ({len(tcs)}), "
                         f"got {len(checkpoint_dirs)}")
    if resume and checkpoint_dirs is None:
        raise ValueError("resume=True needs checkpoint_dirs")
    dirs = list(checkpoint_dirs) if checkpoint_dirs is not None else [None] * len(tcs)
    eng = as_engine(engine)
    if eng.name != "jax" or len(tcs) == 1 or not _same_shapes(name, train_ds, cfg, tcs):
        return _one_by_one(name, train_ds, cfg, tcs, eng, dirs, resume, progress, errors)
    return _together(name, train_ds, cfg, tcs, eng, dirs, resume, progress, errors)


def _same_shapes(name: str, train_ds: Any, cfg: models.ModelConfig,
                 tcs: Sequence[TrainConfig]) -> bool:
    """Whether every run's minibatches have one shape in every epoch (not so only when a
    subset holds fewer windows than one batch)."""
    for epoch in range(tcs[0].epochs):
        shapes = set()
        for tc in tcs:
            st = RunState(name, cfg, tc, subset_scenes(dataset_shape(train_ds)[0], tc.subset,
                                                       tc.seed), np.ones(2), None, None)
            shapes.update(s.shape for s, _ in epoch_plan(st, train_ds, epoch))
        if len(shapes) > 1:
            return False
    return True


def fit_seeds(
    name: str,
    train_ds: Any,
    cfg: models.ModelConfig | None,
    train_cfg: TrainConfig,
    seeds: Sequence[int],
    engine: Any = "jax",
    checkpoint_dirs: Sequence[str | Path] | None = None,
    resume: bool = False,
    progress: bool = True,
    errors: str = "raise",
) -> list[FitResult | TrainingDiverged]:
    """:func:`fit_many` of ``train_cfg`` with each seed of ``seeds``: one result per seed."""
    if not isinstance(train_cfg, TrainConfig):
        raise ValueError(f"train_cfg must be a train.TrainConfig, got train_cfg={train_cfg!r}")
    seeds = list(seeds)
    if not seeds:
        raise ValueError("seeds must hold at least one seed, got none")
    return fit_many(name, train_ds, cfg, [replace(train_cfg, seed=s) for s in seeds],
                    engine=engine, checkpoint_dirs=checkpoint_dirs, resume=resume,
                    progress=progress, errors=errors)


def _one_by_one(name, train_ds, cfg, tcs, eng, dirs, resume, progress, errors):
    out: list[FitResult | TrainingDiverged] = []
    for tc, d in zip(tcs, dirs):
        try:
            out.append(fit(name, train_ds, cfg, tc, engine=eng, checkpoint_dir=d,
                           resume=resume, progress=progress))
        except TrainingDiverged as exc:
            if errors == "raise":
                raise
            out.append(exc)
    return out


def _together(name, train_ds, cfg, tcs, eng, dirs, resume, progress, errors):
    t_start = time.perf_counter()
    K = len(tcs)
    runs: list[RunState] = [start_run(name, train_ds, cfg, tc, d, resume)
                            for tc, d in zip(tcs, dirs)]
    failed: list[TrainingDiverged | None] = [None] * K
    step = _many_step(name, cfg, tcs[0], eng)
    hyper = _stack([hyper_args(st.tc, 1.0 / st.std) for st in runs])
    params = _stack([st.params for st in runs])
    opt = _stack([st.opt_state for st in runs])
    n_epochs = tcs[0].epochs

    def fail(k: int, exc: TrainingDiverged) -> None:
        if errors == "raise":
            raise exc
        failed[k] = exc

    bar = None
    for epoch in range(min(st.start_epoch for st in runs), n_epochs):
        live = [k for k in range(K) if failed[k] is None and runs[k].start_epoch <= epoch]
        if not live:
            continue
        plans = {k: epoch_plan(runs[k], train_ds, epoch) for k in live}
        q_rngs = {k: np.random.default_rng([int(tcs[k].seed), int(epoch), 1]) for k in live}
        n_steps = max(len(p) for p in plans.values())
        if progress:
            bar = tqdm(total=n_steps, desc=f"{name} x{len(live)} epoch {epoch + 1}/{n_epochs}",
                       leave=False)
        totals, counts = np.zeros(K), np.zeros(K, dtype=int)
        filler = None  # the batch a masked run is given (its result is discarded)
        pending = None
        for i in range(n_steps + 1):
            current = None
            if i < n_steps:
                active = np.array([k in plans and i < len(plans[k]) and failed[k] is None
                                   for k in range(K)])
                per_run = []
                for k in range(K):
                    if active[k]:
                        per_run.append(step_batch(runs[k], train_ds, *plans[k][i], q_rngs[k]))
                        runs[k].steps += 1
                    else:
                        per_run.append(None)
                filler = next(b for b in per_run if b is not None)
                batch = _stack([b if b is not None else filler for b in per_run])
                with np.errstate(over="ignore", invalid="ignore"):
                    params, opt, loss_i = step(params, opt, batch, hyper, active)
                current = (loss_i, active)
            if pending is not None:
                losses, was_active = np.asarray(pending[0]), pending[1]
                for k in np.flatnonzero(was_active):
                    if failed[k] is not None:
                        continue
                    loss = float(losses[k])
                    if not math.isfinite(loss):
                        if bar is not None and errors == "raise":
                            bar.close()
                        fail(k, diverged_loss(runs[k], loss, epoch, int(counts[k]) + 1,
                                              len(plans[k])))
                        continue
                    totals[k] += loss
                    counts[k] += 1
                if bar is not None:
                    bar.update(1)
            pending = current
        if bar is not None:
            bar.close()
        for k in live:
            if failed[k] is not None:
                continue
            runs[k].params = _unstack(params, k)
            runs[k].opt_state = _unstack(opt, k)
            runs[k].opt_state["step"] = int(runs[k].opt_state["step"])
            try:
                end_epoch(runs[k], epoch, float(totals[k] / max(counts[k], 1)), eng)
            except TrainingDiverged as exc:
                fail(k, exc)
    seconds = time.perf_counter() - t_start
    out: list[FitResult | TrainingDiverged] = []
    for k, st in enumerate(runs):
        if failed[k] is not None:
            out.append(failed[k])
            continue
        out.append(result_of(st, seconds))
    return out
