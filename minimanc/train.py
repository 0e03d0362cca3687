"""Chapter 8 — behaviour cloning (the paper's Algorithm 1), checkpoints and a learning-rate sweep.

Algorithm 1 of the paper, for every controller of :mod:`minimanc.models`::

    for each minibatch (X, g, g_q, a) of logged samples:
        q' = UniformInit() or RandomInit()            # vAGN models only
        â  = model(params, X, g, g_q, q')              # eqs. 7–11
        L  = MSE(â, a)                                 # on [speed, yaw rate]
        params ← Adam(params, ∇L)

* **Loss.** Mean squared error on the human controls; with
  ``TrainConfig.normalize`` (default) each control's error is divided by its
  standard deviation on the training subset, so that the yaw rate (≈ 0.1
  rad/s) weighs as much as the speed (≈ 5 m/s).
* **Engines.** ``engine="jax"`` (default) jits the whole step (forward,
  backward, Adam) and trains in ``TrainConfig.dtype`` (float32); ``"numpy"``
  runs the same code on our autodiff engine. In float64 both give the same
  losses to 1e-5 (``tests/test_train.py``).
* **Samples.** Every (scene, time) pair of the training subset is one
  sample; an epoch visits each once in a seeded random order. LSTM models
  train on windows of ``seq_len`` consecutive steps (truncated
  back-propagation through time, zero initial state at the window start) so
  that they learn to use history. The DMP models (MANC, DMP-only) train on
  windows of ``dmp_seq_len`` steps in which q *and the DMP's velocity state*
  carry over as in closed loop (``motion_feedback``): trained one step at a
  time from the human's speed, the head only learns speed *changes*, its
  long-run speed is never constrained, and in closed loop the speed drifted
  (we measured runaway to 24 m/s and, with a fixed look-ahead, crawling at
  5.8 instead of 7.5 m/s). The default window is the **whole scene** (40
  steps = 20 s, from its first step): shorter windows start mostly in steady
  driving, where "keep the current speed" fits the loss best, and the head
  never learns the acceleration at a scene's start that the closed loop must
  produce itself. On the ``full`` preset's data (96 training, 48 validation
  scenes, 4 epochs, 3 seeds) MANC's closed-loop ADE was 19.2 ± 6.9 m
  with 8-step windows (a seed crawled at 3.9 m/s) and 15.6 ± 3.1 m with
  whole-scene windows, although its open-loop speed was already unbiased
  with 8-step windows (−0.05 m/s). ``q'`` (Algorithm 1) is set
  at each window's start; ``dmp_seq_len = 1`` gives Algorithm 1 exactly.
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
  ``resume=True`` continues from it. A checkpoint that cannot be read
  (truncated, corrupt) raises :class:`CheckpointError` naming the file:
  delete it, or train without ``resume``, to start again from epoch 0.
* **Divergence.** A NaN or infinite loss, or parameters that are not
  finite or exceed :data:`PARAM_LIMIT` in magnitude (checked after every
  epoch, before the checkpoint is written), stop training with
  :class:`TrainingDiverged`; a checkpoint is never written with such
  parameters, so the one of the last good epoch is left untouched.
* **Data.** A non-finite number in the training (or validation) data is a
  ``ValueError`` naming the array, scene and step: one NaN would otherwise
  change the loss normalisation (:func:`control_std`) of every run.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import time
import zipfile
import zlib
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from minimanc import inputs, models, optim
from minimanc.engine import ENGINES
from minimanc.tree import leaves as tree_leaves
from minimanc.world.dataset import describe_non_finite, first_non_finite, remove_temp_files

__all__ = [
    "CHECKPOINT_NAME",
    "PARAM_LIMIT",
    "CheckpointError",
    "FitResult",
    "SweepResult",
    "TrainConfig",
    "TrainingDiverged",
    "bad_params",
    "batches",
    "control_std",
    "evaluate",
    "fit",
    "load",
    "load_checkpoint",
    "loss_fn",
    "save",
    "subset_scenes",
    "sweep_lr",
]

CHECKPOINT_NAME = "checkpoint.npz"
"""File name of the checkpoint inside ``checkpoint_dir``."""

_DTYPES = {"float32": np.float32, "float64": np.float64}


PARAM_LIMIT = 1e6
"""Largest parameter magnitude :func:`fit` accepts (trained weights stay far below it)."""


class TrainingDiverged(RuntimeError):
    """Raised when the training loss or the parameters become non-finite or explode."""


class CheckpointError(ValueError):
    """A checkpoint file that cannot be used (truncated, corrupt, not a checkpoint)."""


@dataclass(frozen=True)
class TrainConfig:
    """Training hyper-parameters (Algorithm 1).

    ``epochs``, ``batch_size`` (samples per step; a window of ``L`` steps
    counts ``L`` samples), ``lr`` (Adam), ``seed``, ``subset`` of the
    training scenes, ``seq_len`` (LSTM window length), ``dmp_seq_len``
    (window length of the DMP models, MANC and DMP-only; default 40 = a whole
    20-s scene, longer is clipped to the scene) with
    ``motion_feedback`` (inside a window the DMP starts each step from its own
    previous output, as in closed loop), ``q_init`` ("uniform"/"random",
    Algorithm 1's q' at the start of each window), ``q_seq_len`` (window
    length of vAGN-only; 1 = Algorithm 1), ``normalize`` the MSE per control, ``dtype``
    ("float32"/"float64"), ``zeta_weight`` of the auxiliary
    :func:`minimanc.dmp.zeta_penalty` (DMP models), ``max_steps_per_epoch``
    (``None`` = all; for quick runs), ``grad_clip`` (global gradient-norm
    clip, ``None`` = off).
    """

    epochs: int = 6
    batch_size: int = 64
    lr: float = 3e-3
    seed: int = 0
    subset: float = 1.0
    seq_len: int = 8
    dmp_seq_len: int = 40
    motion_feedback: bool = True
    q_init: str = "uniform"
    q_seq_len: int = 1
    normalize: bool = True
    dtype: str = "float32"
    zeta_weight: float = 0.0
    max_steps_per_epoch: int | None = None
    grad_clip: float | None = 5.0

    def __post_init__(self) -> None:
        for name in ("epochs", "batch_size", "seq_len", "dmp_seq_len", "q_seq_len"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {name}={v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer) \
                or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got seed={self.seed!r}")
        if not (isinstance(self.lr, int | float) and math.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr must be a positive finite number, got lr={self.lr!r}")
        if not (isinstance(self.subset, int | float) and 0.0 < self.subset <= 1.0):
            raise ValueError(f"subset must be in (0, 1], got subset={self.subset!r}")
        if self.q_init not in ("uniform", "random"):
            raise ValueError(f"q_init must be 'uniform' or 'random', got q_init={self.q_init!r}")
        if self.dtype not in _DTYPES:
            raise ValueError(f"dtype must be one of {tuple(_DTYPES)}, got dtype={self.dtype!r}")
        if not (math.isfinite(self.zeta_weight) and self.zeta_weight >= 0):
            raise ValueError(f"zeta_weight must be >= 0, got zeta_weight={self.zeta_weight!r}")
        m = self.max_steps_per_epoch
        if m is not None and (isinstance(m, bool) or not isinstance(m, int | np.integer)
                              or m < 1):
            raise ValueError(f"max_steps_per_epoch must be None or a positive integer, "
                             f"got max_steps_per_epoch={m!r}")
        c = self.grad_clip
        if c is not None and not (isinstance(c, int | float) and math.isfinite(c) and c > 0):
            raise ValueError(f"grad_clip must be None or > 0, got grad_clip={c!r}")


@dataclass
class FitResult:
    """What :func:`fit` returns.

    ``params`` (NumPy pytree), ``history`` (mean training loss per epoch),
    ``val_history`` (open-loop validation loss per epoch, if ``val_ds``),
    ``name``, ``cfg``, ``train_cfg``, ``steps`` (optimiser steps),
    ``seconds`` (wall time of this call), ``control_std`` (the
    normalisation used).
    """

    name: str
    params: dict
    history: list[float]
    cfg: models.ModelConfig
    train_cfg: TrainConfig
    val_history: list[float] = field(default_factory=list)
    steps: int = 0
    seconds: float = 0.0
    control_std: np.ndarray = field(default_factory=lambda: np.ones(2))


# --------------------------------------------------------------------------- data


def _shape(ds: Any) -> tuple[int, int]:
    ego = np.asarray(ds.ego) if not hasattr(ds.ego, "shape") else ds.ego
    if len(ego.shape) != 3:
        raise ValueError(f"dataset ego poses must have shape (S, T, 3), got {ego.shape}")
    return int(ego.shape[0]), int(ego.shape[1])


def subset_scenes(n_scenes: int, subset: float, seed: int) -> np.ndarray:
    """Scene indices of a training subset: the first ``⌈subset·S⌉`` of a seeded permutation.

    Nested: for one seed, the 25 % subset is contained in the 50 % one.
    """
    if not 0.0 < subset <= 1.0:
        raise ValueError(f"subset must be in (0, 1], got subset={subset!r}")
    n = max(1, int(math.ceil(subset * n_scenes - 1e-9)))
    perm = np.random.default_rng([int(seed), 7]).permutation(n_scenes)
    return np.sort(perm[:n])


def control_std(ds: Any, scenes: Any = None) -> np.ndarray:
    """Standard deviation of ``[speed, yaw rate]`` over the given scenes (all by default)."""
    c = np.asarray(ds.controls, dtype=np.float64)
    if scenes is not None:
        c = c[np.asarray(scenes)]
    sd = c.reshape(-1, 2).std(axis=0)
    return np.where(sd > 1e-6, sd, 1.0)


def _window_len(name: str, tc: TrainConfig) -> int:
    if name in models.LSTM_MODELS:
        return tc.seq_len
    if name in models.DMP_MODELS:
        return tc.dmp_seq_len
    if name in models.VAGN_MODELS:
        return tc.q_seq_len
    return 1


def batches(name: str, ds: Any, scenes: np.ndarray, tc: TrainConfig, epoch: int
            ) -> list[tuple[np.ndarray, np.ndarray]]:
    """The minibatches of one epoch: a list of ``(scene_idx, t_idx)`` arrays of shape ``(L, b)``.

    ``L`` is the window length (1 for feed-forward models); windows tile each
    scene from a random offset, and ``b = max(1, batch_size // L)`` windows
    form a batch. Only full batches are kept (a constant shape for ``jit``)
    unless there are fewer samples than one batch.
    """
    S, T = _shape(ds)
    L = min(_window_len(name, tc), T)
    rng = np.random.default_rng([int(tc.seed), int(epoch)])
    starts_s, starts_t = [], []
    for s in scenes:
        off = int(rng.integers(0, L)) if L > 1 else 0
        ts = np.arange(off, T - L + 1, L)
        if ts.size == 0:
            ts = np.array([0])
        starts_s.append(np.full(ts.size, s))
        starts_t.append(ts)
    ss = np.concatenate(starts_s)
    tt = np.concatenate(starts_t)
    order = rng.permutation(ss.size)
    ss, tt = ss[order], tt[order]
    b = max(1, tc.batch_size // L)
    b = min(b, ss.size)
    n_batches = ss.size // b
    out = []
    for i in range(n_batches):
        s_b = ss[i * b:(i + 1) * b]
        t_b = tt[i * b:(i + 1) * b]
        out.append((np.broadcast_to(s_b, (L, b)).copy(), t_b[None, :] + np.arange(L)[:, None]))
    return out


def make_batch(name: str, ds: Any, s_idx: np.ndarray, t_idx: np.ndarray,
                cfg: models.ModelConfig, dtype: Any) -> dict:
    """Observations ``(L, b, ...)`` and controls ``(L, b, 2)`` for index arrays ``(L, b)``."""
    L, b = s_idx.shape
    obs = inputs.from_dataset(ds, s_idx.reshape(-1), t_idx.reshape(-1), cfg.setting, model=name)
    batch = {k: v.reshape((L, b) + v.shape[1:]).astype(dtype) for k, v in obs.items()}
    y = np.asarray(ds.controls)[s_idx, t_idx]
    batch["controls"] = y.astype(dtype)
    return batch


def initial_q(name: str, b: int, cfg: models.ModelConfig, tc: TrainConfig,
              rng: np.random.Generator, dtype: Any) -> np.ndarray | None:
    """Algorithm 1's q' for a minibatch of ``b`` samples (uniform or random, ``tc.q_init``);
    ``None`` for models without a vAGN."""
    if name not in models.VAGN_MODELS:
        return None
    st = models.initial_state(name, b, cfg, xp=np, rng=rng, mode=tc.q_init, dtype=dtype)
    return np.asarray(st["q"])


# --------------------------------------------------------------------------- loss and step


def loss_fn(name: str, params: dict, batch: dict, cfg: models.ModelConfig, eng: Any,
            inv_std: Any, zeta_weight: float = 0.0, motion_feedback: bool = False) -> Any:
    """Algorithm 1's loss on a batch of windows: ``mean(((â − a) / σ)²)`` (+ ζ penalty).

    ``batch`` holds observations ``(L, b, ...)``, ``controls (L, b, 2)`` and,
    for vAGN models, ``q0 (b, N)`` (q'). ``inv_std`` is ``1/σ`` per control;
    ``motion_feedback`` see :func:`minimanc.models.sequence`.
    """
    xp = eng.xp
    obs = {k: v for k, v in batch.items() if k not in ("controls", "q0")}
    L, b = batch["controls"].shape[:2]
    if name in models.VAGN_MODELS:
        state = {"q": batch["q0"]}
    else:
        dtype = params["backbone"]["convs"][0]["w"].dtype
        state = models.initial_state(name, b, cfg, xp=xp, dtype=dtype)
    if zeta_weight > 0.0 and name in models.DMP_MODELS:
        from minimanc import dmp

        pred, _, aux = models.sequence(name, params, obs, state, cfg, eng,
                                       feedback_motion=motion_feedback, return_aux=True)
        extra = zeta_weight * dmp.zeta_penalty(aux["alpha"], aux["beta"], xp=xp)
    else:
        pred, _ = models.sequence(name, params, obs, state, cfg, eng,
                                  feedback_motion=motion_feedback)
        extra = 0.0
    err = (pred - batch["controls"]) * inv_std
    return xp.mean(err * err) + extra


def _global_norm(tree: Any, xp: Any) -> Any:
    leaves = tree_leaves(tree)
    return xp.sqrt(sum(xp.sum(g * g) for g in leaves))


def _scale_tree(tree: Any, s: Any) -> Any:
    if isinstance(tree, dict):
        return {k: _scale_tree(v, s) for k, v in tree.items()}
    if isinstance(tree, list | tuple):
        return type(tree)(_scale_tree(v, s) for v in tree)
    return tree * s


def _like(tree: Any, template: Any, xp: Any) -> Any:
    """``tree`` with every array leaf cast to the dtype of the matching ``template`` leaf."""
    if isinstance(tree, dict):
        return {k: _like(v, template[k], xp) for k, v in tree.items()}
    if isinstance(tree, list | tuple):
        items = [_like(v, template[i], xp) for i, v in enumerate(tree)]
        return type(tree)(*items) if hasattr(tree, "_fields") else type(tree)(items)
    dt = getattr(template, "dtype", None)
    if dt is None or getattr(tree, "dtype", None) == dt:
        return tree
    return xp.asarray(tree, dtype=dt)


def make_step(name: str, cfg: models.ModelConfig, tc: TrainConfig, eng: Any,
               inv_std: np.ndarray) -> Callable:
    """The (jitted) training step ``(params, opt_state, batch) → (params, opt_state, loss)``.

    The learning rate and ``1/σ`` enter the jitted function as arguments, not
    constants: runs that differ only in those (the learning-rate sweep, the
    data fractions) share one compilation through JAX's persistent cache.
    """
    xp = eng.xp
    dtype = _DTYPES[tc.dtype]
    hyper = {"lr": np.asarray(tc.lr, dtype=dtype),
             "inv_std": np.asarray(inv_std, dtype=dtype)}

    def objective(params, batch, inv):
        return loss_fn(name, params, batch, cfg, eng, inv, tc.zeta_weight, tc.motion_feedback)

    vg = eng.value_and_grad(objective)

    def train_step(params, opt_state, batch, hyper):
        loss, grads = vg(params, batch, hyper["inv_std"])
        if tc.grad_clip is not None:
            norm = _global_norm(grads, xp)
            factor = xp.minimum(1.0, tc.grad_clip / (norm + 1e-12))
            grads = _scale_tree(grads, factor)
        new_params, new_state = optim.adam_update(grads, opt_state, params, lr=hyper["lr"])
        # keep every leaf's dtype: a float64 scalar must not promote float32 parameters
        # (under jit that would trigger a new compilation at the next step)
        return _like(new_params, params, xp), _like(new_state, opt_state, xp), loss

    step = eng.jit(train_step)
    return lambda params, opt_state, batch: step(params, opt_state, batch, hyper)


# --------------------------------------------------------------------------- checkpoints


def _flatten(tree: Any, prefix: str = "") -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    if isinstance(tree, dict):
        for k in sorted(tree):
            out.update(_flatten(tree[k], f"{prefix}{k}/"))
    elif isinstance(tree, list | tuple):
        for i, v in enumerate(tree):
            out.update(_flatten(v, f"{prefix}#{i}/"))
    elif tree is None:
        pass
    else:
        out[prefix[:-1]] = np.asarray(tree)
    return out


def _unflatten(flat: dict[str, np.ndarray]) -> Any:
    root: dict = {}
    for key, value in flat.items():
        parts = key.split("/")
        node = root
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return _lists(root)


def _lists(node: Any) -> Any:
    if not isinstance(node, dict):
        return node
    if node and all(k.startswith("#") for k in node):
        return [_lists(node[f"#{i}"]) for i in range(len(node))]
    return {k: _lists(v) for k, v in node.items()}


def _to_numpy(tree: Any) -> Any:
    if isinstance(tree, dict):
        return {k: _to_numpy(v) for k, v in tree.items()}
    if isinstance(tree, list | tuple):
        return type(tree)(_to_numpy(v) for v in tree)
    if tree is None:
        return None
    return np.array(tree)


def bad_params(params: Any, limit: float = PARAM_LIMIT) -> str | None:
    """Why ``params`` cannot be kept — a non-finite entry or one above ``limit`` in
    magnitude, naming the array — or ``None`` when they are fine."""
    worst, where = 0.0, ""
    for key, a in _flatten(_to_numpy(params)).items():
        a = np.asarray(a)
        if not np.issubdtype(a.dtype, np.floating) or a.size == 0:
            continue
        if not np.all(np.isfinite(a)):
            return f"non-finite value in {key!r}"
        m = float(np.max(np.abs(a)))
        if m > worst:
            worst, where = m, key
    if worst > limit:
        return f"max |param| = {worst:.3g} in {where!r} exceeds {limit:.0e}"
    return None


def _atomic_savez(path: Path, arrays: dict[str, np.ndarray]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _meta(name: str, cfg: models.ModelConfig, tc: TrainConfig, epoch: int,
          history: list[float], val_history: list[float], steps: int,
          std: np.ndarray) -> np.ndarray:
    meta = {
        "format": 1,
        "name": name,
        "cfg": cfg.to_dict(),
        "train_cfg": asdict(tc),
        "epoch": epoch,
        "history": history,
        "val_history": val_history,
        "steps": steps,
        "control_std": [float(x) for x in std],
    }
    return np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)


def save(path: str | Path, name: str, params: dict, cfg: models.ModelConfig,
         train_cfg: TrainConfig | None = None, opt_state: Any = None, epoch: int = 0,
         history: Sequence[float] = (), val_history: Sequence[float] = (), steps: int = 0,
         std: Any = None) -> Path:
    """Write parameters (and optionally the optimiser state) atomically to ``path`` (.npz).

    Refuses (``ValueError``) parameters that :func:`bad_params` rejects.
    """
    path = Path(path)
    bad = bad_params(params)
    if bad is not None:
        raise ValueError(f"params cannot be saved to {path}: {bad}")
    arrays = {f"params/{k}": v for k, v in _flatten(_to_numpy(params)).items()}
    if opt_state is not None:
        arrays.update({f"opt/{k}": v for k, v in _flatten(_to_numpy(opt_state)).items()})
    std = np.ones(2) if std is None else np.asarray(std, dtype=np.float64)
    arrays["meta"] = _meta(name, cfg, train_cfg or TrainConfig(), int(epoch), list(history),
                           list(val_history), int(steps), std)
    _atomic_savez(path, arrays)
    return path


def load_checkpoint(path: str | Path) -> dict:
    """Read a file written by :func:`save`: ``name, params, cfg, train_cfg, opt_state,
    epoch, history, val_history, steps, control_std``.

    A file that cannot be read raises :class:`CheckpointError` naming it.
    """
    path = Path(path)
    if not path.exists():
        raise ValueError(f"no checkpoint at path={str(path)!r}")
    restart = ("delete it (or train without resume / --resume) to start again from epoch 0")
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(bytes(z["meta"]).decode())
            p = {k[len("params/"):]: z[k] for k in z.files if k.startswith("params/")}
            o = {k[len("opt/"):]: z[k] for k in z.files if k.startswith("opt/")}
        cfg_d = dict(meta["cfg"])
        cfg_d["channels"] = tuple(cfg_d["channels"])
        out = {
            "name": meta["name"],
            "params": _unflatten(p),
            "opt_state": _unflatten(o) if o else None,
            "cfg": models.ModelConfig(**cfg_d),
            "train_cfg": TrainConfig(**meta["train_cfg"]),
            "epoch": meta["epoch"],
            "history": list(meta["history"]),
            "val_history": list(meta["val_history"]),
            "steps": meta["steps"],
            "control_std": np.asarray(meta["control_std"]),
        }
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, KeyError, TypeError, ValueError,
            UnicodeDecodeError, AttributeError) as e:
        raise CheckpointError(f"{path}: unreadable checkpoint (truncated or corrupt: "
                              f"{type(e).__name__}: {e}); {restart}") from e
    bad = bad_params(out["params"])
    if bad is not None:
        raise CheckpointError(f"{path}: checkpoint holds unusable parameters ({bad}); {restart}")
    return out


def load(path: str | Path) -> FitResult:
    """A :class:`FitResult` from a file written by :func:`save` or by :func:`fit`."""
    ck = load_checkpoint(path)
    return FitResult(name=ck["name"], params=ck["params"], history=ck["history"],
                     cfg=ck["cfg"], train_cfg=ck["train_cfg"], val_history=ck["val_history"],
                     steps=ck["steps"], control_std=ck["control_std"])


def _restore_opt(template: Any, loaded: Any) -> Any:
    """Put loaded optimiser arrays into the structure of ``template`` (tuples, scalars)."""
    if isinstance(template, dict):
        return {k: _restore_opt(v, loaded[k]) for k, v in template.items()}
    if isinstance(template, list | tuple):
        items = [_restore_opt(v, loaded[i]) for i, v in enumerate(template)]
        if hasattr(template, "_fields"):  # NamedTuple
            return type(template)(*items)
        return type(template)(items)
    if template is None:
        return None
    if isinstance(template, int | np.integer) and not isinstance(template, bool):
        return int(np.asarray(loaded))
    arr = np.asarray(loaded)
    return arr.astype(np.asarray(template).dtype)


# --------------------------------------------------------------------------- fit


def _cast_tree(tree: Any, dtype: Any) -> Any:
    if isinstance(tree, dict):
        return {k: _cast_tree(v, dtype) for k, v in tree.items()}
    if isinstance(tree, list | tuple):
        return type(tree)(_cast_tree(v, dtype) for v in tree)
    arr = np.asarray(tree)
    return arr.astype(dtype) if np.issubdtype(arr.dtype, np.floating) else arr


def _get_engine(engine: Any) -> Any:
    from minimanc import engine as _engine

    if isinstance(engine, str):
        return _engine(engine)
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
) -> FitResult:
    """Train model ``name`` by behaviour cloning (Algorithm 1) on ``train_ds``.

    ``cfg``: the model's :class:`~minimanc.models.ModelConfig`;
    ``train_cfg``: :class:`TrainConfig`; ``engine``: "jax" (jitted) or
    "numpy"; ``checkpoint_dir``: write ``checkpoint.npz`` every epoch;
    ``resume``: continue from it (its model and configs must match, except
    ``epochs`` and ``lr`` which may be changed to extend a run); ``progress``:
    a tqdm bar with the running loss; ``val_ds``: also record the open-loop
    validation loss each epoch; ``params``: start from these instead of a
    fresh initialisation. Returns a :class:`FitResult`.
    """
    name = models.check_name(name)
    cfg = cfg or models.ModelConfig()
    tc = train_cfg or TrainConfig()
    if not isinstance(cfg, models.ModelConfig):
        raise ValueError(f"cfg must be a models.ModelConfig, got cfg={cfg!r}")
    if not isinstance(tc, TrainConfig):
        raise ValueError(f"train_cfg must be a train.TrainConfig, got train_cfg={tc!r}")
    eng = _get_engine(engine)
    dtype = _DTYPES[tc.dtype]
    S, T = _shape(train_ds)
    H = np.asarray(train_ds.bev[:1, :1]).shape[2]
    if H != cfg.image_size:
        raise ValueError(f"cfg.image_size={cfg.image_size} does not match the dataset's "
                         f"BEV size {H}")
    for label, data in (("train_ds", train_ds), ("val_ds", val_ds)):
        found = first_non_finite(data) if data is not None else None
        if found is not None:
            raise ValueError(f"{label} holds a non-finite number: {describe_non_finite(found)}; "
                             "training needs finite data (check how it was made)")
    scenes = subset_scenes(S, tc.subset, tc.seed)
    std = control_std(train_ds, scenes) if tc.normalize else np.ones(2)
    t_start = time.perf_counter()

    ck_path = Path(checkpoint_dir) / CHECKPOINT_NAME if checkpoint_dir is not None else None
    if ck_path is not None:
        remove_temp_files(ck_path)  # left by a run that was killed while saving
    saved_epoch = None  # epoch of the checkpoint at ck_path written or resumed by this run
    start_epoch, history, val_history, steps = 0, [], [], 0
    if params is None:
        params = models.init(name, np.random.default_rng(tc.seed), cfg)
    params = _cast_tree(params, dtype)
    opt_state = optim.adam_init(params)
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
            params = _cast_tree(ck["params"], dtype)
            if ck["opt_state"] is not None:
                opt_state = _restore_opt(optim.adam_init(params), ck["opt_state"])
            start_epoch = saved_epoch = ck["epoch"]
            history, val_history, steps = ck["history"], ck["val_history"], ck["steps"]
            std = ck["control_std"]

    step_fn = make_step(name, cfg, tc, eng, 1.0 / std)
    params, opt_state = eng.device_put(params), eng.device_put(opt_state)

    bar = None
    for epoch in range(start_epoch, tc.epochs):
        plan = batches(name, train_ds, scenes, tc, epoch)
        if tc.max_steps_per_epoch is not None:
            plan = plan[:tc.max_steps_per_epoch]
        q_rng = np.random.default_rng([int(tc.seed), int(epoch), 1])
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=len(plan), desc=f"{name} epoch {epoch + 1}/{tc.epochs}",
                       leave=False)
        total, count = 0.0, 0
        pending = None  # the previous step's loss: read after the next step is dispatched,
        # so that JAX computes while the host prepares the next batch
        for i in range(len(plan) + 1):
            if i < len(plan):
                s_idx, t_idx = plan[i]
                batch = make_batch(name, train_ds, s_idx, t_idx, cfg, dtype)
                q0 = initial_q(name, s_idx.shape[1], cfg, tc, q_rng, dtype)
                if q0 is not None:
                    batch["q0"] = q0
                # overflow to inf / nan is caught below (loss) and after the epoch (params)
                with np.errstate(over="ignore", invalid="ignore"):
                    params, opt_state, loss_i = step_fn(params, opt_state, batch)
                steps += 1
            if pending is not None:
                loss = float(getattr(pending, "_value", pending))
                if not math.isfinite(loss):
                    if bar is not None:
                        bar.close()
                    kept = _kept(ck_path, saved_epoch)
                    raise TrainingDiverged(
                        f"training {name!r} diverged: loss = {loss} at epoch {epoch + 1}, "
                        f"step {count + 1} of {len(plan)} (lr={tc.lr}); {kept}. "
                        "Lower the learning rate or check the data for NaNs."
                    )
                total += loss
                count += 1
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix(loss=f"{total / count:.4f}")
            pending = loss_i if i < len(plan) else None
        if bar is not None:
            bar.close()
        bad = bad_params(params)
        if bad is not None:
            raise TrainingDiverged(
                f"training {name!r} diverged: after epoch {epoch + 1} (lr={tc.lr}) the "
                f"parameters are unusable ({bad}); {_kept(ck_path, saved_epoch)}. "
                "Lower the learning rate."
            )
        history.append(total / max(count, 1))
        if val_ds is not None:
            val_history.append(evaluate(name, _to_numpy(params), val_ds, cfg, eng,
                                        std=std, q_init=tc.q_init, dtype=dtype))
        if ck_path is not None:
            save(ck_path, name, params, cfg, tc, opt_state, epoch + 1, history, val_history,
                 steps, std)
            saved_epoch = epoch + 1
    return FitResult(name=name, params=_to_numpy(params), history=list(history), cfg=cfg,
                     train_cfg=tc, val_history=list(val_history), steps=steps,
                     seconds=time.perf_counter() - t_start, control_std=np.asarray(std))


def evaluate(name: str, params: dict, ds: Any, cfg: models.ModelConfig | None = None,
             engine: Any = "jax", std: Any = None, q_init: str = "uniform",
             batch_size: int = 256, dtype: Any = np.float32, scenes: Any = None,
             motion_feedback: bool = True) -> float:
    """Open-loop loss of Algorithm 1 on a dataset (every sample once, no gradient).

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
    eng = _get_engine(engine)
    S, T = _shape(ds)
    scenes = np.arange(S) if scenes is None else np.asarray(scenes)
    std = control_std(ds, scenes) if std is None else np.asarray(std)
    inv = (1.0 / std).astype(dtype)
    params = _cast_tree(params, dtype)
    rng = np.random.default_rng(0)
    total, n = 0.0, 0
    feedback = bool(motion_feedback) and name in models.DMP_MODELS
    loss_of = eng.jit(lambda p, b: loss_fn(name, p, b, cfg, eng, inv,
                                           motion_feedback=feedback))
    tc = TrainConfig(q_init=q_init)
    if name in models.LSTM_MODELS or name in models.DMP_MODELS:  # whole scenes from t = 0
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
    validation loss of :func:`evaluate` on ``val_ds``. Pass a closed-loop
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
            scores[lr] = evaluate(name, res.params, val_ds, cfg, engine, std=res.control_std,
                                  q_init=tc.q_init, dtype=_DTYPES[tc.dtype])
        else:
            scores[lr] = float(score(res))
    best = min(scores, key=lambda k: scores[k])
    return SweepResult(scores=scores, best_lr=best, results=results)
