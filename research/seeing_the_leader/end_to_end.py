"""Do the image models drive once they see the leader? The library's end-to-end models
trained by Algorithm 1 on the learner's raster with the masked auxiliary perception loss,
closed loop among reactive and replayed ados, against their bounds on the same scenes.

**Forms.** ``rgb`` is the paper's form (the course's RGB raster, 40 m × ±25 m at 0.78 m/px,
64 × 64, Algorithm 1 alone: λ = 0). ``channels`` is the learner's raster the perception study
chose (``perception.py``'s ``route60``: binary channels for the map, the ego's route ahead
and the vehicles at t, t−1, t−2; 60 m ahead, ±25 m, 0.78 m/px: 90 × 64 × 12) with
λ = ``--weight`` (``TrainConfig.perception_weight``, the targets of
:func:`minimanc.diagnose.perception_targets` for that view); ``channels0`` is the same raster
with λ = 0 (what the raster alone is worth); ``speed`` is ``channels0`` in the ``parity``
setting (:mod:`minimanc.inputs`: the model also reads its own speed and yaw rate and the
lane target as numbers, the odometer LBC, Roach and CILRS give their policies; MANC reads the
same in both settings, its DMP starting from the current motion); ``dagger``
is ``channels0`` trained on-policy: DAgger (:func:`minimanc.dagger.dagger`) with the world's
human among reactive ados as the teacher, :data:`ROUNDS` rounds after the demonstrations
(β from ½ halving), the same 600 scenes' worth of expert-labelled states as behaviour
cloning (``channels0``), the same schedule per round; ``dagger_rgb`` the same on the RGB
raster (against ``rgb``);
``speed_dagger`` is ``speed`` trained on-policy like ``dagger`` (whether on-policy labels
mend the copycat the own speed brings); ``speed_dagger_seq40`` is ``speed_dagger`` with the
LSTM models trained on windows of a whole 40-step scene (``TrainConfig.seq_len = 40``) instead
of 8 steps from a zero state, while the closed loop carries their state through the scene;
``speed_dagger_lr1e-3`` is ``speed_dagger`` at the learning rate the CNN trains with;
``dagger_flat`` is MANC's
``dagger`` with eq. 7 over the flattened features (``ModelConfig.predicate_readout =
"flatten"``: predicates that keep where a feature fires); the ``_warm`` forms continue each
DAgger round from the previous one (one epoch, ``_warm2`` two); ``speed_dagger_warm2_aux``
is ``speed_dagger_warm2`` with the auxiliary loss at λ = ``--weight`` on the demonstrations
and on every state DAgger collects (what the human perceives there, recorded by the teacher:
:func:`minimanc.diagnose.state_targets`), ``_deep`` the same with the perception study's
four convolutions of 32, 64, 64 and 64 channels (``perception.py``'s ``route60``) instead of
the course's three of 16, 32 and 32; ``_p64`` has 64 predicates
and ``_goal10`` the DMP's goal at a fixed 10 m ahead (``ModelConfig.position_lookahead = 10``,
``position_lookahead_time = 0``); ``dagger_flat_warm2_p64_goal10_aux_deep`` is MANC's form of
the library's learner (``dagger_flat_warm2_p64_goal10``) with the auxiliary loss on every
collected state and the four-layer backbone, as ``speed_dagger_warm2_aux_deep`` for the CNN.
Two retired forms (:data:`RETIRED`) stay in the tables: ``speed_drop``, ``speed`` with the
own speed and yaw rate replaced by zeros in 75 % of the training samples (PlanTF's guard
against the copycat), and ``change_dagger``, ``speed_dagger`` with the direct head's speed the
change of its own (``max(v + o₀ s₀, 0)``, what the privileged learner predicts).

**Protocol** (fixed before any closed-loop number was looked at). The seed-0 draw of the
paper preset (``leader_data.py``): train on scenes 0–599, drive the validation scenes
600–799 (never trained on; the scenes of ``drive.py``, whose expert and privileged learner
are the bounds here). The paper preset's schedule (6 epochs of batch 64) and, per model, the
learning rate the paper preset's tuning chose on the RGB raster (``results/paper-paper``:
:data:`LEARNING_RATES`; ``speed_dagger_lr1e-3`` sets its own); every other setting is the
library's default. One run per
(model, form, seed) and protocol, cached as JSON under ``--work`` (a finished run is not
repeated; the trained parameters are checkpointed by :func:`minimanc.train.fit`, so an
interrupted training resumes). The bound rows (expert, style floor, DMP at fixed gains) are
runs of their own on the same scenes (``--bounds``); the privileged learner's rows are
quoted from ``results/drive.md``.

Run: ``SEEING_DATA=/path python research/seeing_the_leader/end_to_end.py --models cnn manc
--forms channels rgb --seeds 0 --work runs/end_to_end``; ``--bounds`` adds the bound rows;
``--report`` writes ``results/end_to_end.md`` from the cached runs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import time
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import leader_data as L
import manc_qp  # noqa: F401  (registers "manc_qp", "manc_qm", "manc_qpm")
import numpy as np
import perception as PC

from minimanc import dagger, diagnose, inputs, metrics, models, rollout, train, world
from minimanc.studies import provenance

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
DRIVE = RESULTS / "drive.md"
"""The privileged learner's closed loop on the same scenes (``drive.py``)."""
TRAIN = L.TRAIN_LARGE
VALIDATE = L.VALIDATE
N_SCENES = VALIDATE.stop
MODELS = ("cnn", "cnn_lstm", "rvs_g", "manc", "manc_qp", "manc_qm", "manc_qpm", "dmp_only")
"""Table I's learned controllers, MANC whose gains read q ⊕ p, q ⊕ m (the odometer) or
q ⊕ p ⊕ m (:mod:`manc_qp`) and the
self-ablation without vAGN (``dmp_only``: the CNN's features straight to the gains)."""
LEARNING_RATES = {"cnn": 1e-3, "cnn_lstm": 3e-4, "rvs_g": 3e-4, "manc": 3e-4, "manc_qp": 3e-4,
                  "manc_qm": 3e-4, "manc_qpm": 3e-4, "dmp_only": 1e-3}
