"""Chapter 12 — the expert and the privileged learner as closed-loop policies.

:class:`ExpertPolicy` (the world's human asked in every reached state: the upper bound of
Table I's learned rows, :func:`minimanc.diagnose.bounds.expert_rollout`) and
:class:`PrivilegedPolicy` (a :class:`~minimanc.diagnose.privileged.Privileged` learner on
the expert's perception, :func:`~minimanc.diagnose.privileged.features`) read the simulator
they drive in through ``bind(sim)`` (:func:`minimanc.rollout.drive`), so they run in the same
closed loop as every model (:class:`SituationPolicy` is what they share). A state the
expert cannot be asked in (off the drivable area, far from its route) is driven with the last
applied controls and counted as ``refused``. :class:`PrivilegedPolicy` can record every state
it visits with the expert's label there: one DAgger round (chapter 11) of the learner.
:func:`evaluate_policy` drives a policy on a dataset and scores it as Table I does.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from minimanc import metrics, rollout
from minimanc.dagger.expert import Situation
from minimanc.dagger.teachers import WorldTeacher
from minimanc.diagnose.privileged import (
    FEATURES,
    V_MAX,
    Privileged,
    blur,
    features,
    predict,
)
from minimanc.metrics.trajectory import along_cross_track
from minimanc.world.geometry import DT

__all__ = ["ExpertPolicy", "PrivilegedPolicy", "SituationPolicy", "evaluate_policy"]


class SituationPolicy:
    """What the policies that ask the world's expert in the simulator's state share: the
    situation of every row (``None`` where the expert cannot be asked), the ego's last
    acceleration, and the refused states, driven with the last applied controls."""

    model = None
    setting = "paper"
    keys: tuple[str, ...] = ("motion",)

    def __init__(self, teacher: WorldTeacher) -> None:
        self.teacher = teacher
        self.sim: Any = None
        self.prev: np.ndarray | None = None
        self.speeds: np.ndarray | None = None
        self.a_prev: np.ndarray = np.zeros(0)
        self.refused = 0

    def bind(self, sim: Any) -> None:
        """Drive in ``sim`` (called by :func:`minimanc.rollout.drive` before each batch)."""
        self.sim, self.prev, self.speeds = sim, None, None

    def initial_state(self, scenes: np.ndarray) -> Any:
        """No recurrent state."""
        return None

    def situations(self, t: int) -> list[Situation | None]:
        """The expert's situation in each row's state at step ``t``; updates ``a_prev``."""
        poses, speeds, traffics = self.teacher.states(self.sim, self.prev)
        v = np.maximum(np.asarray(speeds, dtype=np.float64), 0.0)
        self.a_prev = np.zeros_like(v) if self.speeds is None else (v - self.speeds) / DT
        self.speeds = v
        out: list[Situation | None] = []
        for b, s in enumerate(np.asarray(self.sim.scenes)):
            try:
                out.append(self.teacher.expert.situation(int(s), int(t), poses[b],
                                                         max(speeds[b], 0.0), traffics[b]))
            except ValueError:  # the expert cannot be asked here
                out.append(None)
        return out

    def finish(self, u: np.ndarray, sits: list[Situation | None]) -> np.ndarray:
        """``u`` with the last applied controls where the expert could not be asked (each
        such row counted in ``refused``)."""
        bad = np.array([s is None for s in sits])
        if bad.any():
            self.refused += int(bad.sum())
            u[bad] = self.prev[bad] if self.prev is not None else 0.0
        self.prev = u
        return u


class ExpertPolicy(SituationPolicy):
    """The world's human asked in every state the closed loop reaches (the upper bound of
    Table I's learned rows)."""

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        sits = self.situations(t)
        u = np.zeros((len(sits), 2))
        for b, sit in enumerate(sits):
            if sit is not None:
                u[b] = self.teacher.expert.controls(sit)
        return self.finish(u, sits), state, {}


