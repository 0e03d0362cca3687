"""The expert bound of Table I: the world's own driver driven closed loop.

The world's human (:class:`minimanc.world.expert.HumanExpert`, asked through
:class:`minimanc.dagger.teachers.WorldTeacher`) drives the validation scenes through the
same simulators and the same time loop (:func:`minimanc.rollout.driver.drive`) as the
learned policies, under both protocols (replayed and reactive ados), and the same
metrics (:func:`minimanc.metrics.evaluate`) are taken. Every learned controller's
at-fault rate and ADE are to be read against these numbers: a learner cannot be
expected to beat the driver it copies.

A state the expert refuses to label (off the drivable area, far from its route) is
driven with the last applied controls and counted.

Run: ``python benchmarks/expert_bound.py --scenes 200 --seed 777``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from minimanc import metrics, results, world
from minimanc.dagger.teachers import WorldTeacher
from minimanc.rollout.driver import drive


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


def expert_rollout(ds, agents: str):
    """The expert's closed-loop trajectory on every scene of ``ds`` under ``agents``."""
    teacher = WorldTeacher(ds, agents=agents)
    idx = np.arange(len(ds.ego))
    egos, ados, valids, refused = [], [], [], 0
    n_steps = ds.ego.shape[1] - 1
    for chunk in teacher.groups(idx):
        sim = teacher.simulator(chunk)
        policy = ExpertPolicy(teacher, sim)
        drive(policy, sim, n_steps)
        egos.append(sim.trajectory())
        refused += policy.refused
        if agents == "reactive":
            a, v = sim.ado_trajectory()
            ados.append(a)
            valids.append(v)
    traj = SimpleNamespace(ego=np.concatenate(egos), ado=np.concatenate(ados) if ados else None,
                           ado_valid=np.concatenate(valids) if valids else None)
    return traj, refused


def main() -> None:
    lines: list[str] = []

    def say(text: str) -> None:
        print(text)
        lines.append(text)

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=200)
    ap.add_argument("--seed", type=int, default=777)
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the figures and their provenance to this markdown file")
    args = ap.parse_args()
    t_start = time.perf_counter()
    ds = world.generate(args.scenes, seed=args.seed)
    say(f"expert bound: {args.scenes} scenes of data seed {args.seed}")
    say(f"{'protocol':10s} {'ADE m':>7s} {'at fault %':>11s} "
        f"{'collision %':>12s} {'off road %':>11s} {'refused':>8s} {'s':>6s}")
    for agents in ("replay", "reactive"):
        t0 = time.perf_counter()
        traj, refused = expert_rollout(ds, agents)
        m = metrics.evaluate(traj, ds)
        say(f"{agents:10s} {m['ade']:7.2f} {m['at_fault_collision_rate']:11.1f} "
            f"{m['collision_rate']:12.1f} {m['off_road_rate']:11.1f} {refused:8d} "
            f"{time.perf_counter() - t0:6.0f}")

    if args.out is not None:
        text = "# Expert bound\n\n## Figures\n\n```\n" + "\n".join(lines) + "\n```\n\n"
        results.write_text(args.out, text + results.provenance_markdown(
            results.provenance(), time.perf_counter() - t_start))


if __name__ == "__main__":
    main()
