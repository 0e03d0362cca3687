"""What do the end-to-end models' representations hold of the leader? A ridge probe of the
trained models of ``end_to_end.py``: their flattened backbone features and, for MANC, eq. 7's
predicates (the global average of the features through a dense layer and a sigmoid; in the
form ``dagger_flat`` the flattened features through it), which are all its gains read.

The probe (:func:`minimanc.diagnose.linear_probe`; ridge from ``aux_loss.RIDGES`` by 4-fold
cross-validation over whole training scenes) is fitted on the states of every
:data:`STRIDE`-th training scene (0–599) and scored on the validation scenes 600–799, against
the targets of :func:`minimanc.diagnose.perception_targets` for the model's view: the gap
and the closing speed (fitted on the states with a leader in the view, scored on those whose
leader is within 30 m, as issue 41's targets), whether there is a leader in the view (the
flag regressed, thresholded at ½, scored on every state) and the own speed (t ≥ 2).

Run: ``SEEING_DATA=/path python research/seeing_the_leader/probe_models.py --work
runs/end_to_end`` (after ``end_to_end.py``; each probe is cached as JSON under
``--work/probes``); writes ``results/probe_models.md`` from every cached probe.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import aux_loss as A
import end_to_end as E
import leader_data as L
import numpy as np

from minimanc import diagnose, engine, inputs, models, train, world
from minimanc.models.forward import encode
from minimanc.studies import provenance

STRIDE = 3
"""Every third training scene is probed (200 scenes, 8,000 states)."""
NEAR = 30.0


def representations(fit: train.FitResult, ds: world.Dataset, scenes: list[int]
                    ) -> dict[str, np.ndarray]:
    """``features`` (flattened backbone) and, for a model with eq. 7's layer, ``predicates``
    of every state of ``scenes``, ``(len(scenes) · T, n)``."""
    eng = engine("jax")
    spec = models.get(fit.name)
    T = np.asarray(ds.ego).shape[1]

    def rep(p, obs):
        enc = encode(spec, p, obs, fit.cfg, eng)
        f = enc["features"].reshape(obs["bev"].shape[0], -1)
        return (f, enc["predicates"]) if "predicates" in enc else (f, f[:, :0])

    fn = eng.jit(rep)
    feats, preds = [], []
    for s in scenes:
        obs = inputs.from_dataset(ds, np.full(T, s), np.arange(T), fit.cfg.setting, model=spec)
        f, q = fn(fit.params, obs)
        feats.append(np.asarray(f, dtype=np.float64))
        preds.append(np.asarray(q, dtype=np.float64))
    out = {"features": np.concatenate(feats)}
    if preds[0].shape[1]:
        out["predicates"] = np.concatenate(preds)
    return out


def probe(Z: np.ndarray, Zv: np.ndarray, y: np.ndarray, yv: np.ndarray, T: int) -> dict:
    """The probe's scores (see the module docstring); ``y``, ``yv`` the targets' values."""
    col = {n: k for k, n in enumerate(diagnose.TARGETS)}
    scene = np.repeat(np.arange(len(y) // T), T)
    lead, lead_v = y[:, col["has_leader"]] > 0, yv[:, col["has_leader"]] > 0
    near = lead_v & (yv[:, col["gap"]] <= NEAR)
    late = np.tile(np.arange(T), len(yv) // T) >= 2
    out = {"n_near": int(near.sum())}
    for name, rows, rows_v in (("gap", lead, near), ("dv", lead, near),
                               ("v", np.ones(len(y), bool), late),
                               ("has_leader", np.ones(len(y), bool), np.ones(len(yv), bool))):
        Y = y[rows][:, [col[name]]]
        ridge = A.choose_ridge(Z[rows], Y, scene[rows])
        r = diagnose.linear_probe(Z[rows], Y, Zv[rows_v], yv[rows_v][:, [col[name]]], ridge)
        out[f"{name}_rmse"], out[f"{name}_r2"] = float(r["rmse"][0]), float(r["r2"][0])
        if name == "has_leader":  # the flag regressed: accuracy at ½ from the fitted read-out
            out["lead_accuracy"] = lead_accuracy(Z, Y, Zv, lead_v, ridge)
    return out


def lead_accuracy(Z: np.ndarray, Y: np.ndarray, Zv: np.ndarray, truth: np.ndarray,
                  ridge: float) -> float:
    """The ridge read-out's accuracy on ``Zv`` at the threshold ½."""
    return float(np.mean((A.ridge_predict(Z, Y, Zv, ridge)[:, 0] > 0.5) == truth))


