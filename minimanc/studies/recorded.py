"""Chapter 9 — the studies on a given dataset file (``minimanc reproduce --data FILE``):
which of its scenes train, tune and validate, and what recorded data cannot do.

**Recorded data.** A file imported from nuScenes
(:func:`minimanc.world.nuscenes.import_nuscenes`; ``meta["source"] == "nuscenes"``) names
each scene's official split in ``tags["split"]`` (``train``/``val`` of v1.0-trainval,
``mini_train``/``mini_val`` of v1.0-mini; :mod:`minimanc.world.nuscenes.splits`). As in
the paper, the training split trains and the validation split is Table I's validation set.
The learning rates are tuned on the last :data:`TUNE_SHARE` of the training split (at least
one scene; the scenes in the split's order, that is ``scene.json``'s): scenes of the
training distribution used for neither training nor evaluation, as the generated tuning
split is. The raster is the file's, whatever its encoding. The preset gives everything else
(epochs, learning rates, seeds, studies); its scene counts and data seed are replaced by the
file's.

Recorded data has logged boxes, not drivers: nothing can re-drive its scenes. So

* the **replay** protocol (the paper's: the ados follow their log) is the only one; the
  **reactive** protocol, which re-simulates the world's generated traffic around the
  policy's ego, is refused (:data:`REACTIVE_REFUSAL`; ados following their own logged
  path with IDM, as nuPlan does, are future work);
* Table I has no **Expert** and **Style floor** rows (:mod:`minimanc.diagnose.bounds`): both
  re-drive each scene from the world's generator (map, traffic and driver drawn from the
  dataset's seed), which a recorded scene does not have (:data:`BOUNDS_OMITTED`);
* the human's driving modes (:func:`minimanc.metrics.modes.human_modes`, what vAGN's q-states are
  measured against) come from re-driving the scene too: no modes study and no q-versus-mode
  figures (:data:`MODES_OMITTED`);
* behaviour cloning against DAgger (``--dagger``) asks the world's expert in states the
  log never visited: refused too;
* the auxiliary perception loss (``perception_weight`` > 0) reads the expert's perception
  in every logged state, which comes from re-driving the scene: refused
  (:data:`PERCEPTION_REFUSAL`).

**Generated files.** A file of :func:`minimanc.world.generate` (no ``meta["source"]``) is
used as the preset's data: it must hold at least the preset's ``n_train + n_tune + n_val``
scenes (the first ones are used, in that order) drawn with the preset's raster
(``StudyConfig.raster``, compared by :meth:`~minimanc.world.RasterConfig.as_meta`); its seed becomes
the study's ``data_seed``. Everything else, the bounds included, is as on generated data.

In both cases the study's cache is named by the file's content hash
(:func:`minimanc.world.file_content_hash`, in :meth:`StudyConfig.fingerprint`), not by
its path.
"""

from __future__ import annotations

import math
import os
from collections import Counter
from dataclasses import asdict, replace
from pathlib import Path

from minimanc import world
from minimanc.studies.config import StudyConfig, raster_text
from minimanc.world.nuscenes import SPLITS_OF_VERSION

__all__ = ["BOUNDS_OMITTED", "GENERATED", "MODES_OMITTED", "PERCEPTION_REFUSAL",
           "REACTIVE_REFUSAL", "TUNE_SHARE", "data_config", "data_notes", "how_to_generate",
           "is_recorded"]

TUNE_SHARE: float = 0.05
"""The share of the training split that tunes the learning rates (its last scenes)."""

GENERATED: str = "world"
"""``StudyConfig.data_source`` of a generated dataset file (``meta`` without ``"source"``)."""

REACTIVE_REFUSAL: str = (
    "the reactive protocol is not available on recorded data: it re-simulates the world's "
    "generated traffic, and recorded ados are logged boxes without a driver "
    "(log-following IDM ados, as in nuPlan, are future work)")
"""Why recorded data has no reactive protocol (one line)."""

BOUNDS_OMITTED: str = (
    "Table I has no Expert and Style floor rows: both re-drive each scene with the world's "
    "generator (its map, traffic and driver drawn from the dataset's seed), which recorded "
    "data does not have.")
"""Why recorded data has no bound rows (one line of ``table1.md``)."""

MODES_OMITTED: str = (
    "No study of vAGN's q-states against the human's driving modes: the modes come from "
    "re-driving each scene with the world's driver (minimanc.metrics.modes), which recorded data "
    "does not have.")
"""Why recorded data has no modes study (one line of ``table1.md``)."""


PERCEPTION_REFUSAL: str = (
    "the auxiliary perception loss (perception_weight > 0) is not available on recorded "
    "data: its targets come from re-driving each scene with the world's driver "
    "(minimanc.diagnose.perception_targets), which recorded data does not have")
"""Why recorded data trains without the auxiliary perception loss (one line)."""


