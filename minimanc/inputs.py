"""Chapter 8 — what each controller sees: observations built from the dataset or the closed loop.

An *observation* is a dict of arrays for one time step, batched over ``B``
samples (rows may come from different scenes and times):

=============== ================= ========================================================
key             dtype, shape      meaning (ego frame: +x forward, +y left, metres/radians)
=============== ================= ========================================================
``bev``         float32 (B,H,W,C) the BEV raster seen from the ego, in [0, 1]: RGB ``/ 255``
                                  or binary planes (:func:`minimanc.world.to_input`)
``goal``        float32 (B,3)     the goal: the human's final pose ``[x, y, yaw]`` in the
                                  *current* ego frame (re-expressed every step)
``lane_target`` float32 (B,K,2)   the moving lane target: route centre points every
                                  :data:`~minimanc.world.lanes.TARGET_SPACING` = 4 m of arc
                                  length ahead of the ego's *own* projection on the route
                                  (never indexed by the human's time: that would leak the
                                  human's future speed)
``motion``      float32 (B,2)     the ego's current motion ``[speed m/s, yaw rate rad/s]``:
                                  the controls it applied over the previous step (what a
                                  speedometer and a gyro measure)
``goal_bev``    float32 (B,H,W,C) RvS-G only: the static map rendered at the goal pose
                                  (:func:`minimanc.world.raster.rasterize_goal`)
=============== ================= ========================================================

Values are kept in **physical units**; models scale numbers before any dense
layer with the fixed constants :data:`GOAL_SCALE`, :data:`LANE_SCALE` and
:data:`MOTION_SCALE` (see :func:`numeric_features`), and the DMP heads use the
metres directly.

``motion`` in the dataset is ``controls[t − 1]`` (the human's own previous
controls: no look into the future), or, in a scene another policy drove while the
expert labelled it (a DAgger round, a perturbed demonstration), the control that was
*applied* at ``t − 1`` (:func:`driven_controls`): the speed the state was reached at,
not the label. At ``t = 0`` there is no previous step
in the log; :func:`initial_motion` then uses the human's speed over the first
step with yaw rate 0 — the one place where the log's first control is used,
exactly as the closed loop starts every policy from the human's initial state
(a car enters the scene already moving). In closed loop ``motion`` is the
policy's *own* previous control.

Information parity
------------------
The paper gives the comparison models the BEV and the goal pose, while MANC's
DMP tracks the moving lane target (section IV-C, Algorithm 1). The lesson of
the closed-loop prototype (``REFERENCE.md``) is that such a comparison turns
on the goal information each model gets, so ``setting`` selects one of two
honest protocols. What each model sees (✓ = input, — = not given):

============ ============== ===== ======== ============ ========= ==========
model        setting        bev   goal     lane_target  motion    goal_bev
============ ============== ===== ======== ============ ========= ==========
cnn          paper          ✓     ✓        —            —         —
cnn          parity         ✓     ✓        ✓            ✓         —
cnn_lstm     paper          ✓     ✓        —            —         —
cnn_lstm     parity         ✓     ✓        ✓            ✓         —
rvs_g        paper          ✓     ✓        —            —         ✓
rvs_g        parity         ✓     ✓        ✓            ✓         ✓
manc         paper, parity  ✓     —        ✓ (DMP g,    ✓ (DMP    —
                                           g_q)         state)
vagn_only    paper          ✓     ✓        —            —         —
vagn_only    parity         ✓     ✓        ✓            ✓         —
dmp_only     paper, parity  ✓     —        ✓            ✓         —
============ ============== ===== ======== ============ ========= ==========

Notes: MANC and DMP-only see the same things in both settings — the BEV
drives the gains (eq. 11), the lane target and the current motion are the
DMP's goal and initial state. In "paper" the LSTM models see history only
through their recurrent state; in "parity" every model also gets the lane
target and the current motion as numbers, so any remaining gap is due to
the architecture, not to information. The table is also data: each model's
``observes`` in its spec (:mod:`minimanc.models.registry`); the caller passes the spec
and :func:`visible` reads it (this module sits below the models and imports none of them).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.world.encodings import to_input
from minimanc.world.geometry import goal_in_ego_frame
from minimanc.world.lanes import K_TARGETS, Map
from minimanc.world.maps import lane_targets
from minimanc.world.raster import RasterConfig, rasterize_batch, rasterize_goal

__all__ = [
    "DRIVEN_TAG",
    "GOAL_SCALE",
    "KEYS",
    "LANE_SCALE",
    "MOTION_SCALE",
    "SCENE_CONSTANT_KEYS",
    "SETTINGS",
    "driven_controls",
    "driven_rows",
    "from_dataset",
    "from_state",
    "initial_motion",
    "motion_at",
    "numeric_features",
    "numeric_size",
    "raster_of",
    "select",
    "visible",
]

SETTINGS: tuple[str, ...] = ("paper", "parity")
"""Information settings; see the table in the module docstring."""

KEYS: tuple[str, ...] = ("bev", "goal", "lane_target", "motion", "goal_bev")
"""All observation keys."""

SCENE_CONSTANT_KEYS: tuple[str, ...] = ("goal_bev",)
"""Observation keys that are the same at every step of a scene (the map at the goal
pose): :func:`minimanc.models.sequence` encodes them once per window."""

GOAL_SCALE: tuple[float, float, float] = (50.0, 50.0, float(np.pi))
"""Divisors for the goal ``[x (m), y (m), yaw (rad)]`` before dense layers."""

LANE_SCALE: float = 40.0
"""Divisor for lane-target coordinates (m) before dense layers (40 m = the raster's reach)."""

MOTION_SCALE: tuple[float, float] = (10.0, 0.5)
"""Divisors for ``[speed (m/s), yaw rate (rad/s)]`` before dense layers."""

# --------------------------------------------------------------------------- checks


def check_setting(setting: Any) -> str:
    """``setting`` if it is one of :data:`SETTINGS`, else a ValueError naming it."""
    if setting not in SETTINGS:
        raise ValueError(f"setting must be one of {SETTINGS}, got setting={setting!r}")
    return setting


def visible(model: Any, setting: str = "paper") -> tuple[str, ...]:
    """Observation keys ``model`` receives in ``setting`` (the table of the module docstring).

    ``model`` is the model's spec (:class:`minimanc.models.ModelSpec`, e.g.
    ``minimanc.models.get("manc")``): its ``observes`` maps each setting to its keys. The
    caller looks the spec up; this module, below the models, never reads the registry.
    """
    observes = getattr(model, "observes", None)
    if not isinstance(observes, Mapping):
        raise ValueError("model must be a model spec with its observation keys "
                         f"(minimanc.models.get(name)), got model={model!r}")
    return tuple(observes[check_setting(setting)])


def _name(model: Any) -> str:
    return getattr(model, "name", repr(model))


def select(obs: dict, model: Any, setting: str = "paper") -> dict:
    """The sub-dict of ``obs`` that ``model`` (a spec, see :func:`visible`) may see; a missing
    key raises ValueError."""
    keys = visible(model, setting)
    missing = [k for k in keys if k not in obs]
    if missing:
        raise ValueError(
            f"observation lacks {missing} needed by model={_name(model)!r} in "
            f"setting={setting!r}; "
            f"got keys {sorted(obs)}"
        )
    return {k: obs[k] for k in keys}


def numeric_size(model: Any, setting: str = "paper", k_targets: int = 10) -> int:
    """Length of :func:`numeric_features` for ``model`` in ``setting``."""
    keys = visible(model, setting)
    return (3 * ("goal" in keys) + 2 * int(k_targets) * ("lane_target" in keys)
            + 2 * ("motion" in keys))


def numeric_features(obs: dict, model: Any, setting: str = "paper", xp: Any = np) -> Any:
    """The numbers a model's dense layers receive, scaled to about unit size: ``(B, F)``.

    Concatenates, in this order and only where ``model`` sees them in
    ``setting``: ``goal / GOAL_SCALE`` (3), ``lane_target / LANE_SCALE``
    flattened (2K), ``motion / MOTION_SCALE`` (2). Returns ``None`` when the
    model sees no numbers.
    """
    keys = visible(model, setting)
    parts = []
    if "goal" in keys:
        parts.append(xp.asarray(obs["goal"]) / xp.asarray(np.asarray(GOAL_SCALE, np.float32)))
    if "lane_target" in keys:
        lt = xp.asarray(obs["lane_target"])
        parts.append(xp.reshape(lt, (lt.shape[0], -1)) / LANE_SCALE)
    if "motion" in keys:
        parts.append(xp.asarray(obs["motion"])
                     / xp.asarray(np.asarray(MOTION_SCALE, np.float32)))
    if not parts:
        return None
    out = xp.concatenate(parts, axis=-1)
    return out


# --------------------------------------------------------------------------- the dataset


def initial_motion(ds: Any) -> np.ndarray:
    """The ego's motion at ``t = 0``, ``(S, 2)`` float32: ``[speed over the first step, 0]``.

    The log starts with the car already moving; its speed is the only thing
    the first control reveals (the yaw rate is set to 0). The closed loop
    starts every policy from this same state.
    """
    c = np.asarray(ds.controls)
    return np.stack([c[:, 0, 0], np.zeros_like(c[:, 0, 0])], axis=-1).astype(np.float32)


DRIVEN_TAG = "driven"
_DRIVEN_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_DRIVEN_ROWS_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_GOAL_BEV_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _per_dataset(cache: weakref.WeakKeyDictionary, ds: Any,
                 build: Callable[[Any], np.ndarray]) -> np.ndarray:
    """``build(ds)``, kept in ``cache`` while ``ds`` lives (built each time for a dataset
    that cannot be weakly referenced)."""
    try:
        cached = cache.get(ds)
    except TypeError:  # not weak-referenceable
        return build(ds)
    if cached is None:
        cached = cache[ds] = build(ds)
    return cached


def driven_rows(ds: Any) -> np.ndarray:
    """``(S,)`` bool: the scenes whose tags hold the controls another policy applied
    (``tags[s]["dagger"]["driven"]``, written by :func:`minimanc.dagger.collect` when the
    applied controls differ from the expert's labels). Cached per dataset (every training
    batch asks)."""
    return _per_dataset(_DRIVEN_ROWS_CACHE, ds, _driven_rows)


def _driven_rows(ds: Any) -> np.ndarray:
    tags = getattr(ds, "tags", None) or [{}] * len(np.asarray(ds.controls))
    return np.array([DRIVEN_TAG in (t.get("dagger") or {}) for t in tags], dtype=bool)


def driven_controls(ds: Any) -> np.ndarray:
    """The controls applied from ``t`` to ``t + 1``, ``(S, T, 2)`` float32: ``ds.controls``
    (a demonstration's labels are what was applied), with each scene of :func:`driven_rows`
    replaced by the ``T − 1`` controls its tags record (its last step, which applies nothing,
    keeps the label). Cached per dataset; ``ValueError`` for a record of the wrong shape or
    a non-finite value (an edited file)."""
    return _per_dataset(_DRIVEN_CACHE, ds, _driven_controls)


def _driven_controls(ds: Any) -> np.ndarray:
    c = np.asarray(ds.controls)
    rows = np.nonzero(driven_rows(ds))[0]
    if rows.size:
        c = c.astype(np.float32, copy=True)
        T = c.shape[1]
        for s in rows:
            d = np.asarray(ds.tags[s]["dagger"][DRIVEN_TAG], dtype=np.float64)
            if d.shape != (T - 1, 2) or not np.all(np.isfinite(d)):
                raise ValueError(f"scene {int(s)}: tags['dagger']['{DRIVEN_TAG}'] must hold "
                                 f"{T - 1} finite [speed, yaw rate] pairs, got shape {d.shape}")
            c[s, :-1] = d
    return c


def motion_at(ds: Any, scene_idx: Any, t_idx: Any) -> np.ndarray:
    """``motion`` of the module docstring for index arrays: the control applied at
    ``t − 1`` (:func:`driven_controls`: ``controls[s, t − 1]`` in a demonstration), or the
    :func:`initial_motion` at ``t = 0``. Returns ``(B, 2)`` float32."""
    s = np.asarray(scene_idx)
    t = np.asarray(t_idx)
    c = driven_controls(ds)
    prev = c[s, np.maximum(t - 1, 0)].astype(np.float32)
    first = initial_motion(ds)[s]
    return np.where((t == 0)[..., None], first, prev).astype(np.float32)


def _dataset_goal_bevs(ds: Any) -> np.ndarray:
    """Goal rasters ``(S, H, W, 3)`` uint8 of a dataset, rendered once and cached."""
    return _per_dataset(_GOAL_BEV_CACHE, ds, _render_goal_bevs)


def _render_goal_bevs(ds: Any) -> np.ndarray:
    given = getattr(ds, "goal_bev", None)
    if given is not None:  # a dataset may carry its goal rasters
        return np.asarray(given)
    S, T = np.asarray(ds.ego).shape[:2]
    cfg = raster_of(ds)
    goal_world = _goal_world(ds)
    return np.stack([rasterize_goal(ds.maps[s], goal_world[s], cfg) for s in range(S)])


def raster_of(ds: Any) -> RasterConfig:
    """The :class:`minimanc.world.RasterConfig` a dataset's ``bev`` was drawn with: its
    ``raster`` (or ``raster_config``), else the default RGB raster of its ``(S, T, H, W, 3)``
    images' rows and columns. Its ``input_shape`` is the shape of ``obs["bev"]``."""
    cfg = getattr(ds, "raster", None) or getattr(ds, "raster_config", None)
    if cfg is None:
        H, W = np.shape(ds.bev)[2:4]
        cfg = RasterConfig(size=int(H), cols=None if W == H else int(W))
    return cfg


def _goal_world(ds: Any) -> np.ndarray:
    """The goal pose in the world frame per scene, ``(S, 3)``: the human's final pose."""
    return np.asarray(ds.ego, dtype=np.float64)[:, -1]


def _as_index(name: str, value: Any, upper: int) -> np.ndarray:
    arr = np.asarray(value)
    if arr.ndim == 0:
        arr = arr[None]
    if arr.ndim != 1 or not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"{name} must be an integer or a 1-D integer array, got {name}={value!r}")
    if arr.size and (arr.min() < 0 or arr.max() >= upper):
        raise ValueError(f"{name} must lie in [0, {upper}), got {name}={value!r}")
    return arr


