"""The exercises' last figures of chapters 10 and 11: the student's results drawn over the
library's, a function that raises (or returns the wrong length) named in the title."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from minimanc.viz.dagger import plot_round_attempts  # noqa: E402
from minimanc.viz.highway import plot_episode_attempts  # noqa: E402


class Episode:
    """What the chapter-10 figure reads of a highway-env episode."""

    def __init__(self, poses, speeds, crashed):
        self.poses, self.speeds, self.crashed = poses, speeds, crashed


def episode(turn: float, crash_at: int | None = None, steps: int = 6) -> Episode:
    t = np.arange(steps + 1, dtype=float)
    poses = np.stack([5.0 * t, turn * t ** 2, 0.1 * turn * t], axis=1)
    crashed = np.zeros(steps + 1, dtype=bool)
    if crash_at is not None:
        crashed[crash_at:] = True
    return Episode(poses, np.full(steps + 1, 10.0) - t, crashed)


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


def test_episodes_draw_paths_speeds_and_the_first_crash():
    expert, mine = episode(0.0), episode(0.5, crash_at=3)
    paths, speeds = plot_episode_attempts({"yours": lambda: mine}, {"expert": expert})
    labels = [ln.get_label() for ln in paths.get_lines() if not ln.get_label().startswith("_")]
    assert labels == ["expert (library)", "yours (crashed)"]
    cross = [ln for ln in paths.get_lines() if ln.get_marker() == "x"]
    assert len(cross) == 1 and np.allclose(cross[0].get_xydata(), [mine.poses[3, :2]])
    solid = paths.get_lines()[2]                           # after the expert's path and dot
    assert solid.get_linestyle() == "-" and np.allclose(solid.get_ydata(), mine.poses[:, 1])
    assert [ln.get_label() for ln in speeds.get_lines()] == ["expert (library)", "yours"]
    assert np.allclose(speeds.get_lines()[1].get_ydata(), mine.speeds)
    assert paths.get_title() == "paths (dot: start, cross: first crash)"


def test_episodes_name_a_stub_and_a_malformed_episode():
    bad = Episode(np.zeros((4, 2)), np.zeros(4), np.zeros(4, bool))
    paths, speeds = plot_episode_attempts({"todo": stub, "bad": lambda: bad},
                                          {"expert": episode(0.0)})
    title = paths.get_title()
    assert "todo: NotImplementedError: Exercise ex99_1: to do" in title
    assert "bad: ValueError: expected poses (T+1, 3)" in title
    assert [ln.get_label() for ln in speeds.get_lines()] == ["expert (library)"]
