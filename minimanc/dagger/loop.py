"""Chapter 11 — the DAgger loop with checkpoints per round and behaviour cloning at the same
label budget (see :mod:`minimanc.dagger`; the metric-vs-round figure is
:func:`minimanc.viz.dagger.plot_rounds`)."""

from __future__ import annotations

import copy
import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from minimanc import inputs, models, train
from minimanc.checks import check_int
from minimanc.dagger.aggregate import Collected, collect, concat
from minimanc.dagger.schedule import Budget, beta_schedule, check_beta, plan_budget
from minimanc.dagger.teachers import SIMS, Teacher
from minimanc.engine import ENGINES
from minimanc.rollout import ModelPolicy
from minimanc.world.datareader import load
from minimanc.world.datawriter import save
from minimanc.world.scenes import Dataset

__all__ = ["FINGERPRINT_FILE", "PERCEPTION_FILE", "ROUND_FILE", "DaggerResult", "RoundResult",
           "behaviour_cloning", "dagger", "default_config", "round_dir", "scene_order"]

ROUND_FILE = "round.json"
"""The file that marks a round as complete (written last, atomically)."""


# --------------------------------------------------------------------------- the loop


@dataclass
class RoundResult:
    """One round: ``round`` (0 = BC), ``beta``, ``scenes`` the pool scenes it added,
    ``kept`` the ones aggregated, ``labelled`` samples labelled so far (rounds
    ``0 … round``), ``samples`` in the aggregate it trained on, ``expert_share``,
    ``refusals``, ``metrics`` of :meth:`Teacher.evaluate`, ``history`` the training
    losses, ``seconds`` the wall time, ``loaded`` whether it came from a checkpoint and
    ``params`` the trained parameters (not part of :meth:`to_json`)."""

    round: int
    beta: float
    scenes: list[int]
    kept: list[int]
    labelled: int
    samples: int
    expert_share: float
    metrics: dict[str, float]
    history: list[float]
    seconds: float
    refusals: list[str] = field(default_factory=list)
    loaded: bool = False
    params: dict | None = field(default=None, repr=False)

    def to_json(self) -> dict:
        return {f.name: copy.deepcopy(getattr(self, f.name)) for f in fields(self)
                if f.name not in ("loaded", "params")}


@dataclass
class DaggerResult:
    """What :func:`dagger` returns: the :class:`RoundResult` of every round, the
    :class:`Budget`, the final parameters and the configuration it ran with."""

    name: str
    rounds: list[RoundResult]
    budget: Budget
    params: dict
    cfg: Any
    train_cfg: Any
    params_per_round: list[dict] = field(default_factory=list)

    def table(self, keys: Sequence[str] = ("ade", "collision_rate")) -> str:
        """A markdown table: one row per round (β, labelled samples, metrics)."""
        head = "| round | beta | labelled | samples | " + " | ".join(keys) + " |"
        rows = [head, "|" + "---|" * (4 + len(keys))]
        for r in self.rounds:
            vals = " | ".join(f"{r.metrics[k]:.2f}" if k in r.metrics else "-" for k in keys)
            rows.append(f"| {r.round} | {r.beta:.3f} | {r.labelled} | {r.samples} | {vals} |")
        return "\n".join(rows)


def default_config(pool: Dataset, **kw: Any) -> Any:
    """The :class:`~minimanc.models.ModelConfig` that fits ``pool``: its BEV planes'
    ``input_shape`` (its raster's) and lane-target points (``kw`` sets other fields)."""
    return models.ModelConfig(input_shape=inputs.raster_of(pool).input_shape,
                              k_targets=int(np.asarray(pool.lane_target).shape[2]), **kw)


def round_dir(out: str | os.PathLike, i: int) -> Path:
    """The folder of round ``i`` under ``out``: ``out/round_<i:03d>``."""
    return Path(out) / f"round_{check_int('i', i, 0):03d}"


def _atomic_json(path: Path, obj: dict) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(obj, indent=1, sort_keys=True))
    os.replace(tmp, path)


def _fingerprint(name: str, teacher: Teacher, budget: Budget, betas: list[float], cfg: Any,
                 tc: Any, seed: int, engine: str) -> dict:
    return {"model": name, "sim": teacher.name, "agents": getattr(teacher, "agents", None),
            "pool": len(teacher.pool), "pool_seed": teacher.pool.meta.get("seed"),
            "steps": budget.steps,
            "betas": betas, "cfg": asdict(cfg), "train_cfg": asdict(tc), "seed": int(seed),
            "engine": engine}


