"""Chapter 9 — the figures of a finished study (Table I per protocol of the ados, per
scenario family, Fig. 5a/5b, 7, 8 as PNGs), the speed of every model against the human's,
and the explainability figures of the MANC run, on validation scenes chosen by rule
(:func:`pick_scenes`, :func:`saliency_steps`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from minimanc import rollout, train
from minimanc.studies.runner import Study
from minimanc.viz.explain import (
    plot_explain_trace,
    plot_q_modes,
    plot_saliency_steps,
    plot_speeds,
    plot_trajectories,
    save_rollout_gif,
)
from minimanc.viz.study import (
    plot_ablation,
    plot_families,
    plot_param_counts,
    plot_q_states,
    plot_sample_efficiency,
    plot_table1,
)
from minimanc.viz.style import save_figure


def write_figures(study: Study, results: dict, figdir: Path) -> list[Path]:
    """Every PNG (and the GIF) of a finished study; returns the paths. A study of no models
    (``StudyConfig.sample_models`` or ``ablation_models`` empty) has no figure."""
    paths = []
    for agents, t1 in results["table1"].items():
        paths.append(save_figure(plot_table1(t1), figdir / f"table1_{agents}.png"))
    for agents, by_setting in results.get("families", {}).items():
        setting = "paper" if "paper" in by_setting else next(iter(by_setting))
        title = f"Per scenario family ({agents} agents, setting {setting}); lower is better"
        paths.append(save_figure(plot_families(by_setting[setting], title=title),
                                figdir / f"families_{agents}.png"))
    if results["sample_efficiency"]["models"]:
        paths.append(save_figure(plot_sample_efficiency(results["sample_efficiency"]),
                                 figdir / "sample_efficiency.png"))
    paths += [
        save_figure(plot_param_counts(results["param_counts"]["paper"]),
                   figdir / "param_counts.png"),
        save_figure(plot_q_states(results["q_states"]), figdir / "q_states.png"),
    ]
    if results["ablation"]["models"]:
        paths.append(save_figure(plot_ablation(results["ablation"]), figdir / "ablation.png"))
    paths += write_speeds(study, figdir)
    paths += write_explanations(study, figdir)
    return paths


def write_speeds(study: Study, figdir: Path, k: int = 3) -> list[Path]:
    """Speed over time, each Table I model (paper setting, seed 0, primary protocol)
    against the human, on ``k`` scenes picked by :func:`pick_scenes`."""
    c = study.config
    _, _, val = study.datasets()
    trajs = {}
    for m in c.table_models:
        run = study.runs(m, "paper")[0]
        if "error" not in study.result(run):
            trajs[m] = study.rollout(run)
    if not trajs:
        return []
    scenes = pick_scenes(val, next(iter(trajs.values())), min(k, len(val)))
    fig = plot_speeds(trajs, rollout.human(val), scenes)
    return [save_figure(fig, figdir / f"speeds_{study.primary}.png")]


def write_explanations(study: Study, figdir: Path) -> list[Path]:
    """Explainability figures for a few validation scenes of the MANC run (paper, seed 0):
    the closed-loop trace and saliency, a GIF, and the open-loop q above the human's mode."""
    c = study.config
    if c.explain_scenes == 0:
        return []
    _, _, val = study.datasets()
    run = study.explain_run()
    if "error" in study.result(run):
        study.log(f"figures: no explanations, the closed loop of {run.key} failed")
        return []
    traj = study.rollout(run)
    fit = train.load_fit(study.checkpoint(run))
    human = rollout.human(val)
    scenes = pick_scenes(val, traj, c.explain_scenes)
    paths = [save_figure(plot_trajectories({"MANC": traj}, human, val, scenes),
                        figdir / "trajectories.png")]
    for s in scenes:
        paths.append(save_figure(plot_explain_trace(traj, human, val, s),
                                figdir / f"explain_scene{s:03d}.png"))
        steps = saliency_steps(traj, s)
        paths.append(save_figure(
            plot_saliency_steps(fit.params, fit.cfg, traj, val, s, steps),
            figdir / f"saliency_scene{s:03d}.png"))
    paths.append(save_rollout_gif(traj, human, val, scenes[0], figdir / "rollout.gif"))
    if study.recorded:  # no human modes on recorded data (minimanc.studies.recorded)
        return paths
    labels = study.human_modes()
    q = rollout.open_loop(fit, val, engine=study.engine, scenes=scenes)["q"]
    for k, s in enumerate(scenes):
        title = f"MANC open loop, scene {s} ({val.maps[s].kind}): q and the human's mode"
        paths.append(save_figure(plot_q_modes(q[k], labels[s], title),
                                figdir / f"q_modes_scene{s:03d}.png"))
    return paths


def pick_scenes(ds: Any, traj: Any, k: int) -> list[int]:
    """``k`` validation scenes for the explainability figures, chosen by rule, not by eye:
    first a roundabout, an intersection and a curved road (in that order, the first
    scene of each kind), then the scenes where the q-distribution moves most."""
    chosen: list[int] = []
    for kind in ("roundabout", "intersection", "curved"):
        for s in range(len(ds)):
            if ds.maps[s].kind == kind and s not in chosen:
                chosen.append(s)
                break
    if "q" in traj.aux:
        move = np.abs(np.diff(traj.aux["q"], axis=1)).sum(axis=(1, 2))
        chosen += [int(s) for s in np.argsort(-move) if int(s) not in chosen]
    chosen += [s for s in range(len(ds)) if s not in chosen]
    return chosen[:k]


def saliency_steps(traj: Any, scene: int, k: int = 3) -> list[int]:
    """``k`` consecutive-ish steps around the largest change of the q-distribution."""
    T = traj.controls.shape[1]
    if "q" not in traj.aux or T < 2:
        return list(range(min(k, T)))
    move = np.abs(np.diff(traj.aux["q"][scene], axis=0)).sum(axis=1)
    t = int(np.argmax(move)) + 1
    lo = int(np.clip(t - k // 2 * 2, 0, max(T - 1 - 2 * (k - 1), 0)))
    return [min(lo + 2 * i, T - 1) for i in range(k)]
