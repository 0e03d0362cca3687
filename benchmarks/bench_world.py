"""Chapter 7 benchmark: dataset generation time and BEV raster speed (prints, never asserts).

    python benchmarks/bench_world.py               # 850 scenes, default workers
    python benchmarks/bench_world.py --scenes 100  # quicker

Prints the wall time to generate the scenes (the brief's budget: 850 scenes in
<= 60 s on 2 cores), the CPU time per scene by stage in one process, and the
median time to rasterise one 64 x 64 frame (budget <= 1 ms), single and batched.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from minimanc import world
from minimanc.world import driver, maps, roads


def raster_timing(n_scenes: int = 10) -> tuple[float, float, float]:
    """Median ms per frame for rasterize (single) and rasterize_batch (per frame, 40 frames)."""
    cfg = world.RasterConfig()
    single, batch = [], []
    for i in range(n_scenes):
        rng = np.random.default_rng([123, i])
        m = maps.random_map(rng)
        log = driver.simulate_scene(m, rng)
        world.rasterize(m, log.ego[0], log.ado[0], log.ado_valid[0], cfg)  # warm caches
        for t in range(log.ego.shape[0]):
            t0 = time.perf_counter()
            world.rasterize(m, log.ego[t], log.ado[t], log.ado_valid[t], cfg)
            single.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        world.rasterize_batch(m, log.ego, log.ado, log.ado_valid, cfg)
        batch.append((time.perf_counter() - t0) / log.ego.shape[0])
    big = world.RasterConfig(size=250)
    t0 = time.perf_counter()
    for t in range(10):
        world.rasterize(m, log.ego[t], log.ado[t], log.ado_valid[t], big)
    big_ms = (time.perf_counter() - t0) / 10 * 1e3
    return 1e3 * float(np.median(single)), 1e3 * float(np.median(batch)), big_ms


def stage_timing(n: int = 12) -> dict[str, float]:
    """CPU ms per scene spent in each stage of generate_scene (one process)."""
    cfg = world.RasterConfig()
    stages = {"map": 0.0, "simulate": 0.0, "check": 0.0, "raster+targets": 0.0}
    for i in range(n):
        rng = np.random.default_rng([99, i, 0])
        t0 = time.process_time()
        m = roads.build_map(maps.random_recipe(rng))
        t1 = time.process_time()
        log = driver.simulate_scene(m, rng)
        t2 = time.process_time()
        driver.check_scene(m, log)
        t3 = time.process_time()
        world.rasterize_batch(m, log.ego, log.ado, log.ado_valid, cfg)
        world.lane_targets(m, log.ego)
        t4 = time.process_time()
        for k, dt in zip(stages, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
            stages[k] += dt * 1e3 / n
    return stages


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=850)
    ap.add_argument("--workers", type=int, default=None)
    args = ap.parse_args()
    print(f"cpus: {os.cpu_count()}, load average: {os.getloadavg()[0]:.1f}")
    single, batch, big = raster_timing()
    print(f"raster 64x64: median {single:.3f} ms/frame (rasterize), "
          f"{batch:.3f} ms/frame (rasterize_batch of 40)")
    print(f"raster 250x250 (authors' size): {big:.2f} ms/frame")
    for k, v in stage_timing().items():
        print(f"  cpu per scene, {k:15s} {v:7.1f} ms")
    t0 = time.perf_counter()
    ds = world.generate(args.scenes, seed=0, workers=args.workers, progress=False)
    dt = time.perf_counter() - t0
    print(f"generation: {args.scenes} scenes in {dt:.1f} s "
          f"({dt / args.scenes * 1e3:.1f} ms/scene wall; budget 850 scenes in 60 s)")
    att = np.array(ds.meta["attempts"])
    print(f"redrawn scenes (off road or collision on the first draw): "
          f"{(att > 1).mean():.1%}, mean attempts {att.mean():.3f}")
    print(f"dataset bev: {ds.bev.nbytes / 1e6:.0f} MB in memory")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        path = world.save(ds, Path(tmp) / "world.npz")
        ts = time.perf_counter() - t0
        t0 = time.perf_counter()
        world.load(path)
        tl = time.perf_counter() - t0
        size = path.stat().st_size
    print(f"save {ts:.1f} s, load {tl:.1f} s, file {size / 1e6:.0f} MB "
          f"(compression {ds.bev.nbytes / size:.1f}x on the rasters' size)")


if __name__ == "__main__":
    main()