"""The learning rate the paper preset's tuning chose per model (setting ``paper``; MANC's for its
variants of :mod:`manc_qp`)."""
@dataclass(frozen=True)
class Form:
    """How a model is trained: its raster, λ, setting, on-policy or not, and the fields of
    :class:`~minimanc.models.ModelConfig` and :class:`~minimanc.train.TrainConfig` it sets
    beyond the library's defaults."""

    text: str
    raster: str = "channels"
    aux: bool = False
    setting: str = "paper"
    on_policy: bool = False
    model: tuple[tuple[str, Any], ...] = ()
    train: tuple[tuple[str, Any], ...] = ()
    only: tuple[str, ...] = ()
    """The models the form applies to (empty: every model)."""
    warm: int = 0
    """Epochs of each DAgger round after the first, continuing from the previous round's
    parameters (``dagger``'s ``round_cfg``); 0: every round trains from the start."""


PARITY_TEXT = "own speed and lane target as numbers"
MANCS = ("manc", "manc_qp", "manc_qm", "manc_qpm")
"""MANC and its variants of :mod:`manc_qp` (the forms of eq. 7 over flattened features)."""
FORMS: dict[str, Form] = {
    "channels": Form("channels, λ = {w:g}", aux=True),
    "channels0": Form("channels, λ = 0"),
    "speed": Form(f"channels, λ = 0, {PARITY_TEXT}", setting="parity"),
    "dagger": Form("channels, λ = 0, DAgger {rounds} rounds", on_policy=True),
    "speed_dagger": Form(f"channels, λ = 0, {PARITY_TEXT}, DAgger {{rounds}} rounds",
                         setting="parity", on_policy=True),
    "speed_dagger_seq40": Form(f"channels, λ = 0, {PARITY_TEXT}, DAgger {{rounds}} rounds, the "
                               "LSTM trained on whole 40-step scenes", setting="parity",
                               on_policy=True, train=(("seq_len", 40),),
                               only=("cnn_lstm", "rvs_g")),
    "speed_dagger_lr1e-3": Form(f"channels, λ = 0, {PARITY_TEXT}, DAgger {{rounds}} rounds, "
                                "learning rate 0.001", setting="parity", on_policy=True,
                                train=(("lr", 1e-3),), only=("cnn_lstm", "rvs_g")),
    "dagger_flat": Form("channels, λ = 0, eq. 7 over flatten(f), DAgger {rounds} rounds",
                        on_policy=True, model=(("predicate_readout", "flatten"),),
                        only=("manc",)),
    "dagger_warm": Form("channels, λ = 0, DAgger {rounds} rounds, each continuing 1 epoch",
                        on_policy=True, warm=1),
    "speed_dagger_warm": Form(f"channels, λ = 0, {PARITY_TEXT}, DAgger {{rounds}} rounds, "
                              "each continuing 1 epoch", setting="parity", on_policy=True,
                              warm=1),
    "speed_dagger_warm2": Form(f"channels, λ = 0, {PARITY_TEXT}, DAgger {{rounds}} rounds, "
                               "each continuing 2 epochs", setting="parity", on_policy=True,
                               warm=2),
    "speed_dagger_warm2_aux": Form(f"channels, λ = {{w:g}} on every collected state too, "
                                   f"{PARITY_TEXT}, DAgger {{rounds}} rounds, each continuing "
                                   "2 epochs", aux=True, setting="parity", on_policy=True,
                                   warm=2),
    "speed_dagger_warm2_aux_deep": Form(f"channels, λ = {{w:g}} on every collected state too, "
                                        f"{PARITY_TEXT}, the perception study's 4-layer "
                                        "backbone (32, 64, 64, 64), DAgger {rounds} rounds, "
                                        "each continuing 2 epochs", aux=True, setting="parity",
                                        on_policy=True, warm=2,
                                        model=(("channels", (32, 64, 64, 64)),)),
    "dagger_flat_warm": Form("channels, λ = 0, eq. 7 over flatten(f), DAgger {rounds} rounds, "
                             "each continuing 1 epoch", on_policy=True,
                             model=(("predicate_readout", "flatten"),), only=MANCS, warm=1),
    "dagger_flat_warm2": Form("channels, λ = 0, eq. 7 over flatten(f), DAgger {rounds} rounds, "
                              "each continuing 2 epochs", on_policy=True,
                              model=(("predicate_readout", "flatten"),), only=MANCS, warm=2),
    "dagger_flat_warm2_p64": Form("channels, λ = 0, 64 predicates of eq. 7 over flatten(f), "
                                  "DAgger {rounds} rounds, each continuing 2 epochs",
                                  on_policy=True, only=MANCS, warm=2,
                                  model=(("predicate_readout", "flatten"), ("n_predicates", 64))),
    "dagger_flat_warm2_goal10": Form("channels, λ = 0, eq. 7 over flatten(f), the DMP's goal 10 m "
                                     "ahead, DAgger {rounds} rounds, each continuing 2 epochs",
                                     on_policy=True, only=MANCS, warm=2,
                                     model=(("predicate_readout", "flatten"),
                                            ("position_lookahead", 10.0),
                                            ("position_lookahead_time", 0.0))),
    "dagger_flat_warm2_p64_goal10": Form("channels, λ = 0, 64 predicates of eq. 7 over "
                                         "flatten(f), the DMP's goal 10 m ahead, DAgger {rounds} "
                                         "rounds, each continuing 2 epochs",
                                         on_policy=True, only=MANCS, warm=2,
                                         model=(("predicate_readout", "flatten"),
                                                ("n_predicates", 64),
                                                ("position_lookahead", 10.0),
                                                ("position_lookahead_time", 0.0))),
    "dagger_flat_warm2_p64_goal10_aux_deep": Form(
        "channels, λ = {w:g} on every collected state too, 64 predicates of eq. 7 over "
        "flatten(f), the DMP's goal 10 m ahead, the perception study's 4-layer backbone "
        "(32, 64, 64, 64), DAgger {rounds} rounds, each continuing 2 epochs", aux=True,
        on_policy=True, only=MANCS, warm=2,
        model=(("predicate_readout", "flatten"), ("n_predicates", 64),
               ("position_lookahead", 10.0), ("position_lookahead_time", 0.0),
               ("channels", (32, 64, 64, 64)))),
    "rgb": Form("RGB (paper's form), λ = 0", raster="rgb"),
    "dagger_rgb": Form("RGB, λ = 0, DAgger {rounds} rounds", raster="rgb", on_policy=True),
}
"""The forms, in the report's order."""
RETIRED: dict[str, str] = {
    "speed_drop": f"channels, λ = 0, {PARITY_TEXT}, dropped w.p. 0.75 (retired)",
    "change_dagger": f"channels, λ = 0, {PARITY_TEXT}, speed as its change, DAgger "
                     "{rounds} rounds (retired)",
}
"""Forms measured here whose library option was then removed as rejected (their cached runs
stay in the report, labelled; they can no longer be trained): ``speed_drop`` trained with
``TrainConfig.motion_dropout = 0.75``, ``change_dagger`` with ``ModelConfig.speed_output =
"change"`` (commit 11a2e41)."""
ORDER = (*FORMS, *RETIRED)
"""Every form's place in the report."""
ROUNDS = 10
"""DAgger rounds after the demonstrations (the on-policy forms)."""
AGENTS = ("reactive", "replay")
BOUNDS = ("expert", "floor", "fixed_gains")
RASTERS = {"channels": PC.VARIANTS["route60"].config(), "rgb": world.RasterConfig()}
"""The raster of each form."""


