"""Chapter 11 — DAgger's data: drive with the β-mixture, label every visited state,
aggregate (:class:`MixturePolicy`, :func:`collect`, :func:`concat`; see :mod:`minimanc.dagger`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from tqdm import tqdm

from minimanc import inputs, models
from minimanc.dagger.perturb import Perturbation
from minimanc.dagger.schedule import check_beta, mix
from minimanc.dagger.teachers import Teacher
from minimanc.rollout import SceneState, drive
from minimanc.world.fileformat import ARRAY_FIELDS, PER_SCENE_KEYS, append_scenes, empty_meta
from minimanc.world.geometry import goal_in_ego_frame
from minimanc.world.history import history_of
from minimanc.world.maps import lane_targets
from minimanc.world.raster import rasterize_batch, rasterize_goal
from minimanc.world.scenes import Dataset

__all__ = ["Collected", "MixturePolicy", "collect", "concat"]


# --------------------------------------------------------------------------- aggregation


def concat(datasets: Sequence[Dataset]) -> Dataset:
    """The scenes of ``datasets`` one after the other: the DAgger aggregate.

    Every array of :data:`minimanc.world.fileformat.ARRAY_FIELDS` is concatenated along
    the scene axis, the per-scene metadata lists likewise; the rest of the metadata
    (seed, raster, dt) is the first dataset's, and all must share steps, raster and ado
    slots (``ValueError`` otherwise).
    """
    if len(datasets) == 0:
        raise ValueError("datasets must hold at least one dataset, got 0")
    first = datasets[0]
    for k, d in enumerate(datasets[1:], start=1):
        for f in ARRAY_FIELDS:
            a, b = np.asarray(getattr(first, f)), np.asarray(getattr(d, f))
            if a.shape[1:] != b.shape[1:] or a.dtype != b.dtype:
                raise ValueError(f"datasets[{k}].{f} has shape {b.shape[1:]} ({b.dtype}) per "
                                 f"scene; datasets[0] has {a.shape[1:]} ({a.dtype})")
    if len(datasets) == 1:
        return first
    arrays = {f: np.concatenate([np.asarray(getattr(d, f)) for d in datasets])
              for f in ARRAY_FIELDS}
    meta = dict(first.meta)
    for key in PER_SCENE_KEYS:
        meta[key] = [x for d in datasets for x in d.meta[key]]
    maps = [d.maps[i] for d in datasets for i in range(len(d))]
    return Dataset(**arrays, maps=maps, meta=meta)


# --------------------------------------------------------------------------- collection


class MixturePolicy:
    """The β-mixture of a policy and a :class:`Teacher` as a :class:`minimanc.rollout.Policy`.

    At every step it records the simulator's state, asks the teacher for its labels,
    asks ``policy`` (skipped when ``beta == 1``) and applies :func:`mix` with one
    uniform draw per row from ``rng``. ``policy=None`` is the expert alone (``beta``
    must then be 1). A row the teacher cannot label is driven by the policy (it stands
    still when the policy is not asked, ``beta = 1``); :func:`collect` does not keep it.
    With ``perturb`` (:class:`~minimanc.dagger.perturb.Perturbation`) its offsets, drawn
    from ``rng`` after the coins, are added to the applied controls (never to the labels).
    A teacher with ``perceive`` (:class:`~minimanc.dagger.teachers.WorldTeacher`) is asked
    through ``label_and_perceive``, and what it perceives is recorded too (``perceived``).
    """

    def __init__(self, policy: Any, teacher: Teacher, sim: Any, beta: float,
                 rng: np.random.Generator, perturb: Perturbation | None = None) -> None:
        self.beta = check_beta(beta)
        if perturb is not None and not isinstance(perturb, Perturbation):
            raise ValueError(f"perturb must be a Perturbation or None, got {perturb!r}")
        self.perturb = perturb
        self._offset: np.ndarray | None = None
        if policy is None and self.beta != 1.0:
            raise ValueError(f"without a policy only the expert can drive: beta must be 1, "
                             f"got beta={beta!r}")
        self.policy, self.teacher, self.sim, self.rng = policy, teacher, sim, rng
        self.model = getattr(policy, "model", None)
        self.setting = getattr(policy, "setting", "paper")
        if policy is None or self.beta == 1.0:
            self.keys: tuple[str, ...] = ()
        elif getattr(policy, "keys", None) is not None:
            self.keys = tuple(policy.keys)
        else:
            self.keys = inputs.visible(models.get(policy.model), policy.setting)
        self.states: list[SceneState] = []
        self.labels: list[np.ndarray] = []
        self.applied: list[np.ndarray] = []
        self.refused: list[list[str | None]] = []
        self.perceived: list[tuple[np.ndarray, np.ndarray]] = []
        self.expert_steps = 0
        self._prev: np.ndarray | None = None

    def initial_state(self, scenes: np.ndarray) -> Any:
        return None if self.policy is None else self.policy.initial_state(scenes)

    def record(self, t: int) -> np.ndarray:
        """Record the current state and its labels (also used after the last step)."""
        self.states.append(self.sim.observe())
        if getattr(self.teacher, "perceive", None) is not None:
            labels, why, seen = self.teacher.label_and_perceive(self.sim, t, self._prev)
            self.perceived.append(seen)
        else:
            labels, why = self.teacher.label(self.sim, t, self._prev)
        self.labels.append(labels)
        self.refused.append(why)
        return labels

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        labels = self.record(t)
        u = self.rng.random(len(scenes))
        ok = np.all(np.isfinite(labels), axis=1)
        if self.policy is None or self.beta == 1.0:
            controls = np.where(ok[:, None], labels, 0.0)
        else:
            mine, state, _ = self.policy(obs, state, t, scenes)
            controls = mix(np.where(ok[:, None], labels, mine), mine, self.beta, u)
        if self.perturb is not None:
            if self._offset is None:
                self._offset = np.zeros((len(scenes), 2))
            self._offset = self.perturb.step(self._offset, self.rng)
            controls = self.perturb.apply(controls, self._offset)
        self.expert_steps += int(np.sum((u < self.beta) & ok))
        self._prev = np.asarray(controls, dtype=np.float64)
        self.applied.append(self._prev.astype(np.float32))
        return controls, state, {}


@dataclass
class Collected:
    """What :func:`collect` returns: ``data`` the labelled scenes (``None`` when every row
    was refused), ``scenes`` the pool scenes driven, ``kept`` the rows aggregated,
    ``labelled`` the samples the expert was asked for (all rows, kept or not),
    ``expert_share`` the fraction of the decisions the expert's control was applied,
    ``refusals`` one message per refused row, ``perceived`` (with a teacher that perceives)
    what the expert perceived in every state of ``data``: ``(values (S, T, K), mask
    (S, T, K))``, its rows those of ``data``."""

    data: Dataset | None
    scenes: np.ndarray
    kept: np.ndarray
    labelled: int
    expert_share: float
    refusals: list[str] = field(default_factory=list)
    perceived: tuple[np.ndarray, np.ndarray] | None = None


def _rows_to_scenes(pool: Dataset, scenes: np.ndarray, states: list[SceneState],
                    labels: np.ndarray, applied: np.ndarray, tags: dict
                    ) -> tuple[list[dict], dict]:
    """Dataset scenes (the fields of :data:`ARRAY_FIELDS`) of the driven rows; a row whose
    applied controls ``(T − 1, B, 2)`` differ from its labels records them in its tags
    (:data:`minimanc.inputs.DRIVEN_TAG`)."""
    cfg, K = pool.raster, int(np.asarray(pool.lane_target).shape[2])
    T = len(states)
    out = []
    for b, s in enumerate(scenes):
        ego32 = np.stack([st.pose[b] for st in states]).astype(np.float32)
        ego = ego32.astype(np.float64)
        valid = np.stack([np.asarray(st.ado_valid[b], bool) for st in states])
        ado32 = np.where(valid[..., None], np.stack([st.ado[b] for st in states]),
                         0.0).astype(np.float32)
        maps = [st.maps[b] for st in states]
        goal = np.asarray(states[0].goal[b], dtype=np.float64)
        lt = np.stack([lane_targets(maps[t], ego[t], K) for t in range(T)])
        ado64 = ado32.astype(np.float64)
        past = history_of(ego, ado64, valid, cfg.history) if cfg.history else None
        out.append({
            "bev": rasterize_batch(maps, ego, ado64, valid, cfg, history=past),
            "ego": ego32,
            "controls": labels[:, b].astype(np.float32),
            "goal": goal_in_ego_frame(np.broadcast_to(goal, ego.shape), ego).astype(np.float32),
            "lane_target": lt.astype(np.float32),
            "ado": ado32,
            "ado_valid": valid,
            "goal_bev": rasterize_goal(pool.maps[int(s)], goal, cfg),
        })
    meta = empty_meta(int(pool.meta.get("seed", 0)), cfg)
    for key in ("source",):
        if key in pool.meta:
            meta[key] = pool.meta[key]
    labels32 = labels.astype(np.float32)
    driven = [{} if np.array_equal(applied[:, b], labels32[:-1, b])
              else {inputs.DRIVEN_TAG: applied[:, b].tolist()} for b in range(len(scenes))]
    append_scenes(meta, [pool.meta["recipes"][int(s)] for s in scenes],
                  [{**pool.tags[int(s)], "dagger": {**tags, "pool_scene": int(s), **d}}
                   for s, d in zip(scenes, driven, strict=True)],
                  [pool.meta["attempts"][int(s)] for s in scenes],
                  [pool.meta["scene_index"][int(s)] for s in scenes])
    return out, meta


def collect(policy: Any, teacher: Teacher, scenes: Any, beta: float, seed: Any = 0,
            progress: bool = False, tags: dict | None = None,
            perturb: Perturbation | None = None) -> Collected:
    """Drive pool scenes ``scenes`` with the β-mixture of ``policy`` and ``teacher``
    (:class:`MixturePolicy`) and label every visited state with the expert's controls.

    Each scene is driven for ``T − 1`` decisions (``T`` = the pool's steps) from its
    logged start and its ``T`` visited states are labelled (the last one after the last
    decision), so a scene is ``T`` labelled samples like a demonstration. The coin of
    row ``b`` at step ``t`` comes from ``numpy.random.default_rng(seed)`` (one stream
    per batch of :meth:`Teacher.groups`, drawn in order). ``tags`` are added to the
    scenes' metadata tags under ``"dagger"``; so are the controls that were applied, when
    they differ from the labels (``"driven"``, ``T − 1`` pairs): the ``motion`` a model
    sees in those states (:func:`minimanc.inputs.driven_controls`). ``perturb`` adds a
    :class:`~minimanc.dagger.perturb.Perturbation` to the applied controls: with
    ``policy=None, beta=1`` these are perturbed demonstrations (one stream of offsets per
    batch, from the same generator as the coins). With a teacher that perceives
    (``perceive``), :attr:`Collected.perceived` holds what it perceived in the kept states.
    """
    beta = check_beta(beta)
    pool = teacher.pool
    idx = np.atleast_1d(np.asarray(scenes))
    if idx.ndim != 1 or idx.size == 0 or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"scenes must be a non-empty 1-D array of pool indices, got {scenes!r}")
    if idx.min() < 0 or idx.max() >= len(pool):
        raise ValueError(f"scenes must lie in [0, {len(pool)}), got scenes={scenes!r}")
    T = pool.n_steps
    groups = teacher.groups(idx)
    bar = None
    if progress:
        bar = tqdm(total=len(groups) * T, desc=f"dagger drive (beta {beta:.3f})", unit="step",
                   leave=False)
    rng = np.random.default_rng(seed)
    extra = {} if perturb is None else {"perturb": asdict(perturb)}
    built, metas, kept, refusals, steps, expert = [], [], [], [], 0, 0
    seen_values, seen_mask = [], []
    try:
        for group in groups:
            sim = teacher.simulator(group)
            mixer = MixturePolicy(policy, teacher, sim, beta, rng, perturb)
            drive(mixer, sim, T - 1, None if bar is None else lambda t: bar.update(1))
            mixer.record(T - 1)
            if bar is not None:
                bar.update(1)
            if hasattr(sim, "finish"):
                sim.finish()
            labels = np.stack(mixer.labels)  # (T, B, 2)
            ok = np.all(np.isfinite(labels), axis=(0, 2))
            for b in np.nonzero(~ok)[0]:
                why = next(w for w in (r[b] for r in mixer.refused) if w is not None)
                refusals.append(f"scene {int(group[b])}: {why}")
            steps += (T - 1) * len(group)
            expert += mixer.expert_steps
            if ok.any():
                rows = np.nonzero(ok)[0]
                applied = np.stack(mixer.applied)[:, rows]  # (T - 1, B, 2)
                sc, meta = _rows_to_scenes(pool, group[rows],
                                           [_take(st, rows) for st in mixer.states],
                                           labels[:, rows], applied,
                                           {**(tags or {}), "beta": beta, **extra})
                built += sc
                metas.append(meta)
                kept += [int(group[r]) for r in rows]
                if mixer.perceived:  # (T, B, K) → the kept rows' (B', T, K)
                    seen_values.append(np.stack([v[rows] for v, _ in mixer.perceived], axis=1))
                    seen_mask.append(np.stack([m[rows] for _, m in mixer.perceived], axis=1))
    finally:
        if bar is not None:
            bar.close()
    data, perceived = None, None
    if seen_values:
        perceived = (np.concatenate(seen_values), np.concatenate(seen_mask))
    if built:
        meta = metas[0]
        for m in metas[1:]:
            for key in PER_SCENE_KEYS:
                meta[key] += m[key]
        data = Dataset.build(built, meta, maps=[pool.maps[s] for s in kept],
                             what="dagger scenes")
    return Collected(data, idx, np.asarray(kept, dtype=np.int64), int(idx.size * T),
                     expert / max(steps, 1), refusals, perceived)


def _take(st: SceneState, rows: np.ndarray) -> SceneState:
    return SceneState([st.maps[r] for r in rows], st.pose[rows], st.ado[rows],
                      st.ado_valid[rows], st.goal[rows])
