"""The bounds of Table I: the expert, and the style floor no style-blind learner can beat.

**Expert.** The world's human (:class:`minimanc.world.expert.HumanExpert`, asked through
:class:`minimanc.dagger.teachers.WorldTeacher`) drives the validation scenes through the
same simulators and the same time loop (:func:`minimanc.rollout.driver.drive`) as the
learned policies, under both protocols (replayed and reactive ados); the metrics are
:func:`minimanc.metrics.evaluate`'s. A state the expert refuses to label (off the
drivable area, far from its route) is driven with the last applied controls and counted.

**Style floor.** Each scene's human draws a hidden style
(:func:`minimanc.world.driver.random_style`: desired speed, headway, reaction delay, ...)
that a controller seeing only the scene cannot know. Every validation scene is re-driven
by the world's own driver on the scene's own random stream (same map, traffic and noise
draws), with the style replaced by the population's median style (the median of each
field over ``--population`` draws; :meth:`minimanc.world.driver.SceneRun.restyle`), the
ados reacting to it: its ADE to the logged human (mean, median, 90th percentile), the
along- and cross-track parts (:func:`minimanc.metrics.trajectory.along_cross_track`), the
mean speed difference and its at-fault collisions. Re-driving with the scene's own style
must reproduce the log (checked first).

Run: ``python benchmarks/bounds.py --scenes 200 --seed 777 --out results/bounds.md``
"""

from __future__ import annotations

import argparse
import time
from dataclasses import asdict, fields
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from minimanc import metrics, results, world
from minimanc.dagger.teachers import AGENTS, WorldTeacher
from minimanc.metrics.trajectory import ade, along_cross_track
from minimanc.rollout.driver import drive
from minimanc.world.driver import HumanStyle, random_style, simulate_scene
from minimanc.world.generation import draw_scene
from minimanc.world.geometry import DT


class ExpertPolicy:
    """The teacher's label of the simulator's current state as a policy (reads no image)."""

    model = None
    setting = "paper"
    keys = ("motion",)

    def __init__(self, teacher: WorldTeacher, sim) -> None:
        self.teacher, self.sim = teacher, sim
        self.prev: np.ndarray | None = None
        self.refused = 0

    def initial_state(self, scenes: np.ndarray) -> None:
        return None

    def __call__(self, obs: dict, state, t: int, scenes: np.ndarray):
        out, why = self.teacher.label(self.sim, t, self.prev)
        bad = np.array([w is not None for w in why])
        if bad.any():
            self.refused += int(bad.sum())
            fallback = self.prev if self.prev is not None else np.zeros_like(out)
            out[bad] = fallback[bad]
        self.prev = out
        return out, state, {}


def expert_rollout(ds, agents: str) -> tuple[SimpleNamespace, int]:
    """The expert's closed-loop trajectory on every scene of ``ds`` under ``agents``, and
    the number of states it refused to label."""
    teacher = WorldTeacher(ds, agents=agents)
    egos, ados, valids, refused = [], [], [], 0
    for chunk in teacher.groups(np.arange(len(ds.ego))):
        sim = teacher.simulator(chunk)
        policy = ExpertPolicy(teacher, sim)
        drive(policy, sim, ds.ego.shape[1] - 1)
        egos.append(sim.trajectory())
        refused += policy.refused
        if agents == "reactive":
            a, v = sim.ado_trajectory()
            ados.append(a)
            valids.append(v)
    traj = SimpleNamespace(ego=np.concatenate(egos), ado=np.concatenate(ados) if ados else None,
                           ado_valid=np.concatenate(valids) if valids else None)
    return traj, refused


def median_style(n: int = 20000, seed: int = 0) -> HumanStyle:
    """The field-wise median of ``n`` styles drawn by :func:`random_style`."""
    rng = np.random.default_rng(seed)
    draws = [asdict(random_style(rng)) for _ in range(n)]
    return HumanStyle(**{f.name: float(np.median([d[f.name] for d in draws]))
                         for f in fields(HumanStyle)})