def raster_name(form: str) -> str:
    """``"rgb"`` or ``"channels"``: the raster a form reads."""
    return FORMS[form].raster


def raster_of(form: str) -> world.RasterConfig:
    return RASTERS[raster_name(form)]


def form_text(form: str, weight: float) -> str:
    text = FORMS[form].text if form in FORMS else RETIRED[form]
    return text.format(w=weight, rounds=ROUNDS)


def model_config(form: str, pool: world.Dataset | None = None) -> models.ModelConfig | None:
    """The form's model configuration (``None``: the library's default for behaviour
    cloning; on-policy forms need ``pool`` for the input shape)."""
    f = FORMS[form]
    fields = dict(f.model) | ({"setting": f.setting} if f.setting != "paper" else {})
    if f.on_policy:
        return dagger.default_config(pool, **fields)
    return models.ModelConfig(**fields) if fields else None


def draw(form: str, work: Path) -> world.Dataset:
    """The seed-0 draw's first :data:`N_SCENES` scenes at the form's raster (the stored draw
    for RGB; regenerated at the channels raster, cached, and checked against it)."""
    ref = L.world()
    if raster_name(form) == "rgb":
        return ref.subset(list(range(N_SCENES)))
    ds = world.generate(N_SCENES, seed=0, raster=raster_of(form), cache=work / "world",
                        workers=1, progress=True)
    if not np.allclose(np.asarray(ds.ego), np.asarray(ref.ego)[:N_SCENES], atol=1e-9):
        raise SystemExit("the regenerated draw differs from the stored one")
    return ds


