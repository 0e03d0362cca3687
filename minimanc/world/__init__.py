"""Chapter 7 — a nuScenes-style bird's-eye-view driving world, made from scratch.

The paper trains on nuScenes (850 scenes of 20 s at 2 Hz, 650 train / 200
validation, semantic BEV rasters). Nothing can be downloaded here, so this
package makes its own data:

* :mod:`~minimanc.world.maps` — procedural straight and curved roads,
  intersections and roundabouts with 1–2 lanes per direction, lane
  connectors, drivable area, walkways, pedestrian crossings, the ego's route;
* :mod:`~minimanc.world.traffic` — ado vehicles on lanes (IDM), yielding at
  junctions and roundabout entries, cutting in;
* :mod:`~minimanc.world.driver` — the human ego with a per-scene style;
* :mod:`~minimanc.world.raster` — the ego-centric, heading-up BEV raster
  with the nuScenes devkit colours;
* :mod:`~minimanc.world.dataset` — generate / split / save / load (sharded,
  checksummed files; :func:`generate_file` streams any number of scenes to disk),
  gathering :mod:`~minimanc.world.fileformat` (the format), :mod:`~minimanc.world.scenes`
  (the :class:`Dataset`), :mod:`~minimanc.world.datawriter`,
  :mod:`~minimanc.world.datareader` and :mod:`~minimanc.world.generation`;
* :mod:`~minimanc.world.geometry` — frames and the unicycle (``DT = 0.5`` s).

>>> from minimanc import world
>>> ds = world.generate(n_scenes=20, seed=0)            # doctest: +SKIP
>>> train, val = ds.split(n_train=15)                    # doctest: +SKIP
"""

from minimanc.world.dataset import (
    FILE_FORMAT_VERSION,
    FORMAT_VERSION,
    Dataset,
    DatasetFileError,
    DatasetWriter,
    Estimate,
    check_finite,
    draw_scene,
    estimate,
    file_content_hash,
    generate,
    generate_file,
    generate_scene,
    generate_splits,
    load,
    read_meta,
    save,
)
from minimanc.world.driver import (
    MAX_ADOS,
    T_STEPS,
    HumanStyle,
    check_scene,
    random_style,
    simulate_scene,
)
from minimanc.world.geometry import (
    DT,
    EGO_LENGTH,
    EGO_WIDTH,
    box_corners,
    boxes_overlap,
    controls_from_poses,
    from_ego_frame,
    goal_in_ego_frame,
    to_ego_frame,
    unicycle_step,
    wrap_angle,
)
from minimanc.world.lanes import K_TARGETS, TARGET_SPACING, Lane, Map
from minimanc.world.maps import lane_targets, project_to_route, random_map, random_recipe
from minimanc.world.raster import (
    RasterConfig,
    box_mask,
    hue_colours,
    rasterize,
    rasterize_batch,
    rasterize_goal,
)
from minimanc.world.roads import build_map
from minimanc.world.traffic import idm_acceleration

__all__ = [
    "DT", "Dataset", "DatasetFileError", "DatasetWriter", "EGO_LENGTH", "EGO_WIDTH", "Estimate",
    "FILE_FORMAT_VERSION", "FORMAT_VERSION", "HumanStyle", "K_TARGETS", "Lane", "MAX_ADOS", "Map",
    "RasterConfig", "TARGET_SPACING", "T_STEPS", "box_corners", "box_mask", "boxes_overlap",
    "build_map", "check_finite", "check_scene", "controls_from_poses", "draw_scene", "estimate",
    "file_content_hash", "from_ego_frame", "generate", "generate_file", "generate_scene",
    "generate_splits", "goal_in_ego_frame", "hue_colours", "idm_acceleration", "lane_targets",
    "load", "project_to_route", "random_map", "random_recipe", "random_style", "rasterize",
    "rasterize_batch", "rasterize_goal", "read_meta", "save", "simulate_scene", "to_ego_frame",
    "unicycle_step", "wrap_angle",
]
