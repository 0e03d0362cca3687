"""Chapter 1 — one model code, two engines: our NumPy autodiff or JAX.

``get_engine("numpy")`` and ``get_engine("jax")`` return objects with the same
attributes, so every model of the paper (eqs. 7–11) is written once against
``eng.xp`` and trained with ``eng.grad``:

==================  ==================================  ===========================
attribute           "numpy"                             "jax"
==================  ==================================  ===========================
``name``            ``"numpy"``                         ``"jax"``
``xp``              :mod:`minimanc.autodiff.numpy`      ``jax.numpy``
``grad``            :func:`minimanc.autodiff.grad`      ``jax.grad``
``value_and_grad``  :func:`minimanc.autodiff.value_and_grad`  ``jax.value_and_grad``
``jit``             identity                            ``jax.jit``
``scan``            :func:`minimanc.autodiff.scan`        ``jax.lax.scan``
``custom_vjp``      :class:`minimanc.autodiff.custom_vjp`  ``jax.custom_vjp``
``device_put``      identity                            arrays of a pytree to JAX
``nn``              :mod:`minimanc.autodiff.nn`         the functions below
==================  ==================================  ===========================

``nn`` holds ``relu, sigmoid, silu, softmax(x, axis=-1), log_softmax(x, axis=-1),
conv2d(x, w, b=None, stride=1, padding=0), global_avg_pool(x)`` with NHWC images
and HWIO kernels; ``conv2d`` zero-pads ``padding`` pixels on each side and its
output has spatial size ``(H + 2p - k) // s + 1``. ``get_engine("jax")`` turns on
``jax_enable_x64`` so that float64 runs agree with the NumPy engine to 1e-6.

XLA's CPU results depend, in the last bits of a float32 reduction, on how many
threads its intra-op pool has, and the pool is sized by the CPUs the process may use
when JAX starts. ``get_engine("jax")`` therefore starts JAX with
:func:`xla_threads` threads (one unless ``MINIMANC_XLA_THREADS`` says more): the same
computation gives the same bits on a 2-core laptop, a 64-core node, in a study's worker
processes and in a Ray task, and worker processes that each run one XLA thread do not
oversubscribe the cores (a study's parallelism is its processes). A process that ran
JAX before its first ``get_engine("jax")`` keeps the pool it started with.

Library code that receives only an array namespace ``xp`` (the DMP step of eq. 10)
finds its engine with :func:`engine_of`, e.g. to use ``engine_of(xp).custom_vjp``.
"""

from __future__ import annotations

import functools
import os
import sys
import types
from collections.abc import Callable
from typing import Any

import numpy as np

from minimanc import autodiff
from minimanc.autodiff import nn as autodiff_nn
from minimanc.checks import check_int

__all__ = ["ENGINES", "XLA_THREADS_VAR", "Engine", "engine_of", "fused_kernel", "get_engine",
           "start_jax", "xla_threads"]

ENGINES = ("numpy", "jax")

XLA_THREADS_VAR = "MINIMANC_XLA_THREADS"
"""Environment variable: XLA's intra-op threads per process (a positive integer; default 1)."""


class Engine:
    """An autodiff engine: ``name``, ``xp``, ``grad``, ``value_and_grad``, ``jit``, ``scan``,
    ``custom_vjp``, ``device_put``, ``nn``.

    ``scan(f, init, xs, length=None) -> (carry, ys)`` is ``jax.lax.scan``'s loop
    (``carry, y_i = f(carry, xs[i])``, the ``y_i`` stacked); differentiable with
    respect to ``init``, ``xs`` and the traced values ``f`` closes over. On the
    NumPy engine the whole loop is one node of the tape. ``device_put(tree)``
    returns the pytree with its arrays in the engine's own array type (once, before
    a training loop), unchanged on NumPy. ``custom_vjp(fun, nondiff_argnums)`` with
    ``.defvjp(fwd, bwd)`` is ``jax.custom_vjp``'s API: a function with a hand-written
    VJP (on NumPy, one node of the tape per call).
    """

    def __init__(
        self,
        name: str,
        xp: Any,
        grad: Callable,
        value_and_grad: Callable,
        jit: Callable,
        nn_loader: Callable[[], Any],
        scan: Callable,
        device_put: Callable[[Any], Any],
        custom_vjp: Callable,
    ) -> None:
        self.name = name
        self.xp = xp
        self.grad = grad
        self.value_and_grad = value_and_grad
        self.jit = jit
        self.scan = scan
        self.device_put = device_put
        self.custom_vjp = custom_vjp
        self._nn_loader = nn_loader
        self._nn = None

    @property
    def nn(self) -> Any:
        """Neural-net primitives (loaded on first use)."""
        if self._nn is None:
            self._nn = self._nn_loader()
        return self._nn

    def __repr__(self) -> str:
        return f"Engine({self.name!r})"