class PrivilegedPolicy(SituationPolicy):
    """A :class:`Privileged` learner driving on the expert's perception (:func:`blur`-red by
    ``noise`` with a stream seeded by ``seed``: it then also forms its speed command from the
    speed it perceives); with ``record=True`` it keeps every visited state's features and
    the expert's label there (:meth:`visited`, as :func:`demonstrations` returns them)."""

    def __init__(self, model: Privileged, teacher: WorldTeacher, record: bool = False,
                 noise: Mapping[str, float] | None = None, seed: int = 0) -> None:
        super().__init__(teacher)
        self.net, self.record = model, record
        self.noise = dict(noise or {})
        self.rng = np.random.default_rng(seed)
        self.X: list[np.ndarray] = []
        self.Y: list[list[float]] = []

    def __call__(self, obs: dict, state: Any, t: int, scenes: np.ndarray
                 ) -> tuple[np.ndarray, Any, dict]:
        sits = self.situations(t)
        F = np.array([features(s, a) if s is not None else np.zeros(len(FEATURES))
                      for s, a in zip(sits, self.a_prev)])
        if self.noise:
            F = blur(F, self.noise, self.rng)
        u, state = self.act(F, sits, obs, state)
        return u, state, {}

    def accelerations(self, F: np.ndarray, obs: dict | None, state: Any
                      ) -> tuple[np.ndarray, Any]:
        """The learner's ``[acceleration, yaw rate]`` ``(B, 2)`` on features ``F`` and its
        next state (none: the MLP reads one state)."""
        return predict(self.net, F), state

    def act(self, F: np.ndarray, sits: list[Situation | None], obs: dict | None = None,
            state: Any = None) -> tuple[np.ndarray, Any]:
        """The controls ``[clip(v + a Δt, 0, V_MAX), ω]`` of the learner on features ``F``
        (``v`` their speed) in the states ``sits``, and its next state; with ``record`` it
        keeps ``F`` and the expert's label in each state the expert can be asked in."""
        a, state = self.accelerations(F, obs, state)
        v = F[:, FEATURES.index("v")]
        u = np.stack([np.clip(v + a[:, 0] * DT, 0.0, V_MAX), a[:, 1]], axis=1)
        if self.record:
            for b, sit in enumerate(sits):
                if sit is not None:
                    lab = self.teacher.expert.controls(sit)
                    self.X.append(F[b])
                    self.Y.append([(lab[0] - v[b]) / DT, lab[1]])
        return self.finish(u, sits), state

    def visited(self) -> tuple[np.ndarray, np.ndarray]:
        """The recorded features ``(N, len(FEATURES))`` and labels ``(N, 2)``."""
        return np.asarray(self.X).reshape(-1, len(FEATURES)), np.asarray(self.Y).reshape(-1, 2)


def evaluate_policy(policy: SituationPolicy, ds: Any, agents: str = "replay",
                    progress: bool = False) -> dict[str, float]:
    """A policy's closed-loop metrics on every scene of a dataset.

    Parameters
    ----------
    policy : SituationPolicy
        Its teacher built on ``ds`` under ``agents``; its ``refused`` count is reset.
    ds : minimanc.world.Dataset
    agents : str, optional (default: "replay")
        The ados' protocol (:data:`minimanc.rollout.AGENTS`).
    progress : bool, optional (default: False)
        A progress bar.

    Returns
    -------
    dict of str to float
        :func:`minimanc.metrics.evaluate`'s metrics, the mean along- and cross-track
        errors (:func:`minimanc.metrics.trajectory.along_cross_track`) and the number of
        ``refused`` states.
    """
    policy.refused = 0
    traj = rollout.simulate(policy, ds, agents=agents, progress=progress,
                            desc=f"{type(policy).__name__} ({agents})")
    out = metrics.evaluate(traj, ds)
    along, cross = along_cross_track(traj.ego, np.asarray(ds.ego, dtype=np.float64))
    out["along_track"] = float(np.abs(along).mean())
    out["cross_track"] = float(np.abs(cross).mean())
    out["refused"] = float(policy.refused)
    return out
