"""Chapter 9 — where a study hands its jobs: :class:`Submitter` runs each job inline (no
worker) or submits it to the executor of :mod:`minimanc.studies.executors` (a local pool of
worker processes, or Ray tasks), made on first use with the driver's thread settings."""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from minimanc.checks import check_int
from minimanc.studies.executors import EXECUTORS, check_ray, executor

__all__ = ["THREAD_ENV", "Submitter"]

THREAD_ENV: tuple[str, ...] = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                               "MINIMANC_XLA_THREADS", "XLA_FLAGS", "JAX_PLATFORMS")
"""Environment variables a Ray worker inherits from the driver (so that a task computes as
a local job would)."""


class Submitter:
    """The executor of a study's jobs.

    ``kind``: ``"local"`` (``workers`` processes of this machine; 0: every job inline, in
    this process, one after the other) or ``"ray"`` (Ray tasks on the cluster at
    ``ray_address`` or ``RAY_ADDRESS``, else a local Ray with ``workers`` CPUs). Raises the
    one-line :class:`~minimanc.errors.UsageError` saying how to install Ray before any
    work when it is missing.
    """

    def __init__(self, kind: str = "local", workers: int = 0,
                 ray_address: str | None = None) -> None:
        if kind not in EXECUTORS:
            raise ValueError(f"executor must be one of {EXECUTORS}; got executor={kind!r}")
        if kind == "ray":
            check_ray()  # before any work: the one-line UsageError saying how to install it
        if ray_address is not None and kind != "ray":
            raise ValueError(f"ray_address is only for executor='ray'; got "
                             f"ray_address={ray_address!r} with executor={kind!r}")
        self.kind = kind
        self.workers = check_int("workers", workers, 0)
        self.ray_address = ray_address
        self._pool: Any = None

    @property
    def pooled(self) -> bool:
        """Whether jobs run in the executor (Ray, or a local pool of ``workers`` processes)
        rather than inline in this process."""
        return self.kind == "ray" or self.workers > 0

    def submit(self, fn: Callable, *args: Any) -> Any:
        """``fn(*args)`` as a job of the executor (made on first use); its future.
        An argument may be a future of the same executor (the job waits for it)."""
        if self._pool is None:
            env = {k: os.environ[k] for k in THREAD_ENV if k in os.environ}
            self._pool = executor(self.kind, self.workers, self.ray_address, env=env)
        return self._pool.submit(fn, *args)

    def close(self) -> None:
        """Shut the worker processes down (and a local Ray this study started)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