def restyled_rollout(ds, seed: int, style: HumanStyle | None, scenes=None) -> SimpleNamespace:
    """The scenes ``scenes`` (default: all) of ``ds`` (generated from data seed ``seed``)
    re-driven by the world's human with ``style`` (``None``: the scene's own style)."""
    idx = range(len(ds.ego)) if scenes is None else scenes
    logs = []
    for i in idx:
        rng, _, m = draw_scene(seed, int(ds.meta["scene_index"][i]),
                               int(ds.meta["attempts"][i]) - 1)
        logs.append(simulate_scene(m, rng, T=ds.ego.shape[1], style=style))
    return SimpleNamespace(ego=np.stack([g.ego for g in logs]),
                           ado=np.stack([g.ado for g in logs]),
                           ado_valid=np.stack([g.ado_valid for g in logs]))


def expert_lines(ds) -> list[str]:
    out = [f"{'protocol':10s} {'ADE m':>7s} {'at fault %':>11s} {'collision %':>12s} "
           f"{'off road %':>11s} {'refused':>8s}"]
    for agents in AGENTS:
        traj, refused = expert_rollout(ds, agents)
        m = metrics.evaluate(traj, ds)
        out.append(f"{agents:10s} {m['ade']:7.2f} {m['at_fault_collision_rate']:11.1f} "
                   f"{m['collision_rate']:12.1f} {m['off_road_rate']:11.1f} {refused:8d}")
    return out


def floor_lines(ds, seed: int, population: int) -> list[str]:
    own = restyled_rollout(ds, seed, None, scenes=range(min(len(ds.ego), 4)))
    err = float(np.abs(own.ego[..., :2] - ds.ego[:len(own.ego), :, :2]).max())
    if err > 1e-3:
        raise SystemExit(f"bounds: self-check failed: the scenes' own style re-drives "
                         f"{err:.3g} m from the log (expected float32 rounding)")
    style = median_style(population)
    traj = restyled_rollout(ds, seed, style)
    human = np.asarray(ds.ego, dtype=np.float64)
    dist = ade(traj.ego, human)
    along, cross = along_cross_track(traj.ego, human)
    speed = lambda e: np.linalg.norm(np.diff(e[..., :2], axis=1), axis=-1) / DT  # noqa: E731
    fault = metrics.evaluate(traj, ds)["at_fault_collision_rate"]
    return [
        "median style " + ", ".join(f"{k}={v:.2f}" for k, v in asdict(style).items()),
        f"self-check: own-style re-drive of {len(own.ego)} scenes matches the log to "
        f"{err:.1e} m",
        f"ADE m: mean {dist.mean():.2f}, median {np.median(dist):.2f}, "
        f"90th percentile {np.percentile(dist, 90):.2f}",
        f"along-track m {np.abs(along).mean():.2f}, cross-track m {np.abs(cross).mean():.2f}, "
        f"mean |speed difference| m/s {np.abs(speed(traj.ego) - speed(human)).mean():.2f}",
        f"at-fault collisions of the median-style driver: {fault:.1f} %",
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=200)
    ap.add_argument("--seed", type=int, default=777)
    ap.add_argument("--population", type=int, default=20000)
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the figures and their provenance to this markdown file")
    args = ap.parse_args()
    t0 = time.perf_counter()
    ds = world.generate(args.scenes, seed=args.seed)
    parts = {"Expert": expert_lines(ds),
             "Style floor": floor_lines(ds, args.seed, args.population)}
    text = f"# Bounds of Table I ({args.scenes} scenes of data seed {args.seed})\n\n"
    for title, lines in parts.items():
        text += f"## {title}\n\n```\n" + "\n".join(lines) + "\n```\n\n"
    print(text, end="")
    if args.out is not None:
        results.write_text(args.out, text + results.provenance_markdown(
            results.provenance(), time.perf_counter() - t0))


if __name__ == "__main__":
    main()
