"""Chapter 7 — real nuScenes: the JSON tables, the map expansion and the official splits.

:mod:`~minimanc.world.nuscenes.tables` reads the tables (standard library and NumPy only),
:mod:`~minimanc.world.nuscenes.mapexp` the map expansion (arcline centrelines, areas, the
ego's route through the lane graph) into the world's explicit map recipe, and
:mod:`~minimanc.world.nuscenes.splits` holds the devkit's official scene splits.
"""

from minimanc.world.nuscenes.mapexp import (
    LOCATIONS,
    MapExpansion,
    clip_polygon,
    discretize_arcline,
    route_of,
)
from minimanc.world.nuscenes.splits import SPLITS_OF_VERSION, VERSIONS, scene_split, split_lists
from minimanc.world.nuscenes.tables import TABLES, NuScenesError, Tables, keyframe_poses, yaw_of

__all__ = ["LOCATIONS", "SPLITS_OF_VERSION", "TABLES", "VERSIONS", "MapExpansion",
           "NuScenesError", "Tables", "clip_polygon", "discretize_arcline", "keyframe_poses",
           "route_of", "scene_split", "split_lists", "yaw_of"]
