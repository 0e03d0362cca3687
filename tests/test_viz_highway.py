"""minimanc.viz.highway: chapter 10's exercises figure, the student's episodes drawn over
the library's, a function that raises (or returns a malformed episode) named in the title."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402

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
