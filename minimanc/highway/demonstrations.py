"""Chapter 10 — expert demonstrations in the chapter-7 dataset format.

:func:`expert_episodes` records collision-free expert episodes,
:func:`to_dataset` assembles them into a :class:`minimanc.world.Dataset`
with the world's one builder (:meth:`minimanc.world.Dataset.build`, metadata
from :func:`minimanc.world.fileformat.empty_meta`, maps as explicit recipes),
so ``world.save`` / ``world.load`` and ``minimanc.train`` work unchanged, and
:func:`collect_demonstrations` does both for several scenarios.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from tqdm import tqdm

from minimanc.checks import check_int
from minimanc.highway.env import (
    DEFAULT_STEPS,
    ENV_IDS,
    MAX_ADO,
    SCENARIOS,
    check_scenario,
)
from minimanc.highway.episodes import Episode, check_steps, run_episode
from minimanc.world.fileformat import append_scenes, empty_meta
from minimanc.world.geometry import goal_in_ego_frame
from minimanc.world.history import history_of
from minimanc.world.raster import RasterConfig, rasterize, rasterize_batch
from minimanc.world.scenes import Dataset

EVAL_SEED = 100_000
"""First env seed of evaluation episodes (training demonstrations start at 0)."""


def expert_episodes(
    scenario: str,
    n: int,
    seed: int = 0,
    steps: int = DEFAULT_STEPS,
    cfg: RasterConfig | None = None,
    max_ado: int = MAX_ADO,
    record_bev: bool = True,
    max_tries: int | None = None,
    progress: bool = False,
) -> tuple[list[Episode], int]:
    """``n`` collision-free expert episodes from env seeds ``seed, seed + 1, …``.

    IDM/MOBIL sometimes crashes (roundabout entries, intersections); such
    episodes are skipped, as chapter 7 redraws scenes where the human
    collides. Returns ``(episodes, tries)``; ``tries − n`` were skipped.
    Raises RuntimeError after ``max_tries`` (default ``3 n + 10``) attempts.
    """
    check_scenario(scenario)
    check_steps(steps)
    n = check_int("n", n, 1)
    limit = 3 * int(n) + 10 if max_tries is None else int(max_tries)
    out: list[Episode] = []
    tries = 0
    bar = None
    if progress:
        bar = tqdm(total=int(n), desc=f"expert {scenario}", leave=False)
    try:
        while len(out) < n:
            if tries >= limit:
                raise RuntimeError(f"{scenario}: only {len(out)} collision-free expert "
                                   f"episodes in {tries} tries from seed {seed}")
            ep = run_episode(scenario, int(seed) + tries, "expert", steps=steps, cfg=cfg,
                             max_ado=max_ado, record_bev=record_bev)
            tries += 1
            if not ep.collided:
                out.append(ep)
                if bar is not None:
                    bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return out, tries


def to_dataset(episodes: Sequence[Episode], cfg: RasterConfig | None = None,
               seed: int = 0, attempts: Sequence[int] | None = None) -> Dataset:
    """Chapter-7 :class:`minimanc.world.Dataset` from expert episodes of equal length.

    An episode of ``T`` actions gives one scene of ``T`` steps: ``ego`` the
    poses ``0 … T−1``, ``controls[t]`` (:attr:`Episode.controls`) from ``t`` to
    ``t + 1``, ``goal`` the last pose in each ego frame, the lane targets and
    ados recorded at each step, ``bev`` the rasters (re-rendered with ``cfg``, its
    past steps from the episode's, if the episode has none; a raster with a route needs
    them recorded, since the route follows the lane the ego was in at each step),
    ``goal_bev`` the static raster at the goal, and
    ``maps`` the episode maps (explicit recipes in ``meta["recipes"]``).
    ``meta["tags"]`` records the scenario, env id and seed, destination and
    expert speed per scene.
    """
    cfg = cfg or RasterConfig()
    if len(episodes) == 0:
        raise ValueError("episodes must hold at least one episode, got 0")
    lengths = {ep.steps for ep in episodes}
    if len(lengths) != 1:
        raise ValueError(f"episodes must all have the same number of steps, got {sorted(lengths)}")
    As = {ep.ado.shape[1] for ep in episodes}
    if len(As) != 1:
        raise ValueError(f"episodes must all have the same number of ado rows, got {sorted(As)}")
    T = lengths.pop()
    scenes = []
    for ep in episodes:
        ego = ep.poses[:T]
        bev = ep.bev[:T] if ep.bev is not None and ep.bev.shape[1:] == cfg.shape else None
        if bev is None:
            if cfg.route:
                raise ValueError("episodes drawn with a route must carry their BEV (the route "
                                 "follows the ego's lane at each step): record them with "
                                 "expert_episodes(..., cfg=cfg)")
            past = history_of(ego, ep.ado[:T], ep.ado_valid[:T],
                              cfg.history) if cfg.history else None
            bev = rasterize_batch(ep.map, ego, ep.ado[:T], ep.ado_valid[:T], cfg, history=past)
        scenes.append({
            "bev": bev,
            "ego": ego.astype(np.float32),
            "controls": ep.controls[:T].astype(np.float32),
            "goal": goal_in_ego_frame(np.broadcast_to(ego[-1], ego.shape), ego).astype(np.float32),
            "lane_target": ep.lane_target[:T].astype(np.float32),
            "ado": ep.ado[:T].astype(np.float32),
            "ado_valid": ep.ado_valid[:T],
            "goal_bev": rasterize(ep.map, ego[-1], None, None, cfg),
        })
    tags = [{
        "kind": ep.map.kind, "source": "highway-env", "scenario": ep.scenario,
        "env_id": ENV_IDS[ep.scenario], "env_seed": ep.seed, "destination": ep.destination,
        "expert_speed": round(float(ep.expert_speed), 4),
        "has_junction": ep.map.kind == "intersection",
        "has_roundabout": ep.map.kind == "roundabout",
    } for ep in episodes]
    meta = empty_meta(seed, cfg)
    append_scenes(meta, [ep.map.recipe for ep in episodes], tags,
                  [1] * len(episodes) if attempts is None else attempts,
                  [ep.seed for ep in episodes])  # scene_index: the env seeds
    meta["source"] = "highway-env"
    return Dataset.build(scenes, meta, maps=[ep.map for ep in episodes], what="demonstrations")


def collect_demonstrations(
    scenarios: Sequence[str] | str = tuple(SCENARIOS),
    n_episodes: int = 20,
    seed: int = 0,
    steps: int = DEFAULT_STEPS,
    cfg: RasterConfig | None = None,
    max_ado: int = MAX_ADO,
    progress: bool = False,
) -> Dataset:
    """Expert demonstrations in the chapter-7 format: ``n_episodes`` per scenario.

    Episodes come from :func:`expert_episodes` (env seeds from ``seed``,
    collisions skipped), scenario by scenario, and are assembled by
    :func:`to_dataset`; ``meta["attempts"]`` counts the seeds each scene took.
    Save with :func:`minimanc.world.save`; :func:`minimanc.world.load` reads
    it back (its maps are explicit recipes, see :func:`explicit_map`).
    """
    n_episodes = check_int("n_episodes", n_episodes, 1)
    names = [scenarios] if isinstance(scenarios, str) else list(scenarios)
    if not names:
        raise ValueError("scenarios must name at least one scenario, got none")
    for sc in names:
        check_scenario(sc)
    cfg = cfg or RasterConfig()
    episodes: list[Episode] = []
    attempts: list[int] = []
    for sc in names:
        eps, tries = expert_episodes(sc, n_episodes, seed, steps, cfg, max_ado, True,
                                     progress=progress)
        prev = int(seed) - 1
        for ep in eps:
            attempts.append(ep.seed - prev)
            prev = ep.seed
        episodes += eps
    return to_dataset(episodes, cfg, seed=seed, attempts=attempts)

