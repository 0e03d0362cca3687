"""Chapter 11 benchmark: what DAgger's rounds cost, trained from the start each round (as Ross
et al.) or continuing from the previous round (``dagger``'s ``round_cfg``), beside behaviour
cloning on the same pool (prints, never asserts).

The three run side by side in one process on one pool (``--scenes`` of seed 0, the learner's
raster :data:`minimanc.studies.config.LEARNER_RASTER`), in interleaved repeats; per way its
median wall and CPU time, the gradient steps it took in all rounds and the ratio of CPU time
to behaviour cloning's. With one XLA thread (``--threads 1``) CPU time is the work done
whatever else the machine runs.

    python benchmarks/bench_dagger.py [--scenes 33] [--rounds 10] [--epochs 6] [--model cnn]
                                      [--repeats 2] [--threads 1]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=33, help="pool scenes (generated, seed 0)")
    ap.add_argument("--rounds", type=int, default=10, help="DAgger rounds after round 0")
    ap.add_argument("--epochs", type=int, default=6, help="epochs of BC and of round 0")
    ap.add_argument("--model", default="cnn", help="a registered model")
    ap.add_argument("--repeats", type=int, default=2, help="interleaved repeats")
    ap.add_argument("--threads", type=int, default=None,
                    help="BLAS threads for NumPy; 1 also makes XLA single-threaded")
    return ap.parse_args(argv)


ARGS = _parse_args(sys.argv[1:]) if __name__ == "__main__" else None
if ARGS is not None:
    from threads import set_threads  # benchmarks/threads.py, beside this script

    set_threads(ARGS.threads)

from dataclasses import replace  # noqa: E402

from minimanc import dagger, train, world  # noqa: E402
from minimanc.studies.config import LEARNER_RASTER  # noqa: E402


def run_way(way: str, pool: world.Dataset, args: argparse.Namespace) -> tuple[float, float, int]:
    """One training of ``way`` ("bc", "scratch", "warm"): wall s, CPU s, gradient steps."""
    tc = train.TrainConfig(epochs=args.epochs, batch_size=64, lr=1e-3)
    cfg = dagger.default_config(pool)
    w0, c0 = time.perf_counter(), time.process_time()
    if way == "bc":
        steps = train.fit(args.model, pool, cfg, tc, progress=False).steps
    else:
        teacher = dagger.WorldTeacher(pool, agents="reactive")
        budget = dagger.plan_budget(len(pool) * pool.n_steps, pool.n_steps, args.rounds)
        with tempfile.TemporaryDirectory() as out:
            res = dagger.dagger(args.model, teacher, budget, rounds=args.rounds, beta=0.5,
                                cfg=cfg, train_cfg=tc, out=out, progress=False,
                                evaluate=False,
                                round_cfg=replace(tc, epochs=1) if way == "warm" else None)
            steps = sum(_steps(out, r.round) for r in res.rounds)
    return time.perf_counter() - w0, time.process_time() - c0, steps


def _steps(out: str, i: int) -> int:
    return train.load_checkpoint(dagger.round_dir(out, i) / train.CHECKPOINT_NAME)["steps"]


def main() -> None:
    args = ARGS or _parse_args(None)
    pool = world.generate(args.scenes, seed=0, raster=LEARNER_RASTER, progress=False)
    ways = ("bc", "scratch", "warm")
    seen: dict[str, list[tuple[float, float, int]]] = {w: [] for w in ways}
    run_way("bc", pool, argparse.Namespace(**{**vars(args), "epochs": 1}))  # compile first
    for _ in range(args.repeats):
        for w in ways:
            seen[w].append(run_way(w, pool, args))
    bc_cpu = statistics.median(c for _, c, _ in seen["bc"])
    print(f"{args.model} on {args.scenes} scenes of the learner's raster, {args.epochs} epochs, "
          f"DAgger {args.rounds} rounds; medians of {args.repeats} interleaved repeats")
    print("| way | wall s | CPU s | gradient steps | CPU ÷ BC |\n|---|---|---|---|---|")
    for w in ways:
        wall = statistics.median(x for x, _, _ in seen[w])
        cpu = statistics.median(c for _, c, _ in seen[w])
        print(f"| {w} | {wall:.1f} | {cpu:.1f} | {seen[w][0][2]} | {cpu / bc_cpu:.2f} |")


if __name__ == "__main__":
    main()