def how_to_generate(raster: world.RasterConfig, n: int) -> str:
    """How to make a generated file of ``n`` scenes drawn with ``raster``: the command
    ``minimanc data generate`` for the paper's form (it draws the RGB raster at ``--size``),
    else the Python call (:func:`minimanc.world.generate_file`) with the raster's fields
    that are not the defaults."""
    if raster == world.RasterConfig(size=raster.size):
        return f"generate it with `minimanc data generate --scenes {n} --size {raster.size}`"
    base = asdict(world.RasterConfig())
    fields = ", ".join(f"{k}={v!r}" for k, v in asdict(raster).items() if v != base[k])
    return (f"generate it with `minimanc.world.generate_file(FILE, {n}, "
            f"raster=minimanc.world.RasterConfig({fields}))`")


def is_recorded(config: StudyConfig) -> bool:
    """Whether ``config`` trains on a recorded (imported) dataset file."""
    return config.data_source not in ("", GENERATED)


def _recorded_split(meta: dict, path: Path) -> tuple[int, int, str, str]:
    """``(n_train_split, n_val_split, train_name, val_name)`` of a recorded file, checking
    that every scene names a split and the scenes are the training split then the
    validation split (the importer's order)."""
    tags = meta["tags"]
    splits = [t.get("split") if isinstance(t, dict) else None for t in tags]
    missing = [i for i, s in enumerate(splits) if s is None]
    if missing:
        raise ValueError(f"{path}: {len(missing)} of {len(tags)} recorded scenes name no split "
                         f"(tags['split'], first: scene {missing[0]}); import the file again "
                         "with `minimanc data import-nuscenes`")
    pairs = [p for p in SPLITS_OF_VERSION.values() if splits[0] in p or splits[-1] in p]
    counts = Counter(splits)
    if len(pairs) != 1 or set(counts) - set(pairs[0]):
        raise ValueError(f"{path}: the scenes' splits {sorted(map(str, counts))} are not one "
                         "version's training and validation splits ("
                         + "; ".join("/".join(p) for p in SPLITS_OF_VERSION.values()) + ")")
    train, val = pairs[0]
    n_tr, n_val = counts[train], counts[val]
    if splits != [train] * n_tr + [val] * n_val:
        raise ValueError(f"{path}: the scenes are not the {train} split then the {val} split "
                         "(the order `minimanc data import-nuscenes` writes)")
    if n_val < 1:
        raise ValueError(f"{path}: no scene of the {val} split, the validation set")
    if n_tr < 3:
        raise ValueError(f"{path}: {n_tr} scene(s) of the {train} split; training and tuning "
                         "need at least 3")
    return n_tr, n_val, train, val


def data_config(config: StudyConfig, path: str | os.PathLike) -> StudyConfig:
    """``config`` (a preset) set up to train and evaluate on the dataset file ``path``
    (see the module doc): its scene counts and raster from the file, ``data_file``,
    ``data_hash`` (the file's content hash) and ``data_source`` (``meta["source"]``, or
    :data:`GENERATED`).

    Raises :class:`minimanc.world.DatasetFileError` (or ``FileNotFoundError``) when
    ``path`` is not a readable dataset file, ``ValueError`` (one line) when a generated
    file does not fit the preset or a recorded file's scenes do not name their splits.
    """
    if not isinstance(config, StudyConfig):
        raise ValueError(f"config must be a StudyConfig; got config={config!r}")
    path = Path(path)
    meta = world.read_meta(path)
    n = len(meta["tags"])
    source = meta.get("source", GENERATED)
    if not isinstance(source, str) or not source or source == GENERATED:
        need = config.n_train + config.n_tune + config.n_val
        if n < need or meta["raster"] != config.raster.as_meta():
            raise ValueError(
                f"{path}: a generated file of {n} scenes, "
                f"{raster_text(world.RasterConfig(**meta['raster']))}, does not fit preset "
                f"{config.preset!r} ({need} scenes = {config.n_train} training + "
                f"{config.n_tune} tuning + {config.n_val} validation, "
                f"{raster_text(config.raster)}); {how_to_generate(config.raster, need)} "
                "or choose the preset")
        return replace(config, data_seed=int(meta["seed"]), data_file=str(path),
                       data_hash=world.file_content_hash(path), data_source=GENERATED)
    n_tr, n_val, _, _ = _recorded_split(meta, path)
    n_tune = max(1, math.ceil(TUNE_SHARE * n_tr))
    return replace(config, n_train=n_tr - n_tune, n_tune=n_tune, n_val=n_val,
                   raster=world.RasterConfig(**meta["raster"]), data_seed=int(meta["seed"]),
                   data_file=str(path), data_hash=world.file_content_hash(path),
                   data_source=source)


def data_notes(config: StudyConfig) -> list[str]:
    """The lines ``table1.md`` says about a given dataset file (none for generated data
    made by the study)."""
    if not config.data_file:
        return []
    where = (f"Data: the file `{Path(config.data_file).name}` (content hash "
             f"`{config.data_hash[:12]}`)")
    if not is_recorded(config):
        return [f"{where}, generated (seed {config.data_seed}).", ""]
    return [f"{where}, recorded ({config.data_source}): the first {config.n_train} scenes "
            f"of its training split train, its last {config.n_tune} tune the learning rates "
            f"({100 * TUNE_SHARE:g} %, at least one) and its validation split "
            f"({config.n_val} scenes) validates. Agents `replay` only: {REACTIVE_REFUSAL}.",
            "",
            BOUNDS_OMITTED, "", MODES_OMITTED, ""]