def targets(form: str, ds: world.Dataset, work: Path, split: str = "train"
            ) -> train.PerceptionTargets:
    """The auxiliary targets of the training (``split="train"``) or validation (``"val"``)
    scenes for the form's view (cached)."""
    cfg = raster_of(form)
    scenes = {"train": TRAIN, "val": VALIDATE}[split]
    tag = "" if split == "train" else "val_"
    path = work / f"targets_{tag}{raster_name(form)}.npz"
    if not path.exists():
        tg = diagnose.perception_targets(ds.subset(list(scenes)), view=cfg)
        tmp = path.with_name(path.stem + ".tmp.npz")
        np.savez(tmp, values=tg.values, mask=tg.mask)
        os.replace(tmp, path)
    with np.load(path) as f:
        return train.PerceptionTargets(diagnose.TARGETS, f["values"], f["mask"],
                                       tuple(n in diagnose.LOGITS for n in diagnose.TARGETS))


def train_config(model: str, form: str, seed: int, weight: float) -> train.TrainConfig:
    """The paper preset's schedule with the model's learning rate (unless the form sets its
    own), the form's λ and its other training fields."""
    fields = {"lr": LEARNING_RATES[model]} | dict(FORMS[form].train)
    return train.TrainConfig(epochs=6, batch_size=64, seed=seed,
                             perception_weight=weight_of(form, weight), **fields)


def weight_of(form: str, weight: float) -> float:
    return weight if FORMS[form].aux else 0.0


def run_path(work: Path, row: str, seed: int, agents: str) -> Path:
    return work / "runs" / f"{row}_s{seed}_{agents}.json"


def write_json(path: Path, out: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(out, indent=1))
    os.replace(tmp, path)


def fit_model(model: str, form: str, seed: int, weight: float, ds: world.Dataset,
              work: Path) -> tuple[train.FitResult, float]:
    """Algorithm 1 on the training scenes (checkpointed under ``work/checkpoints``)."""
    lam = weight_of(form, weight)
    tc = train_config(model, form, seed, weight)
    tr = ds.subset(list(TRAIN))
    t0 = time.perf_counter()
    if FORMS[form].on_policy:
        warm = replace(tc, epochs=FORMS[form].warm) if FORMS[form].warm else None
        return on_policy(model, model_config(form, tr), tc, tr,
                         dagger_dir(model, form, seed, work), warm,
                         targets(form, ds, work) if lam > 0 else None), time.perf_counter() - t0
    fit = train.fit(model, tr, model_config(form), tc, engine="jax", progress=False,
                    checkpoint_dir=checkpoint_dir(model, form, seed, lam, work),
                    resume=True, perception=targets(form, ds, work) if lam > 0 else None)
    return fit, time.perf_counter() - t0


