"""Chapter 9 — a study's cache on disk: :class:`StudyFiles` knows where everything of one
:class:`~minimanc.studies.config.StudyConfig` lives under the output directory and reads it
back, or drops what cannot be read.

The layout (every file derived data, recomputed when missing or broken)::

    out/data/world-<n>x<seed>-<raster>.npz          the generated scenes (or the given file;
                                                    <raster>: :func:`raster_name`)
    out/data/<data file>-perception-<n>.npz         the perception targets of its first n
                                                    (training) scenes, with perception_weight > 0
    out/cache/<fingerprint>-<engine>/models/<run>/checkpoint.npz   (and diverged.json)
    out/cache/<fingerprint>-<engine>/rollouts/<run>-<split>[-reactive].npz / .json
    out/cache/jax/                                  JAX's persistent compilation cache
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from minimanc import diagnose, train, world
from minimanc.studies.config import Run, StudyConfig, raster_text
from minimanc.studies.jobs import STUDY_METRICS
from minimanc.studies.provenance import read_json_or_none

__all__ = ["StudyFiles", "raster_name"]


def raster_name(raster: world.RasterConfig) -> str:
    """The part of a generated data file's name that says how it is drawn: ``"<size>px"``
    for the paper's form (the devkit's RGB raster, :class:`~minimanc.world.RasterConfig` at
    its defaults but ``size``), else ``"<rows>x<cols>-<encoding>-<digest>"`` with the first 8
    hex digits of the SHA-256 of :meth:`~minimanc.world.RasterConfig.as_meta`."""
    if raster == world.RasterConfig(size=raster.size):
        return f"{raster.size}px"
    digest = hashlib.sha256(json.dumps(raster.as_meta(), sort_keys=True).encode()).hexdigest()
    return f"{raster.size}x{raster.width}-{raster.encoding}-{digest[:8]}"


class StudyFiles:
    """The files of the study ``config`` under ``out`` for ``engine``.

    ``dir`` is the cache of this configuration and engine (named by
    :meth:`StudyConfig.fingerprint`); ``jax_dir`` the compilation cache every
    configuration shares. ``log`` receives one line per event; ``progress`` shows the
    data generation's bar; ``timing`` (seconds by stage) gets ``"data"``.
    """

    def __init__(self, config: StudyConfig, out: str | Path, engine: str,
                 log: Callable[[str], None], progress: bool = True,
                 timing: dict[str, float] | None = None) -> None:
        self.config = config
        self.out = Path(out)
        self.dir = self.out / "cache" / f"{config.fingerprint()}-{engine}"
        self.jax_dir = self.out / "cache" / "jax"
        self.log = log
        self.progress = progress
        self.timing = {} if timing is None else timing
        self._data: tuple[Any, Any, Any] | None = None

    # ----------------------------------------------------------------- data

    @property
    def data_path(self) -> Path:
        """The dataset file: the given one (``config.data_file``), else the one generated
        under ``data/``."""
        c = self.config
        if c.data_file:
            return Path(c.data_file)
        n = c.n_train + c.n_tune + c.n_val
        return self.out / "data" / f"world-{n}x{c.data_seed}-{raster_name(c.raster)}.npz"

    def derived_path(self, suffix: str) -> Path:
        """Where data derived from the dataset file is cached: next to a generated file,
        under ``data/`` (named by the content hash) for a given one."""
        c = self.config
        if not c.data_file:
            return self.data_path.with_name(self.data_path.stem + suffix)
        folder = self.out / "data"
        folder.mkdir(parents=True, exist_ok=True)
        return folder / f"{self.data_path.stem}-{c.data_hash[:12]}{suffix}"

    def datasets(self) -> tuple[Any, Any, Any]:
        """``(train, tune, val)``: the given file's scenes, or generated once (saved under
        ``data/``), then loaded."""
        if self._data is not None:
            return self._data
        c = self.config
        n = c.n_train + c.n_tune + c.n_val
        t0 = time.perf_counter()
        ds = None
        if c.data_file:
            ds = world.load(self.data_path)
            if ds.content_hash() != c.data_hash:
                raise ValueError(f"{self.data_path}: the file changed since its study "
                                 "configuration was made (another content hash); make the "
                                 "configuration again (minimanc.studies.recorded.data_config)")
            self.log(f"data: loaded {len(ds)} scenes from {self.data_path}")
        elif self.data_path.exists():
            try:
                ds = world.load(self.data_path)
                self.log(f"data: loaded {n} scenes from {self.data_path}")
            except world.DatasetFileError as exc:  # older format, truncated, altered: remake
                self.discard(self.data_path, str(exc))
        if ds is None:
            self.log(f"data: generating {n} scenes ({raster_text(c.raster)})")
            ds = world.generate(n, seed=c.data_seed, raster=c.raster, progress=self.progress)
            world.save(ds, self.data_path)
        self.timing["data"] = time.perf_counter() - t0
        a, b = c.n_train, c.n_train + c.n_tune
        self._data = (ds.subset(slice(0, a)), ds.subset(slice(a, b)), ds.subset(slice(b, n)))
        return self._data

    def perception_path(self) -> Path:
        """Where the perception targets of the training split are cached (next to the data,
        :meth:`derived_path`)."""
        return self.derived_path(f"-perception-{self.config.n_train}.npz")

    def perception_targets(self) -> Path:
        """The file of the perception targets of the training split: every state of its
        scenes as the study's raster shows it (:func:`minimanc.diagnose.perception_targets`
        with ``view=config.raster``), computed once, then read from the cache."""
        path = self.perception_path()
        if path.exists():
            try:
                train.load_targets(path)
                return path
            except (OSError, ValueError) as exc:  # truncated or altered: compute it again
                self.discard(path, str(exc))
        train_ds = self.datasets()[0]
        t0 = time.perf_counter()
        train.save_targets(diagnose.perception_targets(train_ds, view=self.config.raster), path)
        self.timing["perception"] = time.perf_counter() - t0
        self.log(f"data: perception targets of {len(train_ds)} training scenes -> {path}")
        return path

    def rows(self, split: str) -> tuple[int, int]:
        """The rows ``(lo, hi)`` of the split ``"tune"`` or ``"val"`` in the dataset file."""
        c = self.config
        a, b = c.n_train, c.n_train + c.n_tune
        return {"tune": (a, b), "val": (b, b + c.n_val)}[split]

    # ----------------------------------------------------------------- runs

    def checkpoint(self, run: Run) -> Path:
        """The checkpoint of ``run`` (:data:`minimanc.train.CHECKPOINT_NAME`)."""
        return self.dir / "models" / run.key / train.CHECKPOINT_NAME

    def diverged(self, run: Run) -> bool:
        """Whether ``run``'s training diverged (``diverged.json`` beside its checkpoint)."""
        return (self.checkpoint(run).parent / "diverged.json").exists()

    def complete(self, run: Run) -> bool:
        """Whether ``run``'s checkpoint holds every epoch (or the run diverged). An on-policy
        run's checkpoint is written once DAgger's last round is done
        (:func:`minimanc.studies.executors.train_on_policy`): readable means complete."""
        path = self.checkpoint(run)
        if self.diverged(run):
            return True  # scored as inf; delete diverged.json to train it again
        if not path.exists():
            return False
        try:
            epoch = train.load_checkpoint(path)["epoch"]
            return run.on_policy or epoch >= self.config.training.epochs
        except train.CheckpointError as exc:
            # the cache is derived data: drop the broken entry and train the run again
            self.discard(path, str(exc))
            return False

    def rollout_paths(self, run: Run, split: str, agents: str = "replay") -> tuple[Path, Path]:
        """``(rollout .npz, metrics .json)`` of ``run`` on ``split`` under ``agents``."""
        base = self.dir / "rollouts"
        tail = "" if agents == "replay" else f"-{agents}"
        return (base / f"{run.key}-{split}{tail}.npz",
                base / f"{run.key}-{split}{tail}.json")

    def reference_path(self, key: str) -> Path:
        """The scores of the reference driver ``key`` (a Table I row without training, on the
        validation split: :class:`~minimanc.studies.references.References`)."""
        return self.dir / "references" / f"{key}.json"

    def cached_reference(self, key: str) -> dict | None:
        """The scores :meth:`reference_path` holds, or ``None`` (:meth:`read_scores`)."""
        path = self.reference_path(key)
        return self.read_scores(path) if path.exists() else None

    def cached_scores(self, run: Run, split: str, agents: str) -> dict | None:
        """The metrics of ``run`` on ``split`` under ``agents`` when the cache holds them and
        its rollout (``None`` otherwise, :meth:`read_scores`)."""
        roll_path, met_path = self.rollout_paths(run, split, agents)
        if not (met_path.exists() and roll_path.exists()):
            return None
        return self.read_scores(met_path)

    def read_scores(self, path: Path) -> dict | None:
        """The scores in the file ``path``, or ``None``: a file that is not a JSON object is
        discarded, one scored by an older version (without every metric) is ignored."""
        cached = read_json_or_none(path)
        if not isinstance(cached, dict):
            self.discard(path, "not a JSON object")
            return None
        if not ("families" in cached and all(k in cached for k in STUDY_METRICS)):
            return None  # scored by an older version: evaluate again
        return cached

    def discard(self, path: Path, why: str) -> None:
        """Delete the unreadable cache entry ``path`` (it is recomputed), saying so on stderr."""
        print(f"minimanc reproduce: discarding the unreadable cache entry {path} ({why}); "
              "recomputing it", file=sys.stderr)
        self.log(f"cache: discarded {path}")
        path.unlink(missing_ok=True)
