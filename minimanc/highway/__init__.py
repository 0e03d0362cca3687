"""Chapter 10 — a highway-env sandbox: the same controller in a real driving simulator.

`highway-env <https://github.com/Farama-Foundation/HighwayEnv>`_ (an optional
dependency: ``pip install 'minimanc[highway]'``) simulates roundabouts,
intersections and highways with IDM/MOBIL traffic that *reacts* to the ego —
unlike the chapter-7 logs, where the ados replay their recorded paths. This
module connects it to the rest of the package without a second copy of
anything:

* **Map adapter** (:func:`road_map`): each lane of highway-env's road network
  is sampled once per episode with ``lane.position(s, 0)`` (every ~1 m) and
  ``lane.width_at(s)`` into a :class:`minimanc.world.lanes.Map` — lane
  centrelines, one drivable strip per lane (half width = half the lane width,
  so "off-road" means what highway-env's ``on_road`` means) and the ego's route.
  The chapter-7 rasteriser then draws it unchanged.
* **Frames**: highway-env's y axis points *down* the screen, so its
  coordinates are left-handed as seen on screen. We mirror them,
  ``x_w = x``, ``y_w = -y``, ``yaw_w = -heading`` (:func:`to_world`), which
  gives the world's right-handed convention (x east, y north, yaw
  counter-clockwise), keeps right-hand traffic on the right and the
  roundabout counter-clockwise, and makes the BEV look like highway-env's own
  rendering turned heading-up.
* **BEV observation** (:class:`BEVObservation`): a gymnasium observation
  wrapper returning the chapter-7 ego-centric raster (same size, colours,
  ego pixel; :mod:`minimanc.world.raster`), in either encoding: the RGB image or a
  learner's binary channels, whose route runs along the lane the ego is in.
* **Action adapter** (:func:`controls_to_action`, :class:`ActionAdapter`):
  the package's controls ``[speed, yaw rate]`` (the output of MANC's DMP
  step, paper eqs. 10–11, integrated once; DT = 0.5 s) become highway-env's ``ContinuousAction``
  ``[acceleration, steering]`` on its kinematic bicycle.
* **Expert** (:class:`ExpertVehicle`, :func:`install_expert`): the ego is
  replaced by highway-env's own IDM/MOBIL vehicle following the route (plus
  gap acceptance at roundabout entries) — the "human" of this chapter — and
  :func:`collect_demonstrations` records collision-free episodes in the chapter-7 dataset
  format (``world.Dataset``, maps as explicit recipes, so ``world.save`` /
  ``world.load`` and ``minimanc.train`` work unchanged). The logged controls
  are the speed reached at ``t + 1`` and the mean yaw rate over the step —
  what the action adapter realises (:attr:`Episode.controls`).
* **Closed loop** (:func:`drive_episodes`): any chapter-9 policy
  (:class:`minimanc.rollout.ModelPolicy` for MANC and the baselines) drives
  the ego, observations from :func:`minimanc.inputs.from_state` drawn with the raster
  the policy's model was trained on (:attr:`minimanc.train.FitResult.raster`) and, when
  it draws past steps, those of the episode being driven; metrics
  (:attr:`ClosedLoopResult.metrics`): collision rate (highway-env's
  ``crashed``), off-road rate (:func:`minimanc.metrics.off_road`), ADE to the
  expert of the same seed (:func:`minimanc.metrics.ade`), mean speed and
  episodes per second.
* **Rendering**: headless with ``SDL_VIDEODRIVER=offscreen`` (``dummy`` gives
  black frames), frames to PNG and an episode to GIF (:func:`render_episode`).

Time step: the policy acts every ``DT = 0.5`` s (``policy_frequency = 2``),
highway-env integrates at ``simulation_frequency = 10`` Hz (5 sub-steps per
action). Same seed → bit-identical episodes.

Modules: :mod:`~minimanc.highway.env` (environments, frames),
:mod:`~minimanc.highway.mapping` (map adapter, route tracker),
:mod:`~minimanc.highway.observation` (BEV wrapper),
:mod:`~minimanc.highway.control` (action adapter, expert),
:mod:`~minimanc.highway.episodes` (one episode),
:mod:`~minimanc.highway.demonstrations` (expert episodes, dataset),
:mod:`~minimanc.highway.evaluate` (closed loop) and
:mod:`~minimanc.highway.render` (frames, PNG, GIF); everything public is
re-exported here (``import minimanc.highway as hw``).
"""

from __future__ import annotations

import os

if os.environ.get("SDL_VIDEODRIVER", "") in ("", "dummy"):
    # "dummy" renders black frames; "offscreen" renders real pixels without a display.
    os.environ["SDL_VIDEODRIVER"] = "offscreen"
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

try:
    import gymnasium  # noqa: F401
    import highway_env  # noqa: F401  (registers the environments)
except ImportError as exc:  # pragma: no cover - exercised with a monkeypatched sys.modules
    raise ImportError(
        "minimanc.highway needs the optional dependency highway-env (and gymnasium); "
        "install it with: pip install 'minimanc[highway]'"
    ) from exc

from minimanc.highway.control import (
    EXPERT_SPEEDS,
    ActionAdapter,
    ExpertVehicle,
    controls_to_action,
    install_expert,
)
from minimanc.highway.demonstrations import (
    EVAL_SEED,
    collect_demonstrations,
    expert_episodes,
    to_dataset,
)
from minimanc.highway.env import (
    DEFAULT_STEPS,
    ENV_IDS,
    MAX_ADO,
    POLICY_FREQUENCY,
    SCENARIOS,
    SIMULATION_FREQUENCY,
    ado_boxes,
    ego_pose,
    make_env,
    to_world,
)
from minimanc.highway.env import (
    EgoStateObservation as EgoStateObservation,
)
from minimanc.highway.env import (
    HighwaySandbox as HighwaySandbox,
)
from minimanc.highway.env import (
    IntersectionSandbox as IntersectionSandbox,
)
from minimanc.highway.env import (
    RoundaboutSandbox as RoundaboutSandbox,
)
from minimanc.highway.episodes import (
    Episode,
    FunctionPolicy,
    HighwaySim,
    PlainPolicy,
    replay_error,
    run_episode,
)
from minimanc.highway.episodes import PolicyFn as PolicyFn
from minimanc.highway.evaluate import (
    ClosedLoopResult,
    drive_episodes,
    expert_result,
    plain_policy,
    render_episode,
)
from minimanc.highway.mapping import RouteTracker, explicit_map, map_recipe, road_map
from minimanc.highway.observation import BEVObservation
from minimanc.highway.render import render_frame, save_gif, save_png

__all__ = [
    "SCENARIOS",
    "ENV_IDS",
    "POLICY_FREQUENCY",
    "SIMULATION_FREQUENCY",
    "DEFAULT_STEPS",
    "MAX_ADO",
    "make_env",
    "to_world",
    "ego_pose",
    "ado_boxes",
    "road_map",
    "map_recipe",
    "explicit_map",
    "RouteTracker",
    "BEVObservation",
    "controls_to_action",
    "ActionAdapter",
    "EXPERT_SPEEDS",
    "EVAL_SEED",
    "ExpertVehicle",
    "install_expert",
    "Episode",
    "run_episode",
    "replay_error",
    "HighwaySim",
    "FunctionPolicy",
    "PlainPolicy",
    "expert_episodes",
    "to_dataset",
    "collect_demonstrations",
    "ClosedLoopResult",
    "drive_episodes",
    "expert_result",
    "plain_policy",
    "render_frame",
    "save_png",
    "save_gif",
    "render_episode",
]