def run(model: str, form: str, seed: int, work: Path) -> list[dict]:
    """The probes of one trained model (cached)."""
    path = work / "probes" / f"{model}_{form}_s{seed}.json"
    if path.exists():
        return json.loads(path.read_text())
    ck = E.checkpoint_of(model, form, seed, work)
    if ck is None:
        return []
    fit = train.load_fit(ck)
    ds = E.draw(form, work)
    train_scenes = list(E.TRAIN)[::STRIDE]
    tg = E.targets(form, ds, work)
    tv = E.targets(form, ds, work, "val")
    T = tg.values.shape[1]
    y = tg.values[np.asarray(train_scenes) - E.TRAIN.start].reshape(-1, len(tg.names))
    yv = tv.values.reshape(-1, len(tv.names))
    rep = representations(fit, ds, train_scenes)
    rep_v = representations(fit, ds, list(E.VALIDATE))
    rows = [{"model": model, "form": form, "seed": seed, "what": what,
             "dims": int(rep[what].shape[1]), **probe(rep[what], rep_v[what], y, yv, T)}
            for what in rep]
    E.write_json(path, rows)
    return rows


def cached(work: Path) -> list[dict]:
    """Every cached probe under ``work/probes``, in the order of :data:`end_to_end.MODELS`
    and :data:`end_to_end.FORMS`, then seed."""
    rows = [r for p in (work / "probes").glob("*.json") for r in json.loads(p.read_text())]
    forms = list(E.ORDER)
    return sorted(rows, key=lambda r: (E.MODELS.index(r["model"]), forms.index(r["form"]),
                                       r["seed"], r["what"]))


def report(rows: list[dict]) -> str:
    keys = (("gap_rmse", "gap m (≤ 30 m)", 2), ("dv_rmse", "dv m/s (≤ 30 m)", 2),
            ("lead_accuracy", "leader in view %", 1), ("v_rmse", "own speed m/s", 2))
    lines = ["# What the end-to-end models' representations hold of the leader\n",
             __doc__.split("\n\n")[1].replace("\n", " ") + "\n",
             "| model | form | seed | representation | dims | " +
             " | ".join(k[1] for k in keys) + " |", "|---|---|---|---|---|" + "---|" * len(keys)]
    for r in rows:
        cells = [f"{r[k] * (100 if k == 'lead_accuracy' else 1):.{d}f}" for k, _, d in keys]
        lines.append(f"| {r['model']} | {E.form_text(r['form'], 1)} | {r['seed']} | "
                     f"{r['what']} | {r['dims']} | " + " | ".join(cells) + " |")
    n = rows[0]["n_near"] if rows else 0
    lines.append(f"\nValidation states with a leader in the view within 30 m: {n} (channels "
                 "view, 60 m ahead); the RGB view reaches 40 m, so its rows count other "
                 "states.\n")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", choices=E.MODELS, default=["cnn", "manc"])
    ap.add_argument("--forms", nargs="+", choices=E.FORMS, default=["channels", "rgb"])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--work", type=Path, default=L.DATA_DIR / "end_to_end")
    args = ap.parse_args()
    t0 = time.perf_counter()
    for seed in args.seeds:
        for m in args.models:
            for f in args.forms:
                run(m, f, seed, args.work)
    provenance.publish(report(cached(args.work)), str(E.RESULTS / "probe_models.md"),
                       time.perf_counter() - t0)


if __name__ == "__main__":
    main()