def _identity_jit(fun: Callable | None = None, **kwargs) -> Callable:
    """The NumPy engine's ``jit``: returns ``fun`` unchanged (usable as a decorator)."""
    if fun is None:
        return lambda f: f
    return fun


def _numpy_engine() -> Engine:
    return Engine(
        name="numpy",
        xp=autodiff.numpy,
        grad=autodiff.grad,
        value_and_grad=autodiff.value_and_grad,
        jit=_identity_jit,
        nn_loader=lambda: autodiff_nn,
        scan=autodiff.scan,
        device_put=lambda tree: tree,
        custom_vjp=autodiff.custom_vjp,
    )


def _check_conv_args(stride, padding) -> None:
    check_int("stride", stride, 1)
    check_int("padding", padding, 0)


def _jax_nn(jax: Any) -> types.SimpleNamespace:
    jnp = jax.numpy

    def softmax(x, axis=-1):
        """Softmax along ``axis`` (eq. 9 uses ``axis=0``, the column softmax)."""
        return jax.nn.softmax(x, axis=axis)

    def log_softmax(x, axis=-1):
        """Log-softmax along ``axis``."""
        return jax.nn.log_softmax(x, axis=axis)

    def conv2d(x, w, b=None, stride: int = 1, padding: int = 0):
        """2-D convolution (cross-correlation), NHWC images and HWIO kernels (eq. 7)."""
        _check_conv_args(stride, padding)
        if x.ndim != 4 or w.ndim != 4:
            raise ValueError(
                f"conv2d: x must be NHWC and w HWIO (4-D), got shapes {x.shape} and {w.shape}"
            )
        if x.shape[3] != w.shape[2]:
            raise ValueError(
                f"conv2d: input channels {x.shape[3]} (x {x.shape}) != kernel input "
                f"channels {w.shape[2]} (w {w.shape})"
            )
        y = jax.lax.conv_general_dilated(
            x,
            w,
            window_strides=(stride, stride),
            padding=[(padding, padding), (padding, padding)],
            dimension_numbers=("NHWC", "HWIO", "NHWC"),
        )
        return y if b is None else y + b

    def global_avg_pool(x):
        """Mean over the spatial axes: ``(N, H, W, C) -> (N, C)`` (eq. 7's GAP)."""
        return jnp.mean(x, axis=(1, 2))

    return types.SimpleNamespace(
        relu=jax.nn.relu,
        sigmoid=jax.nn.sigmoid,
        silu=jax.nn.silu,
        softmax=softmax,
        log_softmax=log_softmax,
        conv2d=conv2d,
        global_avg_pool=global_avg_pool,
    )


def _jax_jit(jax: Any) -> Callable:
    def jit(fun: Callable | None = None, **kwargs) -> Callable:
        """``jax.jit``, also usable as ``@eng.jit(static_argnums=...)``."""
        if fun is None:
            return lambda f: jax.jit(f, **kwargs)
        return jax.jit(fun, **kwargs)

    return jit


def xla_threads() -> int:
    """XLA's intra-op threads per process: ``$MINIMANC_XLA_THREADS`` (a positive integer),
    default 1. A value that is not a positive integer raises ``ValueError``."""
    raw = os.environ.get(XLA_THREADS_VAR, "1").strip()
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"{XLA_THREADS_VAR} must be a positive integer (XLA threads per "
                         f"process); got {XLA_THREADS_VAR}={raw!r}")
    return n


