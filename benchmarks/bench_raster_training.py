"""Chapters 7–8 benchmark: what the learner's raster costs to train on and to drive with
(prints, never asserts).

Three rasters side by side in one process (:data:`RASTERS`: the paper's RGB 64×64, the
learner's binary channels at 64×64×12, and the channels in the 60 m corridor, 90×64×12),
each drawn for the same scenes (:func:`minimanc.world.generate`, ``--scenes`` of seed 0),
every measurement repeated in interleaved rounds so that the shared machine's load hits
all alike; medians of wall and CPU time, the ratios of CPU time (with one XLA thread, the
library's default, CPU time is the work done whatever else runs). Printed with the load
average.

1. **Training step** of each model of ``--models`` (batch 64 in its window setup,
   :func:`minimanc.train.batches`; float32; JAX), without and with the masked auxiliary
   perception loss (λ = ``perception_weight`` = 1, :mod:`minimanc.train.perception`):
   the host's batch (:func:`minimanc.train.fit.step_batch`: indexing, casts, the
   perception targets) and the jitted step (:func:`minimanc.train.make_step`: forward,
   backward, Adam). For a channels raster also the batch the host unpacks to float32
   planes (:func:`minimanc.world.encodings.to_input`, as training did before the batch kept
   the packed bytes for the step to unpack: :func:`minimanc.train.batches.make_batch`), the
   same step on it, and whether both steps give the same parameters bit for bit.
2. **Closed-loop step** of 8 scenes (:data:`minimanc.rollout.log.BATCH_SIZE`): the
   observation re-rendered from the poses with the history
   (:func:`minimanc.inputs.from_state`) and the policy's jitted step
   (:class:`minimanc.rollout.ModelPolicy`).

    python benchmarks/bench_raster_training.py [--scenes 40] [--rounds 5] [--steps 6]
                                               [--models cnn manc] [--threads 1] [--quick]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=40, help="generated scenes per raster")
    ap.add_argument("--rounds", type=int, default=None, help="interleaved rounds (5; quick 2)")
    ap.add_argument("--steps", type=int, default=6, help="training steps per round")
    ap.add_argument("--models", nargs="+", default=["cnn", "manc"],
                    help="models to train and drive (any of minimanc.models.NAMES)")
    ap.add_argument("--threads", type=int, default=None,
                    help="BLAS threads for NumPy; 1 also makes XLA single-threaded")
    ap.add_argument("--quick", action="store_true", help="2 rounds of 3 steps, 16 scenes")
    return ap.parse_args(argv)


ARGS = _parse_args(sys.argv[1:]) if __name__ == "__main__" else None
if ARGS is not None:
    from threads import set_threads  # benchmarks/threads.py, beside this script

    set_threads(ARGS.threads)

import numpy as np  # noqa: E402  (after the thread settings)

from minimanc import engine, inputs, models, train, world  # noqa: E402
from minimanc.diagnose import perception_targets  # noqa: E402
from minimanc.rollout import BATCH_SIZE, ModelPolicy  # noqa: E402
from minimanc.train.fit import start_run, step_batch, with_perception  # noqa: E402
from minimanc.tree import leaves  # noqa: E402
from minimanc.world.encodings import to_input  # noqa: E402
from minimanc.world.history import latest_history  # noqa: E402

RASTERS = {
    "RGB 64x64x3": world.RasterConfig(),
    "channels 64x64x12": world.RasterConfig(encoding="channels", route=True, history=2),
    "channels 90x64x12 (60 m)": world.RasterConfig.from_extent(
        60.0, 25.0, 50 / 64, encoding="channels", route=True, history=2),
}
"""The paper's raster, the learner's channels in the paper's view, the channels in the 60 m
corridor (``research/seeing_the_leader/perception.py``'s ``ROUTE60``)."""


def interleaved(fns: dict, rounds: int) -> dict:
    """``{key: (wall s, CPU s)}``: medians over ``rounds`` in which each function of no
    argument runs once in turn (each called once before, to compile and warm up)."""
    for fn in fns.values():
        fn()
    wall: dict = {k: [] for k in fns}
    cpu: dict = {k: [] for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            wall[k].append(time.perf_counter() - t0)
            cpu[k].append(time.process_time() - c0)
    return {k: (statistics.median(wall[k]), statistics.median(cpu[k])) for k in fns}


def host_unpacked(batch: dict, ds, s_idx: np.ndarray, t_idx: np.ndarray) -> dict:
    """``batch`` with its packed ``bev`` unpacked on the host to float32 planes, as the
    batches were made before they kept the packed bytes."""
    return {**batch, "bev": to_input(ds.bev[s_idx, t_idx], ds.raster).astype(np.float32)}


class Training:
    """One model's training steps on one raster, with λ = ``weight``: the host's batches
    (``prepare``) and the jitted steps on batches made before (``run``), from the same
    initial parameters each round."""

    def __init__(self, name: str, ds, targets, weight: float, steps: int, host: bool):
        self.eng = engine("jax")
        cfg = train.config_for_data(models.ModelConfig(), ds)
        tc = train.TrainConfig(batch_size=64, dtype="float32", perception_weight=weight)
        self.st = start_run(name, ds, cfg, tc)
        with_perception(self.st, targets if weight else None, ds)
        self.plan = train.batches(name, ds, self.st.scenes, tc, epoch=0)[:steps]
        self.ds, self.host = ds, host
        self.step = train.make_step(name, cfg, tc, self.eng, 1.0 / self.st.std)
        self.batches = self.prepare()
        self.params = None

    def prepare(self) -> list[dict]:
        rng = np.random.default_rng(0)
        out = []
        for s, t in self.plan:
            b = step_batch(self.st, self.ds, s, t, rng)
            out.append(host_unpacked(b, self.ds, s, t) if self.host else b)
        return out

    def run(self) -> None:
        p, o = self.eng.device_put(self.st.params), self.eng.device_put(self.st.opt_state)
        for b in self.batches:
            p, o, loss = self.step(p, o, b)
        float(loss)
        self.params = p


def closed_loop(name: str, ds):
    """Observation and policy step of one closed-loop step of 8 scenes at t = 12, as two
    functions of no argument."""
    idx, t = np.arange(BATCH_SIZE), 12
    cfg = train.config_for_data(models.ModelConfig(), ds)
    past = None
    if ds.raster.history:
        past = latest_history(np.asarray(ds.ego[idx, :t + 1], np.float64),
                              np.asarray(ds.ado[idx, :t + 1], np.float64),
                              np.asarray(ds.ado_valid[idx, :t + 1]), ds.raster.history)
    maps = [ds.maps[i] for i in idx]

    def observe() -> dict:
        return inputs.from_state(maps, np.asarray(ds.ego[idx, t], np.float64),
                                 np.asarray(ds.ado[idx, t], np.float64),
                                 np.asarray(ds.ado_valid[idx, t]),
                                 np.asarray(ds.ego[idx, -1], np.float64), ds.raster,
                                 cfg.setting, motion=np.zeros((BATCH_SIZE, 2), np.float32),
                                 model=models.get(name), history=past)

    policy = ModelPolicy(name, models.init(name, np.random.default_rng(0), cfg), cfg, "jax")
    obs, state = observe(), policy.initial_state(idx)
    return observe, lambda: policy(obs, state, t, idx)


def _ms(x: tuple[float, float]) -> str:
    return f"{1e3 * x[0]:7.1f} ({1e3 * x[1]:6.1f})"


def main(args: argparse.Namespace) -> None:
    rounds = args.rounds or (2 if args.quick else 5)
    steps = 3 if args.quick else args.steps
    n = 16 if args.quick else args.scenes
    data = {r: world.generate(n, seed=0, raster=cfg, workers=1) for r, cfg in RASTERS.items()}
    runs, prep = {}, {}
    for r, ds in data.items():
        targets = perception_targets(ds)
        for name in args.models:
            for weight in (0.0, 1.0):
                hosts = (False, True) if ds.raster.encoding == "channels" else (False,)
                for host in hosts:
                    tr = Training(name, ds, targets, weight, steps, host)
                    runs[r, name, weight, host] = tr
                    prep[r, name, weight, host] = tr.prepare
    step_t = interleaved({k: tr.run for k, tr in runs.items()}, rounds)
    prep_t = interleaved(prep, rounds)
    load = os.getloadavg()[0]
    print(f"Training step, batch 64, float32, JAX ({rounds} interleaved rounds x {steps} "
          f"steps on {n} scenes, medians; ms per step, wall (CPU); XLA threads "
          f"{os.environ.get('MINIMANC_XLA_THREADS', 'default 1')}; load average {load:.1f} "
          f"on {os.cpu_count()} CPUs):")
    print(f"  {'raster':26s} {'model':9s} {'λ':>3s} {'batch':>7s} {'':8s} {'step':>7s} {'':8s}"
          f" {'total':>7s} {'':8s}  batch unpacked on the host: {'batch':>7s} {'':8s} "
          f"{'total':>7s} {'':8s} same params")
    base = {}
    for r in RASTERS:
        for name in args.models:
            for weight in (0.0, 1.0):
                k = (r, name, weight, False)
                p, s = [x / steps for x in prep_t[k]], [x / steps for x in step_t[k]]
                tot = (p[0] + s[0], p[1] + s[1])
                base.setdefault((name, weight), tot)
                line = (f"  {r:26s} {name:9s} {weight:3.0f} {_ms(p)} {_ms(s)} {_ms(tot)}"
                        f"  x{tot[1] / base[name, 0.0][1]:4.1f}")
                h = (r, name, weight, True)
                if h in runs:
                    hp, hs = [x / steps for x in prep_t[h]], [x / steps for x in step_t[h]]
                    htot = (hp[0] + hs[0], hp[1] + hs[1])
                    same = all(np.array_equal(np.asarray(a), np.asarray(b)) for a, b in
                               zip(leaves(runs[k].params), leaves(runs[h].params)))
                    line += (f"  {_ms(hp)} {_ms(htot)} x{htot[1] / tot[1]:4.2f} of now, "
                             f"{'identical' if same else 'DIFFERENT'}")
                print(line)
    print("  (x: CPU time of batch + step against the model's RGB one without λ; 'of now': "
          "the host-unpacked batch's CPU time against today's; with one XLA thread CPU time "
          "is the work done, wall time also what the shared machine's load adds)")
    loop = {}
    for r, ds in data.items():
        for name in args.models:
            observe, act = closed_loop(name, ds)
            loop[r, name, "observe"], loop[r, name, "act"] = observe, act
    loop_t = interleaved(loop, rounds * 4)
    print(f"Closed-loop step of {BATCH_SIZE} scenes (observation rendered with its history, "
          f"then the policy's jitted step; ms, wall (CPU); {rounds * 4} interleaved rounds; "
          f"load average {os.getloadavg()[0]:.1f}):")
    for r in RASTERS:
        for name in args.models:
            o, a = loop_t[r, name, "observe"], loop_t[r, name, "act"]
            print(f"  {r:26s} {name:9s} observe {_ms(o)}  act {_ms(a)}  total "
                  f"{_ms((o[0] + a[0], o[1] + a[1]))}")


if __name__ == "__main__":
    main(ARGS)
