"""Chapter 11 — DAgger's mixing schedule and its label budget: :func:`beta_schedule`,
:func:`mix`, :class:`Budget` and :func:`plan_budget` (see :mod:`minimanc.dagger`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from minimanc.checks import check_int

__all__ = ["Budget", "beta_schedule", "check_beta", "mix", "plan_budget"]


# --------------------------------------------------------------------------- schedule, mixture


def check_beta(beta: Any, name: str = "beta") -> float:
    """``beta`` as a float if it is a finite number in [0, 1], else ``ValueError`` naming it."""
    ok = (not isinstance(beta, bool) and isinstance(beta, int | float | np.integer | np.floating)
          and math.isfinite(float(beta)) and 0.0 <= float(beta) <= 1.0)
    if not ok:
        raise ValueError(f"{name} must be a number in [0, 1], got {name}={beta!r}")
    return float(beta)


def beta_schedule(p: float, rounds: int) -> list[float]:
    """The mixing weights ``β_i = p^i`` of rounds ``i = 0 … rounds``: ``β_0 = 1`` (the
    demonstrations: behaviour cloning), then geometrically less of the expert.

    ``p = 0`` drives with the policy alone from round 1 (``0^0 = 1``); ``p = 1`` never
    lets the policy drive (behaviour cloning on more demonstrations).
    """
    p = check_beta(p, "p")
    rounds = check_int("rounds", rounds, 1)
    return [1.0] + [p ** i for i in range(1, rounds + 1)]


def mix(expert: Any, policy: Any, beta: float, u: Any) -> np.ndarray:
    """The controls of the β-mixture: row ``b`` is ``expert[b]`` where ``u[b] < beta``,
    else ``policy[b]``; ``expert`` and ``policy`` ``(B, 2)``, ``u (B,)`` uniform draws in
    [0, 1). ``beta = 1`` is always the expert, ``beta = 0`` always the policy."""
    beta = check_beta(beta)
    e = np.asarray(expert, dtype=np.float64)
    p = np.asarray(policy, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    if e.shape != p.shape or e.ndim != 2 or u.shape != e.shape[:1]:
        raise ValueError(f"expert and policy must have one shape (B, 2) and u (B,); got "
                         f"{e.shape}, {p.shape} and {u.shape}")
    return np.where((u < beta)[:, None], e, p)


# --------------------------------------------------------------------------- budget


@dataclass(frozen=True)
class Budget:
    """The expert-labelled samples a study may use, and how DAgger spends them.

    ``total`` samples (labelled states) allowed; ``steps`` the states of one scene
    (each driven or demonstrated scene is ``steps`` labelled samples);
    ``initial`` demonstration scenes of round 0; ``per_round`` the scenes driven in
    rounds ``1 … rounds``. :attr:`scenes` is what behaviour cloning trains on with the
    same budget, :attr:`used` the samples both use (``≤ total``).
    """

    total: int
    steps: int
    initial: int
    per_round: tuple[int, ...]

    @property
    def rounds(self) -> int:
        return len(self.per_round)

    @property
    def scenes(self) -> int:
        return self.initial + sum(self.per_round)

    @property
    def used(self) -> int:
        return self.scenes * self.steps

    def round_scenes(self, i: int) -> tuple[int, int]:
        """``(start, stop)``: the positions in the pool's scene order that round ``i`` uses."""
        i = check_int("i", i, 0, self.rounds)
        start = 0 if i == 0 else self.initial + sum(self.per_round[:i - 1])
        n = self.initial if i == 0 else self.per_round[i - 1]
        return start, start + n

    @classmethod
    def fixed(cls, steps: int, initial: int, per_round: int, rounds: int) -> Budget:
        """``initial`` demonstration scenes, then ``per_round`` scenes in each of ``rounds``
        rounds (a plan that a longer run with more rounds extends, so it resumes)."""
        steps = check_int("steps", steps, 1)
        initial = check_int("initial", initial, 1)
        per_round = check_int("per_round", per_round, 1)
        rounds = check_int("rounds", rounds, 1)
        return cls((initial + per_round * rounds) * steps, steps, initial, (per_round,) * rounds)

    def labelled(self, i: int) -> int:
        """Samples labelled in rounds ``0 … i`` (what ``π_i`` was trained from)."""
        return self.round_scenes(i)[1] * self.steps


def plan_budget(total: int, steps: int, rounds: int, initial: int | None = None) -> Budget:
    """Spend ``total`` labelled samples on scenes of ``steps`` states over ``rounds`` rounds.

    ``⌊total / steps⌋`` scenes in all; round 0 gets ``initial`` demonstration scenes
    (default: an equal share, plus the remainder) and the ``rounds`` DAgger rounds
    share the rest equally (the first rounds get one more when it does not divide).
    A budget that cannot give every round a scene is a ``ValueError``.
    """
    total = check_int("total", total, 1)
    steps = check_int("steps", steps, 1)
    rounds = check_int("rounds", rounds, 1)
    n = total // steps
    if n < rounds + 1:
        raise ValueError(f"budget too small: total={total} labelled samples give {n} scenes of "
                         f"{steps} steps, but {rounds} rounds need at least {rounds + 1} scenes "
                         f"({(rounds + 1) * steps} samples)")
    if initial is None:
        share = n // (rounds + 1)
        initial = n - share * rounds
    initial = check_int("initial", initial, 1, n - rounds)
    rest = n - initial
    per = tuple(rest // rounds + (1 if i < rest % rounds else 0) for i in range(rounds))
    return Budget(total, steps, initial, per)
