"""Chapter 7 — the official nuScenes scene splits (``train``/``val``, ``mini_train``/``mini_val``).

The lists are those of the nuScenes devkit, release 1.2.0, file
``python-sdk/nuscenes/utils/splits.py`` (https://github.com/nutonomy/nuscenes-devkit,
Apache-2.0), copied verbatim into ``splits.json`` next to this module: 700 ``train`` and
150 ``val`` scenes of ``v1.0-trainval``, 8 ``mini_train`` and 2 ``mini_val`` scenes of
``v1.0-mini``. The paper trains on nuScenes' recorded scenes; these are the splits the
importer records for every scene (``tags["split"]``) and that ``reproduce --data`` uses.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

__all__ = ["SPLITS_OF_VERSION", "VERSIONS", "scene_split", "split_lists"]

VERSIONS: tuple[str, ...] = ("v1.0-mini", "v1.0-trainval")
"""The dataset versions the importer reads."""
SPLITS_OF_VERSION: dict[str, tuple[str, str]] = {
    "v1.0-mini": ("mini_train", "mini_val"),
    "v1.0-trainval": ("train", "val"),
}
"""The (training, validation) split names of each version."""


@lru_cache(maxsize=1)
def split_lists() -> dict[str, tuple[str, ...]]:
    """``{"train": (...), "val": (...), "mini_train": (...), "mini_val": (...)}``."""
    doc = json.loads((Path(__file__).with_name("splits.json")).read_text())
    return {k: tuple(doc[k]) for k in ("train", "val", "mini_train", "mini_val")}


def scene_split(version: str, name: str) -> str | None:
    """The split (of ``version``) that holds scene ``name``, or ``None`` if none does."""
    for split in SPLITS_OF_VERSION[version]:
        if name in split_lists()[split]:
            return split
    return None
