"""Chapter 7 benchmark: the nuScenes importer's speed and memory (prints, never asserts).

    python benchmarks/nuscenes_import.py               # 20 copies of the fixture's scenes
    python benchmarks/nuscenes_import.py --copies 100  # larger

Writes the package's schema-exact sample DATAROOT (:mod:`minimanc.world.nuscenes.sample`) with
``--copies``
copies of each of its five scenes under the names of the v1.0-trainval splits (two of
every five import, three are skipped: 39 keyframes, a dropped keyframe, no lane), then
times :func:`minimanc.world.nuscenes.import_nuscenes` (tables, map expansion, rasters and
the sharded file) and prints the seconds per scene read and per scene imported (the
issue's budget: <= 1 s per scene of the fixture's size on 2 cores); then, under
``tracemalloc`` (a second import: it slows Python down), the Python heap the read tables
hold and the import's peak on top of them (the arrays stream one shard at a time, so the
peak grows with the scenes until the first shard is full: ``--shard-scenes 8`` shows the
flat part; the per-scene metadata, kept for the header, grows with the scenes), and the
process's peak resident memory.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
import tracemalloc
from pathlib import Path

from minimanc.world import RasterConfig
from minimanc.world.nuscenes import Tables, import_nuscenes
from minimanc.world.nuscenes.sample import write_sample


def run(copies: int, size: int, shard_scenes: int | None) -> dict:
    """Import ``copies`` of the fixture's scenes twice: timed, then under ``tracemalloc``
    (which slows Python down) for the heap the tables hold and the import's peak."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "root"
        write_sample(root, "v1.0-trainval", copies=copies)

        def once(name: str):
            return import_nuscenes(root, "v1.0-trainval", Path(tmp) / name,
                                   raster=RasterConfig(size=size), shard_scenes=shard_scenes)

        t0 = time.perf_counter()
        report = once("timed.npz")
        seconds = time.perf_counter() - t0
        file_mb = (Path(tmp) / "timed.npz").stat().st_size / 1e6
        tracemalloc.start()
        tables = Tables(root, "v1.0-trainval")
        held, tables_peak = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        import_nuscenes(root, "v1.0-trainval", Path(tmp) / "traced.npz",
                        raster=RasterConfig(size=size), shard_scenes=shard_scenes,
                        tables=tables)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    n_read = len(report.imported) + len(report.skipped)
    return {"read": n_read, "imported": len(report.imported), "seconds": seconds,
            "tables_mb": held / 1e6, "tables_peak_mb": tables_peak / 1e6,
            "import_peak_mb": (peak - held) / 1e6, "file_mb": file_mb,
            "rss_peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--copies", type=int, default=20,
                   help="copies of each of the fixture's five scenes (default 20)")
    p.add_argument("--size", type=int, default=64, help="raster size in pixels (default 64)")
    p.add_argument("--shard-scenes", type=int, default=None,
                   help="scenes per shard (default: the format's)")
    a = p.parse_args()
    if a.copies < 1:
        p.error(f"--copies must be >= 1, got {a.copies}")
    r = run(a.copies, a.size, a.shard_scenes)
    print(f"nuScenes import, fixture x {a.copies} ({r['read']} scenes, {r['imported']} "
          f"imported), {a.size} px:")
    print(f"  {r['seconds']:.2f} s: {r['seconds'] / r['read']:.3f} s per scene read, "
          f"{r['seconds'] / r['imported']:.3f} s per scene imported (budget 1 s)")
    print(f"  Python heap (tracemalloc): the tables hold {r['tables_mb']:.1f} MB (peak "
          f"{r['tables_peak_mb']:.1f} MB while read), the import's peak on top of them "
          f"{r['import_peak_mb']:.1f} MB")
    print(f"  process peak RSS {r['rss_peak_mb']:.0f} MB; file {r['file_mb']:.1f} MB")


if __name__ == "__main__":
    main()
