"""Chapter 11 in the study — ``minimanc reproduce --dagger``: behaviour cloning against
DAgger (:mod:`minimanc.dagger`) at equal expert-labelled samples, on the study's own data.

The pool is the study's training split, the evaluation its validation split, the teacher
the world's human driver (:class:`minimanc.dagger.WorldTeacher`) under the study's first
protocol for the ados. Per model and seed: DAgger with ``rounds`` rounds after the
demonstrations (β_i = ``beta``^i) and behaviour cloning on the same number of labels,
each with the model's tuned learning rate and the study's training configuration (with
``perception_weight`` > 0 both learn the auxiliary loss: behaviour cloning on the
demonstrations' targets, DAgger also on what the teacher perceives in the states it
collects). Rounds are checkpointed under the study's cache, so a rerun resumes.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from minimanc import dagger, diagnose, metrics, train
from minimanc.checks import check_int
from minimanc.viz.dagger import plot_study_rounds
from minimanc.viz.style import METRIC_LABELS, pyplot

__all__ = ["DAGGER_METRICS", "dagger_figures", "dagger_markdown", "run_dagger"]

DAGGER_METRICS: tuple[str, ...] = ("ade", "goal_distance", "collision_rate",
                                   "at_fault_collision_rate", "off_road_rate")
"""The metrics of the DAgger table and figures."""


def run_dagger(study: Any, models: Sequence[str] = ("manc", "cnn"), rounds: int = 3,
               beta: float = 0.5) -> dict:
    """BC and DAgger for each of ``models`` and each seed of ``study``.

    Parameters
    ----------
    study : minimanc.studies.Study
        Its data, seeds, tuned learning rates, engine, first protocol and cache are used.
    models : sequence of str
        Registered models.
    rounds : int
        DAgger rounds after the demonstrations (≥ 1).
    beta : float
        ``p`` of the schedule ``β_i = p^i``.

    Returns
    -------
    dict
        ``agents``, ``rounds``, ``beta``, ``labelled`` (samples per method) and
        ``models``: ``{model: {"bc": aggregate, "dagger": aggregate of the last round,
        "by_round": [aggregate per round]}}`` (:func:`minimanc.metrics.aggregate` over
        the seeds).
    """
    rounds = check_int("rounds", rounds, 1)
    train_ds, _, val = study.datasets()
    agents = study.agents[0]
    targets, perceive = None, None
    if study.config.training.perception_weight > 0:
        targets = train.load_targets(study.files.perception_targets())
        perceive = partial(diagnose.state_targets, view=train_ds.raster)
    teacher = dagger.WorldTeacher(train_ds, val, agents=agents, perceive=perceive)
    T = int(np.asarray(train_ds.ego).shape[1])
    budget = dagger.plan_budget(len(train_ds) * T, T, rounds)
    out: dict = {"agents": agents, "rounds": rounds, "beta": float(beta),
                 "labelled": int(budget.used), "models": {}}
    for model in models:
        lr = study.sweeps.lr(model, "paper")
        bcs, lasts, per_round = [], [], []
        for seed in study.config.seeds:
            cfg = dagger.default_config(train_ds, n_states=study.config.n_states)
            tc = study.config.train_config(model, lr, seed, 1.0)
            base = study.files.dir / "dagger" / f"{model}-s{seed}"
            common = dict(cfg=cfg, train_cfg=tc, engine=study.engine, seed=seed,
                          progress=study.progress, perception=targets)
            bc = dagger.behaviour_cloning(model, teacher, budget, rounds, out=base / "bc",
                                          **common)
            res = dagger.dagger(model, teacher, budget, rounds, beta, out=base / "dagger",
                                **common)
            bcs.append(bc.metrics)
            lasts.append(res.rounds[-1].metrics)
            per_round.append([r.metrics for r in res.rounds])
            study.log(f"dagger: {model} seed {seed} done")
        out["models"][model] = {
            "bc": metrics.aggregate(bcs),
            "dagger": metrics.aggregate(lasts),
            "by_round": [metrics.aggregate([pr[i] for pr in per_round])
                         for i in range(rounds + 1)],
        }
    return out


def _cell(agg: dict, key: str, n: int) -> str:
    e = agg.get(key)
    if e is None or not np.isfinite(e["mean"]):
        return "n/a"
    return f"{e['mean']:.2f} ± {e['std']:.2f}" if n > 1 else f"{e['mean']:.2f}"


def dagger_markdown(res: dict, n_seeds: int, label: Any = str) -> list[str]:
    """The ``table1.md`` section of :func:`run_dagger`'s result (a list of lines)."""
    keys = [k for k in DAGGER_METRICS
            if all(k in m["bc"] for m in res["models"].values())]
    lines = [f"## BC against DAgger at equal labels (agents `{res['agents']}`)", "",
             f"{res['rounds']} DAgger rounds after the demonstrations (β_i = "
             f"{res['beta']:g}^i), {res['labelled']} expert-labelled samples for both "
             "methods, the study's training split as the pool (`minimanc.dagger`).", "",
             "| Model | method | " + " | ".join(METRIC_LABELS.get(k, k) for k in keys) + " |",
             "|---" * (len(keys) + 2) + "|"]
    for model, m in res["models"].items():
        for method in ("bc", "dagger"):
            name = "BC" if method == "bc" else "DAgger"
            lines.append(f"| {label(model)} | {name} | "
                         + " | ".join(_cell(m[method], k, n_seeds) for k in keys) + " |")
    lines.append("")
    return lines


def dagger_figures(res: dict, figdir: Path) -> list[Path]:
    """One figure per metric (:func:`minimanc.viz.dagger.plot_study_rounds`): DAgger's value
    by round, BC as a horizontal line."""
    figdir.mkdir(parents=True, exist_ok=True)
    paths = []
    for key in DAGGER_METRICS:
        if not all(key in m["bc"] for m in res["models"].values()):
            continue
        fig = plot_study_rounds(res, key)
        path = figdir / f"dagger_{key}.png"
        fig.savefig(path, dpi=120, bbox_inches="tight")
        pyplot().close(fig)
        paths.append(path)
    return paths
