"""DAgger for the privileged learner (its plain head or MANC's DMP head, :mod:`heads`):
round 0 trains on the demonstrations; each further round drives training scenes with the
current learner, labels every state it reached with the world's human and retrains on the
aggregate from the previous weights (β_0 = 1, then β_i = 0: after the demonstrations, the
learner drives; chapter 11's DAgger with the expert's perception as the learner's input).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from heads import fit_any, head_inputs, policy_of

from minimanc import rollout
from minimanc.checks import check_int
from minimanc.dagger import WorldTeacher
from minimanc.diagnose import policies
from minimanc.diagnose import privileged as P


@dataclass
class Round:
    """One DAgger round of a learner: labels aggregated so far and its closed-loop metrics
    on the validation scenes (:func:`minimanc.diagnose.evaluate_policy`)."""

    labels: int
    metrics: dict[str, float]


def dagger_rounds(train: Any, val: Any, rounds: int, per_round: int, agents: str = "reactive",
                  seed: int = 0, drop: Sequence[str] = (), steps: int = 3000,
                  progress: bool = False, head: str = "acceleration") -> list[Round]:
    """DAgger for the privileged learner with ``head`` (``"acceleration"`` or ``"dmp"``: a
    label per state): round 0 trains on the demonstrations of ``train``; each further round
    drives ``per_round`` training scenes (in a seeded order, cycling) with the current
    learner under ``agents``, labels every state it reached with the expert, aggregates and
    retrains from the previous weights. Every round is evaluated closed loop on ``val``
    under ``agents``."""
    rounds = check_int("rounds", rounds, 0)
    per_round = check_int("per_round", per_round, 1)
    if head not in ("acceleration", "dmp"):
        raise ValueError(f"DAgger of the privileged learner takes head 'acceleration' or "
                         f"'dmp' (a label per state, not per scene), got head={head!r}")
    teacher = WorldTeacher(train, agents=agents)
    vteacher = WorldTeacher(val, agents=agents)
    X, Y = P.demonstrations(train, expert=teacher.expert)
    lane, motion = head_inputs(train) if head == "dmp" else (None, None)
    model = fit_any(head, X, Y, lane, motion, drop=drop, steps=steps, seed=seed)
    out = [Round(len(X), policies.evaluate_policy(policy_of(model, vteacher), val, agents=agents))]
    order = np.random.default_rng(seed).permutation(len(np.asarray(train.ego)))
    for r in range(rounds):
        pick = order[(np.arange(per_round) + r * per_round) % len(order)]
        policy = policy_of(model, teacher, record=True)
        rollout.simulate(policy, train, scenes=np.sort(pick), agents=agents, progress=progress,
                         desc=f"DAgger round {r + 1}")
        Xn, Yn = policy.visited()
        X, Y = np.concatenate([X, Xn]), np.concatenate([Y, Yn])
        if head == "dmp":
            ln, mn = policy.visited_head_inputs()
            lane, motion = np.concatenate([lane, ln]), np.concatenate([motion, mn])
        model = fit_any(head, X, Y, lane, motion, steps=steps, seed=seed + r + 1, init=model)
        out.append(Round(len(X), policies.evaluate_policy(policy_of(model, vteacher), val,
                                                   agents=agents)))
    return out
