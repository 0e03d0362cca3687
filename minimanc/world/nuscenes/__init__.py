"""Chapter 7 — real nuScenes: the JSON tables, the map expansion and the official splits.

:mod:`~minimanc.world.nuscenes.tables` reads the tables (standard library and NumPy only),
:mod:`~minimanc.world.nuscenes.mapexp` the map expansion (arcline centrelines, areas, the
ego's route through the lane graph) into the world's explicit map recipe,
:mod:`~minimanc.world.nuscenes.splits` holds the devkit's official scene splits, and
:mod:`~minimanc.world.nuscenes.importer` streams the scenes into the world's dataset file
(:func:`import_nuscenes`). :mod:`~minimanc.world.nuscenes.sample` writes a tiny made-up
DATAROOT in the exact schema (``write_sample``), to try the importer without the download.
"""

from minimanc.world.nuscenes.importer import (
    MAX_GAP,
    MIN_GAP,
    ImportEstimate,
    ImportReport,
    SceneSkipped,
    ego_track,
    estimate_import,
    import_nuscenes,
    import_scene,
    select_scenes,
    skip_reason,
    vehicle_boxes,
)
from minimanc.world.nuscenes.mapexp import (
    LOCATIONS,
    MapExpansion,
    clip_polygon,
    discretize_arcline,
    route_of,
    simplify_polyline,
)
from minimanc.world.nuscenes.splits import SPLITS_OF_VERSION, VERSIONS, scene_split, split_lists
from minimanc.world.nuscenes.tables import (
    TABLES,
    NuScenesError,
    Tables,
    keyframe_poses,
    read_records,
    yaw_of,
)

__all__ = ["LOCATIONS", "MAX_GAP", "MIN_GAP", "SPLITS_OF_VERSION", "TABLES", "VERSIONS",
           "ImportEstimate", "ImportReport", "MapExpansion", "NuScenesError", "SceneSkipped",
           "Tables",
           "clip_polygon", "discretize_arcline", "ego_track", "estimate_import",
           "import_nuscenes", "import_scene", "keyframe_poses", "read_records", "route_of",
           "scene_split",
           "select_scenes", "simplify_polyline", "skip_reason", "split_lists", "vehicle_boxes",
           "yaw_of"]
