"""Chapter 12 — why the driver crashes: the bounds, the privileged learner, the probe and the
collision taxonomy.

Every behaviour-cloned controller of chapters 9–11 collides among ados that react to it,
where the human whose logs it copies never does. The chapter finds out why with four tools:

* :mod:`minimanc.diagnose.bounds` — what any learner is read against (Table I's "Expert"
  and "Style floor" rows): the world's human asked in every state the closed loop reaches
  (:func:`expert_rollout`), and every scene re-driven with the population's median style
  (:func:`floor_rollout`, :func:`median_style`);
* :mod:`minimanc.diagnose.privileged` — learning or information? An MLP given exactly what
  the expert perceives (:func:`features`, :func:`demonstrations`), trained by Algorithm 1
  (:func:`fit_privileged`); dropping input groups is the ablation that names the
  information that matters;
* :mod:`minimanc.diagnose.perception_targets` — what an image model's perception must read:
  the expert's numbers in every state with the mask of where each means something
  (:func:`perception_targets`, the targets of ``TrainConfig.perception_weight``);
* :mod:`minimanc.diagnose.policies` — the expert and that learner driving closed loop
  (:class:`ExpertPolicy`, :class:`PrivilegedPolicy`, :func:`evaluate_policy`);
* :mod:`minimanc.diagnose.probe` — does a model's representation hold that information?
  (:func:`linear_probe`);
* :mod:`minimanc.diagnose.collisions` — how does it crash? (:func:`collision_taxonomy`).

Its figures are in :mod:`minimanc.viz.investigation`. The investigation these tools served,
with the experiments that go beyond the chapter (MANC's own heads on the expert's perception,
a perception learned from the raster, the fixes measured one at a time), is kept outside the
package, in ``research/why_it_crashes/`` (its ``REPORT.md``).
"""

from minimanc.diagnose.bounds import (
    BOUND_ROWS,
    ExpertRollout,
    check_generated,
    expert_rollout,
    floor_rollout,
    median_style,
    privileged_learner,
    privileged_rollout,
)
from minimanc.diagnose.collisions import collision_taxonomy
from minimanc.diagnose.perception_targets import (
    LOGITS,
    TARGETS,
    in_view,
    leader_boxes,
    perception_targets,
    state_targets,
)
from minimanc.diagnose.policies import (
    ExpertPolicy,
    PrivilegedPolicy,
    SituationPolicy,
    evaluate_policy,
)
from minimanc.diagnose.privileged import (
    AHEAD,
    FAR,
    FEATURE_GROUPS,
    FEATURES,
    V_MAX,
    Privileged,
    blur,
    demonstrations,
    descend,
    features,
    fit_privileged,
    kept,
    mlp_outputs,
    perceived,
    predict,
    standardise,
)
from minimanc.diagnose.probe import linear_probe

__all__ = [
    "AHEAD",
    "BOUND_ROWS",
    "FAR",
    "FEATURES",
    "FEATURE_GROUPS",
    "LOGITS",
    "TARGETS",
    "V_MAX",
    "ExpertPolicy",
    "ExpertRollout",
    "Privileged",
    "PrivilegedPolicy",
    "SituationPolicy",
    "blur",
    "check_generated",
    "collision_taxonomy",
    "demonstrations",
    "descend",
    "evaluate_policy",
    "expert_rollout",
    "features",
    "fit_privileged",
    "floor_rollout",
    "in_view",
    "kept",
    "leader_boxes",
    "linear_probe",
    "median_style",
    "mlp_outputs",
    "perceived",
    "perception_targets",
    "predict",
    "privileged_learner",
    "privileged_rollout",
    "standardise",
    "state_targets",
]
