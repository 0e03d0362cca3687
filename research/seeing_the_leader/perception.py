"""How well can a network read what the expert perceives from the raster? One run per variant.

A perception network (convolutions on the raster, then a read-out) is trained on the numbers
the world's human perceives in each logged state (:mod:`leader_data`): its own speed, the gap
and closing speed to its leader and whether there is one within the view, the distance to
its yield point and whether there is one, the curve bound and the path ahead
(:data:`HEADS`). The gap and closing-speed losses are masked to the states whose leader is in
the view, the yield-point distance to the states that have one; each regression is divided
by its standard deviation over the training states; presence is a logistic loss.

Variants (:data:`VARIANTS`) change one factor at a time from ``base`` — the raster's
encoding, its history, how far it reaches, its resolution, the route channel, the side
extent, the backbone's depth and width, the read-out, the training scenes — then combine
the best. Read-outs: ``flat`` (flattened features → FC 256 → heads), ``gap`` (eq. 7's
global average pooling → FC 256 → heads), ``gap_linear`` (eq. 7 as written, conv → GAP →
linear: the heads are the predicates, supervised as affordances), and ``coord_*``: the
same with two position channels (the pixel's metres ahead and to the side, scaled)
concatenated to the input of every convolution (CoordConv), so that features can carry
where things are through the average.

Protocol (fixed before any validation number; README.md): train on scenes 0–299 (``scale``:
0–599) for :data:`STEPS` Adam steps of batch 64 (cosine decay from 1e-3, gradient norm
clipped at 5), float32, one XLA thread; choose on scenes 300–399 (``select``); report scenes
600–799 (``validate``). Each run's result is cached in ``DATA_DIR/perception/<variant>_s<seed>
.json`` (a finished run is not repeated; a killed one restarts).

Run: ``python research/seeing_the_leader/perception.py --variant base --seed 0``;
``--report`` writes ``results/perception.md`` from the cached runs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import leader_data as L
import numpy as np
import rasters

from minimanc import engine, layers, optim
from minimanc.studies import provenance
from minimanc.train.step import global_norm, like, scale_tree
from minimanc.world import RasterConfig, to_input

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
RUNS = L.DATA_DIR / "perception"
STEPS = 3000
"""Adam steps per run (batch 64)."""
BATCH = 64
SELECT = range(300, 400)
"""Scenes on which variants are compared and chosen."""
HEADS = ("v", "gap", "dv", "lead", "stop", "has_stop", "a_curve", "lateral", "heading",
         "ahead_5", "ahead_10", "ahead_20")
"""What the network predicts, in order: the expert's :data:`leader_data.FEATURES` (``lead``:
whether there is a leader *in the view*), presence heads as logits."""
LOGITS = ("lead", "has_stop")
NEAR = 30.0
"""Leaders within this gap (m) are those the targets speak of."""


@dataclass(frozen=True)
class Variant:
    """One perception: the raster (``RasterConfig`` fields, or ``extent`` = (metres ahead,
    metres to the side, m/px) for :meth:`RasterConfig.from_extent`), the backbone's channels
    (3×3 stride-2 convolutions, ReLU), the read-out, the training scenes (ranges of the
    draw) and the Adam steps (``None``: :data:`STEPS`)."""

    raster: dict = field(default_factory=dict)
    extent: tuple[float, float, float] | None = None
    convs: tuple[int, ...] = (32, 64, 64, 64)
    readout: str = "flat"
    train: tuple[range, ...] = (L.TRAIN,)
    steps: int | None = None

    def config(self) -> RasterConfig:
        if self.extent is None:
            return RasterConfig(**self.raster)
        ahead, side, res = self.extent
        return RasterConfig.from_extent(ahead, side, res, **self.raster)


BASE = Variant(raster={"encoding": "channels", "history": 2})
CORRIDOR = (60.0, 25.0, 50 / 64)  # the measured reach at today's resolution
VARIANTS: dict[str, Variant] = {
    "base": BASE,
    # the raster
    "rgb": replace(BASE, raster={"history": 2}),
    "rgb_history0": replace(BASE, raster={}),
    "history0": replace(BASE, raster={"encoding": "channels"}),
    "reach60": replace(BASE, extent=CORRIDOR),
    "res0.5": replace(BASE, extent=(40.0, 25.0, 0.5), convs=(32, 32, 64, 64, 64)),
    "route": replace(BASE, raster={**BASE.raster, "route": True}),
    "side16_reach60": replace(BASE, extent=(60.0, 16.0, 50 / 64)),
    # the network
    "narrow": replace(BASE, convs=(16, 32, 32, 32)),
    "wide": replace(BASE, convs=(64, 128, 128, 128)),
    "deep": replace(BASE, convs=(32, 64, 64, 64, 64)),
    "gap": replace(BASE, readout="gap"),
    "gap_linear": replace(BASE, readout="gap_linear"),
    "coord_gap": replace(BASE, readout="coord_gap"),
    "coord_gap_linear": replace(BASE, readout="coord_gap_linear"),
    "coord_flat": replace(BASE, readout="coord_flat"),
    # the data
    "scale": replace(BASE, train=(L.TRAIN_LARGE,)),
}
ROUTE60 = replace(BASE, raster={**BASE.raster, "route": True}, extent=CORRIDOR)
"""Round 2 starts from the route channel (round 1's one clear gain) in the measured reach."""
VARIANTS |= {
    "route60": ROUTE60,
    "route60_scale": replace(ROUTE60, train=(L.TRAIN_LARGE,)),
    "route60_res0.5": replace(ROUTE60, extent=(60.0, 25.0, 0.5), convs=(32, 32, 64, 64, 64)),
    "route60_side16": replace(ROUTE60, extent=(60.0, 16.0, 50 / 64)),
    "route60_gap": replace(ROUTE60, readout="gap"),
    "route60_gap_linear": replace(ROUTE60, readout="gap_linear"),
    "route60_coord_gap": replace(ROUTE60, readout="coord_gap"),
    "route60_coord_gap_linear": replace(ROUTE60, readout="coord_gap_linear"),
    "route60_deep": replace(ROUTE60, convs=(32, 64, 64, 64, 64)),
    "route60_wide": replace(ROUTE60, convs=(64, 128, 128, 128)),
    "route60_history4": replace(ROUTE60, raster={**ROUTE60.raster, "history": 4}),
    "route60_narrow": replace(ROUTE60, convs=(16, 32, 32, 32)),
    "route60_course": replace(ROUTE60, convs=(16, 32, 32)),  # the course's backbone, flat
    # more generated scenes (the draw of SEEING_WORLD, 2000 scenes of seed 0: scenes 0–599
    # and 850–1649; validation stays 600–799), trained twice as long
    "route60_xl": replace(ROUTE60, train=(L.TRAIN_LARGE, range(850, 1650)), steps=6000),
}
READOUTS = ("flat", "gap", "gap_linear", "coord_flat", "coord_gap", "coord_gap_linear")


# --------------------------------------------------------------------------- targets


def targets(cfg: RasterConfig, tg: dict) -> tuple[np.ndarray, np.ndarray]:
    """``Y (S, T, len(HEADS))`` and the loss mask ``M`` of the same shape for raster ``cfg``."""
    F = {n: tg["features"][..., i] for i, n in enumerate(L.FEATURES)}
    lead = L.in_view(tg, cfg.metres_ahead, cfg.metres_side).astype(np.float64)
    Y = np.stack([F["v"], F["gap"], F["dv"], lead, F["stop"], F["has_stop"], F["a_curve"],
                  F["lateral"], F["heading"], F["ahead_5"], F["ahead_10"], F["ahead_20"]],
                 axis=-1)
    M = np.ones_like(Y)
    M[..., HEADS.index("gap")] = lead
    M[..., HEADS.index("dv")] = lead
    M[..., HEADS.index("stop")] = F["has_stop"]
    return Y, M


# --------------------------------------------------------------------------- the network


def _coords(h: int, w: int, cfg: RasterConfig) -> np.ndarray:
    """``(1, h, w, 2)`` float32: each cell's centre in metres ahead / 50 and to the left / 25."""
    x = cfg.metres_ahead - (np.arange(h) + 0.5) * (cfg.metres_ahead + cfg.metres_behind) / h
    y = cfg.metres_side - (np.arange(w) + 0.5) * 2 * cfg.metres_side / w
    X, Y = np.meshgrid(x / 50.0, y / 25.0, indexing="ij")
    return np.stack([X, Y], axis=-1)[None].astype(np.float32)


def shapes(v: Variant) -> list[tuple[int, int]]:
    """Spatial size of the input of each convolution and of the final features."""
    cfg = v.config()
    h, w = cfg.size, cfg.width
    out = [(h, w)]
    for _ in v.convs:
        h, w = (h + 1) // 2, (w + 1) // 2
        out.append((h, w))
    return out


def init(v: Variant, rng: np.random.Generator) -> dict:
    cfg = v.config()
    coord = 2 if v.readout.startswith("coord") else 0
    c_in, convs = cfg.input_shape[2], []
    for c in v.convs:
        convs.append(layers.init_conv(rng, 3, 3, c_in + coord, c, np.float32))
        c_in = c
    h, w = shapes(v)[-1]
    n_feat = h * w * c_in if v.readout.endswith("flat") else c_in
    if v.readout.endswith("linear"):
        head = [layers.init_dense(rng, n_feat, len(HEADS), np.float32)]
    else:
        head = [layers.init_dense(rng, n_feat, 256, np.float32),
                layers.init_dense(rng, 256, len(HEADS), np.float32)]
    return {"convs": convs, "head": head}


def forward(params: dict, x, v: Variant, coords: list, eng):
    """The heads ``(B, len(HEADS))`` (standardised regressions and presence logits)."""
    xp, nn = eng.xp, eng.nn
    h = x
    for k, layer in enumerate(params["convs"]):
        if coords:
            c = xp.broadcast_to(coords[k], (h.shape[0],) + coords[k].shape[1:])
            h = xp.concatenate([h, c], axis=-1)
        h = nn.relu(layers.conv(layer, h, nn, stride=2, padding=1))
    f = layers.flatten(h, xp) if v.readout.endswith("flat") else nn.global_avg_pool(h)
    for k, layer in enumerate(params["head"]):
        f = layers.dense(layer, f, xp)
        if k < len(params["head"]) - 1:
            f = nn.relu(f)
    return f


# --------------------------------------------------------------------------- training


def _frames(v: Variant, scenes: range) -> np.ndarray:
    return rasters.frames(v.config(), scenes)


def run(name: str, seed: int, steps: int | None = None) -> tuple[dict, dict[str, np.ndarray]]:
    """Train variant ``name`` with ``seed`` and score it (see the module docstring): the
    scores and the arrays to keep (predictions of each split, trained parameters)."""
    v = VARIANTS[name]
    cfg = v.config()
    eng = engine("jax")
    xp = eng.xp
    tg = L.targets(progress=False)
    Y, M = targets(cfg, tg)
    steps = steps or v.steps or STEPS
    train = np.concatenate([np.arange(r.start, r.stop) for r in v.train])
    X = np.concatenate([_frames(v, r) for r in v.train])
    T = X.shape[1]
    Yt, Mt = Y[train].reshape(-1, len(HEADS)), M[train].reshape(-1, len(HEADS))
    reg = np.array([h not in LOGITS for h in HEADS])
    mean = np.where(reg, (Yt * Mt).sum(0) / Mt.sum(0), 0.0)
    std = np.where(reg, np.sqrt(((Yt - mean) ** 2 * Mt).sum(0) / Mt.sum(0)), 1.0)
    std = np.maximum(std, 1e-6)
    Z = ((Y - mean) / std).astype(np.float32)
    coords = ([_coords(h, w, cfg) for h, w in shapes(v)[:-1]]
              if v.readout.startswith("coord") else [])
    rng = np.random.default_rng(seed)
    params = init(v, rng)
    state = optim.adam_init(params)
    is_logit = np.array([h in LOGITS for h in HEADS], dtype=np.float32)

    def loss_fn(p, x, z, m):
        out = forward(p, x, v, coords, eng)
        sq = (out - z) ** 2
        # logistic loss log(1 + e^-s) with s = (2y - 1) * logit, written stably
        s = (2.0 * z - 1.0) * out
        bce = xp.maximum(-s, 0.0) + xp.log(1.0 + xp.exp(-xp.abs(s)))
        per = is_logit * bce + (1.0 - is_logit) * sq
        return xp.sum(per * m) / x.shape[0]

    vg = eng.value_and_grad(loss_fn)

    def step(p, st, x, z, m, lr):
        loss, g = vg(p, x, z, m)
        g = scale_tree(g, xp.minimum(1.0, 5.0 / (global_norm(g, xp) + 1e-12)))
        p2, st2 = optim.adam_update(g, st, p, lr=lr)
        return like(p2, p, xp), like(st2, st, xp), loss

    step = eng.jit(step)
    Ztr, Mtr = Z[train].reshape(-1, len(HEADS)), M[train].reshape(-1, len(HEADS))
    t0 = time.perf_counter()
    losses = []
    for k in range(steps):
        i = rng.integers(0, len(Ztr), size=BATCH)
        x = to_input(np.asarray(X[i // T, i % T]), cfg)
        lr = np.float32(1e-3 * 0.5 * (1.0 + math.cos(math.pi * k / steps)))
        params, state, loss = step(params, state, x, Ztr[i], Mtr[i].astype(np.float32), lr)
        if k % 200 == 0 or k == steps - 1:
            losses.append(float(loss))
    train_s = time.perf_counter() - t0
    predict = eng.jit(lambda p, x: forward(p, x, v, coords, eng))
    out = {"variant": name, "seed": seed, "steps": steps, "config": asdict(v) | {
        "train": [[r.start, r.stop] for r in v.train], "raster_meta": cfg.as_meta()},
        "input_shape": list(cfg.input_shape), "train_seconds": train_s,
        "ms_per_step": 1e3 * train_s / steps, "losses": losses}
    arrays = {f"{part}.{k}.{key}": np.asarray(value) for part, group in params.items()
              for k, layer in enumerate(group) for key, value in layer.items()}
    for split, scenes in (("select", SELECT), ("validate", L.VALIDATE)):
        if np.isin(np.arange(scenes.start, scenes.stop), train).any():
            out[split] = None  # inside the training scenes: no selection number
            continue
        Xs = _frames(v, scenes)
        pred = []
        for a in range(0, len(scenes) * T, 256):
            j = np.arange(a, min(a + 256, len(scenes) * T))
            pred.append(np.asarray(predict(params, to_input(np.asarray(Xs[j // T, j % T]),
                                                            cfg))))
        P = np.concatenate(pred).reshape(len(scenes), T, len(HEADS)) * std + mean
        idx = np.arange(scenes.start, scenes.stop)
        out[split] = score(P, Y[idx], tg, idx, cfg)
        arrays[f"{split}_predictions"] = P.astype(np.float32)
    return out, arrays


# --------------------------------------------------------------------------- scores


def score(P: np.ndarray, Y: np.ndarray, tg: dict, idx: np.ndarray, cfg: RasterConfig) -> dict:
    """The study's numbers for predictions ``P`` of the states ``Y`` of scenes ``idx``."""
    ds_tags = _tags()
    h = {n: i for i, n in enumerate(HEADS)}
    F = {n: tg["features"][idx][..., i] for i, n in enumerate(L.FEATURES)}
    junction = np.array([ds_tags[s]["kind"] in ("intersection", "roundabout") for s in idx])
    junction = np.broadcast_to(junction[:, None], F["v"].shape)
    near = (F["has_leader"] > 0) & (F["gap"] <= NEAR)
    far = (Y[..., h["lead"]] > 0) & (F["gap"] > NEAR)
    t = np.broadcast_to(np.arange(F["v"].shape[1])[None], F["v"].shape)

    def rmse(k: str, m: np.ndarray) -> float:
        return float(np.sqrt(np.mean((P[..., h[k]][m] - Y[..., h[k]][m]) ** 2))) if m.any() \
            else math.nan

    lead_hat = P[..., h["lead"]] > 0
    stop_hat = P[..., h["has_stop"]] > 0
    return {
        "gap_rmse": rmse("gap", near), "dv_rmse": rmse("dv", near),
        "gap_rmse_road": rmse("gap", near & ~junction),
        "gap_rmse_junction": rmse("gap", near & junction),
        "gap_p90_abs": float(np.percentile(np.abs(P[..., h["gap"]] - Y[..., h["gap"]])[near],
                                           90)) if near.any() else math.nan,
        "dv_rmse_road": rmse("dv", near & ~junction),
        "dv_rmse_junction": rmse("dv", near & junction),
        "lead_accuracy": float(np.mean(lead_hat == (Y[..., h["lead"]] > 0))),
        "lead_recall_far": float(np.mean(lead_hat[far])) if far.any() else math.nan,
        "gap_rmse_far": rmse("gap", far),
        "v_rmse": rmse("v", t >= 2),
        "stop_accuracy": float(np.mean(stop_hat == (F["has_stop"] > 0))),
        "stop_rmse_near": rmse("stop", (F["has_stop"] > 0) & (F["stop"] <= NEAR)),
        "ahead_20_rmse": rmse("ahead_20", np.ones_like(near)),
        "n_near": int(near.sum()), "n_near_road": int((near & ~junction).sum()),
        "n_far": int(far.sum()),
    }


_TAGS: list = []


def _tags() -> list:
    if not _TAGS:
        _TAGS.extend(L.world().tags)
    return _TAGS


# --------------------------------------------------------------------------- report

COLUMNS = (("gap_rmse", "gap m", 2), ("dv_rmse_road", "dv road m/s", 2),
           ("dv_rmse", "dv all m/s", 2), ("lead_accuracy", "leader in view %", 1),
           ("v_rmse", "own speed m/s", 2), ("gap_rmse_far", "gap 30 m+ m", 1),
           ("lead_recall_far", "recall 30 m+ %", 1), ("stop_accuracy", "yield pt %", 1))


def report(split: str = "validate") -> str:
    runs: dict[str, list[dict]] = {}
    for path in sorted(RUNS.glob("*.json")):
        r = json.loads(path.read_text())
        runs.setdefault(r["variant"], []).append(r)
    head = "| variant | raster (H×W×C) | seeds | " + " | ".join(c[1] for c in COLUMNS) + " |"
    lines = [head, "|" + "---|" * (3 + len(COLUMNS))]
    for name in list(VARIANTS) + sorted(set(runs) - set(VARIANTS)):
        rs = runs.get(name)
        if not rs:
            continue
        if any(r[split] is None or _trained_on(r, SELECT if split == "select" else
                                               L.VALIDATE) for r in rs):
            continue  # this split is inside the variant's training scenes
        cells = []
        for key, _, digits in COLUMNS:
            vals = [r.get(key, r[split].get(key)) for r in rs]
            vals = [100 * x if key.endswith(("accuracy", "recall_far")) else x for x in vals]
            cells.append(" / ".join(f"{x:.{digits}f}" for x in vals))
        shape = "×".join(map(str, rs[0]["input_shape"]))
        lines.append(f"| {name} | {shape} | {len(rs)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _trained_on(run: dict, scenes: range) -> bool:
    """Whether ``run`` was trained on any of ``scenes`` (its ``train``: [start, stop] ranges,
    or one pair)."""
    t = run["config"]["train"]
    return any(a < scenes.stop and scenes.start < b
               for a, b in (t if isinstance(t[0], list) else [t]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", choices=sorted(VARIANTS), help="the variant to train")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=None,
                    help=f"Adam steps (default: the variant's, else {STEPS})")
    ap.add_argument("--report", action="store_true",
                    help="write results/perception.md from the cached runs")
    args = ap.parse_args()
    if args.report:
        t0 = time.perf_counter()
        text = ("# Perception by variant\n\n" + _protocol() + "\n## Validation (scenes 600–799)"
                "\n\n" + report("validate") + "\n## Selection (scenes 300–399)\n\n"
                + report("select"))
        provenance.publish(text, RESULTS / "perception.md", time.perf_counter() - t0)
        return
    if args.variant is None:
        ap.error("give --variant NAME (or --report)")
    RUNS.mkdir(parents=True, exist_ok=True)
    path = RUNS / f"{args.variant}_s{args.seed}.json"
    if path.exists():
        print(f"{path} exists: nothing to do")
        return
    out, arrays = run(args.variant, args.seed, args.steps)
    out["provenance"] = provenance.provenance()
    np.savez_compressed(path.with_suffix(".npz"), **arrays)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(out, indent=1, default=list))
    os.replace(tmp, path)
    print(json.dumps({k: out[k] for k in ("variant", "seed", "ms_per_step", "validate")},
                     indent=1))


def _protocol() -> str:
    return ("Train on scenes 0–299 (`scale`: 0–599; `xl`: 0–599 and 850–1649 of the "
            "2,000-scene draw of the same seed, 6000 steps) of the seed-0 draw, "
            f"{STEPS} Adam steps of batch {BATCH}, choose on scenes 300–399, report scenes "
            "600–799. Gap and closing speed (dv) for leaders within 30 m (`road`: scenes "
            "without a junction or roundabout); leader in view: accuracy of the presence "
            "head over all states; own speed for t ≥ 2; `gap 30 m+`, `recall 30 m+`: leaders "
            "beyond 30 m inside the view; `yield pt`: accuracy of whether there is a yield "
            "point. Several seeds: one number per seed.\n")


if __name__ == "__main__":
    main()