def checkpoint_dir(model: str, form: str, seed: int, lam: float, work: Path) -> Path:
    """Where a behaviour-cloned run of ``form`` with λ = ``lam`` is checkpointed."""
    return work / "checkpoints" / f"{model}_{form}_w{lam:g}_s{seed}"


def dagger_dir(model: str, form: str, seed: int, work: Path) -> Path:
    """Where DAgger's rounds of an on-policy form are checkpointed."""
    tag = {"dagger": "", "dagger_rgb": "_rgb"}.get(form, f"_{form}")
    return work / "dagger" / f"{model}{tag}_s{seed}"


def checkpoint_of(model: str, form: str, seed: int, work: Path, weight: float = 1.0
                  ) -> Path | None:
    """The trained model's checkpoint (DAgger's last round for ``dagger``), if it exists."""
    if FORMS[form].on_policy:
        path = dagger.round_dir(dagger_dir(model, form, seed, work), ROUNDS)
        if not (path / dagger.ROUND_FILE).exists():  # the last round is still training
            return None
    else:
        path = checkpoint_dir(model, form, seed, weight_of(form, weight), work)
    path = path / train.CHECKPOINT_NAME
    return path if path.exists() else None


def on_policy(model: str, cfg: models.ModelConfig, tc: train.TrainConfig,
              pool: world.Dataset, out: Path, warm: train.TrainConfig | None = None,
              perception: train.PerceptionTargets | None = None) -> train.FitResult:
    """DAgger on ``pool`` (every round checkpointed under ``out``: a rerun resumes; rounds
    after the first continue from the previous one with ``warm`` if given; with
    ``perception``, the targets of the pool's scenes, the auxiliary loss also on what the
    teacher perceives in the collected states), its last policy as a fit."""
    perceive = None if perception is None else partial(diagnose.state_targets,
                                                       view=pool.raster)
    teacher = dagger.WorldTeacher(pool, agents="reactive", perceive=perceive)
    budget = dagger.plan_budget(len(pool) * pool.n_steps, pool.n_steps, ROUNDS)
    dagger.dagger(model, teacher, budget, rounds=ROUNDS, beta=0.5, cfg=cfg, train_cfg=tc,
                  engine="jax", out=out, seed=tc.seed, progress=False, evaluate=False,
                  round_cfg=warm, perception=perception)
    return train.load_fit(dagger.round_dir(out, ROUNDS) / train.CHECKPOINT_NAME)


def drive(fit: train.FitResult, val: world.Dataset, agents: str) -> dict:
    traj = rollout.closed_loop(fit, val, agents=agents, progress=False)
    return metrics.evaluate(traj, val)


def run_model(model: str, form: str, seed: int, weight: float, work: Path) -> None:
    spec = models.get(model)
    if FORMS[form].only and model not in FORMS[form].only:
        return
    if FORMS[form].setting != "paper" and \
            inputs.visible(spec, "paper") == inputs.visible(spec, FORMS[form].setting):
        return  # the model reads the same in both settings: the form is its paper twin
    row = f"{model}_{form}"
    todo = [a for a in AGENTS if not run_path(work, row, seed, a).exists()]
    if not todo:
        return
    ds = draw(form, work)
    fit, fit_s = fit_model(model, form, seed, weight, ds, work)
    val = ds.subset(list(VALIDATE))
    for agents in todo:
        t0 = time.perf_counter()
        m = drive(fit, val, agents)
        out = {"row": row, "model": model, "form": form, "seed": seed, "agents": agents,
               "weight": weight_of(form, weight), "lr": fit.train_cfg.lr,
               "raster": raster_of(form).as_meta(), "input_shape": list(fit.cfg.input_shape),
               "steps": fit.steps, "fit_seconds": fit_s,
               "drive_seconds": time.perf_counter() - t0, "scenes": len(val), "metrics": m,
               "provenance": provenance.provenance()}
        write_json(run_path(work, row, seed, agents), out)
        print(json.dumps({k: out[k] for k in ("row", "seed", "agents")} | {
            "at_fault": m["at_fault_collision_rate"], "ade": m["ade"]}), flush=True)


