"""Chapter 9 — one closed-loop rollout explained: paths, speeds, q, Figs. 3 and 4, a GIF.

Drawn from a :class:`minimanc.rollout.Rollout` (rows = dataset scenes) and the human's
(:func:`minimanc.rollout.human`): :func:`plot_trajectories` (policy against human in the
world frame), :func:`plot_speeds` (speed over time), :func:`plot_q_modes` (q over time above
the human's driving mode), :func:`plot_explain_trace` (Fig. 4: DMP α/β over time, the
q-distribution, controls against the human's, BEV frames), :func:`saliency_maps` and
:func:`plot_saliency_steps` (Fig. 3: per-q-state saliency of :mod:`minimanc.cam`), and
:func:`gif_frames` / :func:`save_rollout_gif` (the rollout as an animated GIF, via Pillow).  Figures
are returned, never shown; :func:`minimanc.viz.style.save_figure` writes one to PNG.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from minimanc import inputs, models, vagn, world
from minimanc.metrics.modes import MODES
from minimanc.viz.automaton import plot_q_heatmap
from minimanc.viz.saliency import plot_q_saliency
from minimanc.viz.style import model_colour, model_label, pyplot
from minimanc.viz.world import plot_map
from minimanc.world.geometry import EGO_LENGTH, EGO_WIDTH, box_corners, to_ego_frame
from minimanc.world.history import history_of

__all__ = [
    "check_scene_index",
    "plot_trajectories",
    "plot_speeds",
    "plot_q_modes",
    "plot_explain_trace",
    "saliency_maps",
    "plot_saliency_steps",
    "gif_frames",
    "save_rollout_gif",
]


def check_scene_index(traj: Any, scene: int) -> int:
    """``scene`` as an int row of ``traj`` (a rollout or the human's); ``ValueError`` if it
    does not index one."""
    s = int(scene)
    if not 0 <= s < len(traj):
        raise ValueError(f"scene must index the rollout's {len(traj)} rows; got scene={scene!r}")
    return s


def _draw_map(ax: Any, m: Any) -> None:
    """The map under a world-frame plot (:func:`minimanc.viz.world.plot_map`)."""
    plot_map(m, ax=ax)


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
    plt = pyplot()
    scenes = [check_scene_index(human, s) for s in scenes]
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



def plot_speeds(rollouts: Mapping[str, Any], human: Any, scenes: Sequence[int],
                dt: float = 0.5) -> Any:
    """Speed over time of each rollout against the human's, one row per model, one column
    per scene (the speed is the applied control ``controls[..., 0]``, m/s).

    ``rollouts`` maps a model name to a :class:`minimanc.rollout.Rollout`; ``human`` is
    :func:`minimanc.rollout.human` on the same scenes.
    """
    plt = pyplot()
    scenes = [check_scene_index(human, s) for s in scenes]
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
    of :data:`minimanc.metrics.modes.MODES` (:func:`minimanc.metrics.modes.human_modes`).
    """
    q = np.asarray(q, dtype=np.float64)
    labels = np.asarray(modes)
    if q.ndim != 2 or labels.shape != q.shape[:1]:
        raise ValueError(f"q must have shape (T, N) and modes (T,); got {q.shape} and "
                         f"{labels.shape}")
    plt = pyplot()
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



def _past(traj: Any, ds: Any, scene: int, t: int) -> Any:
    """The past boxes of step ``t`` that ``ds.raster`` draws (the rollout's own poses and the
    log's ados; :func:`minimanc.world.history.history_of` of one frame), or ``None``."""
    steps = ds.raster.history
    if not steps:
        return None
    return history_of(traj.ego[scene], ds.ado[scene], ds.ado_valid[scene], steps, frames=[t])


def _bev_at(traj: Any, ds: Any, scene: int, t: int) -> np.ndarray:
    """The BEV the policy saw at step ``t`` (re-rasterised from its own pose, with its past),
    as an RGB picture (:func:`minimanc.world.to_rgb`: the channels painted)."""
    bev = world.rasterize(ds.maps[scene], traj.ego[scene, t], ds.ado[scene, t],
                          ds.ado_valid[scene, t], ds.raster, history=_past(traj, ds, scene, t))
    return world.to_rgb(bev, ds.raster)


def plot_explain_trace(traj: Any, human: Any, ds: Any, scene: int,
                       bev_steps: Sequence[int] | None = None) -> Any:
    """The paper's Fig. 4 for one scene of a closed-loop rollout.

    (a) the DMP gains α, β over time (position and orientation), (b) the
    vAGN q-distribution over time, (c) speed and yaw rate of the policy
    against the human's, (d) the BEV the policy saw at three steps. Panels
    the model has no data for (a direct head has no α, β or q) are left out.
    """
    plt = pyplot()
    s = check_scene_index(traj, scene)
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
            plot_q_heatmap(aux["q"][s], ax=ax, colorbar=False)
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
    """Per-q-state saliency (:func:`minimanc.models.saliency`) at ``steps`` of a rollout.

    The observation of each step is rebuilt from the rollout's own pose and
    the q-distribution of the previous step (uniform before the first), so
    the returned ``q`` equals the rollout's recorded ``q`` at that step.
    Returns one dict per step: ``bev`` (H, W, 3) in [0, 1], ``q`` (N,),
    ``saliency`` (N, H, W), ``step``.
    """
    s = check_scene_index(traj, scene)
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
                                cfg.setting, motion=motion, model=models.get("manc"),
                                history=_past(traj, ds, s, t))
        q_prev = (vagn.uniform_state(n_states)[None] if t == 0
                  else traj.aux["q"][s:s + 1, t - 1])
        ex = models.saliency(params, obs, q_prev, cfg)
        out.append({"step": t, "bev": obs["bev"][0], "q": ex["q"][0],
                    "saliency": ex["saliency"][0]})
    return out


