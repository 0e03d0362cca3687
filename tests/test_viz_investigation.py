"""The figures of chapter 12 (minimanc.viz.investigation): faded history boxes, the ablation
bars, and the exercise figure that names a student's stub instead of stopping."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from minimanc.viz.investigation import (  # noqa: E402
    plot_history_boxes,
    plot_input_ablation,
    plot_investigation_attempts,
)
from minimanc.world.history import fade, history_of  # noqa: E402


def stub():
    raise NotImplementedError("Exercise ex12_4: to do")


def track(T: int = 6):
    """An ego driving along x at 4 m/s, one ado 10 m ahead at 3 m/s, a second ado that
    exists only from step 3 on (slot 1)."""
    t = np.arange(T, dtype=float)
    ego = np.stack([2.0 * t, np.zeros(T), np.zeros(T)], axis=1)
    ado = np.zeros((T, 2, 5))
    ado[:, 0] = np.stack([10 + 1.5 * t, np.zeros(T), np.zeros(T), np.full(T, 4.5),
                          np.full(T, 1.8)], axis=1)
    ado[:, 1] = [0.0, 3.5, 0.0, 4.0, 1.8]
    valid = np.ones((T, 2), bool)
    valid[:3, 1] = False
    return ego, ado, valid


def alphas(ax):
    return sorted(round(p.get_alpha(), 6) for p in ax.patches if p.get_fill())


def test_history_boxes_draw_every_past_box_at_its_brightness():
    ego, ado, valid = track()
    past = history_of(ego, ado, valid, 2, frames=[4])
    ax = plot_history_boxes(ego[4], ado[4], valid[4], past, fade(2))
    # now: ego + 2 ados at 1; one step ago (step 3): ego + 2 ados; two ago (step 2): ego + 1
    assert alphas(ax) == [round(1 / 3, 6)] * 2 + [round(2 / 3, 6)] * 3 + [1.0] * 3
    assert ax.get_title() == "faded history, 2 steps"
    # the leader, 8 m ahead at step 4 (4.5 m long), is drawn ahead: the vertical is forward
    tops = [p.get_xy()[:, 1].max() for p in ax.patches]
    assert max(tops) == pytest.approx(8.0 + 2.25)


def test_history_boxes_before_the_first_step_draw_nothing_of_the_past():
    ego, ado, valid = track()
    past = history_of(ego, ado, valid, 3, frames=[0])
    ax = plot_history_boxes(ego[0], ado[0], valid[0], past, [0.9, 0.5, 0.1], title="t0")
    assert alphas(ax) == [1.0, 1.0] and ax.get_title() == "t0"


def test_history_boxes_refuse_a_wrong_brightness_or_frame_count():
    ego, ado, valid = track()
    past = history_of(ego, ado, valid, 2, frames=[4])
    with pytest.raises(ValueError, match="brightness must hold 2 values"):
        plot_history_boxes(ego[4], ado[4], valid[4], past, [0.5])
    with pytest.raises(ValueError, match="History of one frame"):
        plot_history_boxes(ego[4], ado[4], valid[4], history_of(ego, ado, valid, 2), fade(2))
    with pytest.raises(ValueError, match="ego_pose must be a finite"):
        plot_history_boxes([0.0, np.nan, 0.0], ado[4], valid[4], past, fade(2))


def test_ablation_bars_are_ratios_to_all_inputs():
    table = {"all inputs": (0.2, 0.04), "without lane": (0.3, 0.12)}
    ax = plot_input_ablation(table)
    heights = [round(p.get_height(), 9) for p in ax.patches]
    assert heights == [1.0, 1.5, 1.0, 3.0]  # acceleration bars first, then yaw rate
    with pytest.raises(ValueError, match="'all inputs' row"):
        plot_input_ablation({"without lane": (0.3, 0.1)})
    with pytest.raises(ValueError, match=r"table\['without lane'\] must be two positive"):
        plot_input_ablation({"all inputs": (0.2, 0.04), "without lane": (0.0, 0.1)})
    with pytest.raises(ValueError, match="reference lacks the rows"):
        plot_input_ablation(table, reference={"all inputs": (0.2, 0.04)})


def test_attempts_draw_yours_or_name_the_error():
    ego, ado, valid = track()
    past = history_of(ego, ado, valid, 2, frames=[4])
    shade = np.array([0.6, 0.36])
    ref = {"all inputs": (0.2, 0.04), "without leader": (0.25, 0.04)}

    def mine():
        return (ego[[3, 2]], shade, np.concatenate([ado[3], ado[2, :1]]),
                np.array([0.6, 0.6, 0.36]))

    fig = plot_investigation_attempts(ego[4], ado[4], valid[4], mine, past, shade,
                                      lambda: ref, ref)
    left, mid, right = fig.axes[:3]
    assert alphas(left) == alphas(mid) == [0.36, 0.36, 0.6, 0.6, 0.6, 1.0, 1.0, 1.0]
    assert mid.get_title() == "yours: 2 ego and 3 ado boxes in the past"
    assert right.get_title() == "yours (bars) over the library's (dashed)"
    fig = plot_investigation_attempts(ego[4], ado[4], valid[4], stub, past, shade, stub, ref)
    left, mid, right = fig.axes[:3]
    assert mid.get_title().startswith("your faded boxes: NotImplementedError: Exercise ex12_4")
    assert alphas(mid) == [1.0, 1.0, 1.0]  # only the frame itself
    assert right.get_title().startswith("library; yours: NotImplementedError")
    assert right.patches, "the library's table is still drawn"


def test_attempts_name_a_wrong_shape_and_a_bad_table():
    ego, ado, valid = track()
    past = history_of(ego, ado, valid, 1, frames=[4])
    ref = {"all inputs": (0.2, 0.04)}
    fig = plot_investigation_attempts(
        ego[4], ado[4], valid[4], lambda: (ego[3], np.ones(2), ado[3], np.ones(2)), past,
        [0.5], lambda: {"without lane": (1.0, 1.0)}, ref)
    mid, right = fig.axes[1:3]
    assert "one brightness per box: 1 ego and 2 ado boxes" in mid.get_title()
    assert "'all inputs' row" in right.get_title()
    fig = plot_investigation_attempts(ego[4], ado[4], valid[4], lambda: [1, 2], past, [0.5],
                                      lambda: ref, ref)
    assert "expected (ego_past, ego_brightness" in fig.axes[1].get_title()
