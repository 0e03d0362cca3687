"""Thread settings the benchmarks apply before NumPy and JAX are imported."""

from __future__ import annotations

import os

__all__ = ["set_threads"]


def set_threads(threads: int | None) -> None:
    """``threads`` BLAS threads for NumPy (``None``: leave the defaults); with 1, XLA is made
    single-threaded too, so that CPU time is the work done whatever else the machine runs.
    Call it before importing numpy or jax."""
    if threads is None:
        return
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(threads)
    if threads == 1:
        os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_cpu_multi_thread_eigen"
                                   "=false intra_op_parallelism_threads=1").strip()