def plot_saliency_steps(params: dict, cfg: Any, traj: Any, ds: Any, scene: int,
                        steps: Sequence[int]) -> Any:
    """The paper's Fig. 3: per-q-state saliency overlays at a few steps of one scene.

    One row per step: the BEV the policy saw, then one overlay per q-state
    titled with its probability (:func:`minimanc.viz.saliency.plot_q_saliency`;
    colours high → low: yellow, red, cyan, magenta).
    """
    plt = pyplot()
    maps_ = saliency_maps(params, cfg, traj, ds, scene, steps)
    N = maps_[0]["q"].shape[0]
    fig, axes = plt.subplots(len(maps_), N + 1, figsize=(1.9 * (N + 1), 2.1 * len(maps_)),
                             squeeze=False)
    for row, m in zip(axes, maps_):
        image = m["bev"] if ds.raster.encoding == "rgb" else _bev_at(traj, ds, scene, m["step"])
        plot_q_saliency(image, m["saliency"], m["q"], axes=row)
        row[0].set_title(f"BEV, step {m['step']}", fontsize=9)
        for ax in row[1:]:
            ax.title.set_fontsize(8)
    fig.suptitle(f"Per-q-state saliency, scene {int(scene)}", fontsize=10)
    fig.tight_layout()
    return fig


def _to_pixels(points_world: np.ndarray, pose: np.ndarray, cfg: Any) -> list[tuple[float, float]]:
    p = to_ego_frame(np.asarray(points_world, dtype=np.float64), pose)
    row = (cfg.metres_ahead - p[:, 0]) / cfg.res_row
    col = (cfg.metres_side - p[:, 1]) / cfg.res_col
    return list(zip(col.tolist(), row.tolist()))


def gif_frames(traj: Any, human: Any, ds: Any, scene: int, size: int = 192) -> list[Any]:
    """The frames of :func:`save_rollout_gif` as Pillow images (one per pose of the rollout)."""
    from PIL import Image, ImageDraw  # optional until a GIF is drawn

    s = check_scene_index(traj, scene)
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


def save_rollout_gif(traj: Any, human: Any, ds: Any, scene: int, path: str | Path,
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
