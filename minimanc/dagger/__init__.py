"""Chapter 11 — DAgger: behaviour cloning's compounding error, and asking the expert.

Behaviour cloning (chapter 9, Algorithm 1 of the paper) trains on the states the
*expert* visited. In closed loop the policy's small errors take it to states no
demonstration showed, where its errors are larger: the error compounds over the
horizon (Ross, Gordon & Bagnell 2011, "A reduction of imitation learning and
structured prediction to no-regret online learning"). DAgger (*dataset
aggregation*) asks the expert what to do in the states the policy visits:

* **round 0** trains ``π_0`` on the expert's demonstrations (behaviour cloning,
  β_0 = 1);
* **round i ≥ 1** drives scenes with the mixture ``π = β_i π* + (1 − β_i) π_{i−1}``
  (at every step and in every scene the expert's control with probability ``β_i``,
  else the policy's; :func:`mix`), with the schedule ``β_i = p^i``
  (:func:`beta_schedule`); **labels every visited state** with the expert's
  controls; **aggregates** those labelled states with all earlier data
  (:func:`concat`) and trains ``π_i`` on the aggregate.

The expert is a :class:`Teacher`: :class:`WorldTeacher` asks the world's human
driver (:class:`minimanc.dagger.expert.HumanExpert`, the same
:meth:`~minimanc.world.driver.HumanDriver.act` that generated the data) with the
ados of the simulation step, replayed (``agents="replay"``) or reactive
(``agents="reactive"``, :class:`minimanc.rollout.reactive.ReactiveSim`);
:class:`HighwayTeacher` asks highway-env's IDM/MOBIL expert
(:class:`minimanc.highway.ExpertVehicle`) by installing it on a copy of the env at
the policy's state and stepping the copy once. Both label in the format of their
demonstrations (``[speed, yaw rate]`` applied from ``t`` to ``t + 1``).

**Budget.** The study compares BC and DAgger at equal numbers of expert-labelled
samples: every labelled state counts, the demonstrations of round 0 included
(:class:`Budget`, :func:`plan_budget`). Scenes are taken from the pool in one
seeded order; BC trains on the first ``Budget.scenes`` of them, DAgger's rounds use
the same scenes in turn (round 0 the first ``initial``, then ``per_round`` each), so
the two differ only in *which states* of those scenes are labelled. A driven scene
whose state the expert refuses to label (the world's driver refuses an ego off the
drivable area or far from its route) is not aggregated; its queries still count.

**Perturbed demonstrations** (ChauffeurNet's augmentation, DART's noise): the expert
drives with a slowly varying offset on the controls it applies (:class:`Perturbation`,
``collect(None, teacher, scenes, 1.0, perturb=...)``) and every state it reaches is
labelled with its clean control: off-path states and the way back, without a trained
policy.

**Stored states.** An aggregated scene stores the visited poses and ados, the BEV
re-rasterised there, the goal and lane targets from there and the expert's labels
as ``controls``; as for every dataset, a model's ``motion`` input at ``t`` is then
``controls[t − 1]`` (the expert's label, not the control the mixture applied).

**Checkpoints.** With ``out``, round ``i`` lives in ``out/round_<i:03d>/``: the
configuration it belongs to (``fingerprint.json``, written first), the collected
scenes (``data.npz``; with perception targets what the expert perceived in them,
``perception.npz``, saved before it), the training checkpoint (``checkpoint.npz``,
resumable inside the round) and, written last, ``round.json``; every file is written atomically
(temporary file, then rename). A rerun loads every complete round and resumes an
unfinished one from its data and checkpoint; a folder of another configuration is a
``ValueError``, never mixed in.

**The auxiliary perception loss on-policy.** A :class:`WorldTeacher` given ``perceive``
(:func:`minimanc.diagnose.state_targets`) records what the human perceives in every state
it labels, and :func:`dagger` with ``perception`` (the targets of the pool's demonstrations,
:func:`minimanc.diagnose.perception_targets`) trains every round with the auxiliary loss of
:mod:`minimanc.train.perception` on the aggregate: demonstrations and collected states alike.
"""

from minimanc.dagger.aggregate import Collected, MixturePolicy, collect, concat
from minimanc.dagger.loop import (
    FINGERPRINT_FILE,
    PERCEPTION_FILE,
    ROUND_FILE,
    DaggerResult,
    RoundResult,
    behaviour_cloning,
    dagger,
    default_config,
    round_dir,
    scene_order,
)
from minimanc.dagger.perturb import Perturbation
from minimanc.dagger.schedule import Budget, beta_schedule, check_beta, mix, plan_budget
from minimanc.dagger.teachers import AGENTS, SIMS, HighwayTeacher, Teacher, WorldTeacher

__all__ = [
    "AGENTS",
    "FINGERPRINT_FILE",
    "PERCEPTION_FILE",
    "ROUND_FILE",
    "SIMS",
    "Budget",
    "Collected",
    "DaggerResult",
    "HighwayTeacher",
    "MixturePolicy",
    "Perturbation",
    "RoundResult",
    "Teacher",
    "WorldTeacher",
    "behaviour_cloning",
    "beta_schedule",
    "check_beta",
    "collect",
    "concat",
    "dagger",
    "default_config",
    "mix",
    "plan_budget",
    "round_dir",
    "scene_order",
]
