"""Chapter 12 — the figures of the crash investigation: faded history boxes and the ablation
of the privileged learner, the student's next to the library's.

The investigation reads a learned driver's closed-loop metrics (the ADE and the collisions
of the paper's Table I) against the bounds every row is read against (the expert and the
style floor, :mod:`minimanc.diagnose.bounds`), and asks which information a controller
trained by behaviour cloning (the paper's Algorithm 1) lacks. Two of its pictures are drawn
here:

* :func:`plot_history_boxes` — one frame's boxes in the ego frame (forward up, left to the
  left), each vehicle's past boxes under its current one with the brightness of the faded
  history convention (:mod:`minimanc.world.history`: box ``j`` steps ago drawn at
  ``brightness[j - 1]``), as the raster of ``world.RasterConfig(history=H)`` draws them;
* :func:`plot_input_ablation` — the privileged learner's open-loop RMSE of both controls (its
  outputs ``[acceleration, yaw rate]``, :mod:`minimanc.diagnose.privileged`) with each input
  group removed, as a ratio to the learner given every input.

:func:`plot_investigation_attempts` is chapter 12's exercise figure: the student's faded
boxes over the library's (:func:`minimanc.world.history.history_of`) and the student's
ablation table over the library's. The student's functions run through
:func:`minimanc.viz.exercises.attempt`, so a stub or a bug is named in its panel's title
and only the reference is drawn.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.viz.exercises import attempt
from minimanc.viz.style import pyplot
from minimanc.world.geometry import EGO_LENGTH, EGO_WIDTH, box_corners, to_ego_frame
from minimanc.world.history import History

__all__ = ["plot_input_ablation", "plot_history_boxes", "plot_investigation_attempts"]

EGO_COLOUR = "#1f77b4"
ADO_COLOUR = "#d62728"


def _check_frame(ego_pose: Any, ado: Any, ado_valid: Any) -> tuple[np.ndarray, ...]:
    pose = np.asarray(ego_pose, dtype=np.float64)
    a = np.asarray(ado, dtype=np.float64)
    v = np.asarray(ado_valid, dtype=bool)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"ego_pose must be a finite (x, y, yaw); got shape {pose.shape}")
    if a.ndim != 2 or a.shape[1] != 5 or v.shape != a.shape[:1]:
        raise ValueError(f"ado must have shape (A, 5) and ado_valid (A,); got {a.shape} and "
                         f"{v.shape}")
    return pose, a, v


def _ego_box(poses: np.ndarray) -> np.ndarray:
    """Ego poses ``(n, 3)`` as boxes ``(n, 5)``."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    return np.concatenate([p, np.tile([EGO_LENGTH, EGO_WIDTH], (len(p), 1))], axis=1)


def _draw_boxes(ax: Any, boxes: np.ndarray, pose: np.ndarray, colour: str,
                alpha: np.ndarray, fill: bool, label: str | None = None) -> None:
    """Boxes ``(n, 5)`` (world frame) in the ego frame of ``pose``: forward up, left left."""
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 5)
    if len(boxes) == 0:
        return
    corners = to_ego_frame(box_corners(boxes).reshape(-1, 2), pose).reshape(-1, 4, 2)
    for k, (c, a) in enumerate(zip(corners, np.broadcast_to(alpha, len(boxes)))):
        xy = np.stack([-c[:, 1], c[:, 0]], axis=1)  # right on the horizontal, forward up
        patch = pyplot().Polygon(xy, closed=True, facecolor=colour if fill else "none",
                                 edgecolor=colour, alpha=float(np.clip(a, 0.0, 1.0)) if fill
                                 else 1.0, lw=1.0 if fill else 1.2, ls="-" if fill else "--",
                                 label=label if k == 0 else None)
        ax.add_patch(patch)


def _frame_axes(ax: Any, pose: np.ndarray, ado: np.ndarray, valid: np.ndarray) -> None:
    _draw_boxes(ax, _ego_box(pose), pose, EGO_COLOUR, np.ones(1), True, "ego")
    _draw_boxes(ax, ado[valid], pose, ADO_COLOUR, np.ones(int(valid.sum())), True, "ados")
    ax.set(xlim=(-25, 25), ylim=(-10, 40), xlabel="right (m)", ylabel="ahead (m)")
    ax.set_aspect("equal")