def from_dataset(
    ds: Any,
    scene_idx: Any,
    t_idx: Any,
    setting: str = "paper",
    model: Any = None,
    *,
    packed: bool = False,
) -> dict:
    """Observations of samples ``(scene_idx[b], t_idx[b])`` of a :mod:`minimanc.world` dataset.

    ``scene_idx`` and ``t_idx`` are integers or equal-length 1-D integer
    arrays (an integer or length-1 array broadcasts against the other).
    With ``model`` (a spec, see :func:`visible`) given, only the keys it sees in ``setting`` are
    returned (``goal_bev`` only for RvS-G: the dataset's own goal rasters, or
    rendered once per dataset); without it, every key except ``goal_bev``.
    ``packed``: a ``"channels"`` raster's ``bev`` and ``goal_bev`` stay as stored, uint8
    ``(B, H, W, ⌈C/8⌉)`` bytes, for a compiled training step to unpack
    (:func:`minimanc.world.encodings.unpack`, equal to the float planes bit for bit); an RGB
    raster's are floats either way.
    """
    check_setting(setting)
    S, T = np.asarray(ds.ego).shape[:2]
    s = _as_index("scene_idx", scene_idx, S)
    t = _as_index("t_idx", t_idx, T)
    if s.shape != t.shape:
        if s.size == 1 or t.size == 1:  # one scene at many times, or many scenes at one time
            s, t = np.broadcast_arrays(s, t)
        else:
            raise ValueError(
                f"scene_idx and t_idx must have the same length, got {s.shape} and {t.shape}"
            )
    keys = visible(model, setting) if model is not None else KEYS[:4]
    obs: dict = {}
    if "bev" in keys or "goal_bev" in keys:
        cfg = raster_of(ds)
        keep = packed and cfg.encoding == "channels"
        as_input = (lambda b: np.asarray(b)) if keep else (lambda b: to_input(b, cfg))
    if "bev" in keys:
        obs["bev"] = as_input(ds.bev[s, t])
    if "goal" in keys:
        obs["goal"] = np.asarray(ds.goal[s, t], dtype=np.float32)
    if "lane_target" in keys:
        obs["lane_target"] = np.asarray(ds.lane_target[s, t], dtype=np.float32)
    if "motion" in keys:
        obs["motion"] = motion_at(ds, s, t)
    if "goal_bev" in keys:
        obs["goal_bev"] = as_input(_dataset_goal_bevs(ds)[s])
    return obs


