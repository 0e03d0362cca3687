"""Chapter 9 — every figure of the closed-loop study (the paper's Figures 3–8 and Table I).

Two families:

* **study plots** drawn from the ``results`` dict that :mod:`minimanc.studies`
  writes to ``results.json`` — :func:`plot_table1` (Table I as bars, both
  information settings, one protocol of the ados), :func:`plot_families` (one metric per
  scenario family), :func:`plot_sample_efficiency` (Fig. 5a),
  :func:`plot_param_counts` (Fig. 5b), :func:`plot_q_states` (Fig. 7),
  :func:`plot_ablation` (Fig. 8);
* **explainability** drawn from a :class:`minimanc.rollout.Rollout` —
  :func:`plot_explain_trace` (Fig. 4: DMP α/β over time, the q-distribution,
  controls against the human's, BEV frames), :func:`plot_saliency_steps`
  (Fig. 3: per-q-state saliency overlays via :mod:`minimanc.cam`),
  :func:`plot_trajectories` (policy against human in the world frame),
  :func:`plot_speeds` (speed over time, policies against the human),
  :func:`plot_q_modes` (q over time above the human's driving mode) and
  :func:`save_gif` (a closed-loop rollout as an animated GIF, via Pillow).

Every function returns the matplotlib ``Figure`` (or the GIF's path) and
never calls ``plt.show()``; :func:`save` writes a figure to PNG and closes it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "METRIC_LABELS",
    "REFERENCE_COLOURS",
    "REFERENCE_LABELS",
    "model_colour",
    "model_label",
    "save",
    "plot_table1",
    "plot_families",
    "plot_speeds",
    "plot_q_modes",
    "plot_sample_efficiency",
    "plot_param_counts",
    "plot_q_states",
    "plot_ablation",
    "plot_trajectories",
    "plot_explain_trace",
    "plot_saliency_steps",
    "saliency_maps",
    "gif_frames",
    "save_gif",
]

REFERENCE_LABELS: dict[str, str] = {"human": "Human", "dmp_prior": "DMP at fixed gains"}
"""Display names of the rows that are not learned models: the logged human (Table I) and the
no-learning reference (:func:`minimanc.rollout.fixed_gains`). A model's own display name is
the ``label`` of its :class:`~minimanc.models.ModelSpec`."""

REFERENCE_COLOURS: dict[str, str] = {"human": "#444444", "dmp_prior": "#a0a0a0"}
"""Colours of the rows that are not learned models (a model's is its spec's ``colour``)."""


def model_label(name: str) -> str:
    """Display name of ``name``: its spec's ``label``, a :data:`REFERENCE_LABELS` entry, or
    ``name`` itself."""
    from minimanc.models import registry

    if name in registry.names():
        return registry.get(name).label
    return REFERENCE_LABELS.get(name, name)


def model_colour(name: str, default: str | None = None) -> str | None:
    """Colour of ``name`` in figures: its spec's ``colour``, a :data:`REFERENCE_COLOURS`
    entry, or ``default``."""
    from minimanc.models import registry

    if name in registry.names():
        return registry.get(name).colour
    return REFERENCE_COLOURS.get(name, default)


def __getattr__(name: str) -> Any:
    """``MODEL_LABELS`` and ``MODEL_COLOURS``: ``{name: label}`` and ``{name: colour}`` of the
    registered models and the reference rows, read from the registry when asked."""
    if name in ("MODEL_LABELS", "MODEL_COLOURS"):
        from minimanc.models import registry

        if name == "MODEL_LABELS":
            return {"human": REFERENCE_LABELS["human"],
                    **{s.name: s.label for s in registry.specs()},
                    "dmp_prior": REFERENCE_LABELS["dmp_prior"]}
        return {**REFERENCE_COLOURS, **{s.name: s.colour for s in registry.specs()}}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


METRIC_LABELS: dict[str, str] = {
    "close_encounters": "% close encounters",
    "max_acceleration": "max |acceleration| (m/s²)",
    "ade": "ADE to human (m)",
    "goal_distance": "goal distance (m)",
    "collision_rate": "% scenes with a collision",
    "off_road_rate": "% scenes off road",
    "at_fault_collision_rate": "% scenes with an at-fault collision",
    "ttc_rate": "% steps with TTC < 1 s",
    "route_progress": "route progress (human = 1)",
    "along_track": "along-track error (m)",
    "cross_track": "cross-track error (m)",
    "along_bias": "along-track bias (m, < 0: behind)",
}
"""Axis labels of the metrics of :mod:`minimanc.metrics`."""

_TABLE = ("close_encounters", "max_acceleration", "ade", "goal_distance")


def _plt():
    import matplotlib.pyplot as plt

    return plt


def save(fig: Any, path: str | Path, dpi: int = 110) -> Path:
    """Write ``fig`` to ``path`` (PNG, parents created) and close it. Returns the path."""
    plt = _plt()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return path


def _ms(agg: Mapping[str, Any], metric: str) -> tuple[float, float]:
    entry = agg.get(metric)
    if entry is None:
        return float("nan"), 0.0
    return float(entry["mean"]), float(entry["std"])


def _check_metrics(metrics: Sequence[str]) -> None:
    for m in metrics:
        if m not in METRIC_LABELS:
            raise ValueError(f"metrics must be names from {sorted(METRIC_LABELS)}; got {m!r}")


# --------------------------------------------------------------------------- study plots


def plot_table1(
    table: Mapping[str, Mapping[str, Mapping[str, Any]]],
    metrics: Sequence[str] = _TABLE,
) -> Any:
    """Table I as bar charts: one panel per metric, one bar group per model, one bar per setting.

    ``table[setting][model]`` is an aggregate from :func:`minimanc.metrics.aggregate`
    (``{metric: {"mean", "std"}}``); error bars are the std over seeds.
    """
    _check_metrics(metrics)
    if not table:
        raise ValueError("table must hold at least one setting; got an empty mapping")
    plt = _plt()
    settings = list(table)
    models = list(dict.fromkeys(m for s in settings for m in table[s]))
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.6 * len(metrics), 3.4))
    axes = np.atleast_1d(axes)
    width = 0.8 / len(settings)
    x = np.arange(len(models))
    hatches = ["", "//", "..", "xx"]
    for ax, metric in zip(axes, metrics):
        for k, setting in enumerate(settings):
            means, stds = zip(*[_ms(table[setting].get(m, {}), metric) for m in models])
            ax.bar(x + (k - (len(settings) - 1) / 2) * width, means, width, yerr=stds,
                   color=[model_colour(m, "grey") for m in models],
                   hatch=hatches[k % len(hatches)], edgecolor="black", linewidth=0.5,
                   capsize=2, label=setting)
        ax.set_xticks(x)
        ax.set_xticklabels([model_label(m) for m in models], rotation=40, ha="right")
        ax.set_title(METRIC_LABELS[metric], fontsize=10)
    if len(settings) > 1:
        axes[0].legend(title="setting", fontsize=8)
    fig.suptitle("Closed-loop performance (Table I); lower is better")
    fig.tight_layout()
    return fig


FAMILY_METRICS: tuple[str, ...] = ("ade", "along_track", "cross_track",
                                    "at_fault_collision_rate")
"""The panels of :func:`plot_families`: the ADE, its split, and at-fault collisions."""


def plot_families(
    families: Mapping[str, Mapping[str, Mapping[str, Any]]],
    metrics: Sequence[str] = FAMILY_METRICS,
    title: str = "",
) -> Any:
    """Table I's rows per scenario family: one panel per metric, one bar group per family,
    one bar per model.

    ``families[model][family]`` is an aggregate (:func:`minimanc.metrics.aggregate`), as
    in ``results["families"][agents][setting]``; error bars are the std over seeds.
    """
    _check_metrics(metrics)
    if not families:
        raise ValueError("families must hold at least one model; got an empty mapping")
    plt = _plt()
    models = list(families)
    fams = list(dict.fromkeys(f for m in models for f in families[m]))
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.8 * len(metrics), 3.4))
    axes = np.atleast_1d(axes)
    width = 0.8 / len(models)
    x = np.arange(len(fams))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, metric in zip(axes, metrics):
        for k, m in enumerate(models):
            means, stds = zip(*[_ms(families[m].get(f, {}), metric) for f in fams])
            ax.bar(x + (k - (len(models) - 1) / 2) * width, means, width, yerr=stds,
                   color=model_colour(m, colours[k % len(colours)]), edgecolor="black",
                   linewidth=0.5, capsize=2, label=model_label(m))
        ax.set_xticks(x)
        ax.set_xticklabels([f.replace("_", "-") for f in fams])
        ax.set_title(METRIC_LABELS[metric], fontsize=10)
    axes[0].legend(fontsize=7)
    fig.suptitle(title or "Per scenario family; lower is better")
    fig.tight_layout()
    return fig


def plot_speeds(rollouts: Mapping[str, Any], human: Any, scenes: Sequence[int],
                dt: float = 0.5) -> Any:
    """Speed over time of each rollout against the human's, one row per model, one column
    per scene (the speed is the applied control ``controls[..., 0]``, m/s).

    ``rollouts`` maps a model name to a :class:`minimanc.rollout.Rollout`; ``human`` is
    :func:`minimanc.rollout.human` on the same scenes.
    """
    plt = _plt()
    scenes = [_check_scene(human, s) for s in scenes]
    if not scenes or not rollouts:
        raise ValueError("plot_speeds needs at least one rollout and one scene; got "
                         f"{len(rollouts)} rollouts and scenes={list(scenes)!r}")
    fig, axes = plt.subplots(len(rollouts), len(scenes), squeeze=False, sharex=True,
                             figsize=(3.6 * len(scenes), 2.2 * len(rollouts) + 0.6))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    t = np.arange(human.controls.shape[1]) * dt
    for i, (name, traj) in enumerate(rollouts.items()):
        col = model_colour(name, colours[i % len(colours)])
        for j, s in enumerate(scenes):
            ax = axes[i, j]
            ax.plot(t, human.controls[s, :, 0], "k--", lw=1.3, label="Human")
            ax.plot(t, traj.controls[s, :, 0], "-", color=col, lw=1.5, label=model_label(name))
            if i == 0:
                ax.set_title(f"scene {s}", fontsize=10)
            if j == 0:
                ax.set_ylabel(f"{model_label(name)}\nspeed (m/s)", fontsize=9)
            if i == len(rollouts) - 1:
                ax.set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_q_modes(q: Any, modes: Any, title: str = "", dt: float = 0.5) -> Any:
    """One scene's q-distribution over time (top) above the human's mode at each step
    (bottom): if the q-states were driving modes, q's bands would change where the modes do.

    ``q (T, N)`` (e.g. :func:`minimanc.rollout.open_loop`), ``modes (T,)`` integer labels
    of :data:`minimanc.modes.MODES` (:func:`minimanc.modes.human_modes`).
    """
    from minimanc.modes import MODES

    q = np.asarray(q, dtype=np.float64)
    labels = np.asarray(modes)
    if q.ndim != 2 or labels.shape != q.shape[:1]:
        raise ValueError(f"q must have shape (T, N) and modes (T,); got {q.shape} and "
                         f"{labels.shape}")
    plt = _plt()
    T, N = q.shape
    fig, (a, b) = plt.subplots(2, 1, figsize=(7, 3.6), sharex=True,
                               gridspec_kw={"height_ratios": [N, 2]})
    extent = (0, T * dt, N - 0.5, -0.5)
    a.imshow(q.T, aspect="auto", cmap="viridis", vmin=0, vmax=1, extent=extent,
             interpolation="nearest")
    a.plot((np.arange(T) + 0.5) * dt, q.argmax(axis=1), "w.", ms=4, label="argmax q")
    a.set_ylabel("q-state")
    a.set_title(title or "q over time and the human's mode", fontsize=10)
    a.legend(fontsize=7, loc="upper right")
    b.imshow(labels[None], aspect="auto", cmap="tab10", vmin=0, vmax=9,
             extent=(0, T * dt, 0.5, -0.5), interpolation="nearest")
    b.set_yticks([])
    present = sorted(set(labels.tolist()))
    cmap = plt.get_cmap("tab10")
    handles = [plt.Rectangle((0, 0), 1, 1, color=cmap(k)) for k in present]
    b.legend(handles, [MODES[k] for k in present], fontsize=7, ncol=len(present),
             loc="upper center", bbox_to_anchor=(0.5, -0.6))
    b.set_xlabel("time (s)")
    b.set_ylabel("human")
    fig.tight_layout()
    return fig


def plot_sample_efficiency(study: Mapping[str, Any], metric: str = "ade") -> Any:
    """ADE (or ``metric``) against the share of training data, one line per model (Fig. 5a).

    ``study = {"fractions": [...], "models": {name: [aggregate per fraction]}}``.
    """
    _check_metrics([metric])
    plt = _plt()
    fr = np.asarray(study["fractions"], dtype=float)
    fig, ax = plt.subplots(figsize=(4.6, 3.4))
    for name, aggs in study["models"].items():
        m, s = np.array([_ms(a, metric) for a in aggs]).T
        ax.errorbar(100 * fr, m, yerr=s, marker="o", capsize=3, label=model_label(name),
                    color=model_colour(name))
    ax.set_xlabel("training data used (%)")
    ax.set_ylabel(METRIC_LABELS[metric])
    ax.set_xticks(100 * fr)
    ax.set_title("Sample efficiency")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_param_counts(counts: Mapping[str, int]) -> Any:
    """Number of trainable parameters per model (Fig. 5b)."""
    if not counts:
        raise ValueError("counts must hold at least one model; got an empty mapping")
    plt = _plt()
    names = list(counts)
    fig, ax = plt.subplots(figsize=(4.6, 3.0))
    vals = [int(counts[n]) for n in names]
    bars = ax.bar(range(len(names)), vals, color=[model_colour(n, "grey") for n in names])
    for b, v in zip(bars, vals):
        ax.text(b.get_x() + b.get_width() / 2, v, f"{v:,}", ha="center", va="bottom", fontsize=8)
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels([model_label(n) for n in names], rotation=30, ha="right")
    ax.set_ylabel("parameters")
    ax.set_title("Model size")
    fig.tight_layout()
    return fig


def plot_q_states(study: Mapping[str, Any], metrics: Sequence[str] = _TABLE) -> Any:
    """Every metric against the number of q-states (Fig. 7).

    ``study = {"n_states": [3, 6, ...], "results": [aggregate per n]}``.
    """
    _check_metrics(metrics)
    plt = _plt()
    n = np.asarray(study["n_states"])
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.3 * len(metrics), 3.0))
    axes = np.atleast_1d(axes)
    for ax, metric in zip(axes, metrics):
        m, s = np.array([_ms(a, metric) for a in study["results"]]).T
        ax.errorbar(n, m, yerr=s, marker="o", capsize=3, color=model_colour("manc"))
        ax.set_xticks(n)
        ax.set_xlabel("number of q-states")
        ax.set_title(METRIC_LABELS[metric], fontsize=10)
    fig.suptitle("MANC: varying the number of q-states")
    fig.tight_layout()
    return fig


def plot_ablation(study: Mapping[str, Any], metrics: Sequence[str] = _TABLE) -> Any:
    """MANC against its ablations, one panel per metric (Fig. 8).

    ``study = {"models": {name: aggregate}}``.
    """
    _check_metrics(metrics)
    plt = _plt()
    names = list(study["models"])
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.0 * len(metrics), 3.0))
    axes = np.atleast_1d(axes)
    for ax, metric in zip(axes, metrics):
        m, s = np.array([_ms(study["models"][k], metric) for k in names]).T
        ax.bar(range(len(names)), m, yerr=s, capsize=3,
               color=[model_colour(k, "grey") for k in names])
        ax.set_xticks(range(len(names)))
        ax.set_xticklabels([model_label(k) for k in names], rotation=30, ha="right")
        ax.set_title(METRIC_LABELS[metric], fontsize=10)
    fig.suptitle("Self-ablation")
    fig.tight_layout()
    return fig


# --------------------------------------------------------------------------- explainability


def _check_scene(traj: Any, scene: int) -> int:
    s = int(scene)
    if not 0 <= s < len(traj):
        raise ValueError(f"scene must index the rollout's {len(traj)} rows; got scene={scene!r}")
    return s


def _draw_map(ax: Any, m: Any) -> None:
    """The map under a world-frame plot (:func:`minimanc.world.viz.plot_map`)."""
    from minimanc.world import viz

    viz.plot_map(m, ax=ax)


def _frame_limits(ax: Any, xy: np.ndarray, margin: float = 15.0) -> None:
    lo, hi = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_aspect("equal")


def plot_trajectories(
    rollouts: Mapping[str, Any], human: Any, ds: Any, scenes: Sequence[int]
) -> Any:
    """Closed-loop paths against the human's, in the world frame, one panel per scene.

    ``rollouts`` maps a label to a :class:`minimanc.rollout.Rollout` on ``ds``
    (rows = dataset scenes); ``human`` is :func:`minimanc.rollout.human`.
    """
    plt = _plt()
    scenes = [_check_scene(human, s) for s in scenes]
    if not scenes:
        raise ValueError("scenes must name at least one scene; got an empty sequence")
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.0 * len(scenes), 4.0), squeeze=False)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, s in zip(axes[0], scenes):
        _draw_map(ax, ds.maps[s])
        ax.plot(*human.ego[s, :, :2].T, "k--", lw=1.6, label="Human")
        pts = [human.ego[s, :, :2]]
        for i, (label, traj) in enumerate(rollouts.items()):
            key = label.lower().replace("-", "_")
            col = model_colour(key, colours[i % len(colours)])
            ax.plot(*traj.ego[s, :, :2].T, "-", color=col, lw=1.6, label=label)
            pts.append(traj.ego[s, :, :2])
        ax.plot(*human.ego[s, 0, :2], "ko", ms=4)
        ax.plot(*human.ego[s, -1, :2], "k*", ms=9)
        _frame_limits(ax, np.concatenate(pts))
        ax.set_title(f"scene {s} ({ds.maps[s].kind})", fontsize=10)
        ax.set_xticks([])
        ax.set_yticks([])
    axes[0, 0].legend(fontsize=8, loc="best")
    fig.tight_layout()
    return fig


def _bev_at(traj: Any, ds: Any, scene: int, t: int) -> np.ndarray:
    """The BEV the policy saw at step ``t`` (re-rasterised from its own pose)."""
    from minimanc import world

    return world.rasterize(ds.maps[scene], traj.ego[scene, t], ds.ado[scene, t],
                           ds.ado_valid[scene, t], ds.raster)


def plot_explain_trace(traj: Any, human: Any, ds: Any, scene: int,
                       bev_steps: Sequence[int] | None = None) -> Any:
    """The paper's Fig. 4 for one scene of a closed-loop rollout.

    (a) the DMP gains α, β over time (position and orientation), (b) the
    vAGN q-distribution over time, (c) speed and yaw rate of the policy
    against the human's, (d) the BEV the policy saw at three steps. Panels
    the model has no data for (a direct head has no α, β or q) are left out.
    """
    plt = _plt()
    from minimanc import vagn

    s = _check_scene(traj, scene)
    aux = traj.aux
    T1 = traj.controls.shape[1]
    rows = []
    if "alpha" in aux and "beta" in aux:
        rows.append("gains")
    if "q" in aux:
        rows.append("q")
    rows += ["speed", "yaw"]
    steps = list(bev_steps) if bev_steps is not None else [0, T1 // 2, T1 - 1]
    fig = plt.figure(figsize=(9.0, 1.9 * len(rows) + 2.8))
    gs = fig.add_gridspec(len(rows) + 1, len(steps), height_ratios=[1.0] * len(rows) + [1.6])
    t = np.arange(T1)
    ax0 = None
    for i, row in enumerate(rows):
        ax = fig.add_subplot(gs[i, :], sharex=ax0 if row != "q" else None)
        ax0 = ax0 or ax
        if row == "gains":
            a, b = aux["alpha"][s], aux["beta"][s]
            for k, (name, ls) in enumerate((("position", "-"), ("orientation", "--"))):
                ax.plot(t, a[:, k], ls, color="C0", label=f"α {name}")
                ax.plot(t, b[:, k], ls, color="C3", label=f"β {name}")
            ax.set_ylabel("DMP gains")
            ax.legend(fontsize=7, ncol=4, loc="upper right")
            ax.set_title(f"(a) DMP parameters — scene {s}", fontsize=9, loc="left")
        elif row == "q":
            vagn.plot_q_heatmap(aux["q"][s], ax=ax, colorbar=False)
            ax.set_xlabel("")
            ax.set_title("(b) vAGN state distribution", fontsize=9, loc="left")
        else:
            k = 0 if row == "speed" else 1
            ax.plot(t, traj.controls[s, :, k], color="C0", label=traj.name)
            ax.plot(t, human.controls[s, :T1, k], color="C3", label="human")
            ax.set_ylabel("speed (m/s)" if k == 0 else "yaw rate (rad/s)")
            if k == 0:
                ax.legend(fontsize=7, loc="upper right")
                ax.set_title("(c) controls", fontsize=9, loc="left")
            else:
                ax.set_xlabel("time step")
    for j, st in enumerate(steps):
        ax = fig.add_subplot(gs[len(rows), j])
        ax.imshow(_bev_at(traj, ds, s, int(st)), interpolation="nearest")
        ax.set_title(f"(d) BEV, step {int(st)}", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    return fig


def saliency_maps(params: dict, cfg: Any, traj: Any, ds: Any, scene: int,
                  steps: Sequence[int]) -> list[dict]:
    """Per-q-state saliency (:func:`minimanc.models.explain`) at ``steps`` of a rollout.

    The observation of each step is rebuilt from the rollout's own pose and
    the q-distribution of the previous step (uniform before the first), so
    the returned ``q`` equals the rollout's recorded ``q`` at that step.
    Returns one dict per step: ``bev`` (H, W, 3) in [0, 1], ``q`` (N,),
    ``saliency`` (N, H, W), ``step``.
    """
    from minimanc import inputs, models, vagn

    s = _check_scene(traj, scene)
    if "q" not in traj.aux:
        raise ValueError("saliency needs a vAGN model's rollout (aux 'q'); "
                         f"got aux keys {sorted(traj.aux)}")
    out = []
    n_states = traj.aux["q"].shape[-1]
    for st in steps:
        t = int(st)
        if not 0 <= t < traj.controls.shape[1]:
            raise ValueError(f"steps must lie in [0, {traj.controls.shape[1]}); got {st!r}")
        motion = (inputs.initial_motion(ds)[s:s + 1] if t == 0
                  else traj.controls[s:s + 1, t - 1].astype(np.float32))
        obs = inputs.from_state([ds.maps[s]], traj.ego[s:s + 1, t], ds.ado[s:s + 1, t],
                                ds.ado_valid[s:s + 1, t], ds.ego[s:s + 1, -1], ds.raster,
                                cfg.setting, motion=motion, model="manc")
        q_prev = (vagn.uniform_state(n_states)[None] if t == 0
                  else traj.aux["q"][s:s + 1, t - 1])
        ex = models.explain(params, obs, q_prev, cfg)
        out.append({"step": t, "bev": obs["bev"][0], "q": ex["q"][0],
                    "saliency": ex["saliency"][0]})
    return out


def plot_saliency_steps(params: dict, cfg: Any, traj: Any, ds: Any, scene: int,
                        steps: Sequence[int]) -> Any:
    """The paper's Fig. 3: per-q-state saliency overlays at a few steps of one scene.

    One row per step: the BEV the policy saw, then one overlay per q-state
    titled with its probability (:func:`minimanc.cam.plot_q_saliency`;
    colours high → low: yellow, red, cyan, magenta).
    """
    plt = _plt()
    from minimanc import cam

    maps_ = saliency_maps(params, cfg, traj, ds, scene, steps)
    N = maps_[0]["q"].shape[0]
    fig, axes = plt.subplots(len(maps_), N + 1, figsize=(1.9 * (N + 1), 2.1 * len(maps_)),
                             squeeze=False)
    for row, m in zip(axes, maps_):
        cam.plot_q_saliency(m["bev"], m["saliency"], m["q"], axes=row)
        row[0].set_title(f"BEV, step {m['step']}", fontsize=9)
        for ax in row[1:]:
            ax.title.set_fontsize(8)
    fig.suptitle(f"Per-q-state saliency, scene {int(scene)}", fontsize=10)
    fig.tight_layout()
    return fig


def _to_pixels(points_world: np.ndarray, pose: np.ndarray, cfg: Any) -> list[tuple[float, float]]:
    from minimanc.world.geometry import to_ego_frame

    p = to_ego_frame(np.asarray(points_world, dtype=np.float64), pose)
    row = (cfg.metres_ahead - p[:, 0]) / cfg.res_row
    col = (cfg.metres_side - p[:, 1]) / cfg.res_col
    return list(zip(col.tolist(), row.tolist()))


def gif_frames(traj: Any, human: Any, ds: Any, scene: int, size: int = 192) -> list[Any]:
    """The frames of :func:`save_gif` as Pillow images (one per pose of the rollout)."""
    from PIL import Image, ImageDraw

    from minimanc import world
    from minimanc.world.geometry import EGO_LENGTH, EGO_WIDTH, box_corners

    s = _check_scene(traj, scene)
    T = traj.ego.shape[1]
    chase = world.RasterConfig(size=size, metres_ahead=50.0, metres_behind=30.0,
                               metres_side=40.0)
    has_q = "q" in traj.aux
    qw = 24 * traj.aux["q"].shape[-1] + 16 if has_q else 0
    pad = 18
    frames = []
    for t in range(T):
        pose = traj.ego[s, t]
        bev = _bev_at(traj, ds, s, t)
        k = max(size // bev.shape[0], 1)
        bev = np.repeat(np.repeat(bev, k, axis=0), k, axis=1)
        view = world.rasterize(ds.maps[s], pose, ds.ado[s, t], ds.ado_valid[s, t], chase)
        canvas = Image.new("RGB", (bev.shape[1] + size + qw + 12, size + pad), "white")
        canvas.paste(Image.fromarray(bev), (0, pad))
        right = Image.fromarray(view)
        d = ImageDraw.Draw(right)
        d.line(_to_pixels(human.ego[s, :, :2], pose, chase), fill=(255, 0, 255), width=1)
        if t > 0:
            d.line(_to_pixels(traj.ego[s, : t + 1, :2], pose, chase), fill=(255, 80, 0),
                   width=2)
        hb = box_corners(np.array([*human.ego[s, t], EGO_LENGTH, EGO_WIDTH]))
        d.polygon(_to_pixels(hb, pose, chase), outline=(255, 0, 255))
        canvas.paste(right, (bev.shape[1] + 6, pad))
        d = ImageDraw.Draw(canvas)
        d.text((2, 2), f"{model_label(traj.name)}: BEV input", fill="black")
        d.text((bev.shape[1] + 8, 2), f"scene {s}  t = {t * 0.5:4.1f} s  (human: magenta)",
               fill="black")
        if has_q:
            q = traj.aux["q"][s, min(t, T - 2)]
            x0 = bev.shape[1] + size + 14
            d.text((x0, 2), "vAGN q", fill="black")
            for i, v in enumerate(q):
                h = int(round(float(v) * (size - 16)))
                d.rectangle([x0 + 24 * i, pad + size - 14 - h, x0 + 24 * i + 18, pad + size - 14],
                            fill=(31, 119, 180))
                d.text((x0 + 24 * i + 3, pad + size - 12), f"q{i}", fill="black")
        frames.append(canvas)
    return frames


def save_gif(traj: Any, human: Any, ds: Any, scene: int, path: str | Path,
             fps: float = 4.0) -> Path:
    """A closed-loop rollout of one scene as an animated GIF (Pillow, no matplotlib).

    Left: the BEV the policy sees at each step (re-rasterised from its own
    pose). Middle: a wider chase view around the policy's ego (the same
    rasteriser, 80 × 80 m) with the human's path and box in magenta and the
    policy's path so far in orange. Right (vAGN models): the q-distribution.
    """
    if not fps > 0:
        raise ValueError(f"fps must be positive; got fps={fps!r}")
    frames = gif_frames(traj, human, ds, scene)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    frames[0].save(path, save_all=True, append_images=frames[1:],
                   duration=int(1000 / fps), loop=0)
    return path
