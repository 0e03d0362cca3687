"""Chapter 8 — behaviour cloning (the paper's Algorithm 1), checkpoints and a learning-rate sweep.

Algorithm 1 of the paper, for every controller of :mod:`minimanc.models`::

    for each minibatch (X, g, g_q, a) of logged samples:
        q' = UniformInit() or RandomInit()            # vAGN models only
        â  = model(params, X, g, g_q, q')              # eqs. 7–11
        L  = MSE(â, a)                                 # on [speed, yaw rate]
        params ← Adam(params, ∇L)

* **Loss.** Mean squared error on the human controls; with
  ``TrainConfig.normalize`` (default) each control's error is divided by its
  standard deviation on the training subset, so that the yaw rate weighs as
  much as the speed.
* **Engines.** ``engine="jax"`` (default) jits the whole step (forward,
  backward, Adam) and trains in ``TrainConfig.dtype`` (float32); ``"numpy"``
  runs the same code on our autodiff engine. In float64 both give the same
  losses to 1e-5 (``tests/test_train.py``).
* **Samples and windows.** Every (scene, time) pair of the training subset is
  one sample; an epoch visits each once in a seeded random order. A model
  trains on windows of consecutive steps whose length is the
  :class:`TrainConfig` field its :class:`~minimanc.models.ModelSpec` names
  (:func:`window_len`): ``seq_len`` for the LSTM models (truncated
  back-propagation through time, zero initial state at the window start),
  ``dmp_seq_len`` for the DMP models (MANC, DMP-only), ``q_seq_len`` for
  vAGN-only, one step otherwise. In the DMP models' windows q *and the DMP's
  velocity state* carry over as in closed loop (``motion_feedback``): trained
  one step at a time from the human's speed, the head would learn only speed
  *changes* and its long-run speed would never be constrained. The default
  window is the whole scene (from its first step), so that the head also
  learns the acceleration at a scene's start that the closed loop must
  produce itself. ``q'`` (Algorithm 1) is set at each window's start;
  ``dmp_seq_len = 1`` gives Algorithm 1 exactly.
* **Subsets.** ``subset`` ∈ (0, 1] keeps the first ``⌈subset·S⌉`` scenes of
  a seeded permutation: the 25 % subset is inside the 50 % one, etc.
* **Determinism.** Initial parameters come from ``default_rng(seed)``; epoch
  ``e`` shuffles with ``default_rng([seed, e])``. A resumed run therefore
  repeats an uninterrupted one exactly.
* **Checkpoints.** With ``checkpoint_dir``, ``checkpoint.npz`` is written
  after every epoch through a temporary file in the same directory and
  :func:`os.replace` (atomic: a crash never leaves half a file; the
  temporary file is removed on failure, and those a killed run left,
  ``checkpoint.npz.*.tmp``, are removed when the next run starts).
  ``resume=True`` continues from it. It records the raster the training data
  was drawn with (:attr:`FitResult.raster`, which a closed loop draws the model's
  input with). A checkpoint that cannot be read (truncated, corrupt, or of
  another :data:`~minimanc.train.checkpoint.CHECKPOINT_FORMAT`: written before
  the raster was recorded) raises :class:`CheckpointError` naming the file:
  delete it, or train without ``resume``, to start again from epoch 0.
* **Divergence.** A NaN or infinite loss, or parameters that are not
  finite or exceed :data:`PARAM_LIMIT` in magnitude (checked after every
  epoch, before the checkpoint is written), stop training with
  :class:`TrainingDiverged`; a checkpoint is never written with such
  parameters, so the one of the last good epoch is left untouched.
* **Data.** A non-finite number in the training (or validation) data is a
  ``ValueError`` naming the array, scene and step: one NaN would otherwise
  change the loss normalisation (:func:`control_std`) of every run.

* **The training result.** :func:`fit` returns a :class:`FitResult` (name, params, cfg,
  control_std, ...); every function that runs a trained model takes it whole or in parts
  (:func:`accepts_fit`): ``open_loop_loss(fit, ds)``, ``save_checkpoint(path, fit)``,
  ``minimanc.rollout.closed_loop(fit, ds)``.

Modules: :mod:`~minimanc.train.config`, :mod:`~minimanc.train.trained`,
:mod:`~minimanc.train.batches`,
:mod:`~minimanc.train.step` (loss and optimiser step),
:mod:`~minimanc.train.checkpoint`, :mod:`~minimanc.train.fit`, :mod:`~minimanc.train.many`
(several seeds or learning rates of one configuration in one vmapped step),
:mod:`~minimanc.train.perception` (the masked auxiliary perception loss,
``TrainConfig.perception_weight``).
"""

from __future__ import annotations

from minimanc.train.batches import (
    batches,
    control_std,
    dataset_shape,
    initial_q,
    make_batch,
    subset_scenes,
    window_len,
)
from minimanc.train.checkpoint import bad_params, load_checkpoint, load_fit, save_checkpoint
from minimanc.train.config import (
    CHECKPOINT_NAME,
    DTYPES,
    PARAM_LIMIT,
    CheckpointError,
    FitResult,
    TrainConfig,
    TrainingDiverged,
)
from minimanc.train.fit import (
    SweepResult,
    cast_floats,
    config_for_data,
    fit,
    open_loop_loss,
    sweep_lr,
)
from minimanc.train.many import fit_many, fit_seeds
from minimanc.train.perception import (
    PerceptionTargets,
    concat_targets,
    load_targets,
    masked_perception_loss,
    perception_outputs,
    save_targets,
    standardised_targets,
)
from minimanc.train.step import jitted_step, loss_fn, make_step
from minimanc.train.trained import accepts_fit

__all__ = [
    "CHECKPOINT_NAME",
    "DTYPES",
    "PARAM_LIMIT",
    "CheckpointError",
    "FitResult",
    "PerceptionTargets",
    "SweepResult",
    "TrainConfig",
    "TrainingDiverged",
    "accepts_fit",
    "bad_params",
    "batches",
    "cast_floats",
    "config_for_data",
    "control_std",
    "dataset_shape",
    "open_loop_loss",
    "concat_targets",
    "fit",
    "fit_many",
    "fit_seeds",
    "initial_q",
    "jitted_step",
    "load_fit",
    "load_checkpoint",
    "load_targets",
    "loss_fn",
    "make_batch",
    "make_step",
    "masked_perception_loss",
    "perception_outputs",
    "save_checkpoint",
    "save_targets",
    "standardised_targets",
    "subset_scenes",
    "sweep_lr",
    "window_len",
]