# --------------------------------------------------------------------------- the closed loop

_STATE_GOAL_BEV: dict = {}


def _goal_bev_from_state(m: Any, goal: np.ndarray, cfg: Any) -> np.ndarray:
    key = (id(m), tuple(np.round(goal, 6)), cfg)
    hit = _STATE_GOAL_BEV.get(key)
    if hit is not None and hit[0] is m:
        return hit[1]
    img = rasterize_goal(m, goal, cfg)
    if len(_STATE_GOAL_BEV) > 4096:
        _STATE_GOAL_BEV.clear()
    _STATE_GOAL_BEV[key] = (m, img)
    return img


def from_state(
    maps: Sequence[Any] | Any,
    ego_poses: Any,
    ado: Any,
    ado_valid: Any,
    goal_world: Any,
    cfg: Any = None,
    setting: str = "paper",
    *,
    motion: Any,
    model: Any = None,
    k_targets: int | None = None,
    keys: Sequence[str] | None = None,
    history: Any = None,
) -> dict:
    """Observations for the closed loop, from the policy's *own* poses.

    ``maps`` (one per row, or one for all), ``ego_poses (B, 3)`` world,
    ``ado (B, A, 5)``, ``ado_valid (B, A)`` (the ados at this time step),
    ``goal_world (B, 3)`` the goal poses in the world, ``cfg`` a
    :class:`minimanc.world.RasterConfig`, and ``motion (B, 2)`` — the policy's
    own previous controls (keyword-only and required: the DMP models start
    from it; at the first step use :func:`initial_motion`). The BEV is
    re-rasterised, the goal and the lane targets (``k_targets`` points,
    default :data:`minimanc.world.lanes.K_TARGETS`) re-expressed from each
    ego pose. ``model`` restricts the keys as in :func:`from_dataset`;
    ``keys`` (a subset of :data:`KEYS`) overrides that choice, e.g. for a
    driver that reads no image (the BEV, the costly part, is then not drawn).
    ``history``: the rows' past boxes (:class:`minimanc.world.history.History`), drawn when
    ``cfg.history > 0``.
    """
    check_setting(setting)
    poses = np.asarray(ego_poses, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"ego_poses must have shape (B, 3), got ego_poses with shape "
                         f"{poses.shape}")
    B = poses.shape[0]
    goals = np.asarray(goal_world, dtype=np.float64)
    if goals.shape != (B, 3):
        raise ValueError(f"goal_world must have shape ({B}, 3), got {goals.shape}")
    mot = np.asarray(motion, dtype=np.float32)
    if mot.shape != (B, 2):
        raise ValueError(f"motion must have shape ({B}, 2), got motion with shape {mot.shape}")
    if isinstance(maps, Map):
        map_list = [maps] * B
    else:
        map_list = [maps[i] for i in range(len(maps))]
        if len(map_list) != B:
            raise ValueError(f"maps must have {B} entries, got {len(map_list)}")
    cfg = cfg if cfg is not None else RasterConfig()
    k = K_TARGETS if k_targets is None else int(k_targets)
    if keys is not None:
        unknown = [k for k in keys if k not in KEYS]
        if unknown:
            raise ValueError(f"keys must be from {KEYS}, got unknown keys {unknown}")
    else:
        keys = visible(model, setting) if model is not None else KEYS[:4]
    obs: dict = {}
    if "bev" in keys:
        bev = rasterize_batch(map_list, poses, ado, ado_valid, cfg, history=history)
        obs["bev"] = to_input(bev, cfg)
    if "goal" in keys:
        obs["goal"] = goal_in_ego_frame(goals, poses).astype(np.float32)
    if "lane_target" in keys:
        obs["lane_target"] = np.stack(
            [lane_targets(map_list[b], poses[b], k) for b in range(B)]
        ).astype(np.float32)
    if "motion" in keys:
        obs["motion"] = mot
    if "goal_bev" in keys:
        obs["goal_bev"] = to_input(np.stack(
            [_goal_bev_from_state(map_list[b], goals[b], cfg) for b in range(B)]), cfg)
    return obs
