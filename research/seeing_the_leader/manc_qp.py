"""MANC whose gains read the automaton's state and the predicates, ``FC(q ⊕ p)``: the form
through which the privileged runs drove (issue 27), registered for the image models here
as :mod:`minimanc.models.zoo` shows (``import manc_qp`` registers ``"manc_qp"``)."""

from __future__ import annotations

from typing import Any

from minimanc import models
from minimanc.models import zoo

NAME = "manc_qp"


def init(rng: Any, cfg: models.ModelConfig, n_num: int) -> dict:
    """eq. 7's predicates, vAGN (eqs. 8–9) and a gains FC over ``q ⊕ p``."""
    return {"predicates": zoo.predicate_layer(rng, cfg), "vagn": zoo.vagn_layer(rng, cfg),
            "gains": zoo.gains_layer(rng, cfg.n_states + cfg.n_predicates, cfg)}


def head(params: dict, enc: dict, state: Any, cfg: models.ModelConfig, eng: Any
         ) -> tuple[Any, dict, dict]:
    """One step: q from vAGN, the gains from ``FC(q ⊕ p)``, the DMP step (eqs. 10–11)."""
    q = zoo.vagn_step(params, enc, state, eng)
    x = eng.xp.concatenate([q, enc["predicates"]], axis=-1)
    controls, aux = zoo.dmp_step(zoo.gains_fc(params, x, eng), enc, cfg, eng)
    return controls, {"q": q}, {"q": q, **aux}


if NAME not in models.names():
    models.register_model(models.ModelSpec(
        NAME, "MANC FC(q ⊕ p)", "vagn", models.registry.observes_structured(), init,
        zoo.dmp_encode, head, window="dmp_seq_len", dmp=True))