def _check_common(name: Any, teacher: Any, engine: Any) -> tuple[str, str]:
    name = models.check_name(name)
    if getattr(teacher, "name", None) not in SIMS or not hasattr(teacher, "label"):
        raise ValueError(f"teacher must be a WorldTeacher or HighwayTeacher, got {teacher!r}")
    eng_name = engine if isinstance(engine, str) else getattr(engine, "name", None)
    if eng_name not in ENGINES:
        raise ValueError(f"engine must be one of {ENGINES}, got engine={engine!r}")
    return name, eng_name


def scene_order(n: int, seed: int) -> np.ndarray:
    """The pool's scene order of a study: one seeded permutation shared by BC and DAgger."""
    return np.random.default_rng([int(seed), 11]).permutation(n)


def _budget_for(teacher: Teacher, budget: int | Budget, rounds: int) -> Budget:
    T = teacher.pool.n_steps
    b = budget if isinstance(budget, Budget) else plan_budget(check_int("budget", budget, 1),
                                                              T, rounds)
    if not isinstance(b, Budget) or b.steps != T or b.rounds != rounds:
        raise ValueError(f"budget plans {b.rounds} rounds of {b.steps}-step scenes; the pool's "
                         f"scenes have {T} steps and {rounds} rounds are asked")
    if b.scenes > len(teacher.pool):
        raise ValueError(f"budget needs {b.scenes} scenes but the pool holds {len(teacher.pool)}")
    return b


def _train(name: str, data: Dataset, cfg: Any, tc: Any, engine: Any, where: Path | None,
           progress: bool, params: dict | None = None,
           perception: train.PerceptionTargets | None = None) -> Any:
    return train.fit(name, data, cfg, tc, engine=engine, checkpoint_dir=where,
                     resume=where is not None, progress=progress, params=params,
                     perception=perception)


PERCEPTION_FILE = "perception.npz"
"""What the expert perceived in a round's collected states (beside its ``data.npz``)."""


def _check_perception(perception: Any, teacher: Teacher) -> train.PerceptionTargets | None:
    """``perception`` (the targets of every pool scene) usable with ``teacher``, or None."""
    if perception is None:
        return None
    if not isinstance(perception, train.PerceptionTargets):
        raise ValueError(f"perception must be minimanc.train.PerceptionTargets or None, got "
                         f"{type(perception).__name__}")
    if getattr(teacher, "perceive", None) is None:
        raise ValueError("perception targets need a teacher that perceives the states DAgger "
                         "visits: WorldTeacher(pool, perceive=...), e.g. "
                         "minimanc.diagnose.state_targets")
    pool = teacher.pool
    if np.shape(perception.values)[:2] != (len(pool), pool.n_steps):
        raise ValueError(f"perception covers (S, T) = {np.shape(perception.values)[:2]}; the "
                         f"pool has {(len(pool), pool.n_steps)}")
    return perception


FINGERPRINT_FILE = "fingerprint.json"
"""The configuration a round folder belongs to (written before the round starts)."""


def _load_round(where: Path, fp: dict) -> tuple[RoundResult, dict] | None:
    """The finished round in ``where`` (``None`` if unfinished); claims the folder for ``fp``:
    a folder started or finished by another configuration is a ``ValueError`` (its data
    and checkpoint must not be mixed into this run)."""
    fp = json.loads(json.dumps(fp))
    claim = where / FINGERPRINT_FILE
    f = where / ROUND_FILE
    for path in (claim, f):
        if path.exists():
            saved = json.loads(path.read_text())
            if saved.get("fingerprint", saved) != fp:
                raise ValueError(f"{where} holds a round of another configuration; use another "
                                 "out directory or delete it")
    where.mkdir(parents=True, exist_ok=True)
    if not claim.exists():
        _atomic_json(claim, fp)
    if not f.exists():
        return None
    saved = json.loads(f.read_text())
    res = train.load_fit(where / "checkpoint.npz")
    r = RoundResult(**saved["result"], loaded=True, params=res.params)
    return r, res.params