def plot_history_boxes(ego_pose: Any, ado: Any, ado_valid: Any, past: History,
                       brightness: Any, ax: Any = None, title: str | None = None) -> Any:
    """One frame's boxes and their faded past in the ego frame.

    Parameters
    ----------
    ego_pose : array, shape (3,)
        The ego's world pose ``[x, y, yaw]`` at the frame; the picture is in its frame.
    ado, ado_valid : arrays, shapes (A, 5) and (A,)
        The frame's ado boxes ``[x, y, yaw, length, width]`` and which exist.
    past : History
        The frame's past (:func:`minimanc.world.history.history_of` for one frame).
    brightness : array, shape (H,)
        The opacity of the boxes ``1 … H`` steps ago (e.g. :func:`~minimanc.world.history.fade`).
    ax : matplotlib axes, optional
        Where to draw; None makes a new figure.
    title : str, optional
        The axes' title (default: the number of past steps).

    Returns
    -------
    ax : matplotlib axes

    Raises
    ------
    ValueError
        If the frame's arrays have other shapes, ``past`` holds not exactly one frame, or
        ``brightness`` does not hold one value per past step.
    """
    pose, a, v = _check_frame(ego_pose, ado, ado_valid)
    if not isinstance(past, History) or past.ego.shape[0] != 1:
        raise ValueError("past must be a History of one frame (history_of(..., frames=[t]))")
    shade = np.asarray(brightness, dtype=np.float64).reshape(-1)
    if shade.shape != (past.steps,):
        raise ValueError(f"brightness must hold {past.steps} values (one per past step); got "
                         f"shape {np.shape(brightness)}")
    if ax is None:
        _, ax = pyplot().subplots(figsize=(4, 4))
    for j in range(past.steps - 1, -1, -1):  # the oldest first, under the newer ones
        if past.ego_valid[0, j]:
            _draw_boxes(ax, _ego_box(past.ego[0, j]), pose, EGO_COLOUR, shade[j:j + 1], True)
        ok = past.ado_valid[0, j]
        _draw_boxes(ax, past.ado[0, j][ok], pose, ADO_COLOUR, np.full(int(ok.sum()), shade[j]),
                    True)
    _frame_axes(ax, pose, a, v)
    ax.set_title(title if title is not None else f"faded history, {past.steps} steps")
    ax.legend(fontsize=7, loc="lower right")
    return ax


def plot_input_ablation(table: Mapping[str, Sequence[float]], ax: Any = None,
                  reference: Mapping[str, Sequence[float]] | None = None,
                  title: str = "ablation, open loop") -> Any:
    """An ablation table's RMSEs as a ratio to its ``"all inputs"`` row, one pair of bars
    per row (acceleration, yaw rate); ``reference`` (another table) drawn as outlines.

    Parameters
    ----------
    table : mapping of str to (rmse_acceleration, rmse_yaw_rate)
        Rows named ``"all inputs"`` and ``"without <group>"``.
    ax : matplotlib axes, optional
        Where to draw; None makes a new figure.
    reference : mapping, optional
        The library's table, drawn as dashed outlines over the same rows.
    title : str
        The axes' title.

    Returns
    -------
    ax : matplotlib axes

    Raises
    ------
    ValueError
        If a table has no ``"all inputs"`` row, a row does not hold two positive finite
        numbers, or ``reference`` lacks a row of ``table``.
    """
    rows = _ratios(table, "table")
    ref = None if reference is None else _ratios(reference, "reference")
    if ref is not None and set(rows) - set(ref):
        raise ValueError(f"reference lacks the rows {sorted(set(rows) - set(ref))}")
    if ax is None:
        _, ax = pyplot().subplots(figsize=(6, 3.2))
    names = list(rows)
    x = np.arange(len(names))
    for k, (label, colour) in enumerate((("acceleration", "#ff7f0e"), ("yaw rate", "#2ca02c"))):
        ax.bar(x + (k - 0.5) * 0.38, [rows[n][k] for n in names], 0.38, color=colour,
               label=f"{label} (yours)" if ref is not None else label)
        if ref is not None:
            ax.bar(x + (k - 0.5) * 0.38, [ref[n][k] for n in names], 0.38, fill=False,
                   edgecolor="k", ls="--", label="library" if k == 0 else None)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xticks(x, [n.replace("without ", "− ") for n in names], rotation=30, fontsize=8)
    ax.set(ylabel="RMSE / RMSE with all inputs", title=title)
    ax.legend(fontsize=7)
    return ax


