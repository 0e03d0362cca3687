"""minimanc.viz.exercises: the exercises notebooks' last figures, drawn from a student's
functions over the library's, naming a function that raises instead of failing."""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import minimanc.autodiff.numpy as anp  # noqa: E402
from minimanc import dmp, metrics, models, optim, world  # noqa: E402
from minimanc.autodiff import computation_graph  # noqa: E402
from minimanc.viz import exercises as vx  # noqa: E402


class Var:
    """Chapter 1's scalar node: a value, its parents and the local derivatives."""

    def __init__(self, value, parents=(), local=()):
        self.value, self.parents, self.local = float(value), parents, local


def mul(a, b):
    return Var(a.value * b.value, (a, b), (b.value, a.value))


def add(a, b):
    return Var(a.value + b.value, (a, b), (1.0, 1.0))


def vsin(a):
    return Var(math.sin(a.value), (a,), (math.cos(a.value),))


def edges_right(end):
    cot, out = {id(end): 1.0}, []
    order = [end]
    seen = {id(end)}
    k = 0
    while k < len(order):   # breadth first is a valid order for this small tree-like graph
        for p in order[k].parents:
            if id(p) not in seen:
                seen.add(id(p))
                order.append(p)
        k += 1
    for node in order:
        for p, loc in zip(node.parents, node.local):
            out.append((p, node, cot[id(node)] * loc))
            cot[id(p)] = cot.get(id(p), 0.0) + cot[id(node)] * loc
    return out


def test_attempt_returns_the_value_or_names_the_error():
    assert vx.attempt(lambda a, b: a + b, 1, 2) == (3, "")

    def stub(x):
        raise NotImplementedError("Exercise ex01_6: Cotangent on each edge")

    assert vx.attempt(stub, 1) == (None, "NotImplementedError: Exercise ex01_6: Cotangent on "
                                         "each edge")


def test_graph_of_edges_is_the_library_graph_of_the_same_computation():
    x = Var(0.7)
    y = add(vsin(mul(x, x)), x)
    graph = vx.graph_of_edges(edges_right(y), {id(x): "x"})
    ref = computation_graph(lambda x: anp.sin(x * x) + x, np.array(0.7))
    assert [n.name for n in graph.nodes] == ["x", "v1", "v2", "v3"]
    assert len(graph.edges) == len(ref.edges) == 5 and graph.inputs == (0,)
    assert graph.output == 3
    assert math.isclose(float(graph.gradients()[0]), float(ref.gradients()[0]), rel_tol=1e-12)
    with pytest.raises(ValueError, match="at least one"):
        vx.graph_of_edges([], {})


def test_the_three_figures_draw_yours_over_the_reference_and_name_a_stub():
    def stub(*_):
        raise NotImplementedError("Exercise exNN: stub")

    x = Var(0.7)
    y = add(vsin(mul(x, x)), x)
    ref = computation_graph(lambda x: anp.sin(x * x) + x, np.array(0.7))
    fig = vx.plot_edge_cotangents(edges_right, y, {id(x): "x"}, ref)
    assert fig.axes[1].get_title().startswith("yours")
    fig = vx.plot_edge_cotangents(stub, y, {id(x): "x"}, ref)
    assert "NotImplementedError: Exercise exNN: stub" in fig.axes[1].get_title()

    def sgd(theta, g, state, t):
        return theta - 0.01 * g, state

    def lib_sgd(theta, g, state, t):
        new, state = optim.sgd_update({"t": g}, state, {"t": theta}, lr=0.01, momentum=0.0)
        return new["t"], state

    fig = vx.plot_valley_paths({"your SGD": (sgd, None), "stub": (stub, None)},
                               {"SGD": (lib_sgd, optim.sgd_init({"t": np.ones(2)}))}, steps=20)
    lines = fig.axes[0].get_lines()
    assert len(lines) == 2                              # the library's and yours; not the stub
    assert np.allclose(lines[0].get_xydata(), lines[1].get_xydata())
    assert "stub: NotImplementedError" in fig.axes[0].get_title()

    euler = lambda b: dmp.max_stable_alpha(b, 0.5, "euler", 1)  # noqa: E731
    fig = vx.plot_stability_boundary({"yours": euler, "stub": stub}, {"Euler": euler},
                                     np.linspace(0.1, 3, 7), 0.5)
    ref_line, mine = fig.axes[0].get_lines()
    assert np.allclose(ref_line.get_ydata(), mine.get_ydata())
    assert "stub: NotImplementedError" in fig.axes[0].get_title()
    plt.close("all")


