"""Chapter 8 — behaviour cloning: :func:`fit` (epochs of Algorithm 1 with checkpoints, resume
and divergence checks), the open-loop loss :func:`open_loop_loss` and the learning-rate sweep
:func:`sweep_lr`."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from minimanc import inputs, models, optim
from minimanc.engine import ENGINES, get_engine
from minimanc.train.batches import (
    batches,
    control_std,
    dataset_shape,
    initial_q,
    make_batch,
    subset_scenes,
)
from minimanc.train.checkpoint import (
    bad_params,
    load_checkpoint,
    restore_opt,
    save_checkpoint,
    to_numpy,
)
from minimanc.train.config import CHECKPOINT_NAME, DTYPES, FitResult, TrainConfig, TrainingDiverged
from minimanc.train.perception import (
    PerceptionTargets,
    init_perception_head,
    standardised_targets,
)
from minimanc.train.step import loss_fn, make_step
from minimanc.train.trained import STD_DEFAULT, accepts_fit
from minimanc.tree import cast_floats
from minimanc.world.datawriter import remove_temp_files
from minimanc.world.fileformat import describe_non_finite, first_non_finite

__all__ = ["RunState", "SweepResult", "as_engine", "cast_floats", "check_fit_args",
           "config_for_data", "diverged_loss", "end_epoch", "epoch_plan", "fit", "open_loop_loss",
           "result_of", "start_run", "step_batch", "sweep_lr", "with_perception"]


def as_engine(engine: Any) -> Any:
    """An engine object from its name (:data:`minimanc.engine.ENGINES`) or itself."""
    if isinstance(engine, str):
        return get_engine(engine)
    if hasattr(engine, "xp") and hasattr(engine, "value_and_grad"):
        return engine
    raise ValueError(f"engine must be one of {ENGINES} or an engine object, got engine={engine!r}")


def _kept(ck_path: Path | None, saved_epoch: int | None) -> str:
    """What a divergence leaves behind, for its message."""
    if ck_path is None:
        return "no checkpoint_dir was given"
    if saved_epoch is None:
        return "this run wrote no checkpoint"
    return f"the checkpoint of epoch {saved_epoch} is kept in {ck_path}"


@dataclass
class RunState:
    """One training run between epochs: what :func:`start_run` prepares and
    :func:`end_epoch` updates (shared by :func:`fit` and :func:`minimanc.train.fit_many`).

    ``scenes`` (its training subset), ``std`` (the loss normalisation), ``params`` and
    ``opt_state`` (NumPy or engine arrays), ``start_epoch`` (0, or the resumed
    checkpoint's), ``history`` / ``val_history`` / ``steps`` so far, ``ck_path`` (``None``
    without a ``checkpoint_dir``), ``saved_epoch`` (epoch of the checkpoint this run
    wrote or resumed, else ``None``), ``perception`` (the auxiliary loss's standardised
    ``values``, ``mask`` and ``logit`` flags: :func:`with_perception`; ``None`` without)
    and ``raster`` (the training data's, :func:`minimanc.inputs.raster_of`, which the
    checkpoint and the result record).
    """

    name: str
    cfg: models.ModelConfig
    tc: TrainConfig
    scenes: np.ndarray
    std: np.ndarray
    params: Any
    opt_state: Any
    start_epoch: int = 0
    history: list = field(default_factory=list)
    val_history: list = field(default_factory=list)
    steps: int = 0
    ck_path: Path | None = None
    saved_epoch: int | None = None
    perception: dict | None = None
    raster: Any = None


def check_fit_args(name: str, train_ds: Any, cfg: models.ModelConfig | None,
                   train_cfg: TrainConfig | None, val_ds: Any = None
                   ) -> tuple[str, models.ModelConfig, TrainConfig]:
    """``(name, cfg, train_cfg)`` of :func:`fit` checked against each other and the data
    (defaults filled in); a ``ValueError`` naming the argument otherwise."""
    name = models.check_name(name)
    dataset_shape(train_ds)
    cfg = cfg or models.ModelConfig()
    tc = train_cfg or TrainConfig()
    if not isinstance(cfg, models.ModelConfig):
        raise ValueError(f"cfg must be a models.ModelConfig, got cfg={cfg!r}")
    if not isinstance(tc, TrainConfig):
        raise ValueError(f"train_cfg must be a train.TrainConfig, got train_cfg={tc!r}")
    cfg = config_for_data(cfg, train_ds, "train_ds")
    if val_ds is not None:
        config_for_data(cfg, val_ds, "val_ds")
    for label, data in (("train_ds", train_ds), ("val_ds", val_ds)):
        found = first_non_finite(data) if data is not None else None
        if found is not None:
            raise ValueError(f"{label} holds a non-finite number: {describe_non_finite(found)}; "
                             "training needs finite data (check how it was made)")
    return name, cfg, tc


def config_for_data(cfg: models.ModelConfig, ds: Any, label: str = "ds") -> models.ModelConfig:
    """``cfg`` with the input shape of the dataset ``ds``, the one source of a model's input.

    Parameters
    ----------
    cfg : ModelConfig
        Its ``input_shape`` unset (``None``: filled in) or equal to the data's.
    ds : dataset
        Its raster (:func:`minimanc.inputs.raster_of`) gives ``(H, W, C)``.
    label : str
        The argument's name, for the message.

    Returns
    -------
    ModelConfig

    Raises
    ------
    ValueError
        If ``cfg.input_shape`` is set and differs from the data's
        (:func:`minimanc.models.check_input_shape`).
    """
    shape = inputs.raster_of(ds).input_shape
    if cfg.input_shape is None:
        return replace(cfg, input_shape=shape)
    models.check_input_shape(cfg, shape, label)
    return cfg


def start_run(name: str, train_ds: Any, cfg: models.ModelConfig, tc: TrainConfig,
              checkpoint_dir: str | Path | None = None, resume: bool = False,
              params: dict | None = None) -> RunState:
    """The :class:`RunState` of a run before its first epoch: the subset, the
    normalisation and fresh (or given) parameters cast to ``tc.dtype``, or, with
    ``resume``, the state of the checkpoint in ``checkpoint_dir`` (whose model,
    configuration and raster must match, except ``epochs`` and ``lr``)."""
    dtype = DTYPES[tc.dtype]
    S, _ = dataset_shape(train_ds)
    scenes = subset_scenes(S, tc.subset, tc.seed)
    std = control_std(train_ds, scenes) if tc.normalize else np.ones(2)
    ck_path = Path(checkpoint_dir) / CHECKPOINT_NAME if checkpoint_dir is not None else None
    if ck_path is not None:
        remove_temp_files(ck_path)  # left by a run that was killed while saving
    if params is None:
        params = models.init(name, np.random.default_rng(tc.seed), cfg)
    params = cast_floats(params, dtype)
    st = RunState(name, cfg, tc, scenes, std, params, optim.adam_init(params), ck_path=ck_path,
                  raster=inputs.raster_of(train_ds))
    if resume:
        if ck_path is None:
            raise ValueError("resume=True needs a checkpoint_dir")
        if ck_path.exists():
            ck = load_checkpoint(ck_path)
            if ck["name"] != name or ck["cfg"] != cfg:
                raise ValueError(f"checkpoint at {ck_path.name} is for model {ck['name']!r} "
                                 f"with {ck['cfg']}, not {name!r} with {cfg}")
            same = replace(ck["train_cfg"], epochs=tc.epochs, lr=tc.lr)
            if same != tc:
                raise ValueError(f"checkpoint was trained with {ck['train_cfg']}; only epochs "
                                 f"and lr may change on resume, got {tc}")
            if ck["raster"] != st.raster:
                raise ValueError(f"checkpoint at {ck_path.name} was trained on data drawn with "
                                 f"{ck['raster']}, not {st.raster}")
            st.params = cast_floats(ck["params"], dtype)
            if ck["opt_state"] is not None:
                st.opt_state = restore_opt(optim.adam_init(st.params), ck["opt_state"])
            st.start_epoch = st.saved_epoch = ck["epoch"]
            st.history, st.val_history, st.steps = ck["history"], ck["val_history"], ck["steps"]
            st.std = ck["control_std"]
    return st


def diverged_loss(st: RunState, loss: float, epoch: int, step: int, n_steps: int
                  ) -> TrainingDiverged:
    """The :class:`TrainingDiverged` of a non-finite ``loss`` at ``step`` of ``epoch``."""
    return TrainingDiverged(
        f"training {st.name!r} diverged: loss = {loss} at epoch {epoch + 1}, "
        f"step {step} of {n_steps} (lr={st.tc.lr}, seed={st.tc.seed}); "
        f"{_kept(st.ck_path, st.saved_epoch)}. "
        "Lower the learning rate or check the data for NaNs."
    )


def end_epoch(st: RunState, epoch: int, mean_loss: float, eng: Any, val_ds: Any = None) -> None:
    """After ``epoch``: refuse unusable parameters (:class:`TrainingDiverged`, the last
    good checkpoint kept), record the mean loss (and the validation loss), write the
    checkpoint."""
    bad = bad_params(st.params)
    if bad is not None:
        raise TrainingDiverged(
            f"training {st.name!r} diverged: after epoch {epoch + 1} (lr={st.tc.lr}, "
            f"seed={st.tc.seed}) the parameters are unusable ({bad}); "
            f"{_kept(st.ck_path, st.saved_epoch)}. Lower the learning rate."
        )
    st.history.append(mean_loss)
    if val_ds is not None:
        st.val_history.append(open_loop_loss(st.name, to_numpy(st.params), val_ds, st.cfg, eng,
                                             std=st.std, q_init=st.tc.q_init,
                                             dtype=DTYPES[st.tc.dtype]))
    if st.ck_path is not None:
        save_checkpoint(st.ck_path, st.name, st.params, st.cfg, st.tc, st.opt_state, epoch + 1,
             st.history, st.val_history, st.steps, st.std, st.raster)
        st.saved_epoch = epoch + 1


def with_perception(st: RunState, targets: PerceptionTargets | None, train_ds: Any) -> None:
    """Give run ``st`` the auxiliary perception loss of ``targets`` (every state of
    ``train_ds``; :mod:`minimanc.train.perception`): their standardised values over the run's
    training scenes, and, unless a resumed checkpoint has it, the read-out
    ``params["perception"]`` drawn from its own stream ``default_rng([seed, 41])`` (the
    model's parameters stay those of a run without it).

    Raises
    ------
    ValueError
        For targets without ``perception_weight > 0`` or the converse, targets that are not
        :class:`~minimanc.train.perception.PerceptionTargets` or whose ``(S, T)`` is not the
        dataset's.
    """
    if targets is None:
        if st.tc.perception_weight > 0:
            raise ValueError("perception_weight > 0 needs perception targets: fit(..., "
                             "perception=minimanc.diagnose.perception_targets(train_ds))")
        return
    if st.tc.perception_weight == 0:
        raise ValueError("perception targets were given but perception_weight is 0: set "
                         "TrainConfig(perception_weight=...) > 0 or leave them out")
    if not isinstance(targets, PerceptionTargets):
        raise ValueError(f"perception must be a train.perception.PerceptionTargets, got "
                         f"{type(targets).__name__}")
    shape = dataset_shape(train_ds)
    if np.shape(targets.values)[:2] != shape:
        raise ValueError(f"perception targets cover (S, T) = {np.shape(targets.values)[:2]}, "
                         f"the training data {shape}")
    st.perception = {"values": standardised_targets(targets, st.scenes),
                     "mask": np.asarray(targets.mask),
                     "logit": np.asarray(targets.logit, dtype=np.float64)}
    have = st.params.get("perception")
    if have is not None and np.shape(have["b"]) != (len(targets.names),):
        raise ValueError(f"params['perception'] reads {np.shape(have['b'])[0]} targets, the "
                         f"perception targets are {len(targets.names)}")
    if have is None:
        head = init_perception_head(np.random.default_rng([int(st.tc.seed), 41]), st.cfg,
                                    len(targets.names))
        st.params = {**st.params, "perception": cast_floats(head, DTYPES[st.tc.dtype])}
        st.opt_state = optim.adam_init(st.params)


def result_of(st: RunState, seconds: float) -> FitResult:
    """The :class:`FitResult` of a finished run (the controller's parameters, without the
    read-out of the auxiliary perception loss)."""
    params = {k: v for k, v in to_numpy(st.params).items() if k != "perception"}
    return FitResult(name=st.name, params=params, history=list(st.history),
                     cfg=st.cfg, train_cfg=st.tc, val_history=list(st.val_history),
                     steps=st.steps, seconds=seconds, control_std=np.asarray(st.std),
                     raster=st.raster)


def epoch_plan(st: RunState, train_ds: Any, epoch: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The minibatches of ``epoch`` (:func:`batches`, cut at ``max_steps_per_epoch``)."""
    plan = batches(st.name, train_ds, st.scenes, st.tc, epoch)
    if st.tc.max_steps_per_epoch is not None:
        plan = plan[:st.tc.max_steps_per_epoch]
    return plan


def step_batch(st: RunState, train_ds: Any, s_idx: np.ndarray, t_idx: np.ndarray,
               q_rng: np.random.Generator) -> dict:
    """The batch of one step: observations and controls, and Algorithm 1's q' (vAGN)."""
    dtype = DTYPES[st.tc.dtype]
    batch = make_batch(st.name, train_ds, s_idx, t_idx, st.cfg, dtype)
    if st.perception is not None:
        batch["perception"] = st.perception["values"][s_idx, t_idx].astype(dtype)
        batch["perception_mask"] = st.perception["mask"][s_idx, t_idx].astype(dtype)
        batch["perception_logit"] = st.perception["logit"].astype(dtype)
    q0 = initial_q(st.name, s_idx.shape[1], st.cfg, st.tc, q_rng, dtype)
    if q0 is not None:
        batch["q0"] = q0
    return batch


def fit(
    name: str,
    train_ds: Any,
    cfg: models.ModelConfig | None = None,
    train_cfg: TrainConfig | None = None,
    engine: Any = "jax",
    checkpoint_dir: str | Path | None = None,
    resume: bool = False,
    progress: bool = True,
    val_ds: Any = None,
    params: dict | None = None,
    perception: PerceptionTargets | None = None,
) -> FitResult:
    """Train model ``name`` by behaviour cloning (Algorithm 1) on ``train_ds``.

    ``cfg``: the model's :class:`~minimanc.models.ModelConfig` (default: the defaults at
    the dataset's image size; the raster sets the size, and a ``cfg`` that disagrees is
    refused);
    ``train_cfg``: :class:`TrainConfig`; ``engine``: "jax" (jitted) or
    "numpy"; ``checkpoint_dir``: write ``checkpoint.npz`` every epoch;
    ``resume``: continue from it (its model and configs must match, except
    ``epochs`` and ``lr`` which may be changed to extend a run); ``progress``:
    a tqdm bar with the running loss; ``val_ds``: also record the open-loop
    validation loss each epoch; ``params``: start from these instead of a
    fresh initialisation; ``perception``: the targets of the masked auxiliary perception
    loss for every state of ``train_ds`` (:func:`minimanc.diagnose.perception_targets`),
    with ``train_cfg.perception_weight > 0`` (:func:`with_perception`). Returns a
    :class:`FitResult`. Several seeds or
    learning rates of one configuration train faster together:
    :func:`minimanc.train.fit_many`.
    """
    name, cfg, tc = check_fit_args(name, train_ds, cfg, train_cfg, val_ds)
    eng = as_engine(engine)
    t_start = time.perf_counter()
    st = start_run(name, train_ds, cfg, tc, checkpoint_dir, resume, params)
    with_perception(st, perception, train_ds)
    step_fn = make_step(name, cfg, tc, eng, 1.0 / st.std)
    st.params, st.opt_state = eng.device_put(st.params), eng.device_put(st.opt_state)

    bar = None
    for epoch in range(st.start_epoch, tc.epochs):
        plan = epoch_plan(st, train_ds, epoch)
        q_rng = np.random.default_rng([int(tc.seed), int(epoch), 1])
        if progress:
            bar = tqdm(total=len(plan), desc=f"{name} epoch {epoch + 1}/{tc.epochs}",
                       leave=False)
        total, count = 0.0, 0
        pending = None  # the previous step's loss: read after the next step is dispatched,
        # so that JAX computes while the host prepares the next batch
        for i in range(len(plan) + 1):
            if i < len(plan):
                batch = step_batch(st, train_ds, *plan[i], q_rng)
                # overflow to inf / nan is caught below (loss) and after the epoch (params)
                with np.errstate(over="ignore", invalid="ignore"):
                    st.params, st.opt_state, loss_i = step_fn(st.params, st.opt_state, batch)
                st.steps += 1
            if pending is not None:
                loss = float(getattr(pending, "_value", pending))
                if not math.isfinite(loss):
                    if bar is not None:
                        bar.close()
                    raise diverged_loss(st, loss, epoch, count + 1, len(plan))
                total += loss
                count += 1
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix(loss=f"{total / count:.4f}")
            pending = loss_i if i < len(plan) else None
        if bar is not None:
            bar.close()
        end_epoch(st, epoch, total / max(count, 1), eng, val_ds)
    return result_of(st, time.perf_counter() - t_start)


@accepts_fit(STD_DEFAULT)
def open_loop_loss(name: str | FitResult, params: dict, ds: Any,
                   cfg: models.ModelConfig | None = None, engine: Any = "jax", std: Any = None,
                   q_init: str = "uniform", batch_size: int = 256, dtype: Any = np.float32,
                   scenes: Any = None, motion_feedback: bool = True) -> float:
    """Open-loop loss of Algorithm 1 on a dataset (every sample once, no gradient).

    ``open_loop_loss(fit, ds)`` with the :class:`FitResult` of :func:`fit` (``std`` then
    defaults to its ``control_std``, the normalisation it was trained with), or
    ``open_loop_loss(name, params, ds, cfg)`` with its parts.

    Feed-forward models and vAGN-only see each step with ``q'`` as in
    training; LSTM models run each scene from ``t = 0`` with their state
    carried; the DMP models (MANC, DMP-only) run each scene from ``t = 0``
    with q carried and, with ``motion_feedback`` (default, as trained), their
    own speed fed back — the loss they are trained on.
    ``std`` normalises as in training (``None``: the dataset's own).
    Open-loop error ranks closed-loop quality poorly (``REFERENCE.md``); it is
    a cheap check, not the paper's metric.
    """
    name = models.check_name(name)
    cfg = cfg or models.ModelConfig()
    eng = as_engine(engine)
    S, T = dataset_shape(ds)
    scenes = np.arange(S) if scenes is None else np.asarray(scenes)
    std = control_std(ds, scenes) if std is None else np.asarray(std)
    inv = (1.0 / std).astype(dtype)
    params = cast_floats(params, dtype)
    rng = np.random.default_rng(0)
    total, n = 0.0, 0
    spec = models.spec(name)
    feedback = bool(motion_feedback) and spec.dmp
    loss_of = eng.jit(lambda p, b: loss_fn(name, p, b, cfg, eng, inv,
                                           motion_feedback=feedback))
    tc = TrainConfig(q_init=q_init)
    if spec.family == "lstm" or spec.dmp:  # whole scenes from t = 0
        per = max(1, batch_size // T)
        plan = [(np.broadcast_to(sc, (T, len(sc))), np.broadcast_to(np.arange(T)[:, None],
                                                                    (T, len(sc))))
                for sc in (scenes[i:i + per] for i in range(0, len(scenes), per))]
    else:  # every (scene, time) sample on its own
        ss, tt = np.repeat(scenes, T), np.tile(np.arange(T), len(scenes))
        plan = [(ss[None, i:i + batch_size], tt[None, i:i + batch_size])
                for i in range(0, ss.size, batch_size)]
    for s_idx, t_idx in plan:
        batch = make_batch(name, ds, s_idx, t_idx, cfg, dtype)
        q0 = initial_q(name, s_idx.shape[1], cfg, tc, rng, dtype)
        if q0 is not None:
            batch["q0"] = q0
        loss = loss_of(params, batch)
        total += float(np.asarray(loss)) * s_idx.size
        n += s_idx.size
    return total / n


# --------------------------------------------------------------------------- learning-rate sweep


@dataclass
class SweepResult:
    """What :func:`sweep_lr` returns: ``scores[lr]`` (lower is better), ``best_lr``,
    and the :class:`FitResult` of every run in ``results[lr]``."""

    scores: dict[float, float]
    best_lr: float
    results: dict[float, FitResult]


def sweep_lr(
    name: str,
    train_ds: Any,
    val_ds: Any,
    cfg: models.ModelConfig | None = None,
    lrs: Sequence[float] = (3e-4, 1e-3, 3e-3),
    train_cfg: TrainConfig | None = None,
    engine: Any = "jax",
    score: Callable[[FitResult], float] | None = None,
    progress: bool = False,
) -> SweepResult:
    """Train ``name`` once per learning rate and pick the best, so every model is tuned alike.

    ``score(result)`` rates a run (lower is better); by default the open-loop
    validation loss of :func:`open_loop_loss` on ``val_ds``. Pass a closed-loop
    score (e.g. ADE from :mod:`minimanc.rollout`) for a choice that reflects
    driving. A diverged run scores ``inf``.
    """
    lrs = tuple(float(x) for x in lrs)
    if not lrs or any(not (math.isfinite(x) and x > 0) for x in lrs):
        raise ValueError(f"lrs must be positive finite learning rates, got lrs={lrs!r}")
    cfg = cfg or models.ModelConfig()
    tc = train_cfg or TrainConfig()
    scores: dict[float, float] = {}
    results: dict[float, FitResult] = {}
    for lr in lrs:
        try:
            res = fit(name, train_ds, cfg, replace(tc, lr=lr), engine=engine, progress=progress)
        except TrainingDiverged:
            scores[lr] = float("inf")
            continue
        results[lr] = res
        if score is None:
            scores[lr] = open_loop_loss(name, res.params, val_ds, cfg, engine, std=res.control_std,
                                        q_init=tc.q_init, dtype=DTYPES[tc.dtype])
        else:
            scores[lr] = float(score(res))
    best = min(scores, key=lambda k: scores[k])
    return SweepResult(scores=scores, best_lr=best, results=results)
