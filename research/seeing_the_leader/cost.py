"""What the learner's raster costs: time per training step and per closed-loop step, and the
paper preset's budget (``minimanc reproduce --preset paper``: 83 min on 2 cores today with the
64 × 64 RGB raster; it must stay ≤ 90 min).

Measured in one process, one XLA thread, float32, JAX:

1. **Training step** of each model the paper preset trains (batch 64 and its window setup:
   :func:`minimanc.train.batches`, Algorithm 1's step :func:`minimanc.train.make_step`) on
   today's raster; the models cannot read another raster yet, so the new raster's step is
   that time plus the difference of the backbone's forward and backward pass on the same
   number of frames (the heads, vAGN and the DMP do not see the raster).
2. **Closed-loop step** of a batch of 8 scenes (:data:`minimanc.rollout.log.BATCH_SIZE`): the
   observation re-rendered from the policy's poses with its history
   (:func:`minimanc.inputs.from_state`) plus the backbone's forward pass on 8 frames.
3. **The paper preset**: :func:`minimanc.studies.config.plan` counts its trainings and
   closed-loop rollouts; the time they take at the measured step costs, scaled so that
   today's raster gives the 83 min measured (``results/paper-paper/table1.md``), is the budget
   the new raster would need.

Run: ``python research/seeing_the_leader/cost.py`` (writes ``results/cost.md``);
``--quick`` for fewer repetitions.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import leader_data as L
import numpy as np

from minimanc import engine, inputs, layers, models, optim, train
from minimanc.studies import provenance
from minimanc.studies.config import PRESETS, plan
from minimanc.train.step import like
from minimanc.world import RasterConfig
from minimanc.world.history import latest_history

RESULTS = Path(__file__).resolve().parent / "results"
PAPER_MINUTES = 83.3
"""Wall time of ``minimanc reproduce --preset paper`` with the 64 × 64 RGB raster
(``results/paper-paper/table1.md``)."""
PAPER_FIXED_S = 44.4 + 15.4 + 63.6 + 70.1
"""Of which data, figures, the modes study and the reference rows (``results/paper-paper/
results.json``, ``timing_s``): not training nor the learned models' closed loop."""
RASTERS = {
    "today: RGB 64×64 (40 m × ±25 m, 0.78 m/px)": RasterConfig(),
    "channels 60 m × ±25 m, 0.78 m/px, history 2, route":
        RasterConfig.from_extent(60.0, 25.0, 50 / 64, encoding="channels", history=2, route=True),
    "channels 60 m × ±20 m, 0.78 m/px, history 2, route":
        RasterConfig.from_extent(60.0, 20.0, 50 / 64, encoding="channels", history=2, route=True),
    "channels 60 m × ±16 m, 0.78 m/px, history 2, route":
        RasterConfig.from_extent(60.0, 16.0, 50 / 64, encoding="channels", history=2, route=True),
    "channels 60 m × ±25 m, 0.5 m/px, history 2, route":
        RasterConfig.from_extent(60.0, 25.0, 0.5, encoding="channels", history=2, route=True),
}
BACKBONES = {"course (16, 32, 32) + GAP": ((16, 32, 32), "gap"),
             "perception (32, 64, 64, 64) + flat": ((32, 64, 64, 64), "flat")}
CLOSED_LOOP_BATCH = 8


def interleaved(fns: dict, reps: int) -> dict:
    """CPU seconds per call of each function of ``fns`` (name → function of no argument):
    each called once to compile and warm up, then ``reps`` rounds in which every function
    runs once in turn; the median of its rounds. CPU time (this process's, all its threads)
    is the work done: with one XLA thread it hardly depends on what else the shared machine
    runs, which wall time does."""
    for fn in fns.values():
        fn()
    times: dict = {k: [] for k in fns}
    for _ in range(reps):
        for k, fn in fns.items():
            t0 = time.process_time()
            fn()
            times[k].append(time.process_time() - t0)
    return {k: float(np.median(v)) for k, v in times.items()}