def _thread_ids() -> list[int]:
    return [int(t) for t in os.listdir("/proc/self/task")]


def start_jax(jax: Any, threads: int) -> None:
    """Start JAX's CPU backend with an intra-op pool of ``threads`` threads.

    XLA sizes its pool by the CPUs the process may use, so the calling thread is
    restricted to ``threads`` of them while the backend starts, and every thread of the
    process gets its own CPU mask back afterwards (the pool's threads the caller's):
    the operating system still places them on any CPU. Without CPU masks (macOS,
    Windows) or with ``threads`` ≥ the usable CPUs, JAX starts as it would.
    """
    try:
        mask = os.sched_getaffinity(0)
        before = {tid: os.sched_getaffinity(tid) for tid in _thread_ids()}
    except (AttributeError, OSError):  # no CPU masks here
        jax.devices()
        return
    if threads >= len(mask):
        jax.devices()
        return
    os.sched_setaffinity(0, set(sorted(mask)[:threads]))
    try:
        jax.devices()  # creates the CPU client and its thread pool
    finally:
        for tid in _thread_ids():
            try:
                os.sched_setaffinity(tid, before.get(tid, mask))
            except OSError:  # the thread ended meanwhile
                pass


def _jax_engine() -> Engine:
    try:
        import jax  # JAX only for the jax engine
    except ImportError as err:  # pragma: no cover - jax is a dependency
        raise ImportError(
            "the 'jax' engine needs JAX: install it with  pip install 'jax[cpu]'"
        ) from err
    jax.config.update("jax_enable_x64", True)
    start_jax(jax, xla_threads())
    return Engine(
        name="jax",
        xp=jax.numpy,
        grad=jax.grad,
        value_and_grad=jax.value_and_grad,
        jit=_jax_jit(jax),
        nn_loader=lambda: _jax_nn(jax),
        scan=jax.lax.scan,
        device_put=lambda tree: jax.tree_util.tree_map(jax.numpy.asarray, tree),
        custom_vjp=jax.custom_vjp,
    )


@functools.cache
def get_engine(name: str = "numpy") -> Engine:
    """Return the engine called ``name`` ("numpy" or "jax"); the same object each time.

    The first ``get_engine("jax")`` of a process starts JAX with :func:`xla_threads`
    intra-op threads (see the module docstring)."""
    if name == "numpy":
        return _numpy_engine()
    if name == "jax":
        return _jax_engine()
    raise ValueError(f"unknown engine name={name!r}; choose one of {', '.join(ENGINES)}")


def engine_of(xp: Any) -> Engine | None:
    """The engine whose array namespace is ``xp``, or ``None`` for another namespace.

    Plain ``numpy`` gives the NumPy engine (its functions also run on plain arrays
    of any kind, JAX's included: with nothing traced they only call the function).

    >>> import numpy as np
    >>> engine_of(np).name
    'numpy'
    """
    if xp is np or xp is get_engine("numpy").xp:
        return get_engine("numpy")
    jnp = sys.modules.get("jax.numpy")
    if jnp is not None and xp is jnp:
        return get_engine("jax")
    return None


def fused_kernel(xp: Any, *values: Any) -> Engine | None:
    """The engine whose hand-written one-node kernel should compute on ``values``, or
    ``None`` for the operation-by-operation code: the one rule every fused kernel follows.

    The fused kernels of :mod:`minimanc.vagn.fused` and :mod:`minimanc.models.head_vjp` are
    the NumPy engine's: they serve when that engine's tape records one of ``values`` (one
    tape node instead of dozens). JAX differentiates the plain operations, and plain
    arrays (nothing traced) take them too, so a forward pass gives the same numbers traced
    or not. :mod:`minimanc.dmp` asks :func:`engine_of` directly: its flow has a kernel on
    both engines.
    """
    eng = engine_of(xp)
    if eng is None or eng.name != "numpy":
        return None
    return eng if any(isinstance(v, autodiff.Box) for v in values) else None
