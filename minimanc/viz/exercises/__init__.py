"""Chapter 0 — a chapter's key figure, redrawn from the student's own functions.

Every exercises notebook ends with one cell that calls a function of this module with
the functions the student wrote (it saves nothing, the cell ends in ``plt.show()``).
The figure draws the student's result over the library's reference, so a wrong answer
shows as a curve, a path or a label that departs from it. A function that raises (a
stub still raising ``NotImplementedError``, or a bug) is named in its panel's title
with the error, and only the reference is drawn: the notebook runs to the end
(:func:`attempt`).

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
  closed loop (:func:`minimanc.rollout.drive_on_route`: its controls integrated by the
  unicycle, the lane target re-read from the new pose every step), the student's head over
  the library's :func:`minimanc.models.dmp_head`;
* chapter 9: :func:`plot_track_error_attempts` — the displacement from the human split
  along and across the human's heading over time, for closed-loop runs, measured by the
  student's split next to :func:`minimanc.metrics.along_cross_track`.

One module per figure (or pair of figures): :mod:`~minimanc.viz.exercises.attempts`,
:mod:`~minimanc.viz.exercises.graphs`, :mod:`~minimanc.viz.exercises.optimisers`,
:mod:`~minimanc.viz.exercises.curves`, :mod:`~minimanc.viz.exercises.bev`,
:mod:`~minimanc.viz.exercises.driving`.
"""

from minimanc.viz.exercises.attempts import attempt
from minimanc.viz.exercises.bev import plot_bev_attempts
from minimanc.viz.exercises.curves import plot_curve_attempts, plot_stability_boundary
from minimanc.viz.exercises.driving import plot_drive_attempts, plot_track_error_attempts
from minimanc.viz.exercises.graphs import graph_of_edges, plot_edge_cotangents
from minimanc.viz.exercises.optimisers import plot_valley_paths

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
