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
  in two encodings: the nuScenes devkit colours, or binary planes for a learner
  (the ego's route, the vehicles of each past step apart);
  :mod:`~minimanc.world.encodings` reads a stored raster back;
* the dataset (see below) — :mod:`~minimanc.world.generation` (:func:`generate`,
  :func:`generate_file` streams any number of scenes to disk),
  :mod:`~minimanc.world.scenes` (the :class:`Dataset` in memory: build, subset, split),
  :mod:`~minimanc.world.fileformat` (the file format and its checksums),
  :mod:`~minimanc.world.datawriter` (:func:`save`) and :mod:`~minimanc.world.datareader`
  (:func:`load`);
* :mod:`~minimanc.world.geometry` — frames and the unicycle (``DT = 0.5`` s).

**The dataset.** ``generate(n_scenes, seed)`` draws each scene ``i`` from its own random stream
``default_rng([seed, i, attempt])`` — a map, a human style, traffic — and
simulates 40 steps of 0.5 s. A scene in which the human would leave the
drivable area or touch an ado is drawn again (next ``attempt``), so the data
contain neither; the attempts are recorded in ``meta["attempts"]``. Because
each scene depends only on ``(seed, i)``, the result is the same whatever the
number of worker processes, and the first 650 scenes of an 850-scene set are
the 650-scene set.

**Files** (:data:`FILE_FORMAT_VERSION` 2) are zip archives that ``numpy.load`` also opens
(``.npz``, deflate-compressed). The scenes are stored in *shards* of
consecutive scenes, one member ``<array>-<k>.npy`` per array and shard, so
that :func:`generate_file` writes a dataset of any size while holding one
shard in memory. The member ``header.npy`` (JSON, written last) holds the
format version, the metadata (seed, ``dt``, raster config, map recipes, tags,
attempts, scene indices), the shape, dtype and SHA-256 of every shard's
arrays, and a SHA-256 of all of that. A file is written under a temporary
name in its directory and renamed (:func:`os.replace`) once complete, so a
partial dataset is never taken for a complete one; the temporary file is
removed on failure, and stale ones of the same target are removed by the
next write. :func:`load` rebuilds the maps from their recipes and refuses,
with a :class:`DatasetFileError` naming the file, any file that is not one
of ours, truncated, corrupt, altered (arrays *or* metadata), of another
version, missing a metadata key, or holding a non-finite number.

>>> from minimanc import world
>>> ds = world.generate(n_scenes=20, seed=0)            # doctest: +SKIP
>>> train, val = ds.split(n_train=15)                    # doctest: +SKIP
"""

from minimanc.world.datareader import file_content_hash, load, read_meta
from minimanc.world.datawriter import DatasetWriter, save
from minimanc.world.driver import (
    MAX_ADOS,
    T_STEPS,
    HumanStyle,
    check_scene,
    random_style,
    simulate_scene,
)
from minimanc.world.encodings import planes, to_input, to_rgb
from minimanc.world.fileformat import (
    FILE_FORMAT_VERSION,
    FORMAT_VERSION,
    DatasetFileError,
    check_arrays_finite,
)
from minimanc.world.generation import (
    Estimate,
    draw_scene,
    estimate,
    generate,
    generate_file,
    generate_scene,
    generate_splits,
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
    ENCODINGS,
    RasterConfig,
    box_mask,
    channel_names,
    hue_colours,
    rasterize,
    rasterize_batch,
    rasterize_goal,
)
from minimanc.world.roads import build_map
from minimanc.world.scenes import Dataset
from minimanc.world.traffic import idm_acceleration

__all__ = [
    "DT", "Dataset", "DatasetFileError", "DatasetWriter", "EGO_LENGTH", "EGO_WIDTH", "ENCODINGS",
    "Estimate", "FILE_FORMAT_VERSION", "FORMAT_VERSION", "HumanStyle", "K_TARGETS", "Lane",
    "MAX_ADOS", "Map", "RasterConfig", "TARGET_SPACING", "T_STEPS", "box_corners", "box_mask",
    "boxes_overlap", "build_map", "channel_names", "check_arrays_finite", "check_scene",
    "controls_from_poses", "draw_scene", "estimate", "file_content_hash", "from_ego_frame",
    "generate", "generate_file", "generate_scene", "generate_splits", "goal_in_ego_frame",
    "hue_colours", "idm_acceleration", "lane_targets", "load", "planes", "project_to_route",
    "random_map", "random_recipe", "random_style", "rasterize", "rasterize_batch",
    "rasterize_goal", "read_meta", "save", "simulate_scene", "to_ego_frame", "to_input", "to_rgb",
    "unicycle_step", "wrap_angle",
]
