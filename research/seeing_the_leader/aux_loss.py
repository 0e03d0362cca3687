"""Does the masked auxiliary perception loss make a behaviour-cloned CNN's features hold the
leader? An open-loop probe at the quick preset's size.

The library's ``cnn`` (the shared backbone and a direct head) is trained by Algorithm 1
(:func:`minimanc.train.fit`) on the quick preset's data size and schedule (64 training
scenes, 3 epochs of batch 64, the default learning rate), once per auxiliary weight λ
(``TrainConfig.perception_weight``; λ = 0 is Algorithm 1 alone) and seed, with the targets of
:func:`minimanc.diagnose.perception_targets` for the raster the model reads (a leader counts
only inside its view). Then a ridge probe (:func:`minimanc.diagnose.linear_probe`) of the
flattened backbone features, fitted on the training scenes' states, reads on the validation
scenes: the gap and the closing speed (fitted and scored on the states whose leader is in
the view; scored for leaders within 30 m, as issue 41's targets), whether there is a leader
in the view (a regression of the flag, thresholded at ½) and the own speed (t ≥ 2). Also the
open-loop control loss on the validation scenes (:func:`minimanc.train.open_loop_loss`):
whether the auxiliary loss costs behaviour cloning anything.

The CNN reads the course's RGB raster (40 m × ±25 m at 0.78 m/px, no history) or, with
``--raster channels``, the learner's binary channels of the same view with the route and
the vehicles at t, t−1, t−2 (the perception study's ``route`` variant; the model takes its
input shape from the data). Both views are the same, so are the targets.

Data: the seed-0 draw (scenes 0–63 train, 72–95 validate at the quick size; the preset's
tuning scenes 64–71 unused), generated once into ``DATA_DIR/aux_loss``. Each run's result is
cached in ``DATA_DIR/aux_loss/n<scenes>_e<epochs>_w<λ>_s<seed>.json`` (a rerun skips it).

Run: ``python research/seeing_the_leader/aux_loss.py`` (writes ``results/aux_loss.md``);
``--weights`` and ``--seeds`` choose the runs, ``--train-scenes`` and ``--epochs`` a larger
size (``results/aux_loss_n<scenes>_e<epochs>.md``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import leader_data as L
import numpy as np

from minimanc import diagnose, engine, inputs, models, train, world
from minimanc.studies import provenance

HERE = Path(__file__).resolve().parent
WORK = L.DATA_DIR / "aux_loss"
MODEL = "cnn"
N_TRAIN = 64
"""The quick preset's training scenes (``minimanc.studies.PRESETS["quick"]``)."""
EPOCHS = 3
"""The quick preset's epochs."""
GAP = 8
"""Scenes between the training and the validation scenes (the quick preset's tuning scenes)."""
N_VAL = 24
"""The quick preset's validation scenes."""
NEAR = 30.0
"""Leaders within this gap (m) are those the targets speak of."""
RASTERS = {"rgb": world.RasterConfig(),
           "channels": world.RasterConfig(encoding="channels", history=2, route=True)}
"""The rasters the CNN may read (one view: 40 m × ±25 m at 0.78 m/px)."""
RASTER_TEXT = {"rgb": "RGB raster", "channels": "binary channels (map, route, vehicles at t, "
               "t−1, t−2: 12 planes)"}
RIDGES = (1.0, 10.0, 100.0, 1e3, 1e4, 1e5)
"""The probe's ridge, chosen per quantity by 4-fold cross-validation over the training
scenes (never the validation scenes)."""


def splits(n_train: int) -> tuple[range, range]:
    """The training and validation scenes of a run on ``n_train`` training scenes."""
    return range(0, n_train), range(n_train + GAP, n_train + GAP + N_VAL)


def data(n_train: int, raster: str) -> tuple:
    """The dataset and its targets (cached under :data:`WORK`)."""
    WORK.mkdir(parents=True, exist_ok=True)
    n = splits(n_train)[1].stop
    ds = world.generate(n, seed=0, raster=RASTERS[raster], cache=str(WORK / "world"),
                        workers=1)
    path = WORK / f"targets_{n}.npz"
    if not path.exists():
        tg = diagnose.perception_targets(ds, view=world.RasterConfig())
        tmp = path.with_name("targets.tmp.npz")
        np.savez(tmp, values=tg.values, mask=tg.mask)
        os.replace(tmp, path)
    with np.load(path) as f:
        tg = train.PerceptionTargets(diagnose.TARGETS, f["values"], f["mask"],
                                     tuple(n in diagnose.LOGITS for n in diagnose.TARGETS))
    return ds, tg


