"""Chapter 10 — the closed loop: a chapter-9 policy drives the ego in highway-env.

:func:`drive_episodes` runs any chapter-9 policy (:class:`minimanc.rollout.ModelPolicy`
for MANC and the baselines) from the seeds of expert episodes, observations
from :func:`minimanc.inputs.from_state`; :attr:`ClosedLoopResult.metrics`
reports collision rate (highway-env's ``crashed``), off-road rate
(:func:`minimanc.metrics.off_road`), ADE to the expert of the same seed
(:func:`minimanc.metrics.ade`), mean speed and episodes per second.
:func:`plain_policy` wraps a policy for one ego and :func:`render_episode`
films an episode headless.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from minimanc import metrics
from minimanc.highway.env import DEFAULT_STEPS, MAX_ADO, POLICY_FREQUENCY, check_scenario
from minimanc.highway.episodes import Episode, HighwaySim, PlainPolicy, PolicyFn, run_episode
from minimanc.highway.render import save_gif, save_png
from minimanc.rollout import drive
from minimanc.world.encodings import to_rgb
from minimanc.world.raster import RasterConfig


@dataclass
class ClosedLoopResult:
    """Policy episodes and the expert episodes of the same seeds, with :attr:`metrics`."""

    scenario: str
    name: str
    episodes: list[Episode]
    experts: list[Episode]
    seconds: float

    @property
    def metrics(self) -> dict[str, float]:
        """Collision and off-road rates (%), ADE to the expert (m), goal distance (m),
        mean speed (m/s) and episodes per second.

        * ``collision_rate``: episodes in which highway-env flags the ego
          ``crashed`` at some step (its own collision test, 5 m × 2 m boxes);
        * ``off_road_rate``: episodes in which the ego's centre leaves the
          drivable area (:func:`minimanc.metrics.off_road` on the episode map);
        * ``ade``: :func:`minimanc.metrics.ade` to the expert of the same
          seed, same clock; ``goal_distance`` to the expert's final position;
        * ``mean_speed``: mean of the ego's speed over all recorded steps;
        * ``episodes_per_second``: wall clock, environment and policy included.
        """
        ego = np.stack([ep.poses for ep in self.episodes])
        ref = np.stack([ep.poses for ep in self.experts])
        return {
            "collision_rate": 100.0 * float(np.mean([ep.collided for ep in self.episodes])),
            "off_road_rate": 100.0 * float(metrics.off_road(
                ego, [ep.map for ep in self.episodes]).mean()),
            "ade": float(metrics.ade(ego, ref).mean()),
            "goal_distance": float(metrics.goal_distance(ego, ref[:, -1]).mean()),
            "mean_speed": float(np.mean([ep.speeds.mean() for ep in self.episodes])),
            "episodes_per_second": len(self.episodes) / max(self.seconds, 1e-9),
        }


def drive_episodes(
    policy: Any,
    scenario: str,
    experts: Sequence[Episode],
    cfg: RasterConfig | None = None,
    max_ado: int = MAX_ADO,
    progress: bool = False,
    record_bev: bool = False,
) -> ClosedLoopResult:
    """Drive a chapter-9 policy (:class:`minimanc.rollout.ModelPolicy` or any
    :class:`minimanc.rollout.Policy`) in highway-env from the seeds of ``experts``.

    All episodes run in lock-step so the policy sees one batch per step. Each
    episode starts from ``env.reset(seed)`` of its expert, lasts ``T − 1``
    decisions (``T`` = the expert episode's recorded states minus one, as the
    chapter-9 closed loop makes ``T − 1`` decisions on a ``T``-step log) and
    at each step the observation comes from :func:`minimanc.inputs.from_state`
    at the ego's own pose: the BEV (drawn with ``cfg``, the raster the policy's model was
    trained on, :attr:`minimanc.train.FitResult.raster`) of the map with the live traffic
    and, when ``cfg.history > 0``, the ego's and the ados' boxes of the past steps of
    this episode, the goal
    = the expert's pose at ``T − 1``, the lane target on the route from the
    current lane, and ``motion`` = the policy's previous control (at ``t = 0``
    the ego's speed and yaw rate 0). Controls go through
    :class:`ActionAdapter`. The result's experts are cut to the same ``T``
    states.
    """
    check_scenario(scenario)
    if len(experts) == 0:
        raise ValueError("experts must hold at least one expert episode, got 0")
    if any(ep.scenario != scenario for ep in experts):
        raise ValueError(f"experts must all be {scenario!r} episodes")
    T = experts[0].steps
    if any(ep.steps != T for ep in experts):
        raise ValueError("experts must all have the same number of steps")
    t0 = time.perf_counter()
    sim = HighwaySim(scenario, [ep.seed for ep in experts], T,
                     [ep.poses[T - 1] for ep in experts], cfg, max_ado, record_bev,
                     k_targets=experts[0].lane_target.shape[1])
    bar = None
    if progress:
        bar = tqdm(total=T - 1, desc=f"{scenario} {policy.model}", leave=False)
    drive(policy, sim, T - 1, None if bar is None else lambda t: bar.update(1))
    if bar is not None:
        bar.close()
    episodes = sim.finish()
    cut = [dataclasses.replace(
        ep, poses=ep.poses[:T], speeds=ep.speeds[:T], ado=ep.ado[:T], ado_valid=ep.ado_valid[:T],
        lane_target=ep.lane_target[:T], commands=ep.commands[:T - 1], actions=ep.actions[:T - 1],
        crashed=ep.crashed[:T], on_road=ep.on_road[:T],
        bev=None if ep.bev is None else ep.bev[:T]) for ep in experts]
    name = getattr(policy, "model", None) or "policy"
    return ClosedLoopResult(scenario, str(name), episodes, cut, time.perf_counter() - t0)


def plain_policy(policy: Any, goal: np.ndarray, cfg: RasterConfig | None = None) -> PolicyFn:
    """Wrap a chapter-9 policy (e.g. :class:`minimanc.rollout.ModelPolicy`) as a
    :data:`PolicyFn` for :func:`run_episode` / :func:`render_episode` (one ego).

    The observation is built with :func:`minimanc.inputs.from_state` exactly
    as :func:`drive_episodes` does (``goal`` a world pose, ``cfg`` the raster of
    the model) and the policy's recurrent state is carried (:class:`PlainPolicy`).
    """
    return PlainPolicy(policy, goal, cfg)


def expert_result(scenario: str, experts: Sequence[Episode]) -> ClosedLoopResult:
    """The experts as a :class:`ClosedLoopResult` (the "human" row: ADE 0 by definition)."""
    T = experts[0].steps
    cut = [dataclasses.replace(ep, poses=ep.poses[:T], speeds=ep.speeds[:T],
                               crashed=ep.crashed[:T]) for ep in experts]
    return ClosedLoopResult(scenario, "expert", cut, cut,
                            float(sum(ep.seconds for ep in experts)))


def render_episode(
    scenario: str,
    seed: int,
    out_dir: str | Path,
    policy: PolicyFn | str = "expert",
    steps: int = DEFAULT_STEPS,
    goal: np.ndarray | None = None,
    cfg: RasterConfig | None = None,
    bev_scale: int = 4,
) -> dict[str, Path]:
    """Run an episode headless and write highway-env's frames and the BEV frames to ``out_dir``.

    Writes ``frame_000.png`` … (highway-env's view), ``episode.gif`` (its
    frames at 2 fps = real time) and ``bev.gif`` (the policy's input drawn with ``cfg``,
    the channels painted in the devkit's colours by :func:`minimanc.world.to_rgb`,
    upscaled ``bev_scale`` times). Returns the paths by name.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ep = run_episode(scenario, seed, policy, steps=steps, goal=goal, cfg=cfg, render=True)
    paths: dict[str, Path] = {}
    for t, fr in enumerate(ep.frames):
        paths[f"frame_{t:03d}"] = save_png(fr, out / f"frame_{t:03d}.png")
    paths["episode"] = save_gif(ep.frames, out / "episode.gif", fps=POLICY_FREQUENCY)
    paths["bev"] = save_gif(list(to_rgb(ep.bev, cfg or RasterConfig())), out / "bev.gif",
                            fps=POLICY_FREQUENCY, scale=bev_scale)
    return paths