def _ratios(table: Mapping[str, Sequence[float]], name: str) -> dict[str, np.ndarray]:
    if not isinstance(table, Mapping) or "all inputs" not in table:
        raise ValueError(f"{name} must be a mapping with an 'all inputs' row; got "
                         f"{type(table).__name__}")
    out = {}
    for row, value in table.items():
        v = np.asarray(value, dtype=np.float64)
        if v.shape != (2,) or not np.all(np.isfinite(v)) or np.any(v <= 0):
            raise ValueError(f"{name}[{row!r}] must be two positive finite RMSEs; got {value!r}")
        out[str(row)] = v
    base = out["all inputs"]
    return {row: v / base for row, v in out.items()}


def _check_faded(value: Any) -> tuple[np.ndarray, ...]:
    """The student's faded boxes: ``(ego_past (n, 3), ego_bright (n,), ado_past (m, 5),
    ado_bright (m,))``."""
    if not isinstance(value, tuple) or len(value) != 4:
        raise ValueError("expected (ego_past, ego_brightness, ado_past, ado_brightness)")
    e, eb, a, ab = (np.asarray(x, dtype=np.float64) for x in value)
    if e.size % 3 or a.size % 5:
        raise ValueError(f"ego_past must hold poses (n, 3) and ado_past boxes (m, 5); got "
                         f"shapes {e.shape} and {a.shape}")
    e, a = e.reshape(-1, 3), a.reshape(-1, 5)
    if eb.shape != (len(e),) or ab.shape != (len(a),):
        raise ValueError(f"one brightness per box: {len(e)} ego and {len(a)} ado boxes, got "
                         f"{eb.shape} and {ab.shape}")
    return e, eb, a, ab


def plot_investigation_attempts(ego_pose: Any, ado: Any, ado_valid: Any,
                                faded: Callable[[], Any], reference: History,
                                brightness: Any, ablation: Callable[[], Any],
                                reference_table: Mapping[str, Sequence[float]]) -> Any:
    """Chapter 12's exercise figure: the library's faded history of a frame, the student's,
    and the student's ablation table over the library's.

    Parameters
    ----------
    ego_pose, ado, ado_valid : arrays, shapes (3,), (A, 5), (A,)
        The frame drawn (world frame).
    faded : callable
        No arguments; the student's faded boxes of that frame,
        ``(ego_past (n, 3), ego_brightness (n,), ado_past (m, 5), ado_brightness (m,))``.
    reference : History
        The library's past of the frame (:func:`minimanc.world.history.history_of`, one
        frame).
    brightness : array, shape (H,)
        The brightness asked for, per step ago: the library's panel is drawn with it.
    ablation : callable
        No arguments; the student's ablation table (see :func:`plot_input_ablation`).
    reference_table : mapping
        The library's table.

    Returns
    -------
    fig : matplotlib Figure
        Three axes: the library's past (left), the student's (middle; the two must look
        alike), the ablation (right).
    """
    pose, a, v = _check_frame(ego_pose, ado, ado_valid)
    fig, (left, mid, right) = pyplot().subplots(1, 3, figsize=(14, 4.4))
    plot_history_boxes(pose, a, v, reference, brightness, ax=left,
                       title="library: history_of at your decay")
    value, error = attempt(faded)
    if not error:
        value, error = attempt(_check_faded, value)
    if error:
        mid.set_title(f"your faded boxes: {error}", fontsize=9)
    else:
        e, eb, past_ado, ab = value
        boxes = np.concatenate([_ego_box(e), past_ado])
        colours = [EGO_COLOUR] * len(e) + [ADO_COLOUR] * len(past_ado)
        shade = np.concatenate([eb, ab])
        for k in np.argsort(shade, kind="stable"):  # the faintest first, under the others
            _draw_boxes(mid, boxes[k:k + 1], pose, colours[k], shade[k:k + 1], True)
        mid.set_title(f"yours: {len(e)} ego and {len(past_ado)} ado boxes in the past",
                      fontsize=9)
    _frame_axes(mid, pose, a, v)
    mid.legend(fontsize=7, loc="lower right")
    table, error = attempt(ablation)
    if not error:
        _, error = attempt(_ratios, table, "your table")
    if error:
        plot_input_ablation(reference_table, ax=right, title=f"library; yours: {error}")
        right.title.set_fontsize(9)
    else:
        plot_input_ablation(table, ax=right, reference=reference_table,
                      title="yours (bars) over the library's (dashed)")
    fig.tight_layout()
    return fig
