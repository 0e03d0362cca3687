"""minimanc.viz.dagger: chapter 11's exercises figure, the student's DAgger rounds drawn over
the library's, a function that raises (or returns the wrong length) named in the title."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from minimanc.viz.dagger import plot_round_attempts  # noqa: E402


def stub():
    raise NotImplementedError("Exercise ex99_1: to do")


def test_rounds_draw_yours_over_the_reference_with_bc():
    ref = [3.0, 2.5, 2.0, 1.8]
    ax = plot_round_attempts({"p = 0.5": lambda: list(ref)}, {"p = 0.5": ref}, bc=2.2)
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels == ["p = 0.5 (library)", "p = 0.5 (yours)", "BC, same budget"]
    yours = ax.get_lines()[1]
    assert np.array_equal(yours.get_xdata(), [0, 1, 2, 3])
    assert np.array_equal(yours.get_ydata(), ref)
    assert ax.get_lines()[0].get_linestyle() == "--" and yours.get_linestyle() == "-"
    assert np.allclose(ax.get_lines()[2].get_ydata(), 2.2)
    assert ax.get_title() == "your DAgger rounds (solid) over the library's (dashed)"
    assert ax.get_ylabel() == "ADE to human (m)"


def test_rounds_name_a_stub_and_a_wrong_length_and_keep_the_reference():
    ax = plot_round_attempts({"todo": stub, "short": lambda: [1.0, 2.0]},
                             {"todo": [1.0, 1.0, 1.0], "short": [2.0, 2.0, 2.0]})
    title = ax.get_title()
    assert "todo: NotImplementedError: Exercise ex99_1: to do" in title
    assert "short: expected 3 rounds, got 2" in title
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels == ["todo (library)", "short (library)"]   # only the references drawn


def test_rounds_refuse_values_that_are_not_numbers_in_the_title():
    ax = plot_round_attempts({"bad": lambda: ["a", "b"]}, {})
    assert ax.get_title().startswith("bad: ValueError")
    assert not ax.get_lines() and ax.get_legend() is None


def test_rounds_draw_on_given_axes_without_a_reference():
    _, given = plt.subplots()
    ax = plot_round_attempts({"mine": lambda: np.array([4.0, 3.0])}, {}, ax=given)
    assert ax is given and [ln.get_label() for ln in ax.get_lines()] == ["mine (yours)"]
