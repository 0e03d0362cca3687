"""Chapter 9 — closed-loop metrics of the paper's Table I (section V-A), defined precisely.

The paper names four metrics ("all metrics are the lower the better") without
formulas; these are ours, stated exactly so that every number in
``table1.md`` can be recomputed by hand.  Trajectories are ego poses
``(S, T, 3) = [x, y, yaw]`` in the world frame at the log's rate
(``DT = 0.5`` s), one row per validation scene.

* the paper's four: **% close encounters** (safety), **max |acceleration|**
  (comfort), **ADE** (the paper's "human driving similarity") and **goal distance**;
* two honesty checks the paper does not report: **collision** and **off-road**;
* safety and progress beyond the paper, with nuPlan's closed-loop metrics as the
  anchor: **at-fault collision** (nuPlan's classes, and where ours differ),
  **time-to-collision** and **route progress**.

Each module states the exact definitions of the metrics it computes:

* :mod:`~minimanc.metrics.boxes` — the checks of the inputs, ego boxes, box-to-box gaps;
* :mod:`~minimanc.metrics.trajectory` — max |acceleration|, ADE and its along/cross-track
  split, goal distance, off-road, route progress;
* :mod:`~minimanc.metrics.safety` — close encounters, collisions, collision events and the
  at-fault rule, time-to-collision;
* :mod:`~minimanc.metrics.table` — :func:`evaluate` (one rollout's averages, keys
  :data:`ALL_METRICS`) and :func:`aggregate` (``mean ± std`` over training seeds).

Everything public is re-exported here (``from minimanc import metrics; metrics.ade(...)``).
"""

from minimanc.metrics.boxes import ado_gaps, box_gap, ego_boxes
from minimanc.metrics.safety import (
    AT_FAULT,
    CLOSE_GAP,
    COLLISION_TYPES,
    IN_LANE,
    TTC_THRESHOLD,
    V_STOPPED,
    CollisionEvent,
    at_fault_collisions,
    close_encounters,
    collision_events,
    collisions,
    ego_in_lane,
    time_to_collision,
    ttc_rate,
)
from minimanc.metrics.safety import TTC_STEP as TTC_STEP  # outside __all__, as before
from minimanc.metrics.table import (
    ALL_METRICS,
    METRICS,
    SAFETY_METRICS,
    TABLE_METRICS,
    aggregate,
    evaluate,
)
from minimanc.metrics.trajectory import (
    PROGRESS_MIN,
    ade,
    along_cross_track,
    goal_distance,
    max_acceleration,
    off_road,
    route_progress,
)
from minimanc.world.geometry import DT as DT  # the log's step and the ego's size, likewise
from minimanc.world.geometry import EGO_LENGTH as EGO_LENGTH
from minimanc.world.geometry import EGO_WIDTH as EGO_WIDTH

__all__ = [
    "CLOSE_GAP",
    "METRICS",
    "TABLE_METRICS",
    "ego_boxes",
    "box_gap",
    "ado_gaps",
    "close_encounters",
    "max_acceleration",
    "ade",
    "along_cross_track",
    "goal_distance",
    "collisions",
    "off_road",
    "ALL_METRICS",
    "COLLISION_TYPES",
    "IN_LANE",
    "PROGRESS_MIN",
    "SAFETY_METRICS",
    "TTC_THRESHOLD",
    "V_STOPPED",
    "AT_FAULT",
    "CollisionEvent",
    "at_fault_collisions",
    "collision_events",
    "ego_in_lane",
    "route_progress",
    "time_to_collision",
    "ttc_rate",
    "evaluate",
    "aggregate",
]
