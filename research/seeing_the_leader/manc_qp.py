"""MANC whose gains read more than the automaton's state, registered for the image models here
as :mod:`minimanc.models.zoo` shows (``import manc_qp`` registers the three):

* ``"manc_qp"``: ``FC(q ⊕ p)``, the form through which the privileged runs drove (issue 27):
  the library's MANC with ``ModelConfig(gains_input="q_p")``, registered under this name
  for the runs cached under it (``hero.py`` loads them as the library's MANC);
* ``"manc_qm"``: ``FC(q ⊕ m)``, eq. 11 with the odometer beside q (``m`` = the current
  ``motion`` / :data:`minimanc.inputs.MOTION_SCALE`, the own speed and yaw rate the DMP
  already starts from);
* ``"manc_qpm"``: ``FC(q ⊕ p ⊕ m)``, both (the privileged runs' predicates read the own
  speed among the expert's numbers)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from minimanc import inputs, models
from minimanc.models import zoo

READS = {"manc_qm": ("m",), "manc_qpm": ("p", "m")}
"""What each model's gains read beside q (``manc_qp`` is the library's MANC, :func:`make_qp`)."""


def width(name: str, cfg: models.ModelConfig) -> int:
    """The width of the gains FC's input of model ``name``."""
    return cfg.n_states + sum({"p": cfg.n_predicates, "m": 2}[r] for r in READS[name])


def gains_input(name: str, q: Any, enc: dict, eng: Any) -> Any:
    """``q ⊕ …`` as model ``name``'s gains read it."""
    parts = [q]
    for r in READS[name]:
        parts.append(enc["predicates"] if r == "p" else
                     enc["motion"] / eng.xp.asarray(np.asarray(inputs.MOTION_SCALE, np.float32)))
    return eng.xp.concatenate(parts, axis=-1)


def make(name: str) -> models.ModelSpec:
    """The spec of model ``name`` (one of :data:`READS`): eq. 7's predicates, vAGN
    (eqs. 8–9), a gains FC over its input and the DMP step (eqs. 10–11)."""
    def init(rng: Any, cfg: models.ModelConfig, n_num: int) -> dict:
        return {"predicates": zoo.predicate_layer(rng, cfg), "vagn": zoo.vagn_layer(rng, cfg),
                "gains": zoo.gains_layer(rng, width(name, cfg), cfg)}

    def head(params: dict, enc: dict, state: Any, cfg: models.ModelConfig, eng: Any
             ) -> tuple[Any, dict, dict]:
        q = zoo.vagn_step(params, enc, state, eng)
        x = gains_input(name, q, enc, eng)
        controls, aux = zoo.dmp_step(zoo.gains_fc(params, x, eng), enc, cfg, eng)
        return controls, {"q": q}, {"q": q, **aux}

    label = "MANC FC(q ⊕ " + " ⊕ ".join(READS[name]) + ")"
    return models.ModelSpec(name, label, "vagn", models.registry.observes_structured(), init,
                            zoo.dmp_encode, head, window="dmp_seq_len", dmp=True)


def make_qp() -> models.ModelSpec:
    """``manc_qp``: the library's MANC (:func:`minimanc.models.zoo.manc_init`, ``manc_head``)
    with its gains over q ⊕ p whatever the configuration says."""
    def init(rng: Any, cfg: models.ModelConfig, n_num: int) -> dict:
        return zoo.manc_init(rng, replace(cfg, gains_input="q_p"), n_num)

    def head(params: dict, enc: dict, state: Any, cfg: models.ModelConfig, eng: Any
             ) -> tuple[Any, dict, dict]:
        return zoo.manc_head(params, enc, state, replace(cfg, gains_input="q_p"), eng)

    return models.ModelSpec("manc_qp", "MANC FC(q ⊕ p)", "vagn",
                            models.registry.observes_structured(), init, zoo.dmp_encode, head,
                            window="dmp_seq_len", dmp=True)


for _spec in (make_qp(), *(make(n) for n in READS)):
    if _spec.name not in models.names():
        models.register_model(_spec)
