"""Chapter 9 — the closed-loop driver written once: :func:`drive` runs a :class:`Policy` in a
:class:`Simulator` (reset, observe, step), building each observation from the ego's own state
(:func:`observation`) and checking every control (:func:`check_controls`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from minimanc import inputs, models
from minimanc.checks import check_int

__all__ = ["AUX_KEYS", "BadControls", "Drive", "Policy", "SceneState", "Simulator",
           "check_controls", "drive", "observation"]

AUX_KEYS: tuple[str, ...] = ("q", "alpha", "beta", "predicates")
"""The per-step model outputs a rollout records (when the model returns them)."""


class BadControls(ValueError):
    """A policy returned controls of the wrong shape or not finite (NaN or infinite)."""


class Policy(Protocol):
    """What :func:`simulate` needs from a driver.

    ``model`` (a name of :func:`minimanc.models.names`, or ``None`` for
    every key but ``goal_bev``) and ``setting`` choose which observation keys
    are built (:func:`minimanc.inputs.visible`); a policy may instead name them
    in an optional ``keys`` attribute (a driver that reads no image then costs
    no rasterising).  ``scenes`` are the dataset indices of the batch rows.

    A policy that reads the simulator itself (the world's expert, a learner given the
    expert's own perception: :mod:`minimanc.diagnose.policies`) has an optional
    ``bind(sim)``, which :func:`drive` calls after ``sim.reset()``.
    """

    model: str | None
    setting: str

    def initial_state(self, scenes: np.ndarray) -> Any: ...

    def __call__(
        self, obs: dict, state: Any, t: int, scenes: np.ndarray
    ) -> tuple[np.ndarray, Any, dict]: ...


@dataclass
class SceneState:
    """What a :class:`Simulator` shows at one step, for a batch of ``B`` scenes.

    ``maps`` one :class:`minimanc.world.lanes.Map` per row, ``pose (B, 3)`` the
    ego's world pose ``[x, y, yaw]``, ``ado (B, A, 5)`` the ado boxes
    ``[x, y, yaw, length, width]`` at this step with ``ado_valid (B, A)`` bool,
    ``goal (B, 3)`` the goal world pose, and ``history`` the past boxes of every row when
    the raster draws them (a :class:`minimanc.world.history.History`, else ``None``).
    """

    maps: list
    pose: np.ndarray
    ado: np.ndarray
    ado_valid: np.ndarray
    goal: np.ndarray
    history: Any = None


class Simulator(Protocol):
    """A world that :func:`drive` runs a :class:`Policy` in, ``B`` scenes at a time.

    Attributes: ``scenes (B,)`` the integer ids of the rows (passed to the
    policy), ``raster`` the :class:`minimanc.world.RasterConfig` the BEV is
    drawn with, ``k_targets`` the number of lane-target points (``None``: the
    default :data:`minimanc.world.lanes.K_TARGETS`).

    * ``reset()`` puts every row at its start and returns the ego's motion
      there, ``(B, 2)`` float32 ``[speed, yaw rate]`` (the ``motion`` input at
      ``t = 0``);
    * ``observe()`` returns the current :class:`SceneState` (ego poses
      ``(B, 3)``, ados ``(B, A, 5)`` and ``(B, A)``, maps, goals ``(B, 3)``);
    * ``step(controls)`` applies ``controls (B, 2)`` float64
      ``[speed, yaw rate]`` for one decision (``DT`` = 0.5 s) and returns
      ``None`` — or, when the ego does not move by the policy's controls (a
      replay that follows the log), the ``(B, 2)`` motion it actually had,
      which becomes the next ``motion`` input; the simulator keeps whatever
      trajectory it records.

    Implemented by :class:`LogReplay` (the chapter-9 log: ados replay their
    recorded boxes) and :class:`minimanc.highway.HighwaySim` (highway-env,
    reactive traffic).
    """

    scenes: np.ndarray
    raster: Any
    k_targets: int | None

    def reset(self) -> np.ndarray: ...

    def observe(self) -> SceneState: ...

    def step(self, controls: np.ndarray) -> np.ndarray | None: ...


@dataclass
class Drive:
    """What :func:`drive` returns: ``controls (B, steps, 2)`` float64, the policy's controls,
    and, for the keys of :data:`AUX_KEYS` the policy returned at every step,
    ``aux[key] (B, steps, ...)`` in the dtype the policy returned."""

    controls: np.ndarray
    aux: dict[str, np.ndarray]


def observation(policy: Policy, scene: SceneState, motion: np.ndarray, raster: Any = None,
                k_targets: int | None = None) -> dict:
    """The observation a policy sees in a scene (:func:`minimanc.inputs.from_state`).

    Parameters
    ----------
    policy : Policy
        Its ``keys`` when it names them, else those its ``model`` and ``setting`` see.
    scene : SceneState
        What the simulator shows for ``B`` rows.
    motion : array, shape (B, 2)
        The ego's current ``[speed, yaw rate]`` (the policy's previous control).
    raster : RasterConfig, optional
        How the BEV is drawn.
    k_targets : int, optional
        Lane-target points (default :data:`minimanc.world.lanes.K_TARGETS`).

    Returns
    -------
    dict
        Observations ``(B, ...)`` of :mod:`minimanc.inputs`.
    """
    return inputs.from_state(
        scene.maps, scene.pose, scene.ado, scene.ado_valid, scene.goal, raster, policy.setting,
        motion=motion, model=None if policy.model is None else models.get(policy.model),
        k_targets=k_targets,
        keys=getattr(policy, "keys", None), history=scene.history,
    )


def check_controls(controls: Any, batch: int, t: int, policy: Any = None) -> np.ndarray:
    """A policy's controls, checked.

    Parameters
    ----------
    controls : array_like
        What the policy returned.
    batch : int
        Rows ``B`` expected.
    t : int
        The step (for the message).
    policy : Policy, optional
        Named in the message by its ``model``.

    Returns
    -------
    numpy.ndarray, shape (batch, 2)
        float64 ``[speed, yaw rate]``.

    Raises
    ------
    BadControls
        For another shape or a NaN / infinite entry.
    """
    u = np.asarray(controls, dtype=np.float64)
    if u.shape != (batch, 2) or not np.all(np.isfinite(u)):
        raise BadControls(
            f"policy {getattr(policy, 'model', None)!r} returned controls of shape {u.shape} "
            f"(finite: {bool(np.all(np.isfinite(u)))}) at step {t}; "
            f"expected finite ({batch}, 2)"
        )
    return u


def drive(policy: Policy, sim: Simulator, steps: int,
          on_step: Callable[[int], None] | None = None) -> Drive:
    """Run ``policy`` in closed loop in ``sim`` for ``steps`` decisions.

    ``sim.reset()`` (and ``policy.bind(sim)`` for a policy that has it), then at each
    step ``t``: observe the scene, build the policy's observation from the ego's own
    state (:func:`observation`, with ``motion`` the policy's previous control — or the
    motion ``sim.step`` returned, when it returns one — and at ``t = 0`` the motion
    ``reset`` returned), call the policy, check its controls (:func:`check_controls`),
    carry its state over and ``sim.step`` them.

    Parameters
    ----------
    policy : Policy
    sim : Simulator
        ``B`` scenes (``sim.scenes``).
    steps : int
        Decisions to make (>= 1).
    on_step : callable, optional
        ``on_step(t)`` after each step (e.g. a progress bar).

    Returns
    -------
    Drive
        ``controls`` ``(B, steps, 2)`` and the recorded ``aux`` ``(B, steps, ...)``.
    """
    steps = check_int("steps", steps, 1)
    scenes = np.asarray(sim.scenes)
    motion = np.asarray(sim.reset(), dtype=np.float32)
    if hasattr(policy, "bind"):
        policy.bind(sim)
    state = policy.initial_state(scenes)
    controls, aux_steps = [], {}
    for t in range(int(steps)):
        obs = observation(policy, sim.observe(), motion, sim.raster, sim.k_targets)
        u, state, aux = policy(obs, state, t, scenes)
        u = check_controls(u, len(scenes), t, policy)
        for key in AUX_KEYS:
            if key in aux and aux[key] is not None:
                aux_steps.setdefault(key, []).append(np.asarray(aux[key]))
        moved = sim.step(u)
        motion = np.asarray(u if moved is None else moved, dtype=np.float32)
        controls.append(u)
        if on_step is not None:
            on_step(t)
    return Drive(np.stack(controls, axis=1),
                 {k: np.stack(v, axis=1) for k, v in aux_steps.items() if len(v) == steps})
