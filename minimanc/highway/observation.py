"""Chapter 10 — the BEV observation: the chapter-7 raster as a gymnasium observation.

:class:`BEVObservation` wraps a sandbox environment and returns the
chapter-7 ego-centric raster (same size, colours and ego pixel as
:mod:`minimanc.world.raster`) of the episode's map (:func:`road_map`) and
the live traffic.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from minimanc.checks import check_int
from minimanc.highway.env import MAX_ADO, ado_boxes, ego_pose
from minimanc.highway.mapping import road_map
from minimanc.world.lanes import Map
from minimanc.world.raster import RasterConfig, rasterize


class BEVObservation(gym.ObservationWrapper):
    """Observation wrapper: the chapter-7 ego-centric BEV raster of a highway-env scene.

    ``observation_space`` is ``Box(0, 255, (H, W, 3), uint8)`` with ``H = W =
    cfg.size``. On ``reset`` the road network is sampled once into a
    :class:`minimanc.world.lanes.Map` (:func:`road_map`, kept as ``self.map``);
    every observation is :func:`minimanc.world.raster.rasterize` of that map
    from the ego's pose with the ``max_ado`` nearest vehicles: drivable area
    white, lane centrelines coloured by heading, vehicles yellow, the ego red
    at ``cfg.ego_pixel``, heading up.
    """

    def __init__(self, env, cfg: RasterConfig | None = None, max_ado: int = MAX_ADO) -> None:
        super().__init__(env)
        self.cfg = cfg or RasterConfig()
        self.max_ado = check_int("max_ado", max_ado, 0)
        self.observation_space = spaces.Box(0, 255, self.cfg.shape, dtype=np.uint8)
        self.map: Map | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.map = road_map(self.env)
        return self.observation(obs), info

    def observation(self, observation: Any) -> np.ndarray:
        if self.map is None:
            raise RuntimeError("BEVObservation: call reset() before step()")
        ado, valid = ado_boxes(self.env, self.max_ado)
        return rasterize(self.map, ego_pose(self.env), ado, valid, self.cfg)