def run_bound(kind: str, work: Path) -> None:
    ds = None
    for agents in AGENTS if kind != "floor" else ("reactive",):
        path = run_path(work, kind, 0, agents)
        if path.exists():
            continue
        ds = ds or draw("rgb", work).subset(list(VALIDATE))
        t0 = time.perf_counter()
        if kind == "expert":
            traj = diagnose.expert_rollout(ds, agents=agents)
        elif kind == "floor":
            traj = diagnose.floor_rollout(ds, diagnose.median_style(), agents=agents)
        else:
            traj = rollout.fixed_gains(ds, agents=agents)
        out = {"row": kind, "seed": 0, "agents": agents, "scenes": len(ds),
               "metrics": metrics.evaluate(traj, ds),
               "drive_seconds": time.perf_counter() - t0, "provenance": provenance.provenance()}
        write_json(path, out)


# --------------------------------------------------------------------------- report

KEYS = (("ade", "ADE m", 2), ("collision_rate", "coll. %", 2),
        ("at_fault_collision_rate", "at fault %", 2), ("off_road_rate", "off road %", 2),
        ("route_progress", "progress", 2), ("max_acceleration", "max \\|a\\| m/s²", 2))
LABELS = {"expert": "Expert (the world's human)", "floor": "Style floor (median style)",
          "fixed_gains": "DMP at fixed gains"}


def cell(vals: list[float], d: int) -> str:
    x = np.asarray(vals, dtype=float)
    if len(x) == 1:
        return f"{x[0]:.{d}f}"
    return f"{x.mean():.{d}f} ± {x.std(ddof=1):.{d}f}"


def privileged_rows() -> dict[str, str]:
    """The privileged learner's rows of ``results/drive.md``, per protocol."""
    rows, agents = {}, None
    for line in DRIVE.read_text().splitlines():
        m = re.match(r"agents `(\w+)`", line)
        if m:
            agents = m.group(1)
        if line.startswith("| Privileged MLP") and agents:
            c = [s.strip() for s in line.strip("|").split("|")]
            rows[agents] = f"| Privileged MLP, exact features (`drive.md`) | {c[1]} | {c[2]} | " \
                           f"{c[3]} | {c[4]} | {c[5]} | {c[6]} | |"
    return rows


HEADLINE = (("cnn", "rgb"), ("cnn", "speed_dagger_warm2"), ("cnn_lstm", "rgb"),
            ("cnn_lstm", "speed_dagger"), ("rvs_g", "rgb"), ("rvs_g", "speed_dagger"),
            ("manc", "rgb"), ("manc", "dagger_flat_warm"),
            ("manc_qp", "dagger_flat_warm2_p64_goal10"))
"""The rows of the headline: each model in the paper's form and in the best learner's form
measured for it (MANC both as the paper writes it and with the gains the learner's form
adopts)."""


def at_fault_cells(runs: list[dict], model: str, form: str) -> list[str]:
    """The at-fault cells of one (model, form) row, per protocol: mean [one per seed]."""
    cells = []
    for agents in AGENTS:
        rs = sorted((r for r in runs if r.get("model") == model and r.get("form") == form
                     and r["agents"] == agents), key=lambda r: r["seed"])
        x = [r["metrics"]["at_fault_collision_rate"] for r in rs]
        cells.append(f"{np.mean(x):.1f} [{', '.join(f'{v:.1f}' for v in x)}]" if x else "")
    return cells


def bound_lines(runs: list[dict]) -> list[str]:
    """The bound rows of the at-fault tables."""
    lines = []
    for kind in BOUNDS:
        cells = [", ".join(f"{r['metrics']['at_fault_collision_rate']:.1f}" for r in runs
                           if r["row"] == kind and r["agents"] == agents) for agents in AGENTS]
        if any(cells):
            lines.append(f"| {LABELS[kind]} | bound | {cells[0]} | {cells[1]} |")
    priv = privileged_at_fault()
    if priv:
        lines.append(f"| Privileged MLP, exact features (`drive.md`) | bound | "
                     f"{priv.get('reactive', '')} | {priv.get('replay', '')} |")
    return lines