def dagger(name: str, teacher: Teacher, budget: int | Budget, rounds: int = 3,
           beta: float | Sequence[float] = 0.5, cfg: Any = None, train_cfg: Any = None,
           engine: Any = "jax", out: str | os.PathLike | None = None, seed: int = 0,
           progress: bool = True, evaluate: bool = True,
           on_round: Callable[[RoundResult], None] | None = None,
           round_cfg: Any = None, perception: Any = None) -> DaggerResult:
    """DAgger for model ``name`` (any of :func:`minimanc.models.names`) with ``teacher``.

    ``budget`` the expert-labelled samples (an int for :func:`plan_budget` over
    ``rounds``, or a :class:`Budget`); ``rounds ≥ 1`` DAgger rounds after round 0
    (BC); ``beta`` the ``p`` of :func:`beta_schedule`, or the list of ``rounds + 1``
    weights itself (``β_0`` must be 1); ``cfg`` / ``train_cfg`` the model's
    :class:`~minimanc.models.ModelConfig` (default: the pool's image size) and
    :class:`~minimanc.train.TrainConfig`, used for every round (each trains from the
    same initialisation on the aggregate, as Ross et al. train a new policy per round);
    ``round_cfg`` a :class:`~minimanc.train.TrainConfig` for rounds ``≥ 1`` that instead
    continue from the previous round's parameters (a fresh Adam state) on the aggregate:
    with one epoch per round the rounds together take about as many gradient steps as
    behaviour cloning on the pool; ``engine`` "jax" or "numpy"; ``out`` the
    checkpoint folder (see the module docstring); ``seed`` the scene order and the
    mixture's coins (round ``i`` draws from ``default_rng([seed, i])``);
    ``evaluate`` runs :meth:`Teacher.evaluate` after each round; ``on_round`` is
    called with each finished round; ``perception`` the
    :class:`~minimanc.train.PerceptionTargets` of every pool scene, for a ``train_cfg``
    with ``perception_weight`` > 0: round 0 trains with those of its demonstrations, every
    later round also with what the teacher (its ``perceive``) perceived in the states it
    collected (saved as ``perception.npz`` beside the round's data); the auxiliary loss's
    read-out starts afresh in each round.
    """
    name, eng_name = _check_common(name, teacher, engine)
    rounds = check_int("rounds", rounds, 1)
    if isinstance(beta, Sequence) and not isinstance(beta, str):
        betas = [check_beta(b, f"beta[{i}]") for i, b in enumerate(beta)]
        if len(betas) != rounds + 1 or betas[0] != 1.0:
            raise ValueError(f"beta as a schedule must hold rounds + 1 = {rounds + 1} weights "
                             f"starting with 1.0 (round 0 is BC), got beta={list(beta)!r}")
    else:
        betas = beta_schedule(check_beta(beta), rounds)
    plan = _budget_for(teacher, budget, rounds)
    pool = teacher.pool
    cfg = cfg or default_config(pool)
    tc = train_cfg or train.TrainConfig()
    if round_cfg is not None and not isinstance(round_cfg, train.TrainConfig):
        raise ValueError(f"round_cfg must be a minimanc.train.TrainConfig or None; got "
                         f"round_cfg={round_cfg!r}")
    seed = check_int("seed", seed, 0)
    perception = _check_perception(perception, teacher)
    order = scene_order(len(pool), seed)
    # "motion": the aggregate records the applied controls (inputs.driven_controls)
    fp = {**_fingerprint(name, teacher, plan, betas[:1], cfg, tc, seed, eng_name),
          "motion": "driven"}
    if round_cfg is not None:
        fp["round_cfg"] = asdict(round_cfg)
    if perception is not None:
        fp["perception"] = list(perception.names)
    results: list[RoundResult] = []
    per_round: list[dict] = []
    parts: list[Dataset] = []
    seen: list[train.PerceptionTargets] = []
    params = None
    bar = None
    if progress:
        bar = tqdm(total=rounds + 1, desc=f"dagger {name}", unit="round")
    try:
        for i in range(rounds + 1):
            t0 = time.perf_counter()
            a, b = plan.round_scenes(i)
            scenes = order[a:b]
            where = None if out is None else round_dir(out, i)
            fp_i = {**fp, "betas": betas[:i + 1],
                    "round_plan": [plan.initial, *plan.per_round[:i]]}
            loaded = _load_round(where, fp_i) if where is not None else None
            new_seen = None
            if i == 0:
                new = pool.subset(np.sort(scenes))
                col = Collected(new, scenes, np.sort(scenes), int(len(scenes) * plan.steps), 1.0)
                if perception is not None:
                    new_seen = perception.subset(np.sort(scenes))
            elif loaded is not None or (where is not None and (where / "data.npz").exists()):
                new = load(where / "data.npz") if (where / "data.npz").exists() else None
                if new is not None and perception is not None:
                    new_seen = train.load_targets(where / PERCEPTION_FILE)
                col = None
            else:
                policy = ModelPolicy(name, params, cfg, engine)
                col = collect(policy, teacher, scenes, betas[i], seed=[seed, i],
                              progress=progress, tags={"round": i})
                new = col.data
                if new is not None and perception is not None:
                    new_seen = replace(perception, values=col.perceived[0],
                                       mask=col.perceived[1])
                if where is not None and new is not None:
                    if new_seen is not None:  # before the data: data.npz marks both saved
                        train.save_targets(new_seen, where / PERCEPTION_FILE)
                    save(new, where / "data.npz")
            if new is not None:
                parts.append(new)
                if new_seen is not None:
                    seen.append(new_seen)
            data = concat(parts)
            if loaded is not None:
                r, params = loaded
            else:
                warm = i > 0 and round_cfg is not None
                fit = _train(name, data, cfg, round_cfg if warm else tc, engine, where,
                             progress, params if warm else None,
                             train.concat_targets(seen) if seen else None)
                params = fit.params
                if col is None:  # data collected by a killed run: its stats are in its tags
                    kept = [] if new is None else [t["dagger"]["pool_scene"] for t in new.tags]
                    col = Collected(new, scenes, np.asarray(kept), int(len(scenes) * plan.steps),
                                    float("nan"))
                m = teacher.evaluate(ModelPolicy(name, params, cfg, engine),
                                     progress) if evaluate else {}
                r = RoundResult(i, betas[i], [int(s) for s in scenes],
                                [int(s) for s in col.kept], plan.labelled(i),
                                len(data) * plan.steps,
                                float(col.expert_share), {k: float(v) for k, v in m.items()},
                                [float(x) for x in fit.history], time.perf_counter() - t0,
                                list(col.refusals))
                if where is not None:
                    _atomic_json(where / ROUND_FILE, {"fingerprint": fp_i, "result": r.to_json()})
            r.params = params
            results.append(r)
            per_round.append(params)
            if on_round is not None:
                on_round(r)
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return DaggerResult(name, results, plan, params, cfg, tc, per_round)


