"""Test-suite settings shared by every test module.

Hypothesis runs randomised on a developer's machine (new examples every run, so the
property tests keep searching) and derandomised in CI: with ``CI`` set (as CI services
do) or ``HYPOTHESIS_PROFILE=ci``, every run draws the same examples, so a red CI is
reproducible and never the luck of the draw.
"""

import os
import sys

# One BLAS thread per process, as the library gives XLA (minimanc.engine): the suite runs a
# process per core (pytest -n 2, each notebook's kernel under its worker), and BLAS threads
# on top of them oversubscribe the cores, where the NumPy autodiff's small matrix products
# run several times slower. Set before NumPy loads, and inherited by the workers and kernels;
# a value the caller set is kept.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# XLA compiles the suite's many small programs without its backend optimisations (LLVM at
# -O0 instead of XLA's default level 3): compiling, not running, is most of a JAX test's time
# here. Set before JAX starts, and inherited by the workers and kernels, so every process of
# a run computes with the same compiled code; a level the caller set is kept (.ci/run's
# second stage sets the default level, so the library is also tested as a user runs it).
_LEVEL = "--xla_backend_optimization_level"
if _LEVEL not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {_LEVEL}=0".strip()

import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

# Health checks about how hard examples are to *generate* (not about the code under
# test) differ between hypothesis releases: the oldest release we support rejects
# strategies of small arrays that newer ones accept.
GENERATION_CHECKS = [HealthCheck.too_slow, HealthCheck.data_too_large]
settings.register_profile("default", deadline=None, suppress_health_check=GENERATION_CHECKS)
settings.register_profile(
    "ci",
    derandomize=True,
    database=None,
    deadline=None,
    print_blob=True,
    suppress_health_check=GENERATION_CHECKS,
)
settings.load_profile(
    os.environ.get("HYPOTHESIS_PROFILE") or ("ci" if os.environ.get("CI") else "default")
)

# Start JAX the way the library does (one XLA thread, minimanc.engine) before any test
# computes with it, so that in-process results have the bits of a study's worker
# processes whichever test happens to run JAX first.
from minimanc.engine import get_engine  # noqa: E402

get_engine("jax")


@pytest.fixture(autouse=True)
def close_figures():
    """Close every matplotlib figure a test left open (only where a test loaded pyplot)."""
    yield
    pyplot = sys.modules.get("matplotlib.pyplot")
    if pyplot is not None:
        pyplot.close("all")


@pytest.fixture(scope="module")
def eng_np():
    """The NumPy autodiff engine (:func:`minimanc.engine.get_engine`)."""
    return get_engine("numpy")


@pytest.fixture(scope="module")
def eng_jax():
    """The JAX engine."""
    return get_engine("jax")
