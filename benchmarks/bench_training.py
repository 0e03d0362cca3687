"""Chapter 8 benchmark: MANC training speed on both engines, inference latency, one full training.

Prints figures, asserts nothing:

1. **Train steps/s** of MANC (forward + backward + Adam, Algorithm 1) on
   minibatches of the default data (64×64 BEV, float32), our NumPy engine
   versus JAX jit, rounds interleaved so machine noise hits both alike;
   medians and the ratio NumPy time / JAX time.
2. **Inference latency** of one MANC control step (:func:`minimanc.models.step`)
   at batch 1 under JAX jit (target ≤ 1 ms), median of many calls.
3. **One full MANC training** on the default data (650 training scenes × 40
   steps, :class:`minimanc.train.TrainConfig` defaults) with JAX (target ≤ 3
   min), then its open-loop validation loss on the 200 validation scenes.

    python benchmarks/bench_training.py [--quick] [--rounds 5] [--steps 5] [--batch 64]
                                        [--steps-only] [--threads 1]

``--quick``: fewer rounds and a one-epoch training on 100 scenes; ``--steps-only``:
part 1 alone; ``--threads 1`` runs OpenBLAS (NumPy) and XLA (JAX) single-threaded
(set before NumPy and JAX load, so this script reads it first: on a busy shared
machine a 2-thread BLAS waits for its second thread). The data come
from :func:`minimanc.world.generate_splits` with ``cache=True`` (generated once,
several minutes; then loaded in seconds).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short runs (minutes -> seconds)")
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument("--steps", type=int, default=5)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--steps-only", action="store_true",
                    help="only the train-step comparison (part 1)")
    ap.add_argument("--threads", type=int, default=None,
                    help="BLAS threads for NumPy; 1 also makes XLA single-threaded")
    return ap.parse_args(argv)


ARGS = _parse_args(sys.argv[1:]) if __name__ == "__main__" else None
if ARGS is not None:
    from threads import set_threads  # benchmarks/threads.py, beside this script

    set_threads(ARGS.threads)

import numpy as np  # noqa: E402  (after the thread settings)

from minimanc import engine, inputs, models, optim, train, world  # noqa: E402


def _batches(name, ds, cfg, tc, n):
    plan = train.batches(name, ds, np.arange(len(ds)), tc, epoch=0)[:n]
    rng = np.random.default_rng(0)
    out = []
    for s, t in plan:
        b = train.make_batch(name, ds, s, t, cfg, np.float32)
        q0 = train.initial_q(name, s.shape[1], cfg, tc, rng, np.float32)
        if q0 is not None:
            b["q0"] = q0
        out.append(b)
    return out


def bench_steps(ds, cfg, batch: int, rounds: int, steps: int) -> None:
    name = "manc"
    tc = train.TrainConfig(batch_size=batch, dtype="float32")
    data = _batches(name, ds, cfg, tc, steps)
    inv = 1.0 / train.control_std(ds)
    state = {}
    for e in ("numpy", "jax"):
        eng = engine(e)
        params = models.init(name, np.random.default_rng(0), cfg, dtype=np.float32)
        opt = optim.adam_init(params)
        fn = train.make_step(name, cfg, tc, eng, inv)
        t0 = time.perf_counter()
        params, opt, loss = fn(params, opt, data[0])  # JAX compiles here
        float(loss)
        state[e] = [fn, params, opt, time.perf_counter() - t0, [], []]
    for _ in range(rounds):
        for e in ("numpy", "jax"):
            fn, params, opt, _, times, cpu = state[e]
            t0, c0 = time.perf_counter(), time.process_time()
            for b in data:
                params, opt, loss = fn(params, opt, b)
            float(loss)  # wait for JAX's asynchronous dispatch
            times.append((time.perf_counter() - t0) / len(data))
            cpu.append((time.process_time() - c0) / len(data))
            state[e][1], state[e][2] = params, opt
    med = {e: statistics.median(state[e][4]) for e in state}
    med_cpu = {e: statistics.median(state[e][5]) for e in state}
    print(f"MANC train step, batch {batch}x{'x'.join(map(str, cfg.bev_shape))} float32 "
          f"({rounds} rounds x {steps} steps, medians; threads: "
          f"{os.environ.get('OPENBLAS_NUM_THREADS', 'default')}; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs):")
    for e in ("numpy", "jax"):
        print(f"  {e:5s}: {1e3 * med[e]:7.1f} ms/step  {1.0 / med[e]:6.1f} steps/s"
              f"  (CPU {1e3 * med_cpu[e]:7.1f} ms/step; first call {state[e][3]:.1f} s)")
    print(f"  ratio numpy/jax time: {med['numpy'] / med['jax']:.2f}  (CPU time: "
          f"{med_cpu['numpy'] / med_cpu['jax']:.2f}; with --threads 1 CPU time is the work "
          "done, whatever the other load on the machine)")


def bench_latency(ds, cfg, calls: int) -> None:
    eng = engine("jax")
    params = models.init("manc", np.random.default_rng(0), cfg, dtype=np.float32)
    obs = inputs.from_dataset(ds, 0, 5, model=models.get("manc"))
    obs = {k: v.astype(np.float32) for k, v in obs.items()}
    state = models.initial_state("manc", 1, cfg)
    step = eng.jit(lambda p, o, s: models.step("manc", p, o, s, cfg, eng)[:2])
    t0 = time.perf_counter()
    out, _ = step(params, obs, state)
    out.block_until_ready()
    compile_s = time.perf_counter() - t0
    times = []
    for _ in range(calls):
        t0 = time.perf_counter()
        out, state = step(params, obs, state)
        out.block_until_ready()
        times.append(time.perf_counter() - t0)
    print(f"MANC inference, one control step at batch 1 (JAX jit, {calls} calls): "
          f"median {1e3 * statistics.median(times):.3f} ms, "
          f"p90 {1e3 * float(np.percentile(times, 90)):.3f} ms (target <= 1 ms; "
          f"compile {compile_s:.1f} s)")


def bench_training(train_ds, val_ds, cfg, quick: bool) -> None:
    tc = train.TrainConfig(epochs=1) if quick else train.TrainConfig()
    ds = train_ds.subset(slice(0, 100)) if quick else train_ds
    t0 = time.perf_counter()
    res = train.fit("manc", ds, cfg, tc, engine="jax", progress=False)
    secs = time.perf_counter() - t0
    val = train.open_loop_loss("manc", res.params, val_ds, cfg, engine="jax", std=res.control_std)
    print(f"MANC full training (JAX): {len(ds)} scenes x {ds.ego.shape[1]} steps, "
          f"{tc.epochs} epochs, batch {tc.batch_size}: {res.steps} steps in {secs:.0f} s "
          f"({res.steps / secs:.1f} steps/s; target <= 180 s for 650 scenes)")
    print("  training loss per epoch: " + ", ".join(f"{h:.4f}" for h in res.history))
    print(f"  open-loop validation loss (normalised MSE, {len(val_ds)} scenes): {val:.4f}")
    print(f"  parameters: {models.param_count(res.params)}")


def main(args: argparse.Namespace) -> None:
    rounds = args.rounds or (2 if args.quick else 5)
    train_ds, val_ds = world.generate_splits(650, 200, seed=0, cache=True, progress=True)
    cfg = models.ModelConfig()
    print(f"data: {train_ds}")
    bench_steps(train_ds, cfg, args.batch, rounds, args.steps)
    if args.steps_only:
        return
    bench_latency(train_ds, cfg, 100 if args.quick else 500)
    bench_training(train_ds, val_ds, cfg, args.quick)


if __name__ == "__main__":
    main(ARGS)