def backbone_fn(shape: tuple[int, int, int], convs: tuple[int, ...], readout: str,
                frames: int, grad: bool):
    """The backbone's forward (and backward, ``grad``) pass on ``frames`` rasters of
    ``shape``, compiled: a function of no argument that waits for its result."""
    eng = engine("jax")
    rng = np.random.default_rng(0)
    params, c_in = [], shape[2]
    for c in convs:
        params.append(layers.init_conv(rng, 3, 3, c_in, c, np.float32))
        c_in = c

    def f(p, x):
        h = x
        for layer in p:
            h = eng.nn.relu(layers.conv(layer, h, eng.nn, stride=2, padding=1))
        out = layers.flatten(h, eng.xp) if readout == "flat" else eng.nn.global_avg_pool(h)
        return eng.xp.sum(out ** 2)

    fn = eng.jit(eng.value_and_grad(f) if grad else f)
    x = (np.random.default_rng(1).random((frames,) + shape) < 0.2).astype(np.float32)
    return lambda: np.asarray(fn(params, x)[0] if grad else fn(params, x))


def train_step_fn(name: str, ds):
    """One training step of model ``name`` on today's raster (batch 64 in its window setup),
    as a function of no argument, and the frames a step reads."""
    eng = engine("jax")
    cfg = train.config_for_data(models.ModelConfig(), ds)
    tc = train.TrainConfig(batch_size=64, dtype="float32")
    s, t = train.batches(name, ds, np.arange(len(ds)), tc, epoch=0)[0]
    batch = train.make_batch(name, ds, s, t, cfg, np.float32)
    q0 = train.initial_q(name, s.shape[1], cfg, tc, np.random.default_rng(0), np.float32)
    if q0 is not None:
        batch["q0"] = q0
    params = models.init(name, np.random.default_rng(0), cfg, dtype=np.float32)
    opt = optim.adam_init(params)
    step = train.make_step(name, cfg, tc, eng, 1.0 / train.control_std(ds))
    state = {"p": params, "o": opt}

    def go() -> None:
        p, o, loss = step(state["p"], state["o"], batch)
        float(loss)
        state["p"], state["o"] = like(p, params, eng.xp), like(o, opt, eng.xp)

    return go, int(s.size)


