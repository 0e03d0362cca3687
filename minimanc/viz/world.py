"""Chapter 7 — looking at the world: map plots, raster galleries with routes, scene animations.

Everything here draws existing data (no simulation): :func:`plot_map` (a
top-down map with lanes, route and the logged trajectory), :func:`gallery`
(BEV rasters with the human's future path and the lane target on top),
:func:`scene_frames` / :func:`save_scene_gif` (one scene as an animation).
"""

from __future__ import annotations

import os

import numpy as np

from minimanc.world.geometry import to_ego_frame
from minimanc.world.lanes import Map, class_grid
from minimanc.world.raster import RasterConfig
from minimanc.world.scenes import Dataset


def ego_to_image_xy(points_ego: np.ndarray, cfg: RasterConfig) -> tuple[np.ndarray, np.ndarray]:
    """Continuous image coordinates ``(u = column, v = row)`` of ego-frame points (for plots)."""
    p = np.asarray(points_ego, dtype=np.float64)
    u = (cfg.metres_side - p[..., 1]) / cfg.res_col - 0.5
    v = (cfg.metres_ahead - p[..., 0]) / cfg.res_row - 0.5
    return u, v


def plot_map(m: Map, ax=None, ego: np.ndarray | None = None, ado: np.ndarray | None = None,
             ado_valid: np.ndarray | None = None, res: float = 0.5):
    """Top-down plot of a map: drivable classes, lane centrelines, route, optional trajectory."""
    import matplotlib.pyplot as plt  # matplotlib only when a figure is drawn
    from matplotlib.colors import ListedColormap  # matplotlib only when a figure is drawn

    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    ax.set_facecolor("black")
    grid, origin, r = class_grid(m, res)
    cmap = ListedColormap([(0, 0, 0), (1, 1, 1), (119 / 255, 136 / 255, 153 / 255), (0, 0, 1)])
    ext = [origin[0], origin[0] + grid.shape[1] * r, origin[1], origin[1] + grid.shape[0] * r]
    ax.imshow(grid, origin="lower", extent=ext, cmap=cmap, vmin=0, vmax=3,
              interpolation="nearest")
    for ln in m.lanes:
        ax.plot(ln.points[:, 0], ln.points[:, 1], color="tab:cyan", lw=0.6)
    ax.plot(m.route_points[:, 0], m.route_points[:, 1], color="tab:orange", lw=1.5,
            label="route")
    if ego is not None:
        ax.plot(ego[:, 0], ego[:, 1], "r.-", ms=3, lw=1, label="human ego")
        lo, hi = ego[:, :2].min(0) - 40, ego[:, :2].max(0) + 40
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
    if ado is not None:
        valid = np.ones(ado.shape[:-1], bool) if ado_valid is None else ado_valid
        for k in range(ado.shape[1]):
            tr = ado[:, k][valid[:, k]]
            if len(tr):
                ax.plot(tr[:, 0], tr[:, 1], color="gold", lw=0.8)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    return ax


def draw_scene_step(ax, ds: Dataset, i: int, t: int, future: bool = True,
                    targets: bool = True) -> None:
    """Show ``ds.bev[i, t]`` with the human's future path (red) and the lane target (cyan)."""
    cfg = ds.raster
    ax.imshow(ds.bev[i, t], interpolation="nearest")
    if future:
        fut = to_ego_frame(ds.ego[i, t:, :2].astype(np.float64), ds.ego[i, t].astype(np.float64))
        u, v = ego_to_image_xy(fut, cfg)
        ax.plot(u, v, color="tab:red", lw=1.2)
    if targets:
        u, v = ego_to_image_xy(ds.lane_target[i, t], cfg)
        ax.plot(u, v, ".", color="tab:blue", ms=3)
    ax.set_xlim(-0.5, cfg.size - 0.5)
    ax.set_ylim(cfg.size - 0.5, -0.5)
    ax.set_xticks([])
    ax.set_yticks([])


def gallery(ds: Dataset, indices=None, t: int | None = None, cols: int = 6):
    """A figure of BEV rasters (scene indices ``indices``, step ``t``, default mid-scene)."""
    import matplotlib.pyplot as plt  # matplotlib only when a figure is drawn

    idx = list(range(min(len(ds), 12))) if indices is None else list(indices)
    t = ds.n_steps // 2 if t is None else t
    rows = int(np.ceil(len(idx) / cols))
    fig, axs = plt.subplots(rows, cols, figsize=(2.2 * cols, 2.4 * rows), squeeze=False)
    for ax in axs.flat:
        ax.axis("off")
    for ax, i in zip(axs.flat, idx):
        draw_scene_step(ax, ds, i, t)
        tg = ds.tags[i]
        extra = " cut-in" if tg.get("has_cut_in") else ""
        ax.set_title(f"#{i} {tg['kind']}{extra}", fontsize=8)
        ax.axis("on")
    fig.tight_layout()
    return fig


def scene_frames(ds: Dataset, i: int, scale: int = 4, goal: bool = True) -> np.ndarray:
    """Frames ``(T, H*scale, W*scale, 3)`` of scene ``i``, upscaled, with the goal as a dot."""
    cfg = ds.raster
    frames = np.repeat(np.repeat(ds.bev[i], scale, axis=1), scale, axis=2).copy()
    if goal:
        u, v = ego_to_image_xy(ds.goal[i, :, :2], cfg)
        for t in range(ds.n_steps):
            r = int(round((v[t] + 0.5) * scale))
            c = int(round((u[t] + 0.5) * scale))
            r0, r1 = max(r - 2, 0), min(r + 3, frames.shape[1])
            c0, c1 = max(c - 2, 0), min(c + 3, frames.shape[2])
            if r1 > r0 and c1 > c0:
                frames[t, r0:r1, c0:c1] = (255, 0, 255)
    return frames


def save_scene_gif(frames: np.ndarray, path: str | os.PathLike, fps: float = 2.0) -> None:
    """Write frames ``(T, H, W, 3)`` uint8 as an animated GIF (real time at 2 Hz by default)."""
    from PIL import Image  # Pillow only when an image is written

    imgs = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
    imgs[0].save(path, save_all=True, append_images=imgs[1:], duration=int(1000 / fps), loop=0)