def features(fit: train.FitResult, ds, scenes: range) -> np.ndarray:
    """The flattened backbone features ``(len(scenes) · T, n)`` of every state of ``scenes``."""
    eng = engine("jax")
    T = np.asarray(ds.ego).shape[1]
    spec = models.get(MODEL)
    fn = eng.jit(lambda p, x: models.backbone(p, x, fit.cfg, eng))
    out = []
    for s in scenes:
        obs = inputs.from_dataset(ds, np.full(T, s), np.arange(T), fit.cfg.setting, model=spec)
        f = np.asarray(fn(fit.params["backbone"], obs["bev"]))
        out.append(f.reshape(T, -1))
    return np.concatenate(out)


def probe(Z: np.ndarray, Zv: np.ndarray, tg: train.PerceptionTargets, n_train: int) -> dict:
    """The probe's scores on the validation states (see the module docstring)."""
    tr, va = splits(n_train)
    T = tg.values.shape[1]
    col = {n: k for k, n in enumerate(tg.names)}
    y = tg.values[np.asarray(tr)].reshape(-1, len(tg.names))
    yv = tg.values[np.asarray(va)].reshape(-1, len(tg.names))
    scene = np.repeat(np.arange(len(tr)), T)
    lead, lead_v = y[:, col["has_leader"]] > 0, yv[:, col["has_leader"]] > 0
    near = lead_v & (yv[:, col["gap"]] <= NEAR)
    late = np.tile(np.arange(T), len(va)) >= 2
    out = {"n_near": int(near.sum())}
    for name, rows, rows_v in (("gap", lead, near), ("dv", lead, near), ("v", None, late)):
        fit_rows = np.ones(len(y), bool) if rows is None else rows
        Y = y[fit_rows][:, [col[name]]]
        ridge = choose_ridge(Z[fit_rows], Y, scene[fit_rows])
        r = diagnose.linear_probe(Z[fit_rows], Y, Zv[rows_v], yv[rows_v][:, [col[name]]], ridge)
        out[f"{name}_rmse"], out[f"{name}_r2"] = float(r["rmse"][0]), float(r["r2"][0])
        out[f"{name}_ridge"] = ridge
    flag = y[:, [col["has_leader"]]]
    ridge = choose_ridge(Z, flag, scene)
    out["lead_accuracy"] = float(np.mean((ridge_predict(Z, flag, Zv, ridge)[:, 0] > 0.5) == lead_v))
    out["lead_ridge"] = ridge
    return out


def choose_ridge(Z: np.ndarray, Y: np.ndarray, scene: np.ndarray) -> float:
    """The ridge of :data:`RIDGES` with the least RMSE over 4 folds of whole scenes."""
    fold = scene % 4
    err = {r: np.mean([diagnose.linear_probe(Z[fold != k], Y[fold != k], Z[fold == k],
                                             Y[fold == k], r)["rmse"][0] for k in range(4)])
           for r in RIDGES}
    return min(err, key=err.get)


def ridge_predict(Z: np.ndarray, Y: np.ndarray, Zv: np.ndarray, ridge: float) -> np.ndarray:
    """The predictions on ``Zv`` of :func:`minimanc.diagnose.linear_probe`'s read-out (ridge
    ``ridge`` on the standardised features, an unpenalised intercept)."""
    mu, sd = Z.mean(0), Z.std(0) + 1e-8
    A = np.hstack([(Z - mu) / sd, np.ones((len(Z), 1))])
    pen = np.full(A.shape[1], ridge)
    pen[-1] = 0.0
    W = np.linalg.solve(A.T @ A + np.diag(pen), A.T @ Y)
    return np.hstack([(Zv - mu) / sd, np.ones((len(Zv), 1))]) @ W


def run(weight: float, seed: int, ds, tg: train.PerceptionTargets, n_train: int,
        epochs: int, raster: str) -> dict:
    """One training and its probe (cached)."""
    tag = "" if raster == "rgb" else f"_{raster}"
    path = WORK / f"n{n_train}_e{epochs}{tag}_w{weight:g}_s{seed}.json"
    if path.exists():
        return json.loads(path.read_text())
    scenes, val_scenes = splits(n_train)
    tr, val = ds.subset(list(scenes)), ds.subset(list(val_scenes))
    sub = train.PerceptionTargets(tg.names, tg.values[np.asarray(scenes)],
                                  tg.mask[np.asarray(scenes)], tg.logit)
    tc = train.TrainConfig(epochs=epochs, batch_size=64, seed=seed, perception_weight=weight)
    t0 = time.perf_counter()
    fit = train.fit(MODEL, tr, models.ModelConfig(), tc, engine="jax", progress=False,
                    perception=sub if weight > 0 else None)
    seconds = time.perf_counter() - t0
    out = {"weight": weight, "seed": seed, "n_train": n_train, "epochs": epochs, "raster": raster,
           "train_seconds": seconds, "steps": fit.steps,
           "val_control_loss": train.open_loop_loss(fit, val),
           **probe(features(fit, ds, scenes), features(fit, ds, val_scenes), tg, n_train)}
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(out, indent=1))
    os.replace(tmp, path)
    return out