def render_fn(ds, cfg: RasterConfig):
    """Building the observation of one closed-loop step of 8 scenes (re-rendered from the
    poses, with the recorded history), as a function of no argument."""
    idx = np.arange(CLOSED_LOOP_BATCH)
    t = 12
    poses = np.asarray(ds.ego[idx, t], dtype=np.float64)
    ado, valid = np.asarray(ds.ado[idx, t], dtype=np.float64), np.asarray(ds.ado_valid[idx, t])
    past = None
    if cfg.history:
        past = latest_history(np.asarray(ds.ego[idx, :t + 1], np.float64),
                              np.asarray(ds.ado[idx, :t + 1], np.float64),
                              np.asarray(ds.ado_valid[idx, :t + 1]), cfg.history)
    maps = [ds.maps[i] for i in idx]
    goal = np.asarray(ds.ego[idx, -1], dtype=np.float64)
    motion = np.zeros((CLOSED_LOOP_BATCH, 2), np.float32)
    return lambda: inputs.from_state(maps, poses, ado, valid, goal, cfg, motion=motion,
                                     keys=("bev", "lane_target"), history=past)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repetitions")
    ap.add_argument("--out", default=str(RESULTS / "cost.md"))
    args = ap.parse_args()
    reps = 5 if args.quick else 20
    t_start = time.perf_counter()
    full = L.world()
    ds = full.subset(slice(0, 40))
    names = sorted({m for m, _ in plan(PRESETS["paper"])["train"]})
    made = {name: train_step_fn(name, ds) for name in names}
    secs = interleaved({name: fn for name, (fn, _) in made.items()}, reps)
    steps = {name: (secs[name], made[name][1]) for name in names}
    lines = ["# What the learner's raster costs\n",
             "One process, one XLA thread, float32, JAX; each figure the median CPU time "
             f"of {reps} interleaved repetitions (the work done, whatever else the shared "
             "2-core machine runs).\n",
             "## Backbone forward + backward, per training step (ms)\n",
             "| raster | input H×W×C | " + " | ".join(
                 f"{b}, {n} frames" for b in BACKBONES for n in (40, 64)) + " |",
             "|---|---|" + "---|" * (2 * len(BACKBONES))]
    bb = interleaved({(r, b, n): backbone_fn(cfg.input_shape, c, ro, n, True)
                      for r, cfg in RASTERS.items() for b, (c, ro) in BACKBONES.items()
                      for n in (40, 64)}, reps)
    for rname, cfg in RASTERS.items():
        cells = [f"{1e3 * bb[rname, b, n]:.0f}" for b in BACKBONES for n in (40, 64)]
        lines.append(f"| {rname} | {'×'.join(map(str, cfg.input_shape))} | "
                     + " | ".join(cells) + " |")
    lines += ["", "## Training step of each model (ms; batch 64 in its window setup)\n",
              "Today's raster measured; the others = today's + the backbone's difference on "
              "the same frames (course backbone).\n",
              "| model | frames/step | " + " | ".join(RASTERS) + " |",
              "|---|---|" + "---|" * len(RASTERS)]
    base = next(iter(RASTERS))
    course = next(iter(BACKBONES))
    step_ms: dict = {}
    for name, (sec, frames) in steps.items():
        n = 40 if frames <= 40 else 64
        cells = []
        for rname in RASTERS:
            s = sec + bb[rname, course, n] - bb[base, course, n]
            step_ms[name, rname] = s
            cells.append(f"{1e3 * s:.0f}")
        lines.append(f"| {name} | {frames} | " + " | ".join(cells) + " |")
    # closed loop
    lines += ["", "## Closed-loop step, 8 scenes (ms)\n",
              "| raster | observation (render + lane targets) | course backbone forward | "
              "perception backbone forward | total (course) |", "|---|---|---|---|---|"]
    render = interleaved({r: render_fn(full, cfg) for r, cfg in RASTERS.items()}, reps)
    fwd = interleaved({(r, b): backbone_fn(cfg.input_shape, c, ro, CLOSED_LOOP_BATCH, False)
                       for r, cfg in RASTERS.items() for b, (c, ro) in BACKBONES.items()},
                      reps)
    cl: dict = {}
    for rname in RASTERS:
        cl[rname] = render[rname] + fwd[rname, course]
        lines.append(f"| {rname} | {1e3 * render[rname]:.1f} | "
                     f"{1e3 * fwd[rname, course]:.1f} | "
                     f"{1e3 * fwd[rname, list(BACKBONES)[1]]:.1f} | {1e3 * cl[rname]:.1f} |")
    # the paper preset
    c = PRESETS["paper"]
    p = plan(c)
    tc = train.TrainConfig()
    per_epoch = {}
    for (name, frac), _ in p["train"].items():
        n = int(round(frac * c.n_train))
        per_epoch[name, frac] = len(train.batches(name, full.subset(slice(0, n)),
                                                  np.arange(n), tc, epoch=0))
    T = full.ego.shape[1]
    cl_steps = (p["rollouts"]["tune"] * -(-c.n_tune // CLOSED_LOOP_BATCH)
                + p["rollouts"]["val"] * -(-c.n_val // CLOSED_LOOP_BATCH)) * (T - 1)
    budget = {}
    for rname in RASTERS:
        tr = sum(k * c.epochs * per_epoch[m, f] * step_ms[m, rname]
                 for (m, f), k in p["train"].items())
        budget[rname] = (tr, cl_steps * cl[rname])
    scale = (PAPER_MINUTES * 60 - PAPER_FIXED_S) / sum(budget[base])
    lines += ["", "## The paper preset (`minimanc reproduce --preset paper`)\n",
              f"{sum(p['train'].values())} trainings of {c.epochs} epochs, "
              f"{cl_steps} closed-loop steps of 8 scenes. Modelled CPU time (one process) "
              f"of training and closed loop, and the wall time: {PAPER_FIXED_S / 60:.1f} min "
              f"of data, figures and reference rows plus the modelled time scaled so that "
              f"today's raster gives the {PAPER_MINUTES} min measured (scale {scale:.2f}).\n",
              "| raster | training (CPU min) | closed loop (CPU min) | projected wall time "
              "(min) |", "|---|---|---|---|"]
    for rname, (tr, cl_s) in budget.items():
        lines.append(f"| {rname} | {tr / 60:.0f} | {cl_s / 60:.0f} | "
                     f"{(PAPER_FIXED_S + scale * (tr + cl_s)) / 60:.0f} |")
    provenance.publish("\n".join(lines) + "\n", args.out, time.perf_counter() - t_start)


if __name__ == "__main__":
    main()
