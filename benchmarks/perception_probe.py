"""What the image models perceive: a linear probe
(:func:`minimanc.metrics.diagnostics.linear_probe`) from each model's backbone features of a
state to what the world's human perceives there
(:mod:`minimanc.dagger.privileged`: its own speed, the gap and speed difference to its leader,
the distance to the point where it must yield, the braking bound of the curves ahead, the lateral
offset and heading error) and to the acceleration the human applied.

Backbones probed: an untrained one (the control: what random convolutions of the raster
already hold), and those of models trained by Algorithm 1 on the paper preset's draw
(data seed 0: 650 training, 40 tuning, 200 validation scenes). The probe is fitted on the
states of the first ``--probe-train`` training scenes and scored on the validation scenes.

Run: ``python benchmarks/perception_probe.py --out results/perception_probe.md``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from minimanc import engine, inputs, models, results, train, world
from minimanc.dagger import privileged as P
from minimanc.metrics.diagnostics import linear_probe

N_TRAIN, N_TUNE, N_VAL = 650, 40, 200
TARGETS = ("v", "gap", "dv", "has_leader", "stop", "a_curve", "lateral", "heading")
MODELS = {"untrained CNN backbone": None,
          "CNN (parity, speed change)": ("cnn", "parity", "change", "change"),
          "CNN (paper)": ("cnn", "paper", "level", "level"),
          "MANC (paper)": ("manc", "paper", "level", "level")}


def features(name: str, params: dict, ds, cfg, batch: int = 500) -> np.ndarray:
    """Backbone features ``(S·T, h·w·C)`` of every state of ``ds``, scene-major."""
    eng = engine("jax")
    S, T = np.asarray(ds.ego).shape[:2]
    s, t = np.divmod(np.arange(S * T), T)
    out = []
    for i in range(0, S * T, batch):
        obs = inputs.from_dataset(ds, s[i:i + batch], t[i:i + batch], cfg.setting, name)
        state = models.initial_state(name, len(obs["bev"]), cfg)
        _, _, aux = models.step(name, params, obs, state, cfg, eng)
        f = np.asarray(aux["features"], dtype=np.float32)
        out.append(f.reshape(len(f), -1))
    return np.concatenate(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--probe-train", type=int, default=200)
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--ridge", type=float, default=10.0)
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
    for label, spec in MODELS.items():
        if spec is None:
            name, cfg = "cnn", models.ModelConfig()
            params = models.init(name, np.random.default_rng(0), cfg, dtype=np.float32)
        else:
            name, setting, out, scale = spec
            cfg = models.ModelConfig(setting=setting, speed_output=out)
            tc = train.TrainConfig(epochs=args.epochs, lr=args.lr, seed=0, speed_scale=scale)
            params = train.fit(name, tr, cfg, tc, progress=False).params
        z, zv = features(name, params, ptr, cfg), features(name, params, val, cfg)
        r = linear_probe(z, y, zv, yv, ridge=args.ridge)
        g = names.index("gap"), names.index("dv")
        rc = linear_probe(z[closetr], y[closetr][:, g], zv[close], yv[close][:, g],
                          ridge=args.ridge)
        rows.append(f"| {label} | " + " | ".join(f"{v:.2f}" for v in r["r2"])
                    + f" | {rc['r2'][0]:.2f} ({rc['rmse'][0]:.1f} m) | {rc['r2'][1]:.2f} "
                    f"({rc['rmse'][1]:.2f} m/s) |")
        print(f"[{time.perf_counter() - t0:6.0f} s] {rows[-1]}", flush=True)
    head = ("| backbone | " + " | ".join(f"R² {n}" for n in names)
            + " | R² gap, leader < 30 m (RMSE) | R² dv, leader < 30 m (RMSE) |")
    text = (f"# What the image models perceive: linear probes of the backbone features "
            f"(probe fitted on {len(X)} states of {args.probe_train} training scenes, scored on "
            f"{len(Xv)} states of {N_VAL} validation scenes; ridge {args.ridge:g}; models "
            f"trained {args.epochs} epochs, lr {args.lr:g}, seed 0)\n\n"
            f"{head}\n" + "|---" * (len(names) + 3) + "|\n" + "\n".join(rows) + "\n\n"
            "Target spread on the validation states (std): "
            + ", ".join(f"{n} {s:.2f}" for n, s in zip(names, yv.std(0))) + ".\n")
    results.publish(text, args.out, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
