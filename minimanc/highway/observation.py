"""Chapter 10 — the BEV observation: the chapter-7 raster as a gymnasium observation.

:class:`BEVObservation` wraps a sandbox environment and returns the
chapter-7 ego-centric raster (same geometry, encodings and ego pixel as
:mod:`minimanc.world.raster`) of the episode's map (:func:`road_map`) and
the live traffic: the devkit-look RGB image, or a learner's binary planes
(``RasterConfig(encoding="channels")``). With ``cfg.history > 0`` it keeps the
last ``history`` steps' poses and boxes of the episode (as the world's closed loop
does, :mod:`minimanc.world.history`) and draws them.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from minimanc.checks import check_int
from minimanc.highway.env import MAX_ADO, ado_boxes, ego_pose
from minimanc.highway.mapping import road_map
from minimanc.world.encodings import planes
from minimanc.world.history import History
from minimanc.world.lanes import Map
from minimanc.world.raster import RasterConfig, rasterize


class BEVObservation(gym.ObservationWrapper):
    """Observation wrapper: the chapter-7 ego-centric BEV raster of a highway-env scene.

    ``observation_space`` is ``Box(0, 255, (H, W, 3), uint8)`` for the RGB encoding and
    ``Box(0, 1, (H, W, C), uint8)`` for the channels (the planes unpacked,
    :func:`minimanc.world.planes`; ``C = len(cfg.channel_names)``), ``H = cfg.size``,
    ``W = cfg.width``. On ``reset`` the road network is sampled once into a
    :class:`minimanc.world.lanes.Map` (:func:`road_map`, kept as ``self.map``);
    every observation is :func:`minimanc.world.raster.rasterize` of that map
    from the ego's pose with the ``max_ado`` nearest vehicles: in RGB, drivable area
    white, lane centrelines coloured by heading, vehicles yellow, the ego red
    at ``cfg.ego_pixel``, heading up. The past ``cfg.history`` steps (none before the
    episode's first) are drawn from what this wrapper saw.
    """

    def __init__(self, env, cfg: RasterConfig | None = None, max_ado: int = MAX_ADO) -> None:
        super().__init__(env)
        self.cfg = cfg or RasterConfig()
        if not isinstance(self.cfg, RasterConfig):
            raise ValueError(f"cfg must be a RasterConfig, got {cfg!r}")
        self.max_ado = check_int("max_ado", max_ado, 0)
        high = 255 if self.cfg.encoding == "rgb" else 1
        self.observation_space = spaces.Box(0, high, self.cfg.input_shape, dtype=np.uint8)
        self.map: Map | None = None
        self._past: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.map = road_map(self.env)
        self._past = []
        return self.observation(obs), info

    def _history(self) -> History:
        """The last ``cfg.history`` steps seen, most recent first (invalid before the
        episode's first step)."""
        H, A = self.cfg.history, self.max_ado
        ego, ego_valid = np.zeros((1, H, 3)), np.zeros((1, H), bool)
        ado, ado_valid = np.zeros((1, H, A, 5)), np.zeros((1, H, A), bool)
        for j, (pose, boxes, valid) in enumerate(reversed(self._past[-H:])):
            ego[0, j], ego_valid[0, j] = pose, True
            ado[0, j], ado_valid[0, j] = boxes, valid
        return History(ego, ego_valid, ado, ado_valid)

    def observation(self, observation: Any) -> np.ndarray:
        if self.map is None:
            raise RuntimeError("BEVObservation: call reset() before step()")
        ado, valid = ado_boxes(self.env, self.max_ado)
        pose = ego_pose(self.env)
        past = self._history() if self.cfg.history else None
        img = rasterize(self.map, pose, ado, valid, self.cfg, history=past)
        if self.cfg.history:
            self._past = (self._past + [(pose, ado, valid)])[-self.cfg.history:]
        return planes(img, self.cfg)
