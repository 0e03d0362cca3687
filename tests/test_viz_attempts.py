"""The exercises' last figures of chapters 4–6: a student's curves, automata and CAM
overlays drawn over the library's, a function that raises named in the title."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from minimanc import vagn  # noqa: E402
from minimanc.viz.automaton import plot_automaton_attempts  # noqa: E402
from minimanc.viz.exercises import plot_curve_attempts  # noqa: E402
from minimanc.viz.saliency import plot_overlay_attempts  # noqa: E402


def stub():
    raise NotImplementedError("Exercise ex99_1: to do")


def test_curves_draw_yours_over_the_reference_and_name_a_stub():
    x = np.arange(5.0)
    ax = plot_curve_attempts(x, [("mine", lambda: x ** 2, x ** 2), ("todo", stub, -x)],
                             title="t")
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels == ["mine: reference", "mine: yours", "todo: reference"]
    assert "todo: NotImplementedError: Exercise ex99_1" in ax.get_title()


def test_curves_refuse_a_wrong_length_in_the_title():
    ax = plot_curve_attempts(np.arange(3.0), [("short", lambda: [1.0, 2.0], None)])
    assert ax.get_title() == "short: expected 3 values, got shape (2,)"
    assert not ax.get_lines()


def test_automaton_panels_fall_back_to_the_reference():
    W = vagn.init_vagn(np.random.default_rng(0), 2, 3, scale=1.0)
    T = vagn.transition_matrix(np.array([1.0, 0.0]), W)
    qs = vagn.rollout(vagn.uniform_state(3), np.ones((4, 2)), W)
    axes = plot_automaton_attempts([("T", "T", lambda: T, T), ("todo", "T", stub, T),
                                    ("bad", "q", lambda: -qs, None), ("q", "q", lambda: qs, qs)])
    titles = [ax.get_title() for ax in axes]
    assert titles[0] == "T (yours)" and titles[3] == "q (yours)"
    assert titles[1].startswith("todo: reference\nyours: NotImplementedError")
    assert titles[2].startswith("bad: nothing\nyours: ")         # not a distribution
    assert axes[1].patches or axes[1].collections               # the reference was drawn


def test_automaton_panels_refuse_unknown_kinds_and_axes_counts():
    with pytest.raises(ValueError, match="kinds must be 'T' or 'q'"):
        plot_automaton_attempts([("x", "graph", stub, None)])
    _, axes = plt.subplots(1, 2)
    with pytest.raises(ValueError, match="expected 1 axes, got 2"):
        plot_automaton_attempts([("x", "T", stub, None)], axes=axes)


def test_overlays_draw_yours_or_name_the_error():
    image = np.zeros((4, 4, 3), np.uint8)
    ramp = np.arange(16.0).reshape(4, 4)
    axes = plot_overlay_attempts(image, [("mine", lambda: ramp, None), ("todo", stub, ramp),
                                         ("none", stub, None)])
    assert len(axes) == 4 and axes[1].get_title() == "mine"
    assert axes[2].get_title().startswith("todo: reference\nyours: NotImplementedError")
    assert axes[2].images and not axes[3].images
    with pytest.raises(ValueError, match="expected 2 axes, got 1"):
        plot_overlay_attempts(image, [("x", stub, None)], axes=[axes[0]])
