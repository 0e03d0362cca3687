"""Chapter 9 — the bounds every closed-loop number is read against: the expert and the style
floor (rows of Table I).

**Expert.** The world's human (:class:`minimanc.world.expert.HumanExpert`) asked in every
state the closed loop reaches (:class:`minimanc.dagger.privileged.ExpertPolicy`), driving
through the same simulators and the same time loop as the learned policies, under either
protocol: :func:`expert_rollout`. The upper bound of every learner.

**Style floor.** Each scene's human draws a hidden style
(:func:`minimanc.world.driver.random_style`: desired speed, headway, reaction delay, ...)
that a controller seeing only the scene cannot know. :func:`floor_rollout` re-drives every
scene with the world's own driver on the scene's own map, traffic and random stream, the
style replaced by the population's field-wise median (:func:`median_style`;
:meth:`minimanc.world.driver.SceneRun.restyle`), the ados reacting to it. Its distance to
the logged human is what a style-blind driver that sees road and traffic perfectly still
makes: the floor of the along-track error. Re-driving with each scene's own style
reproduces the log (:func:`floor_rollout` with ``style=None``; checked by the tests).
"""

from __future__ import annotations

from dataclasses import asdict, fields
from types import SimpleNamespace
from typing import Any

import numpy as np

from minimanc import rollout
from minimanc.checks import check_int
from minimanc.dagger.privileged import ExpertPolicy
from minimanc.dagger.teachers import WorldTeacher
from minimanc.world.driver import HumanStyle, random_style, simulate_scene
from minimanc.world.generation import draw_scene

__all__ = ["BOUND_ROWS", "expert_rollout", "floor_rollout", "median_style"]

BOUND_ROWS: tuple[str, ...] = ("expert", "style_floor")
"""The bound rows of Table I."""


def expert_rollout(ds: Any, agents: str, progress: bool = False) -> tuple[Any, int]:
    """The expert's closed-loop :class:`minimanc.rollout.Rollout` on every scene of ``ds``
    (a dataset that regenerates: :func:`minimanc.world.generate`) under ``agents``, and
    the number of states it could not be asked in."""
    policy = ExpertPolicy(WorldTeacher(ds, agents=agents))
    traj = rollout.simulate(policy, ds, agents=agents, progress=progress,
                            desc=f"expert ({agents})")
    return traj, policy.refused


def median_style(n: int = 20000, seed: int = 0) -> HumanStyle:
    """The field-wise median of ``n`` styles drawn by :func:`random_style` from ``seed``."""
    n = check_int("n", n, 1)
    rng = np.random.default_rng(seed)
    draws = [asdict(random_style(rng)) for _ in range(n)]
    return HumanStyle(**{f.name: float(np.median([d[f.name] for d in draws]))
                         for f in fields(HumanStyle)})


def floor_rollout(ds: Any, style: HumanStyle | None, scenes: Any = None) -> SimpleNamespace:
    """The scenes ``scenes`` (default: all) of ``ds`` re-driven by the world's human with
    ``style`` (``None``: each scene's own), ados reacting: ``ego (S, T, 3)``,
    ``ado (S, T, A, 5)``, ``ado_valid (S, T, A)`` (what :func:`minimanc.metrics.evaluate`
    reads). ``ds`` must be a generated dataset (its ``meta`` names the seed and each
    scene's draw)."""
    meta = ds.meta
    if "scene_index" not in meta or "attempts" not in meta or "seed" not in meta:
        raise ValueError("the style floor needs a generated dataset (minimanc.world.generate): "
                         "its meta must name seed, scene_index and attempts")
    idx = range(len(ds.ego)) if scenes is None else [int(i) for i in scenes]
    T = int(np.asarray(ds.ego).shape[1])
    logs = []
    for i in idx:
        rng, _, m = draw_scene(int(meta["seed"]), int(meta["scene_index"][i]),
                               int(meta["attempts"][i]) - 1)
        logs.append(simulate_scene(m, rng, T=T, style=style,
                                   max_ados=int(np.asarray(ds.ado).shape[2])))
    return SimpleNamespace(ego=np.stack([g.ego for g in logs]),
                           ado=np.stack([g.ado for g in logs]),
                           ado_valid=np.stack([g.ado_valid for g in logs]))
