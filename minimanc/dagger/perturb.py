"""Chapter 11 — perturbed demonstrations: the expert drives with a slowly varying offset
added to the controls it applies, and every state it visits is labelled with its clean
control (:class:`Perturbation`; used by :func:`minimanc.dagger.collect`).

Behaviour cloning's demonstrations only show states on the expert's own path; the learner's
errors leave that path and it has never seen how to come back. ChauffeurNet (Bansal, Krizhevsky
& Ogale 2018) synthesises deviations from the logged trajectory, DART (Laskey et al. 2017)
injects noise into the controls the supervisor applies while it demonstrates; either way
the labels are the expert's answers in the deviated states, and no policy is trained
between collections (one round, unlike DAgger's).

The offset is an Ornstein–Uhlenbeck process per driven scene, one for the speed command
(m/s) and one for the yaw rate (rad/s), sampled every step ``DT``:

    x_{t+1} = a x_t + σ √(1 − a²) ε_t,   a = exp(−DT / τ),   ε_t ~ N(0, 1),

starting from 0 (so every scene starts in its logged state), with stationary standard
deviation ``σ`` and correlation time ``τ``: a sustained error (too fast for a second or
two, drifting to one side), the kind a learner's closed loop makes, rather than white noise
that the vehicle's own dynamics would average away. The applied speed command is clipped at
0 (a car does not reverse here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from minimanc.checks import check_finite
from minimanc.dmp.params import DT

__all__ = ["Perturbation"]


@dataclass(frozen=True)
class Perturbation:
    """Offsets added to the applied ``[speed, yaw rate]`` controls: stationary standard
    deviations ``speed`` (m/s) and ``yaw_rate`` (rad/s), correlation time ``tau`` (s)."""

    speed: float
    yaw_rate: float
    tau: float

    def __post_init__(self) -> None:
        for name in ("speed", "yaw_rate", "tau"):
            value = check_finite(name, getattr(self, name))
            if value.ndim != 0:
                raise ValueError(f"{name} must be one number, got {getattr(self, name)!r}")
            if value < 0 or (name == "tau" and value == 0):
                raise ValueError(f"{name} must be {'> 0' if name == 'tau' else '>= 0'}, "
                                 f"got {name}={getattr(self, name)!r}")

    @property
    def decay(self) -> float:
        """``a = exp(−DT / τ)``, the offset kept from one step to the next."""
        return math.exp(-DT / self.tau)

    def step(self, offset: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The next offsets ``(B, 2)`` from ``offset (B, 2)``: one Ornstein–Uhlenbeck step."""
        x = np.asarray(offset, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 2:
            raise ValueError(f"offset must have shape (B, 2), got {x.shape}")
        a = self.decay
        sigma = np.array([self.speed, self.yaw_rate])
        return a * x + sigma * math.sqrt(1.0 - a * a) * rng.standard_normal(x.shape)

    def apply(self, controls: np.ndarray, offset: np.ndarray) -> np.ndarray:
        """``controls + offset`` with the speed command clipped at 0."""
        out = np.asarray(controls, dtype=np.float64) + offset
        out[:, 0] = np.maximum(out[:, 0], 0.0)
        return out
