"""Chapter 8 — Algorithm 1's loss (:func:`loss_fn`) and one optimiser step (:func:`make_step`:
gradient, global-norm clip, Adam), jitted once per model and configuration."""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np

from minimanc import dmp, models, optim
from minimanc.train.batches import unpack_batch
from minimanc.train.config import DTYPES, TrainConfig
from minimanc.train.perception import BATCH_KEYS, perception_term
from minimanc.tree import leaves as tree_leaves
from minimanc.tree import map as tree_map

__all__ = ["global_norm", "hyper_args", "jitted_step", "like", "loss_fn", "make_step",
           "scale_tree", "train_step_fn"]


def loss_fn(name: str, params: dict, batch: dict, cfg: models.ModelConfig, eng: Any,
            inv_std: Any, zeta_weight: float = 0.0, motion_feedback: Any = False,
            perception_weight: float = 0.0) -> Any:
    """Algorithm 1's loss on a batch of windows: ``mean(((â − a) / σ)²)`` (+ ζ penalty)
    (+ ``perception_weight`` times the masked auxiliary perception loss,
    :func:`minimanc.train.perception.perception_term`).

    ``batch`` holds observations ``(L, b, ...)`` (a raster may be packed:
    :func:`~minimanc.train.batches.unpack_batch`), ``controls (L, b, 2)`` and,
    for vAGN models, ``q0 (b, N)`` (q'). ``inv_std`` is ``1/σ`` per control;
    ``motion_feedback`` see :func:`minimanc.models.sequence`; it never applies to the windows
    that ``driven (b,)`` marks (:func:`~minimanc.train.batches.make_batch`): a state another
    policy drove is shown with the speed it was driven at, as DAgger's labels are for that
    state.
    """
    xp = eng.xp
    batch = unpack_batch(batch, cfg)
    obs = {k: v for k, v in batch.items()
           if k not in ("controls", "q0", "driven", *BATCH_KEYS)}
    if motion_feedback and "driven" in batch:
        motion_feedback = xp.logical_not(batch["driven"])
    b = batch["controls"].shape[1]
    spec = models.spec(name)
    if spec.family == "vagn":
        state = {"q": batch["q0"]}
    else:
        dtype = params["backbone"]["convs"][0]["w"].dtype
        state = models.initial_state(name, b, cfg, xp=xp, dtype=dtype)
    extra = 0.0
    if zeta_weight > 0.0 and spec.dmp:
        pred, _, aux = models.sequence(name, params, obs, state, cfg, eng,
                                       feedback_motion=motion_feedback, return_aux=True)
        extra = zeta_weight * dmp.zeta_penalty(aux["alpha"], aux["beta"], xp=xp)
    else:
        pred, _ = models.sequence(name, params, obs, state, cfg, eng,
                                  feedback_motion=motion_feedback)
    if perception_weight > 0.0:
        extra = extra + perception_weight * perception_term(params, batch, cfg, eng)
    err = (pred - batch["controls"]) * inv_std
    return xp.mean(err * err) + extra


def global_norm(tree: Any, xp: Any) -> Any:
    """``sqrt(Σ g²)`` over every leaf of ``tree``."""
    leaves = tree_leaves(tree)
    return xp.sqrt(sum(xp.sum(g * g) for g in leaves))


def scale_tree(tree: Any, s: Any) -> Any:
    """Every leaf of ``tree`` times ``s``."""
    return tree_map(lambda x: x * s, tree)


def like(tree: Any, template: Any, xp: Any) -> Any:
    """``tree`` with every array leaf cast to the dtype of the matching ``template`` leaf."""
    def cast(x: Any, t: Any) -> Any:
        dt = getattr(t, "dtype", None)
        if dt is None or getattr(x, "dtype", None) == dt:
            return x
        return xp.asarray(x, dtype=dt)

    return tree_map(cast, tree, template)


def hyper_args(tc: TrainConfig, inv_std: Any) -> dict:
    """The arguments of a training step that vary between runs of one compiled step:
    ``{"lr", "inv_std"}`` in ``tc.dtype``."""
    dtype = DTYPES[tc.dtype]
    return {"lr": np.asarray(tc.lr, dtype=dtype), "inv_std": np.asarray(inv_std, dtype=dtype)}


def train_step_fn(name: str, cfg: models.ModelConfig, tc: TrainConfig, eng: Any) -> Callable:
    """The un-jitted training step ``(params, opt_state, batch, hyper) → (params, opt_state,
    loss)``: Algorithm 1's loss (:func:`loss_fn`), its gradient, the global-norm clip and
    one Adam step, with ``hyper`` from :func:`hyper_args`."""
    xp = eng.xp

    def objective(params, batch, inv):
        return loss_fn(name, params, batch, cfg, eng, inv, tc.zeta_weight, tc.motion_feedback,
                       tc.perception_weight)

    vg = eng.value_and_grad(objective)

    def train_step(params, opt_state, batch, hyper):
        loss, grads = vg(params, batch, hyper["inv_std"])
        if tc.grad_clip is not None:
            norm = global_norm(grads, xp)
            factor = xp.minimum(1.0, tc.grad_clip / (norm + 1e-12))
            grads = scale_tree(grads, factor)
        new_params, new_state = optim.adam_update(grads, opt_state, params, lr=hyper["lr"])
        # keep every leaf's dtype: a float64 scalar must not promote float32 parameters
        # (under jit that would trigger a new compilation at the next step)
        return like(new_params, params, xp), like(new_state, opt_state, xp), loss

    return train_step


def make_step(name: str, cfg: models.ModelConfig, tc: TrainConfig, eng: Any,
               inv_std: np.ndarray) -> Callable:
    """The (jitted) training step ``(params, opt_state, batch) → (params, opt_state, loss)``.

    The learning rate and ``1/σ`` enter the jitted function as arguments, not
    constants: runs that differ only in those (the learning-rate sweep, the
    data fractions) share one compilation through JAX's persistent cache.
    """
    hyper = hyper_args(tc, inv_std)
    step = jitted_step(name, cfg, tc, eng)
    return lambda params, opt_state, batch: step(params, opt_state, batch, hyper)


@lru_cache(maxsize=32)
def jitted_step(name: str, cfg: models.ModelConfig, tc: TrainConfig, eng: Any) -> Callable:
    """:func:`train_step_fn` jitted, one function per ``(name, cfg, tc, eng)``: fits with
    the same configurations (DAgger's rounds, a model trained again) reuse its compilations
    instead of compiling an equal step anew."""
    return eng.jit(train_step_fn(name, cfg, tc, eng))
