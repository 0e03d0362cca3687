"""Thread settings the benchmarks apply before NumPy and JAX are imported."""

from __future__ import annotations

import os

__all__ = ["set_threads"]


def set_threads(threads: int | None) -> None:
    """``threads`` BLAS threads for NumPy and XLA threads for JAX (``None``: leave the
    defaults, which for JAX is :func:`minimanc.engine.xla_threads`' one thread). With 1,
    CPU time is the work done whatever else the machine runs. Call it before importing
    numpy or jax."""
    if threads is None:
        return
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(threads)
    os.environ["MINIMANC_XLA_THREADS"] = str(threads)  # read by minimanc.engine