def report(rows: list[dict], n_train: int, epochs: int, raster: str) -> str:
    tr, va = splits(n_train)
    weights = sorted({r["weight"] for r in rows})
    keys = [("gap_rmse", "gap m (≤ 30 m)", 2), ("dv_rmse", "dv m/s (≤ 30 m)", 2),
            ("lead_accuracy", "leader in view %", 1), ("v_rmse", "own speed m/s", 2),
            ("val_control_loss", "control loss (val)", 3)]
    lines = ["# The masked auxiliary perception loss and a CNN's features\n",
             f"`{MODEL}` trained by Algorithm 1 on scenes {tr.start}–{tr.stop - 1} of the "
             f"seed-0 draw, {epochs} epochs of batch 64, lr 3e-3 (the quick preset: 64 "
             f"scenes, 3 epochs), {RASTER_TEXT[raster]} 64×64 (40 m × ±25 m); λ = "
             "`TrainConfig.perception_weight`. A ridge probe of the flattened backbone "
             "features (ridge chosen per quantity by 4-fold cross-validation over the "
             f"training scenes), fitted on the training states, scored on scenes {va.start}–"
             f"{va.stop - 1}: gap and closing speed (dv) for leaders in the view within 30 m "
             "(fitted on every state with a leader in the view), whether there is a leader "
             "in the view (the flag regressed, thresholded at ½), own speed (t ≥ 2); and the "
             f"open-loop control loss on scenes {va.start}–{va.stop - 1}. Mean ± standard "
             "deviation over the seeds (one number per seed in brackets).\n",
             "| λ | seeds | " + " | ".join(k[1] for k in keys) + " | train s |",
             "|---|---|" + "---|" * len(keys) + "---|"]
    for w in weights:
        rs = [r for r in rows if r["weight"] == w]
        cells = []
        for k, _, d in keys:
            x = np.array([r[k] for r in rs]) * (100 if k == "lead_accuracy" else 1)
            spread = f" ± {x.std(ddof=1):.{d}f}" if len(x) > 1 else ""
            cells.append(f"{x.mean():.{d}f}{spread} [{', '.join(f'{v:.{d}f}' for v in x)}]")
        secs = np.mean([r["train_seconds"] for r in rs])
        lines.append(f"| {w:g} | {len(rs)} | " + " | ".join(cells) + f" | {secs:.0f} |")
    n = rows[0]["n_near"] if rows else 0
    lines.append(f"\n{n} validation states have a leader in the view within 30 m.\n")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", type=float, nargs="+", default=[0.0, 0.3, 1.0, 3.0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--train-scenes", type=int, default=N_TRAIN)
    ap.add_argument("--epochs", type=int, default=EPOCHS)
    ap.add_argument("--raster", choices=tuple(RASTERS), default="rgb")
    ap.add_argument("--out", default=None,
                    help="default results/aux_loss.md (quick size, RGB), else results/"
                         "aux_loss_n<scenes>_e<epochs>[_channels].md")
    args = ap.parse_args()
    if args.train_scenes < 8 or args.epochs < 1:
        raise SystemExit("--train-scenes must be >= 8 and --epochs >= 1")
    if any(not (math.isfinite(w) and w >= 0) for w in args.weights):
        raise SystemExit(f"--weights must be finite numbers >= 0, got {args.weights}")
    t_start = time.perf_counter()
    n, e, r = args.train_scenes, args.epochs, args.raster
    tag = "" if r == "rgb" else f"_{r}"
    out = args.out or str(HERE / "results" / (
        "aux_loss.md" if (n, e, r) == (N_TRAIN, EPOCHS, "rgb") else f"aux_loss_n{n}_e{e}{tag}.md"))
    ds, tg = data(n, r)
    rows = []
    for seed in args.seeds:
        for w in args.weights:
            rows.append(run(w, seed, ds, tg, n, e, r))
            print(json.dumps(rows[-1]), flush=True)
    provenance.publish(report(rows, n, e, r), out, time.perf_counter() - t_start)


if __name__ == "__main__":
    main()