def behaviour_cloning(name: str, teacher: Teacher, budget: int | Budget, rounds: int = 3,
                      cfg: Any = None, train_cfg: Any = None, engine: Any = "jax",
                      out: str | os.PathLike | None = None, seed: int = 0,
                      progress: bool = True, evaluate: bool = True,
                      perception: Any = None) -> RoundResult:
    """Behaviour cloning with DAgger's budget: trained on the first :attr:`Budget.scenes`
    demonstrations of the pool's scene order (the scenes :func:`dagger` drives with the
    same ``budget``, ``rounds`` and ``seed``), so both use :attr:`Budget.used` labelled
    samples; with ``perception`` (as :func:`dagger`'s) the auxiliary loss on their
    targets. Checkpointed in ``out/bc`` and loaded from there on a rerun."""
    name, eng_name = _check_common(name, teacher, engine)
    rounds = check_int("rounds", rounds, 1)
    plan = _budget_for(teacher, budget, rounds)
    pool = teacher.pool
    cfg = cfg or default_config(pool)
    tc = train_cfg or train.TrainConfig()
    seed = check_int("seed", seed, 0)
    perception = _check_perception(perception, teacher)
    scenes = scene_order(len(pool), seed)[:plan.scenes]
    fp = {**_fingerprint(name, teacher, plan, [1.0], cfg, tc, seed, eng_name), "bc": plan.scenes}
    if perception is not None:
        fp["perception"] = list(perception.names)
    where = None if out is None else Path(out) / "bc"
    loaded = _load_round(where, fp) if where is not None else None
    if loaded is not None:
        return loaded[0]
    t0 = time.perf_counter()
    data = pool.subset(np.sort(scenes))
    fit = _train(name, data, cfg, tc, engine, where, progress, None,
                 None if perception is None else perception.subset(np.sort(scenes)))
    m = teacher.evaluate(ModelPolicy(name, fit.params, cfg, engine), progress) if evaluate else {}
    r = RoundResult(0, 1.0, [int(s) for s in scenes], sorted(int(s) for s in scenes), plan.used,
                    plan.used, 1.0, {k: float(v) for k, v in m.items()},
                    [float(x) for x in fit.history], time.perf_counter() - t0,
                    params=fit.params)
    if where is not None:
        _atomic_json(where / ROUND_FILE, {"fingerprint": fp, "result": r.to_json()})
    return r
