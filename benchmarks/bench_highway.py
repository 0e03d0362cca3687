"""Chapter 10 benchmark: highway-env sandbox throughput (prints figures, asserts nothing).

For each scenario: actions per second of the bare environment (ContinuousAction,
constant action), of the IDM/MOBIL expert with and without the chapter-7 BEV,
the cost of one BEV raster, and the cost of highway-env's own rendering with
``enable_auto_render`` left on versus switched off after each frame.
One action = 0.5 s of simulated time (5 sub-steps at 10 Hz).

    python benchmarks/bench_highway.py [--steps 24] [--repeats 2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from minimanc import highway as hw
from minimanc import world


def _bare(scenario: str, steps: int, seed: int) -> float:
    env = hw.make_env(scenario, steps=steps)
    env.reset(seed=seed)
    t0 = time.perf_counter()
    for _ in range(steps):
        env.step(np.zeros(2, np.float32))
    dt = time.perf_counter() - t0
    env.close()
    return steps / dt


def _expert(scenario: str, steps: int, seed: int, bev: bool) -> float:
    t0 = time.perf_counter()
    hw.run_episode(scenario, seed, "expert", steps=steps, record_bev=bev)
    return steps / (time.perf_counter() - t0)


def _raster_ms(scenario: str, n: int = 50) -> float:
    env = hw.make_env(scenario)
    env.reset(seed=0)
    m = hw.road_map(env, scenario)
    ado, valid = hw.ado_boxes(env)
    pose = hw.ego_pose(env)
    cfg = world.RasterConfig()
    world.rasterize(m, pose, ado, valid, cfg)  # build the class grid once
    t0 = time.perf_counter()
    for _ in range(n):
        world.rasterize(m, pose, ado, valid, cfg)
    return 1000 * (time.perf_counter() - t0) / n


def _render(scenario: str, steps: int, auto_off: bool) -> float:
    env = hw.make_env(scenario, steps=steps, render=True)
    env.reset(seed=0)
    env.render()
    t0 = time.perf_counter()
    for _ in range(steps):
        env.step(np.zeros(2, np.float32))
        env.render()
        if auto_off:
            env.enable_auto_render = False
    dt = time.perf_counter() - t0
    env.close()
    return steps / dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=24)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    print(f"{'scenario':<13} {'bare':>7} {'expert':>7} {'+BEV':>7} {'raster':>8} "
          f"{'render':>7} {'render':>7} {'ratio':>6}")
    print(f"{'':<13} {'act/s':>7} {'act/s':>7} {'act/s':>7} {'ms':>8} "
          f"{'auto on':>7} {'off':>7} {'':>6}")
    for sc in hw.SCENARIOS:
        bare = np.median([_bare(sc, args.steps, s) for s in range(args.repeats)])
        exp = np.median([_expert(sc, args.steps, s, False) for s in range(args.repeats)])
        bev = np.median([_expert(sc, args.steps, s, True) for s in range(args.repeats)])
        ras = _raster_ms(sc)
        on = _render(sc, max(args.steps // 3, 4), auto_off=False)
        off = _render(sc, max(args.steps // 3, 4), auto_off=True)
        print(f"{sc:<13} {bare:>7.1f} {exp:>7.1f} {bev:>7.1f} {ras:>8.2f} "
              f"{on:>7.1f} {off:>7.1f} {off / on:>6.2f}")
    print("act/s = actions of 0.5 s per wall-clock second (x0.5 = simulated s per s); "
          "ratio = rendering with auto-render switched off / left on")


if __name__ == "__main__":
    main()
