"""Chapter 0 — a chapter's key figure, redrawn from the student's own functions.

Every exercises notebook ends with one cell that calls a function of this module with
the functions the student wrote (it saves nothing, the cell ends in ``plt.show()``).
The figure draws the student's result over the library's reference, so a wrong answer
shows as a curve, a path or a label that departs from it. A function that raises (a
stub still raising ``NotImplementedError``, or a bug) is named in its panel's title
with the error, and only the reference is drawn: the notebook runs to the end.

* chapter 1: :func:`plot_edge_cotangents` — the computation graph with the cotangent
  on each edge (the student's ``edge_cotangents`` next to
  :func:`minimanc.autodiff.graph.computation_graph`);
* chapter 2: :func:`plot_valley_paths` — optimiser paths on the valley
  ½(100 θ₀² + θ₁²) (the student's momentum and Adam steps next to
  :mod:`minimanc.optim`);
* chapter 3: :func:`plot_stability_boundary` — the largest stable α over β for one
  sub-step of each integrator (the student's bounds next to the library's);
* chapter 4 (and any chapter whose figure is curves over time):
  :func:`plot_curve_attempts` — each of the student's curves solid over its reference
  dashed (the yaw of the quaternion DMP of eq. 2 turning the short way, trailing and
  tracking a turning goal).
* chapter 7: :func:`plot_bev_attempts` — one BEV frame of the dataset with the ado boxes
  and the human's future path put into pixels by the student's ego-frame transform,
  box test and pixel grid, over the library's :func:`minimanc.world.rasterize`;
* chapter 8: :func:`plot_drive_attempts` — the DMP head of eqs. 10–11 driving a map in
  closed loop (its controls integrated by the unicycle, the lane target re-read from the
  new pose every step), the student's head over the library's
  :func:`minimanc.models.dmp_head`;
* chapter 9: :func:`plot_track_error_attempts` — the displacement from the human split
  along and across the human's heading over time, for closed-loop runs, measured by the
  student's split next to :func:`minimanc.metrics.along_cross_track`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from minimanc.autodiff import toposort
from minimanc.autodiff.graph import Edge, Graph, Node
from minimanc.metrics.trajectory import along_cross_track as library_along_cross_track
from minimanc.viz.graph import plot_graph
from minimanc.viz.style import pyplot
from minimanc.viz.world import plot_map
from minimanc.world.geometry import DT, goal_in_ego_frame, to_ego_frame, unicycle_step
from minimanc.world.lanes import Map
from minimanc.world.maps import lane_targets
from minimanc.world.raster import RasterConfig, box_mask

__all__ = [
    "attempt",
    "graph_of_edges",
    "plot_bev_attempts",
    "plot_curve_attempts",
    "plot_drive_attempts",
    "plot_edge_cotangents",
    "plot_stability_boundary",
    "plot_track_error_attempts",
    "plot_valley_paths",
]


def attempt(fn: Callable[..., Any], *args: Any) -> tuple[Any, str]:
    """``(fn(*args), "")``, or ``(None, "ErrorName: message")`` when ``fn`` raises.

    Parameters
    ----------
    fn : callable
        A student's function (or anything that may raise).
    *args
        Its arguments.

    Returns
    -------
    value, error : tuple
        The value (None on an error) and the error as one line ("" when none).
    """
    try:
        return fn(*args), ""
    except Exception as exc:  # noqa: BLE001 - the figure names any error of the student's
        text = " ".join(str(exc).split())
        return None, f"{type(exc).__name__}: {text[:80]}" if text else type(exc).__name__


def graph_of_edges(edges: Sequence[tuple[Any, Any, Any]], names: Mapping[int, str]) -> Graph:
    """A :class:`~minimanc.autodiff.graph.Graph` of ``(parent, child, cotangent)`` triples.

    The nodes are any objects with ``.parents`` and ``.value`` (chapter 1's ``Var``);
    the output is the one child that is nobody's parent.

    Parameters
    ----------
    edges : sequence of (parent, child, cotangent)
        One triple per edge, as chapter 1's ``edge_cotangents`` returns them.
    names : mapping of id(node) to str
        Labels of the inputs; other nodes are named ``v<k>`` in forward order.

    Returns
    -------
    Graph
        Nodes in forward order (inputs first), one edge per triple.

    Raises
    ------
    ValueError
        If ``edges`` is empty or has no single output.
    """
    if not edges:
        raise ValueError("edges must hold at least one (parent, child, cotangent) triple")
    parents = {id(p) for p, _, _ in edges}
    ends = {id(c): c for _, c, _ in edges if id(c) not in parents}
    if len(ends) != 1:
        raise ValueError(f"edges must have one output (a child that is nobody's parent), "
                         f"got {len(ends)}")
    forward = toposort(next(iter(ends.values())), parents_of=lambda v: v.parents)[::-1]
    index = {id(n): k for k, n in enumerate(forward)}
    nodes = tuple(
        Node(k, names.get(id(n), f"v{k}"), (), np.asarray(getattr(n, "value", np.nan)))
        for k, n in enumerate(forward)
    )
    argnum: dict[int, int] = {}
    out = []
    for p, c, cot in edges:
        argnum[id(c)] = argnum.get(id(c), -1) + 1
        out.append(Edge(index[id(p)], index[id(c)], argnum[id(c)], np.asarray(cot, float)))
    inputs = tuple(index[id(n)] for n in forward if not n.parents)
    return Graph(nodes, tuple(out), inputs, index[id(forward[-1])])


def plot_edge_cotangents(
    edge_cotangents: Callable[[Any], Sequence[tuple[Any, Any, Any]]],
    end: Any,
    names: Mapping[int, str],
    reference: Graph,
) -> Any:
    """Chapter 1's figure: the library's computation graph (left) and the student's (right).

    Parameters
    ----------
    edge_cotangents : callable
        The student's function: output node → list of ``(parent, child, cotangent)``.
    end : node
        The output of a computation built from nodes with ``.parents`` and ``.value``.
    names : mapping of id(node) to str
        Labels of the inputs.
    reference : Graph
        The same computation from :func:`~minimanc.autodiff.graph.computation_graph`.

    Returns
    -------
    fig : matplotlib Figure
    """
    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 3.6))
    plot_graph(reference, ax=left)
    left.set_title("library: computation_graph")
    edges, error = attempt(edge_cotangents, end)
    if not error:
        graph, error = attempt(graph_of_edges, list(edges), names)
    if error:
        right.set_axis_off()
        right.set_title(f"your edge_cotangents: {error}", fontsize=9)
    else:
        plot_graph(graph, ax=right)
        right.set_title("yours: edge_cotangents (the labels must agree)")
    return fig


Step = Callable[[np.ndarray, np.ndarray, Any, int], tuple[np.ndarray, Any]]


def _path(step: Step, state: Any, scales: np.ndarray, start: np.ndarray, steps: int):
    theta, path = start.copy(), [start.copy()]
    for t in range(1, steps + 1):
        theta, state = step(theta, scales * theta, state, t)
        path.append(np.asarray(theta, float).copy())
    return np.array(path)


def plot_valley_paths(
    yours: Mapping[str, tuple[Step, Any]],
    reference: Mapping[str, tuple[Step, Any]],
    steps: int = 100,
    scales: Sequence[float] = (100.0, 1.0),
    start: Sequence[float] = (1.0, 1.0),
) -> Any:
    """Chapter 2's figure: optimiser paths on the valley f(θ) = ½ Σ scalesᵢ θᵢ².

    Each run is ``(step, state)`` with ``step(theta, grad, state, t) -> (theta, state)``
    (``t`` counts from 1); the gradient is ``scales * theta``.

    Parameters
    ----------
    yours : mapping of label to (step, initial state)
        Runs that call the student's functions (solid lines).
    reference : mapping of label to (step, initial state)
        The same runs with the library's optimisers (dashed lines).
    steps : int, optional (default: 100)
        Steps per run.
    scales : sequence of float, optional (default: (100, 1))
        The curvature of each coordinate.
    start : sequence of float, optional (default: (1, 1))
        The first θ.

    Returns
    -------
    fig : matplotlib Figure
    """
    plt = pyplot()
    scale, theta0 = np.asarray(scales, float), np.asarray(start, float)
    fig, ax = plt.subplots(figsize=(6.5, 4))
    errors, drawn = [], [np.array([[-1.2, -0.3], [1.2, 1.2]])]
    for label, (step, state) in reference.items():
        path = _path(step, state, scale, theta0, steps)
        drawn.append(path)
        ax.plot(path[:, 0], path[:, 1], "--", lw=2.5, alpha=0.6, label=f"{label} (library)")
    for label, (step, state) in yours.items():
        path, error = attempt(_path, step, state, scale, theta0, steps)
        if error:
            errors.append(f"{label}: {error}")
        else:
            drawn.append(path[np.all(np.isfinite(path), axis=1)])
            ax.plot(path[:, 0], path[:, 1], ".-", lw=1, ms=3, label=label)
    every = np.concatenate(drawn)
    lo, hi = np.clip(every.min(axis=0), -10, 0), np.clip(every.max(axis=0), 0, 10)
    t0, t1 = np.meshgrid(np.linspace(lo[0], hi[0], 120), np.linspace(lo[1], hi[1], 120))
    ax.contour(t0, t1, scale[0] * t0 ** 2 + scale[1] * t1 ** 2, levels=20, colors="0.85")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_xlabel("θ0 (steep)")
    ax.set_ylabel("θ1 (flat)")
    ax.set_title("\n".join(errors) or "your steps (solid) over the library's (dashed)",
                 fontsize=9)
    ax.legend(fontsize=8)
    return fig


def plot_stability_boundary(
    yours: Mapping[str, Callable[[float], float]],
    reference: Mapping[str, Callable[[float], float]],
    betas: Sequence[float],
    h: float,
) -> Any:
    """Chapter 3's figure: the largest stable α over β for one sub-step of length ``h``.

    Parameters
    ----------
    yours : mapping of label to callable
        ``beta -> alpha_max`` from the student's functions (markers).
    reference : mapping of label to callable
        The same bounds from the library (lines), in the same order.
    betas : sequence of float
        Where to evaluate them.
    h : float
        The sub-step length in seconds (for the title).

    Returns
    -------
    fig : matplotlib Figure
    """
    plt = pyplot()
    grid = np.asarray(betas, float)
    fig, ax = plt.subplots(figsize=(7, 4))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (label, fn) in enumerate(reference.items()):
        ax.plot(grid, [fn(float(b)) for b in grid], "-", color=colours[k % len(colours)],
                alpha=0.6, label=f"{label} (library)")
    errors = []
    for k, (label, fn) in enumerate(yours.items()):
        values, error = attempt(lambda f=fn: [float(f(float(b))) for b in grid])
        if error:
            errors.append(f"{label}: {error}")
        else:
            ax.plot(grid, values, "o", ms=3.5, color=colours[k % len(colours)], label=label)
    ax.set_xlabel("β (1/s)")
    ax.set_ylabel("largest stable α (1/s)")
    ax.set_title("\n".join(errors) or f"stable below each curve, one sub-step h = {h:g} s",
                 fontsize=9)
    ax.legend(fontsize=8)
    return fig


def plot_curve_attempts(
    x: Any,
    curves: Sequence[tuple[str, Callable[[], Any], Any]],
    ax: Any = None,
    title: str = "",
) -> Any:
    """Draw each of a student's curves (solid) over its reference (dashed).

    Parameters
    ----------
    x : array-like, shape (n,)
        Abscissa shared by every curve.
    curves : sequence of (label, fn, reference)
        ``fn()`` returns the student's ``n`` values; ``reference`` is the library's
        (or None: nothing to compare with). A ``fn`` that raises is named in the title
        and only its reference is drawn.
    ax : matplotlib Axes, optional (default: None)
        Axes to draw on; a new figure when None.
    title : str, optional (default: "")
        Title when no function raised.

    Returns
    -------
    ax : matplotlib Axes
        The axes with one line per curve that could be drawn, and a legend if any.
    """
    plt = pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(6.5, 3.5))
    x = np.asarray(x, dtype=float)
    errors = []
    for k, (label, fn, reference) in enumerate(curves):
        colour = f"C{k}"
        if reference is not None:
            ax.plot(x, np.asarray(reference, dtype=float), "--", color=colour, lw=1,
                    label=f"{label}: reference")
        values, error = attempt(fn)
        if error:
            errors.append(f"{label}: {error}")
            continue
        values = np.asarray(values, dtype=float)
        if values.shape != x.shape:
            errors.append(f"{label}: expected {x.shape[0]} values, got shape {values.shape}")
            continue
        ax.plot(x, values, "o-", color=colour, ms=3, label=f"{label}: yours")
    ax.set_title("\n".join(errors) or title, fontsize=7 if errors else None)
    if ax.get_lines():
        ax.legend(fontsize=8)
    return ax



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
    ego frame by the student's ``pose_in_ego_frame`` and rasterised by their
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
    pose_in_ego_frame, world_to_pixel, box_pixels : callable
        The student's functions of exercises 7.1, 7.2 and 7.3.

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


Head = Callable[[np.ndarray, np.ndarray], Any]


def drive_on_route(head: Head, m: Map, start: Any, motion: Any, steps: int,
                   dt: float = DT) -> tuple[np.ndarray, np.ndarray]:
    """Drive ``head`` along the route of the map ``m`` in closed loop, alone on the road.

    A figure's minimal loop (no traffic, no scene, no observation but the lane target and
    the motion), so that a student's bare head function can drive; the course's closed
    loop is :func:`minimanc.rollout.drive`.

    Every step the lane target is read from the current pose
    (:func:`minimanc.world.lane_targets`), the head maps ``(lane_target (1, K, 2),
    motion (1, 2))`` to the controls ``[speed, yaw rate]``, the unicycle moves the pose
    by them (:func:`minimanc.world.unicycle_step`) and they become the next motion.

    Parameters
    ----------
    head : callable
        ``(lane_target, motion) -> controls`` of shape ``(1, 2)``.
    m : Map
        The map whose route gives the lane target.
    start : array-like, shape (3,)
        The first pose ``[x, y, yaw]``.
    motion : array-like, shape (2,)
        The first ``[speed, yaw rate]``.
    steps : int
        Control steps.
    dt : float, optional (default: 0.5)
        The step in seconds.

    Returns
    -------
    poses : ndarray, shape (steps + 1, 3)
    controls : ndarray, shape (steps, 2)

    Raises
    ------
    ValueError
        If the head returns another shape than ``(1, 2)`` or a value that is not finite.
    """
    pose, mot = np.asarray(start, dtype=float), np.asarray(motion, dtype=float)
    poses, controls = [pose], []
    for _ in range(steps):
        u = np.asarray(head(lane_targets(m, pose)[None], mot[None]), dtype=float)
        if u.shape != (1, 2) or not np.all(np.isfinite(u)):
            raise ValueError(f"the head must return finite controls of shape (1, 2), got "
                             f"{u.shape} {np.round(u, 3).tolist()}")
        mot = u[0]
        pose = unicycle_step(pose, mot, dt)
        poses.append(pose)
        controls.append(mot)
    return np.array(poses), np.array(controls)


def plot_drive_attempts(
    m: Map,
    start: Any,
    motion: Any,
    head: Head,
    reference: Head,
    steps: int = 40,
    dt: float = DT,
) -> Any:
    """Chapter 8's figure: the student's DMP head and the library's driving one map.

    Both heads run :func:`drive_on_route` from the same pose and motion; the left panel draws
    the two paths on the map (the student's solid, the library's dashed), the right
    one the speed over time. The title gives the largest distance between the two
    paths, or names the error of a head that raised.

    Parameters
    ----------
    m : Map
        The map (its route gives the lane target).
    start : array-like, shape (3,)
        The first pose.
    motion : array-like, shape (2,)
        The first ``[speed, yaw rate]``.
    head : callable
        The student's head, ``(lane_target (1, K, 2), motion (1, 2)) -> (1, 2)``.
    reference : callable
        The library's head, same signature.
    steps : int, optional (default: 40)
        Control steps.
    dt : float, optional (default: 0.5)
        The step in seconds.

    Returns
    -------
    fig : matplotlib Figure
    """
    ref_poses, ref_u = drive_on_route(reference, m, start, motion, steps, dt)
    out, error = attempt(drive_on_route, head, m, start, motion, steps, dt)
    plt = pyplot()
    fig, (top, speed) = plt.subplots(1, 2, figsize=(10, 4.2))
    plot_map(m, top)
    top.plot(ref_poses[:, 0], ref_poses[:, 1], "--", color="tab:green", lw=2.5,
             label="library head")
    t = dt * np.arange(1, steps + 1)
    speed.plot(t, ref_u[:, 0], "--", color="tab:green", lw=2.5, label="library head")
    drawn = [ref_poses[:, :2]]
    if error:
        title = f"your head: {error}"
    else:
        poses, u = out
        drawn.append(poses[:, :2])
        top.plot(poses[:, 0], poses[:, 1], "-", color="tab:red", lw=1.2, label="your head")
        speed.plot(t, u[:, 0], "-", color="tab:red", lw=1.2, label="your head")
        gap = float(np.max(np.linalg.norm(poses[:, :2] - ref_poses[:, :2], axis=1)))
        title = f"your head (solid) over the library's (dashed): paths at most {gap:.2f} m apart"
    every = np.concatenate(drawn)
    lo, hi = every.min(axis=0) - 20.0, every.max(axis=0) + 20.0
    half = 0.5 * float(np.max(hi - lo))
    mid = 0.5 * (lo + hi)
    top.set_xlim(mid[0] - half, mid[0] + half)
    top.set_ylim(mid[1] - half, mid[1] + half)
    top.legend(fontsize=8, loc="lower right")
    speed.set_xlabel("time (s)")
    speed.set_ylabel("speed (m/s)")
    speed.legend(fontsize=8)
    fig.suptitle(title, fontsize=9)
    return fig


def plot_track_error_attempts(
    runs: Mapping[str, Callable[[], Any]],
    human: Any,
    along_cross_track: Callable[[Any, Any], Any],
    dt: float = DT,
) -> Any:
    """Chapter 9's figure: how far each closed-loop run is behind or ahead of the human
    (left) and beside the human's line (right), over time.

    The displacement from the human at each step is split in the frame of the human's
    heading (along, cross); each panel shows its mean magnitude over the scenes, from
    the student's ``along_cross_track`` (solid) over
    :func:`minimanc.metrics.along_cross_track` (dashed), one colour per run. A run or a
    split that raises is named in the title and only what could be computed is drawn.

    Parameters
    ----------
    runs : mapping of label to callable
        ``run()`` returns the poses ``(S, T, 3)`` of one closed-loop run.
    human : array-like, shape (S, T, 3)
        The human's poses.
    along_cross_track : callable
        The student's ``(ego, human) -> (along, cross)``, each ``(S, T)``.
    dt : float, optional (default: 0.5)
        The step in seconds (the time axis).

    Returns
    -------
    fig : matplotlib Figure

    Raises
    ------
    ValueError
        If ``human`` is not ``(S, T, 3)``.
    """
    ref_human = np.asarray(human, dtype=float)
    if ref_human.ndim != 3 or ref_human.shape[-1] != 3:
        raise ValueError(f"human must have shape (S, T, 3), got {ref_human.shape}")
    t = dt * np.arange(ref_human.shape[1])
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    errors = []
    for k, (label, run) in enumerate(runs.items()):
        colour = f"C{k}"
        ego, error = attempt(run)
        if error:
            errors.append(f"{label}: {error}")
            continue
        reference = library_along_cross_track(ego, ref_human)
        split, error = attempt(along_cross_track, ego, ref_human)
        if not error:
            shapes = [np.shape(x) for x in split] if isinstance(split, tuple) else None
            if shapes != [np.shape(reference[0])] * 2:
                error = f"expected (along, cross) of shape {np.shape(reference[0])}, got {shapes}"
        if error:
            errors.append(f"your along_cross_track on {label}: {error}")
        for j, ax in enumerate(axes):
            ax.plot(t, np.abs(reference[j]).mean(axis=0), "--", color=colour, lw=1,
                    label=f"{label}: library")
            if not error:
                ax.plot(t, np.abs(np.asarray(split[j], dtype=float)).mean(axis=0), "o-",
                        color=colour, ms=3, label=f"{label}: yours")
    for ax, name in zip(axes, ("along", "across")):
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"mean |{'along' if name == 'along' else 'cross'}| (m)")
        ax.set_yscale("symlog", linthresh=0.1)
        ax.set_title(f"{name} the human's heading", fontsize=9)
        if ax.get_lines():
            ax.legend(fontsize=7)
    fig.suptitle("\n".join(errors) or "your along_cross_track (solid) over the library's "
                 "(dashed)", fontsize=9)
    return fig