def test_the_bev_figure_counts_what_agrees_with_the_library_and_names_a_stub():
    cfg = world.RasterConfig()
    m = world.random_map(np.random.default_rng(3), "straight")
    p, h = m.route_pose(m.start_s + 20.0)
    ego = np.array([p[0], p[1], h])
    ahead = np.array([np.cos(h), np.sin(h)])
    left = np.array([-np.sin(h), np.cos(h)])
    boxes = np.array([[*(p + 12 * ahead), h + 0.3, 4.5, 1.9],
                      [*(p + 25 * ahead + 3.5 * left), h + np.pi, 4.7, 1.9]])
    bev = world.rasterize(m, ego, boxes, np.array([True, True]), cfg)
    path = p + np.outer(np.arange(0.0, 30.0, 3.0), ahead) + 0.2 * left   # 10 points

    def to_pixel(points, pose, c):
        return c.ego_to_pixel(world.to_ego_frame(points, pose))

    def box(b, c):
        return world.box_mask(*c.pixel_centres(), b)

    fig = vx.plot_bev_attempts(bev, ego, boxes, path, cfg, world.goal_in_ego_frame, to_pixel,
                               box)
    title = fig.axes[1].get_title()
    X, Y = cfg.pixel_centres()
    ego_boxes = np.concatenate([world.goal_in_ego_frame(boxes[:, :3], ego), boxes[:, 3:]], 1)
    n = int(world.box_mask(X, Y, ego_boxes).any(axis=0).sum())
    assert n > 10
    assert f"box pixels: yours {n}, library {n}, shared {n}" in title
    assert "path: 10 of 10 points on the library's pixel" in title
    yellow = np.all(bev == [255, 255, 0], axis=-1)
    assert yellow.sum() > 0 and np.all(world.box_mask(X, Y, ego_boxes).any(axis=0)[yellow])

    def mirrored(points, pose, c):      # the rotation by +yaw instead of -yaw: a wrong frame
        return to_pixel(points, pose * np.array([1.0, 1.0, -1.0]), c)

    def stub(*_):
        raise NotImplementedError("Exercise ex07_3: stub")

    fig = vx.plot_bev_attempts(bev, ego, boxes, path, cfg, world.goal_in_ego_frame, mirrored,
                               stub)
    title = fig.axes[1].get_title()
    assert "boxes: NotImplementedError: Exercise ex07_3: stub" in title
    hits = int(title.split("path: ")[1].split(" of")[0])
    assert hits < 10
    with pytest.raises(ValueError, match="bev must have shape"):
        vx.plot_bev_attempts(bev[:10], ego, boxes, path, cfg, stub, stub, stub)
    plt.close("all")


def test_the_drive_figure_puts_a_head_on_the_road_and_names_a_stub():
    cfg = models.ModelConfig()
    m = world.random_map(np.random.default_rng(3), "curved")
    p, h = m.route_pose(m.start_s)
    start, motion = np.array([p[0], p[1], h]), np.array([5.0, 0.0])
    logits = np.array([[*dmp.logits_from_gains(4.0, 0.45), *dmp.logits_from_gains(3.0, 1.0)]])

    def library(lane, mot):
        return models.dmp_head(logits, lane, mot, cfg)[0]

    fig = vx.plot_drive_attempts(m, start, motion, library, library, steps=12)
    assert "paths at most 0.00 m apart" in fig._suptitle.get_text()
    lines = fig.axes[1].get_lines()
    assert len(lines) == 2 and np.allclose(lines[0].get_ydata(), lines[1].get_ydata())

    def constant(lane, mot):     # a head that ignores the lane: drives straight on
        return np.array([[5.0, 0.0]])

    fig = vx.plot_drive_attempts(m, start, motion, constant, library, steps=12)
    gap = float(fig._suptitle.get_text().split("at most ")[1].split(" m")[0])
    assert gap > 0.5

    def stub(*_):
        raise NotImplementedError("Exercise ex08_2: stub")

    fig = vx.plot_drive_attempts(m, start, motion, stub, library, steps=12)
    assert "your head: NotImplementedError: Exercise ex08_2: stub" in fig._suptitle.get_text()
    assert len(fig.axes[1].get_lines()) == 1
    plt.close("all")


def test_the_track_error_figure_draws_your_split_over_the_library_and_names_errors():
    human = np.zeros((2, 6, 3))
    human[:, :, 0] = 5.0 * np.arange(6)                     # east at 10 m/s
    human[1, :, 2] = np.pi / 2                               # scene 1 faces north
    left = human + [0.0, 1.0, 0.0]                           # 1 m north of the human
    runs = {"north": lambda: left, "broken run": lambda: 1 / 0}
    fig = vx.plot_track_error_attempts(runs, human, metrics.along_cross_track)
    along_ax, cross_ax = fig.axes
    ref, mine = cross_ax.get_lines()
    assert np.allclose(ref.get_ydata(), 0.5) and np.allclose(mine.get_ydata(), 0.5)
    assert np.allclose(along_ax.get_lines()[1].get_ydata(), 0.5)   # along for scene 1
    assert "broken run: ZeroDivisionError" in fig._suptitle.get_text()

    def swapped(ego, h):   # along and cross exchanged: the panels disagree with the library
        a, c = metrics.along_cross_track(ego, h)
        return c, a

    fig = vx.plot_track_error_attempts({"north": lambda: left[:1]}, human[:1], swapped)
    assert fig._suptitle.get_text().startswith("your along_cross_track (solid)")
    ref, mine = fig.axes[0].get_lines()
    assert not np.allclose(ref.get_ydata(), mine.get_ydata())

    def stub(*_):
        raise NotImplementedError("Exercise ex09_4: stub")

    fig = vx.plot_track_error_attempts({"north": lambda: left}, human, stub)
    assert ("your along_cross_track on north: NotImplementedError: Exercise ex09_4: stub"
            in fig._suptitle.get_text())
    assert len(fig.axes[0].get_lines()) == 1                # the library's only
    with pytest.raises(ValueError, match="human must have shape"):
        vx.plot_track_error_attempts({}, human[0], stub)
    plt.close("all")


def _stub():
    raise NotImplementedError("Exercise ex99_1: to do")


def test_curves_draw_yours_over_the_reference_and_name_a_stub():
    x = np.arange(5.0)
    ax = vx.plot_curve_attempts(x, [("mine", lambda: x ** 2, x ** 2), ("todo", _stub, -x)],
                                title="t")
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels == ["mine: reference", "mine: yours", "todo: reference"]
    assert "todo: NotImplementedError: Exercise ex99_1" in ax.get_title()


def test_curves_refuse_a_wrong_length_in_the_title():
    ax = vx.plot_curve_attempts(np.arange(3.0), [("short", lambda: [1.0, 2.0], None)])
    assert ax.get_title() == "short: expected 3 values, got shape (2,)"
    assert not ax.get_lines()
