"""Chapter 9 — the closed loop: the policy drives the ego, the ados replay the log
(the paper's protocol) or react to it.

The paper's evaluation (section V-A): "we control the ego vehicle with our
learned planner, the ado vehicles move according to the trajectories
recorded in the dataset with synchronized time".  For every validation scene,
all scenes batched:

1. the ego starts at the logged pose ``ego[:, 0]``, moving at the logged
   initial speed (:func:`minimanc.inputs.initial_motion`);
2. at each step ``t = 0 … T−2`` the observation is rebuilt from the ego's
   *own* pose (:func:`minimanc.inputs.from_state`): the BEV is re-rasterised
   (:func:`minimanc.world.rasterize_batch`) with the ados at their logged
   boxes of time ``t``, the goal (the human's final pose) is re-expressed in
   the current ego frame, the lane targets are recomputed from the map at the
   ego's projection on its route, and ``motion`` is the policy's own previous
   control;
3. the policy returns ``[speed, yaw rate]`` and its new state (the vAGN
   distribution ``q`` of eq. 9, or an LSTM carry), which is carried over;
4. the ego moves by one explicit-Euler unicycle step of ``DT = 0.5`` s
   (:func:`minimanc.world.unicycle_step`).

The result is a :class:`Rollout`: poses ``(S, T, 3)`` on the log's clock,
the applied controls ``(S, T−1, 2)`` and, per step, the model's explanation
outputs (``q``, DMP ``alpha`` and ``beta``, ``predicates``) for the paper's
explainability figures.  :func:`human` is the replay of the logged ego — the
"Human" row of Table I — and :func:`fixed_gains` drives with MANC's DMP head
at constant gains and no network at all (eqs. 10–11 with ``FC(q)`` replaced
by a constant): the structured prior alone, the reference that tells how much
the learned part adds.

**Two protocols for the ados** (``agents=`` on :func:`simulate`, :func:`closed_loop`,
:func:`fixed_gains`, :func:`human`; :data:`AGENTS`): ``"replay"`` is the paper's, above;
``"reactive"`` drives them by the world's own IDM / yielding / gap-acceptance rules,
reacting to the policy's ego from the logged start (:mod:`minimanc.rollout.reactive`, as
nuPlan's reactive agents); :mod:`minimanc.rollout.protocols` picks the simulator. A
reactive :class:`Rollout` holds the ados it simulated (``ado``, ``ado_valid``), and
:func:`minimanc.metrics.evaluate` scores it on them.

Any object with ``model``, ``setting``, ``initial_state(scenes)`` and
``__call__(obs, state, t, scenes) -> (controls, state, aux)`` can drive
(:class:`Policy`); :class:`ModelPolicy` wraps :func:`minimanc.models.step`.
The loop itself is :func:`drive`, written once over a :class:`Simulator`
(reset, observe, step): :class:`LogReplay` is the log above, and
:class:`minimanc.highway.HighwaySim` is highway-env (chapter 10). The
open-loop trace of chapter 8 (:func:`replay`) is the same loop in a
:class:`LogReplay` whose ego follows the log (``follow_log=True``) while the
model is queried.

The smallest loop, a bare head function alone on a map's route with no dataset, is
:func:`drive_on_route` (the DMP head a student writes in chapter 8 drives with it).

The recorded ``aux`` arrays keep the dtype the model computed them in (a
float32 model's ``q`` stays float32), so their precision is known downstream.
"""

from __future__ import annotations

from minimanc.rollout.driver import (
    AUX_KEYS,
    BadControls,
    Drive,
    Policy,
    SceneState,
    Simulator,
    check_controls,
    drive,
    observation,
)
from minimanc.rollout.log import AGENTS, BATCH_SIZE, LogReplay, Rollout, check_agents
from minimanc.rollout.policies import (
    FixedGainsPolicy,
    ModelPolicy,
    closed_loop,
    fixed_gains,
    open_loop,
    replay,
)
from minimanc.rollout.protocols import human, simulate
from minimanc.rollout.route import drive_on_route

__all__ = [
    "AGENTS",
    "AUX_KEYS",
    "BATCH_SIZE",
    "BadControls",
    "Drive",
    "FixedGainsPolicy",
    "LogReplay",
    "ModelPolicy",
    "Policy",
    "Rollout",
    "SceneState",
    "Simulator",
    "check_agents",
    "check_controls",
    "closed_loop",
    "drive",
    "drive_on_route",
    "fixed_gains",
    "human",
    "observation",
    "open_loop",
    "replay",
    "simulate",
]
