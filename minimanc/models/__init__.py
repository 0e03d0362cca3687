"""Chapter 8 — MANC and the comparison controllers as pure functions ``(params, inputs)``.

Every controller shares **one CNN backbone** (:func:`backbone`) and differs in its
head; each is one :class:`ModelSpec` in the registry (:mod:`minimanc.models.registry`),
and the six of the paper (section V, "Comparison cases" and the self-ablation) are
listed in :mod:`minimanc.models.zoo`:

* ``cnn``, ``cnn_lstm``, ``rvs_g`` — direct heads on the flattened features and
  the numbers the model sees (:mod:`minimanc.inputs`), the last two through an LSTM;
  they output ``o · CONTROL_SCALE`` (10 m/s, 0.5 rad/s) so that the last layer
  works with numbers of order one;
* ``manc`` — predicates ``p = σ(Linear(GAP(f)))`` (eq. 7; or over ``flatten(f)``,
  :attr:`ModelConfig.predicate_readout`, :mod:`minimanc.models.readout`), the automaton
  ``q = vAGN(p, q')`` (eqs. 8–9), gains ``FC(q)`` and one DMP step
  (eqs. 10–11, :func:`dmp_head`) → ``[speed, yaw rate]``;
* ``vagn_only`` — eq. 7 and vAGN, then a direct head on ``q`` and the numbers;
* ``dmp_only`` — eq. 7, gains ``FC(p)`` and the DMP head.

Two choices the paper leaves open, made here for trainability:

* **Predicates in (0, 1).** Eq. 7 is ``p = Linear(GAP(f))``; we follow it with a
  sigmoid (:attr:`ModelConfig.predicate_activation`; ``"linear"`` gives eq. 7
  literally), reading ``p_i`` as "how much predicate ``i`` holds". Unbounded
  predicates let the column softmax of eq. 9 saturate, so that q no longer
  depends on the image; bounded ones leave the scale of ``W^p`` to the vAGN
  weights. The CAMs of chapter 6 are those of the logits.
* **Scales at initialisation.** vAGN weights ``N(0, vagn_scale²)`` so that q
  moves visibly from image to image, and the gains FC starts ``gains_scale``
  times larger than Glorot, so that a change of q (on the simplex) moves the
  gains. Its bias starts at :data:`DEFAULT_GAINS`.

During training ``q'`` is uniform or random per window (Algorithm 1); in closed
loop the state returned by :func:`step` is fed back, so ``q`` carries over.

Every function takes an engine ``eng`` (``minimanc.engine("numpy"|"jax")``) and
uses only ``eng.xp`` / ``eng.nn`` / ``eng.scan``: the same code runs on both, and
gradients agree to 1e-6 in float64 (``tests/test_models.py``).

Modules: :mod:`~minimanc.models.config` (:class:`ModelConfig`),
:mod:`~minimanc.models.registry` (:class:`ModelSpec`, :func:`register_model`, :func:`get` (a spec by
name), and the registered
names: :func:`names`, :func:`vagn_models`, :func:`lstm_models`, :func:`dmp_models`, read
from the registry on every call),
:mod:`~minimanc.models.backbone`, :mod:`~minimanc.models.dmp_head` (with
:mod:`~minimanc.models.head_vjp`, its one-node VJP on the NumPy engine),
:mod:`~minimanc.models.zoo` (the six specs), :mod:`~minimanc.models.forward`
(:func:`init`, :func:`initial_state`, :func:`step`, :func:`sequence`) and
:mod:`~minimanc.models.explain` (:func:`saliency`; the open-loop trace of a logged scene is
:func:`minimanc.rollout.replay`).
"""

from __future__ import annotations

from minimanc.models import registry
from minimanc.models.backbone import backbone
from minimanc.models.config import (
    CONTROL_SCALE,
    DEFAULT_GAINS,
    DEFAULT_INPUT_SHAPE,
    GAINS_INPUTS,
    ModelConfig,
    gain_logits,
)
from minimanc.models.dmp_head import dmp_head, lane_point, lane_points
from minimanc.models.explain import saliency
from minimanc.models.forward import (
    check_input_shape,
    init,
    initial_state,
    param_count,
    param_counts,
    sequence,
    step,
)
from minimanc.models.registry import (
    ModelSpec,
    check_name,
    dmp_models,
    get,
    lstm_models,
    names,
    register_model,
    registered,
    vagn_models,
)
from minimanc.models.zoo import BUILTIN

__all__ = [
    "BUILTIN",
    "CONTROL_SCALE",
    "DEFAULT_GAINS",
    "DEFAULT_INPUT_SHAPE",
    "GAINS_INPUTS",
    "ModelConfig",
    "ModelSpec",
    "backbone",
    "check_input_shape",
    "check_name",
    "dmp_head",
    "dmp_models",
    "gain_logits",
    "get",
    "init",
    "initial_state",
    "lane_point",
    "lane_points",
    "lstm_models",
    "names",
    "param_count",
    "param_counts",
    "register_model",
    "saliency",
    "registered",
    "sequence",
    "spec",
    "step",
    "vagn_models",
]

spec = registry.get
"""``spec(name)``: the :class:`ModelSpec` of a registered model."""
