"""Chapter 2 benchmark: one train step, NumPy engine vs JAX jit (prints, asserts nothing).

The step is forward + backward + Adam of the eq. 7 shape, a 3-conv network:
batch 32×64×64×3 (NHWC), three 3×3 convolutions with stride 2 and padding 1
(16, 32, 32 filters, ReLU), global average pooling, a linear layer to 2
outputs, mean squared error. The **same** model and step functions run on
both engines; only ``eng`` changes. Rounds are interleaved (numpy f32, jax
f32, numpy f64, jax f64, repeat) so that machine noise hits every variant
alike, and the median step time of each is reported with the ratio
NumPy / JAX (lower is better for NumPy).

    python benchmarks/bench_engine.py [--rounds 7] [--steps 5] [--batch 32] [--size 64]
                                      [--threads 1]

``--threads N`` gives OpenBLAS (NumPy) and XLA (JAX) N threads (default: the BLAS
default, and JAX's one XLA thread per process of :mod:`minimanc.engine`); it must be
applied before NumPy and JAX load, so this script reads it first. On a busy
shared machine a 2-thread BLAS waits for its second thread and single-threaded
runs are both faster and steadier.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from typing import Any


def _parse_args(argv: list[str]) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description="one train step: NumPy engine vs JAX jit")
    ap.add_argument("--rounds", type=int, default=7, help="interleaved rounds")
    ap.add_argument("--steps", type=int, default=5, help="timed steps per round and variant")
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--size", type=int, default=64, help="image height = width")
    ap.add_argument("--threads", type=int, default=None,
                    help="BLAS threads for NumPy and XLA threads for JAX")
    return ap.parse_args(argv)


ARGS = _parse_args(sys.argv[1:]) if __name__ == "__main__" else None
if ARGS is not None:
    from threads import set_threads  # benchmarks/threads.py, beside this script

    set_threads(ARGS.threads)

import numpy as np  # noqa: E402  (after the thread settings)

from minimanc import layers, optim  # noqa: E402
from minimanc.engine import get_engine  # noqa: E402
from minimanc.tree import tree_flatten  # noqa: E402


def init_params(rng: np.random.Generator, dtype: Any) -> dict:
    convs, c_in = [], 3
    for c_out in (16, 32, 32):
        convs.append(layers.init_conv(rng, 3, 3, c_in, c_out, dtype=dtype))
        c_in = c_out
    return {"convs": convs, "out": layers.init_dense(rng, c_in, 2, dtype=dtype)}


def model(params: dict, x: Any, eng: Any) -> Any:
    h = x
    for p in params["convs"]:
        h = eng.nn.relu(layers.conv(p, h, eng.nn, stride=2, padding=1))
    return layers.dense(params["out"], eng.nn.global_avg_pool(h), xp=eng.xp)


def make_step(eng: Any):
    def loss(params, x, y):
        return eng.xp.mean((model(params, x, eng) - y) ** 2)

    vg = eng.value_and_grad(loss)

    def step(params, state, x, y):
        value, grads = vg(params, x, y)
        params, state = optim.adam_update(grads, state, params, lr=1e-3)
        return params, state, value

    return eng.jit(step)


def _block(tree: Any) -> None:
    for leaf in tree_flatten(tree)[0]:
        if hasattr(leaf, "block_until_ready"):
            leaf.block_until_ready()


def main(args: argparse.Namespace) -> None:

    variants = []
    for dtype in (np.float32, np.float64):
        rng = np.random.default_rng(0)
        params = init_params(rng, dtype)
        x = rng.random((args.batch, args.size, args.size, 3)).astype(dtype)
        y = rng.standard_normal((args.batch, 2)).astype(dtype)
        for name in ("numpy", "jax"):
            eng = get_engine(name)
            step = make_step(eng)
            data, p0 = eng.device_put((x, y)), eng.device_put(params)
            state = optim.adam_init(p0)
            t0 = time.perf_counter()
            out = step(p0, state, *data)  # warm-up (JAX compiles here)
            _block(out)
            first = time.perf_counter() - t0
            variants.append({"name": name, "dtype": np.dtype(dtype).name, "step": step,
                             "carry": out[:2], "data": data, "first": first, "times": [],
                             "cpu": [], "loss0": float(out[2])})

    for _ in range(args.rounds):
        for v in variants:
            params, state = v["carry"]
            for _ in range(args.steps):
                t0, c0 = time.perf_counter(), time.process_time()
                params, state, loss = v["step"](params, state, *v["data"])
                _block((params, loss))
                v["times"].append(time.perf_counter() - t0)
                v["cpu"].append(time.process_time() - c0)
            v["carry"] = (params, state)
            v["loss"] = float(loss)

    print(f"one train step: batch {args.batch}x{args.size}x{args.size}x3, 3 conv 3x3/s2 "
          f"(16-32-32) + ReLU + GAP + linear + MSE + Adam; {args.rounds} rounds x "
          f"{args.steps} steps, interleaved; threads: "
          f"{'default' if args.threads is None else args.threads}; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    med, med_cpu = {}, {}
    for v in variants:
        m = statistics.median(v["times"]) * 1e3
        med[(v["name"], v["dtype"])] = m
        med_cpu[(v["name"], v["dtype"])] = statistics.median(v["cpu"]) * 1e3
        print(f"  {v['name']:5s} {v['dtype']:7s}  median {m:7.1f} ms   min "
              f"{min(v['times']) * 1e3:7.1f} ms   CPU {med_cpu[(v['name'], v['dtype'])]:7.1f} ms"
              f"   first call {v['first'] * 1e3:7.0f} ms   "
              f"loss {v['loss0']:.6f} -> {v['loss']:.6f}")
    for dt in ("float32", "float64"):
        print(f"  ratio numpy/jax {dt}: {med[('numpy', dt)] / med[('jax', dt)]:.2f}  (CPU time "
              f"{med_cpu[('numpy', dt)] / med_cpu[('jax', dt)]:.2f})")
    l64 = [v["loss0"] for v in variants if v["dtype"] == "float64"]
    print(f"  float64 first-step loss, numpy - jax: {l64[0] - l64[1]:.2e}")


if __name__ == "__main__":
    main(ARGS)