def at_fault_summary(runs: list[dict], pairs: Any = None,
                     title: str = "At fault, per training seed") -> list[str]:
    """The at-fault rates of the learned rows ``pairs`` of (model, form) (default: every
    one), both protocols, one number per seed, under the bounds."""
    lines = [f"## {title}\n",
             "% of the 200 validation scenes with an at-fault collision, one number per "
             "training seed (seed order), mean in front.\n",
             "| model | form | reactive | replay |", "|---|---|---|---|", *bound_lines(runs)]
    pairs = pairs or [(m, f) for m in MODELS for f in ORDER]
    for model, form in pairs:
        cells = at_fault_cells(runs, model, form)
        if any(cells):
            lines.append(f"| {model} | {form_text(form, 1)} | {cells[0]} | {cells[1]} |")
    return lines + [""]


def privileged_at_fault() -> dict[str, str]:
    """The privileged learner's at-fault cell (mean ± std) of ``results/drive.md``, per
    protocol."""
    return {a: row.split("|")[5].strip() for a, row in privileged_rows().items()}


def report(work: Path) -> str:
    runs = [json.loads(p.read_text()) for p in sorted((work / "runs").glob("*.json"))]
    head = "| driver | seeds | " + " | ".join(k[1] for k in KEYS) + " |"
    lines = ["# The end-to-end image models on the learner's raster, closed loop\n",
             __doc__.split("\n\n")[1].replace("\n", " ") + "\n",
             __doc__.split("\n\n")[2].replace("\n", " ") + "\n"]
    priv = privileged_rows()
    for agents in AGENTS:
        lines += [f"## agents `{agents}`\n", head, "|---|---|" + "---|" * len(KEYS)]
        for kind in BOUNDS:
            rs = [r for r in runs if r["row"] == kind and r["agents"] == agents]
            if rs:
                lines.append(f"| {LABELS[kind]} | 1 | " + " | ".join(
                    cell([r["metrics"][k] for r in rs], d) for k, _, d in KEYS) + " |")
        if agents in priv:
            lines.append(priv[agents])
        for model in MODELS:
            for form in ORDER:
                rs = [r for r in runs if r.get("model") == model and r.get("form") == form
                      and r["agents"] == agents]
                if not rs:
                    continue
                label = f"{model}, {form_text(form, rs[0]['weight'])}"
                seeds = ", ".join(str(r["seed"]) for r in rs)
                lines.append(f"| {label} | {len(rs)} ({seeds}) | " + " | ".join(
                    cell([r["metrics"][k] for r in rs], d) for k, _, d in KEYS) + " |")
        lines.append("")
    lines += at_fault_summary(runs, HEADLINE, "The paper's form against the learner's")
    lines += at_fault_summary(runs)
    lines += ["## Runs\n", "| row | agents | seed | steps | fit s | drive s | date | commit |",
              "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        p = r["provenance"]
        lines.append(f"| {r['row']} | {r['agents']} | {r['seed']} | {r.get('steps', '')} | "
                     f"{r.get('fit_seconds', 0):.0f} | {r['drive_seconds']:.0f} | "
                     f"{p.get('date', '')} | {p.get('commit', '')} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", choices=MODELS, default=["cnn", "manc"],
                    help="the models (the speed form is not run for MANC: see above)")
    ap.add_argument("--forms", nargs="+", choices=FORMS, default=["channels"])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--weight", type=float, default=1.0,
                    help="λ of the channels form (default 1)")
    ap.add_argument("--bounds", action="store_true", help="also run the bound rows")
    ap.add_argument("--work", type=Path, default=L.DATA_DIR / "end_to_end",
                    help="where the draws, checkpoints and runs are cached")
    ap.add_argument("--report", action="store_true",
                    help="write results/end_to_end.md from the cached runs")
    args = ap.parse_args()
    if not (math.isfinite(args.weight) and args.weight > 0):
        raise SystemExit(f"--weight must be a finite number > 0, got {args.weight}")
    if any(s < 0 for s in args.seeds):
        raise SystemExit(f"--seeds must be >= 0, got {args.seeds}")
    t_start = time.perf_counter()
    if args.report:
        provenance.publish(report(args.work), str(RESULTS / "end_to_end.md"),
                           time.perf_counter() - t_start)
        return
    if args.bounds:
        for kind in BOUNDS:
            run_bound(kind, args.work)
    for seed in args.seeds:
        for model in args.models:
            for form in args.forms:
                run_model(model, form, seed, args.weight, args.work)


if __name__ == "__main__":
    main()
