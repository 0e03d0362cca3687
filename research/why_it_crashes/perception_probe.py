"""What the image models perceive: a linear probe
(:func:`minimanc.diagnose.linear_probe`) from each model's backbone features of a
state to what the world's human perceives there
(:mod:`minimanc.diagnose.privileged`: its own speed, the gap and speed difference to its leader,
the distance to the point where it must yield, the braking bound of the curves ahead, the lateral
offset and heading error) and to the acceleration the human applied.

Representations probed: the backbone features (flattened) of an untrained CNN (the control:
what random convolutions of the raster already hold) and of models trained by Algorithm 1 on
the paper preset's draw (data seed 0: 650 training, 40 tuning, 200 validation scenes), and
what each trained model's head reads (the CNN's hidden layer FC(64); MANC's predicates of eq.
7), to which the model's output is linear or nearly so. The probe is fitted on the states of
the first ``--probe-train`` training scenes (its ridge chosen from :data:`RIDGES` on their
last quarter) and scored on the validation scenes.

Run: ``python research/why_it_crashes/perception_probe.py
--out research/why_it_crashes/results/perception_probe.md``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from minimanc import engine, inputs, models, train, world
from minimanc.diagnose import linear_probe
from minimanc.diagnose import privileged as P
from minimanc.layers import dense
from minimanc.models.backbone import activate
from minimanc.models.forward import encode
from minimanc.studies import provenance as results

N_TRAIN, N_TUNE, N_VAL = 650, 40, 200
RIDGES = (1.0, 10.0, 100.0, 1000.0, 10000.0)
TARGETS = ("v", "gap", "dv", "has_leader", "stop", "a_curve", "lateral", "heading")
MODELS = {"untrained CNN backbone": None,
          "CNN (parity)": ("cnn", "parity"),
          "CNN (paper)": ("cnn", "paper"),
          "MANC (paper)": ("manc", "paper")}
"""label → (model, setting). The committed results also probed models trained with switches
measured and deleted since (the speed as a change, the loss's speed scale, the flat
predicates, the auxiliary perception loss; ``REPORT.md`` names their commits)."""


def representations(name: str, params: dict, ds, cfg, batch: int = 500
                    ) -> dict[str, np.ndarray]:
    """``{"backbone": (S·T, h·w·C), "head input": (S·T, ·)}`` of every state of ``ds``,
    scene-major (the head input: the CNN's FC(64), a vAGN model's predicates)."""
    eng = engine("jax")
    spec = models.spec(name)
    S, T = np.asarray(ds.ego).shape[:2]
    s, t = np.divmod(np.arange(S * T), T)
    out: dict[str, list] = {"backbone": [], "head input": []}
    for i in range(0, S * T, batch):
        obs = inputs.from_dataset(ds, s[i:i + batch], t[i:i + batch], cfg.setting, models.get(name))
        enc = encode(spec, params, obs, cfg, eng)
        f = np.asarray(enc["features"], dtype=np.float32)
        out["backbone"].append(f.reshape(len(f), -1))
        if "predicates" in enc:
            out["head input"].append(np.asarray(enc["predicates"], dtype=np.float32))
        elif "fc1" in params:
            h = activate(dense(params["fc1"], enc["pre"], eng.xp), cfg, eng)
            out["head input"].append(np.asarray(h, dtype=np.float32))
    return {k: np.concatenate(v) for k, v in out.items() if v}


def probe(z: np.ndarray, y: np.ndarray, zv: np.ndarray, yv: np.ndarray) -> dict:
    """:func:`linear_probe` with the ridge of :data:`RIDGES` best on the last quarter of
    the training states (mean R² over the targets), refitted on all of them."""
    k = 3 * len(z) // 4
    best = max(RIDGES, key=lambda r: float(np.mean(linear_probe(z[:k], y[:k], z[k:], y[k:],
                                                                 ridge=r)["r2"])))
    return {**linear_probe(z, y, zv, yv, ridge=best), "ridge": best}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--probe-train", type=int, default=200)
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--models", nargs="+", default=list(MODELS), metavar="LABEL",
                    help="labels of MODELS to probe (default: all)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    t0 = time.perf_counter()
    ds = world.generate(N_TRAIN + N_TUNE + N_VAL, seed=0, cache=True, progress=True)
    tr = ds.subset(slice(0, N_TRAIN))
    ptr = ds.subset(slice(0, args.probe_train))
    val = ds.subset(slice(N_TRAIN + N_TUNE, None))
    cols = [P.FEATURES.index(f) for f in TARGETS]
    X, Y = P.demonstrations(ptr)
    Xv, Yv = P.demonstrations(val)
    y, yv = np.c_[X[:, cols], Y[:, 0]], np.c_[Xv[:, cols], Yv[:, 0]]
    names = (*TARGETS, "acceleration")
    close = (Xv[:, P.FEATURES.index("has_leader")] > 0) & (Xv[:, P.FEATURES.index("gap")] < 30)
    closetr = (X[:, P.FEATURES.index("has_leader")] > 0) & (X[:, P.FEATURES.index("gap")] < 30)
    print(f"[{time.perf_counter() - t0:6.0f} s] {len(X)} probe-training, {len(Xv)} validation "
          f"states ({close.sum()} with a leader within 30 m)", flush=True)
    rows = []
    bad = [m for m in args.models if m not in MODELS]
    if bad:
        ap.error(f"unknown --models {bad}; choose from {list(MODELS)}")
    for label in args.models:
        spec = MODELS[label]
        if spec is None:
            name, cfg = "cnn", models.ModelConfig()
            params = models.init(name, np.random.default_rng(0), cfg, dtype=np.float32)
        else:
            name, setting = spec
            cfg = models.ModelConfig(setting=setting)
            tc = train.TrainConfig(epochs=args.epochs, lr=args.lr, seed=0)
            params = train.fit(name, tr, cfg, tc, progress=False).params
        reps, repsv = representations(name, params, ptr, cfg), representations(name, params,
                                                                                 val, cfg)
        for part in reps if spec is not None else ("backbone",):
            z, zv = reps[part], repsv[part]
            r = probe(z, y, zv, yv)
            g = [names.index("gap"), names.index("dv")]
            rc = probe(z[closetr], y[closetr][:, g], zv[close], yv[close][:, g])
            rows.append(f"| {label} | {part} ({z.shape[1]}) | " + " | ".join(
                f"{v:.2f}" for v in r["r2"]) + f" | {rc['r2'][0]:.2f} ({rc['rmse'][0]:.1f} m) "
                f"| {rc['r2'][1]:.2f} ({rc['rmse'][1]:.2f} m/s) |")
            print(f"[{time.perf_counter() - t0:6.0f} s] {rows[-1]}", flush=True)
    head = ("| model | representation (size) | " + " | ".join(f"R² {n}" for n in names)
            + " | R² gap, leader < 30 m (RMSE) | R² dv, leader < 30 m (RMSE) |")
    text = (f"# What the image models perceive (models trained {args.epochs} epochs, lr "
            f"{args.lr:g}, seed 0)\n\n## Linear probes\n\n"
            f"Fitted on {len(X)} states of {args.probe_train} training scenes, scored on "
            f"{len(Xv)} states of {N_VAL} validation scenes.\n\n"
            f"{head}\n" + "|---" * (len(names) + 4) + "|\n" + "\n".join(rows) + "\n\n"
            "Target spread on the validation states (std): "
            + ", ".join(f"{n} {s:.2f}" for n, s in zip(names, yv.std(0))) + ".\n\n")
    results.publish(text, args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
