"""Chapter 0 — chapter 7's figure: one BEV frame of the dataset with the ado boxes and the
human's future path put into pixels by the student's ego-frame transform, box test and
pixel grid, over the library's :func:`minimanc.world.rasterize` (:func:`plot_bev_attempts`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from minimanc.viz.exercises.attempts import attempt
from minimanc.viz.style import pyplot
from minimanc.world.geometry import goal_in_ego_frame, to_ego_frame
from minimanc.world.raster import RasterConfig, box_mask

__all__ = ["plot_bev_attempts"]


def _student_boxes(pose_in_ego_frame: Callable[..., Any], box_pixels: Callable[..., Any],
                   boxes: np.ndarray, ego_pose: np.ndarray, cfg: RasterConfig) -> np.ndarray:
    """The union of the student's box masks, the box poses put into the ego frame by the
    student's ``pose_in_ego_frame``."""
    poses = np.asarray(pose_in_ego_frame(boxes[:, :3], ego_pose), dtype=float)
    if poses.shape != (len(boxes), 3):
        raise ValueError(f"pose_in_ego_frame: expected shape {(len(boxes), 3)}, "
                         f"got {poses.shape}")
    mask = np.zeros((cfg.size, cfg.size), dtype=bool)
    for pose, size in zip(poses, boxes[:, 3:]):
        one = np.asarray(box_pixels(np.concatenate([pose, size]), cfg))
        if one.shape != mask.shape:
            raise ValueError(f"box_pixels: expected shape {mask.shape}, got {one.shape}")
        mask = mask | one.astype(bool)
    return mask


def plot_bev_attempts(
    bev: Any,
    ego_pose: Any,
    boxes: Any,
    path: Any,
    cfg: RasterConfig,
    pose_in_ego_frame: Callable[..., Any],
    world_to_pixel: Callable[..., Any],
    box_pixels: Callable[..., Any],
) -> Any:
    """Chapter 7's figure: a BEV frame (left) and the same frame drawn with the student's
    functions (right).

    The library's frame is ego-centric and heading up (row 0 is ``cfg.metres_ahead``
    ahead, column 0 is ``cfg.metres_side`` to the left); an ado box is the set of
    pixels whose centres lie inside it in its own frame, and a world point falls into
    the pixel of its ego-frame coordinates. On the right the ado boxes are put into the
    ego frame by ``pose_in_ego_frame`` and rasterised by the student's
    ``box_pixels`` (magenta), and the human's future path is put into pixels by their
    ``world_to_pixel`` (dots; the library's pixels are rings). The title counts what
    agrees with the library, or names the function that raised.

    Parameters
    ----------
    bev : array-like, shape (H, W, 3)
        The library's raster of this frame (``world.rasterize``).
    ego_pose : array-like, shape (3,)
        The ego's world pose ``[x, y, yaw]``.
    boxes : array-like, shape (A, 5)
        The visible ado boxes ``[x, y, yaw, length, width]`` in the world frame.
    path : array-like, shape (P, 2)
        World points to put into pixels (the human's future positions).
    cfg : RasterConfig
        The raster of ``bev``.
    pose_in_ego_frame : callable
        ``(poses (A, 3), ego_pose (3,)) -> (A, 3)``: world poses into the ego frame
        (chapter 7 passes the library's ``world.goal_in_ego_frame``).
    world_to_pixel, box_pixels : callable
        The student's functions of exercises 7.2 and 7.3.

    Returns
    -------
    fig : matplotlib Figure

    Raises
    ------
    ValueError
        If ``bev``, ``boxes`` or ``path`` has the wrong shape.
    """
    image = np.asarray(bev)
    ego = np.asarray(ego_pose, dtype=float)
    box = np.asarray(boxes, dtype=float).reshape(-1, 5) if np.size(boxes) else np.zeros((0, 5))
    points = np.asarray(path, dtype=float)
    if image.shape != cfg.shape:
        raise ValueError(f"bev must have shape {cfg.shape}, got {image.shape}")
    if ego.shape != (3,):
        raise ValueError(f"ego_pose must have shape (3,), got {ego.shape}")
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"path must have shape (P, 2), got {points.shape}")
    X, Y = cfg.pixel_centres()
    ref_boxes = np.concatenate([goal_in_ego_frame(box[:, :3], ego), box[:, 3:]], axis=1)
    ref_mask = box_mask(X, Y, ref_boxes).any(axis=0) if len(box) else np.zeros(X.shape, bool)
    ref_rows, ref_cols = cfg.ego_to_pixel(to_ego_frame(points, ego))

    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 4.6))
    left.imshow(image, interpolation="nearest")
    left.plot(ref_cols, ref_rows, "o", mfc="none", mec="r", ms=5)
    left.set_title("library: world.rasterize", fontsize=9)
    grey = np.repeat(image.mean(axis=-1, keepdims=True), 3, axis=-1) * 0.45 / 255.0
    errors, notes = [], []
    mask, error = attempt(_student_boxes, pose_in_ego_frame, box_pixels, box, ego, cfg)
    if error:
        errors.append(f"boxes: {error}")
    else:
        grey[mask] = (1.0, 0.0, 1.0)
        shared = int((mask & ref_mask).sum())
        notes.append(f"box pixels: yours {int(mask.sum())}, library {int(ref_mask.sum())}, "
                     f"shared {shared}")
    right.imshow(grey, interpolation="nearest")
    right.plot(ref_cols, ref_rows, "o", mfc="none", mec="r", ms=5)
    pixels, error = attempt(world_to_pixel, points, ego, cfg)
    if not error:
        rows, cols = (np.asarray(a) for a in pixels)
        if rows.shape != ref_rows.shape or cols.shape != ref_cols.shape:
            error = f"expected {len(points)} rows and cols, got shapes {rows.shape}, {cols.shape}"
    if error:
        errors.append(f"path: {error}")
    else:
        right.plot(cols, rows, ".", color="r", ms=6)
        hits = int(((rows == ref_rows) & (cols == ref_cols)).sum())
        notes.append(f"path: {hits} of {len(points)} points on the library's pixel")
    for ax in (left, right):
        ax.set_xlim(-0.5, cfg.size - 0.5)
        ax.set_ylim(cfg.size - 0.5, -0.5)
        ax.set_xticks([])
        ax.set_yticks([])
    right.set_title("\n".join(errors + notes), fontsize=8)
    return fig
