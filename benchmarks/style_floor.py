"""The style floor of Table I: the ADE that no controller ignorant of the scene's style can beat.

Each scene's human draws a hidden style (:func:`minimanc.world.driver.random_style`:
desired speed, headway, reaction delay, ...). A controller that sees only the scene cannot
know it. This script re-drives every validation scene with the world's own driver, on
the scene's own random stream (same map, same traffic, same noise draws), with the style
replaced by the population's median style (the median of each field over
``--population`` draws), the ados reacting to it; it reports the ADE to the logged human
(mean, median, 90th percentile), the along- and cross-track parts, the mean speed
difference, and the median-style driver's at-fault collisions.

Run: ``python benchmarks/style_floor.py --scenes 200 --seed 777``
"""

from __future__ import annotations

import argparse
import time
from dataclasses import asdict, fields
from pathlib import Path

import numpy as np

from minimanc import results, world
from minimanc.metrics.safety import at_fault_collisions
from minimanc.world.driver import HumanStyle, random_style, simulate_scene
from minimanc.world.generation import draw_scene


def median_style(n: int = 20000, seed: int = 0) -> HumanStyle:
    """The field-wise median of ``n`` styles drawn by :func:`random_style`."""
    rng = np.random.default_rng(seed)
    draws = [asdict(random_style(rng)) for _ in range(n)]
    return HumanStyle(**{f.name: float(np.median([d[f.name] for d in draws]))
                         for f in fields(HumanStyle)})


def redrive(seed: int, index: int, attempt: int, style: HumanStyle | None, T: int):
    """Scene ``index`` of data seed ``seed`` driven by the world's human with ``style``
    (``None``: the scene's own style, which reproduces the log: the script's self-check)."""
    rng, _, m = draw_scene(seed, index, attempt)
    log = simulate_scene(m, rng, T=T, style=style)
    return log.ego, log.ado, log.ado_valid, m


def along_cross(ego: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    """Mean |along-| and |cross-track| error of ``ego (T, 3)`` in the frame of ``ref (T, 3)``."""
    d = ego[:, :2] - ref[:, :2]
    c, s = np.cos(ref[:, 2]), np.sin(ref[:, 2])
    return float(np.mean(np.abs(d[:, 0] * c + d[:, 1] * s))), float(
        np.mean(np.abs(-d[:, 0] * s + d[:, 1] * c)))


def main() -> None:
    lines: list[str] = []

    def say(text: str) -> None:
        print(text)
        lines.append(text)

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=200)
    ap.add_argument("--seed", type=int, default=777)
    ap.add_argument("--population", type=int, default=20000)
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the figures and their provenance to this markdown file")
    args = ap.parse_args()
    t_start = time.perf_counter()
    t0 = time.perf_counter()
    ds = world.generate(args.scenes, seed=args.seed)
    style = median_style(args.population)
    say(f"style floor: {args.scenes} scenes of data seed {args.seed}; median style "
          + ", ".join(f"{k}={v:.2f}" for k, v in asdict(style).items()))
    S, T = ds.ego.shape[:2]
    own = [redrive(args.seed, int(ds.meta["scene_index"][i]), int(ds.meta["attempts"][i]) - 1,
                   None, T)[0] for i in range(min(S, 4))]
    err = max(float(np.abs(e[:, :2] - ds.ego[i, :, :2]).max()) for i, e in enumerate(own))
    if err > 1e-3:
        raise SystemExit(f"style_floor: self-check failed: the scene's own style re-drives "
                         f"{err:.3g} m from the log (expected float32 rounding)")
    say(f"self-check: own-style re-drive of {len(own)} scenes matches the log to {err:.1e} m")
    ades, alongs, crosses, dv = [], [], [], []
    egos, ados, vals, maps = [], [], [], []
    for i in range(S):
        ego, ado, val, m = redrive(args.seed, int(ds.meta["scene_index"][i]),
                                   int(ds.meta["attempts"][i]) - 1, style, T)
        ref = np.asarray(ds.ego[i], dtype=np.float64)
        ades.append(float(np.mean(np.linalg.norm(ego[:, :2] - ref[:, :2], axis=-1))))
        a, c = along_cross(ego, ref)
        alongs.append(a)
        crosses.append(c)
        v = np.linalg.norm(np.diff(ego[:, :2], axis=0), axis=-1)
        v_ref = np.linalg.norm(np.diff(ref[:, :2], axis=0), axis=-1)
        dv.append(float(np.mean(np.abs(v - v_ref)) / 0.5))
        egos.append(ego)
        ados.append(ado)
        vals.append(val)
        maps.append(m)
    fault = at_fault_collisions(np.stack(egos), np.stack(ados), np.stack(vals), maps)
    ades_a = np.array(ades)
    say(f"ADE m: mean {ades_a.mean():.2f}, median {np.median(ades_a):.2f}, "
          f"90th percentile {np.percentile(ades_a, 90):.2f}")
    say(f"along-track m {np.mean(alongs):.2f}, cross-track m {np.mean(crosses):.2f}, "
          f"mean |speed difference| m/s {np.mean(dv):.2f}")
    say(f"at-fault collisions of the median-style driver: {100 * fault.mean():.1f} % "
          f"({int(fault.sum())} of {S}); {time.perf_counter() - t0:.0f} s")

    if args.out is not None:
        text = "# Style floor\n\n## Figures\n\n```\n" + "\n".join(lines) + "\n```\n\n"
        results.write_text(args.out, text + results.provenance_markdown(
            results.provenance(), time.perf_counter() - t_start))


if __name__ == "__main__":
    main()
