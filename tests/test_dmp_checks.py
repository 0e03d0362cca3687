"""Tests for minimanc.dmp (chapter 3): what the library refuses — bad input, gains whose
step runs away (eqs. 12, 13) — and the exact boundaries of its stability tests."""

from __future__ import annotations

import numpy as np
import pytest
from dmp_helpers import ENGINES, finite
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import dmp, engine

# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: dmp.damping_ratio(0.0, 1.0), "alpha=0.0"),
        (lambda: dmp.damping_ratio(1.0, -2.0), "beta=-2.0"),
        (lambda: dmp.damping_ratio(np.nan, 1.0), "alpha"),
        (lambda: dmp.damping_ratio(1.0, np.inf), "beta"),
        (lambda: dmp.eigenvalues(np.nan, 1.0), "alpha"),
        (lambda: dmp.classify(1.0, np.inf), "beta"),
        (lambda: dmp.spectral_radius(-1.0, 1.0), "alpha=-1.0"),
        (lambda: dmp.spectral_radius(1.0, 0.0), "beta=0.0"),
        (lambda: dmp.spectral_radius(np.array([1.0, np.nan]), 1.0), "alpha=nan"),
        (lambda: dmp.spectral_radius(1.0, 1.0, dt=0.0), "dt=0.0"),
        (lambda: dmp.spectral_radius(1.0, 1.0, dt=np.inf), "dt"),
        (lambda: dmp.spectral_radius(1.0, 1.0, method="leapfrog"), "method='leapfrog'"),
        (lambda: dmp.step_stable(1.0, 1.0, substeps=0), "substeps=0"),
        (lambda: dmp.step_stable(1.0, 1.0, substeps=2.5), "substeps=2.5"),
        (lambda: dmp.step_matrix(0.0, 1.0), "alpha=0.0"),
        (lambda: dmp.max_stable_alpha(-1.0), "beta=-1.0"),
        (lambda: dmp.max_stable_alpha(1.0, method="rk45"), "method='rk45'"),
        (lambda: dmp.step(0.0, 0.0, 1.0, 1.0, 1.0, method="Euler"), "method='Euler'"),
        (lambda: dmp.step(0.0, 0.0, 1.0, 1.0, 1.0, dt=-0.5), "dt=-0.5"),
        (lambda: dmp.rollout(0.0, 0.0, 1.0, 1.0, 1.0, steps=-1), "steps=-1"),
        (lambda: dmp.rollout(np.nan, 0.0, 1.0, 1.0, 1.0), "y0"),
        (lambda: dmp.rollout(0.0, 0.0, np.ones(3), 1.0, 1.0, steps=4, per_step=("goal",)),
         "leading axis"),
        (lambda: dmp.rollout(0.0, 0.0, 1.0, 1.0, 1.0, per_step=("tau",)), "tau"),
        (lambda: dmp.gains_from_logits(0.0, 0.0, alpha_range=(2.0, 1.0)), "alpha_range"),
        (lambda: dmp.gains_from_logits(0.0, 0.0, beta_range=(0.0, 1.0)), "beta_range"),
        (lambda: dmp.gains_from_logits(0.0), "z_beta"),
        (lambda: dmp.logits_from_gains(30.0, 1.0), "alpha=30.0"),
        (lambda: dmp.zeta_penalty(1.0, 1.0, zeta_min=-1.0), "zeta_min=-1.0"),
    ],
)
def test_bad_input_raises_value_error_naming_parameter(call, match):
    with pytest.raises(ValueError, match=match.replace("(", r"\(").replace(")", r"\)")):
        call()


# ---------------------------------------------------------------- gains and stability checks


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"alpha": 0.0}, r"alpha must be > 0 .*got alpha=0\.0"),
        ({"alpha": -3.0}, r"alpha must be > 0 .*got alpha=-3\.0"),
        ({"alpha": np.array([[2.0], [-1.0]])}, r"got alpha=-1\.0"),
        ({"beta": -0.5}, r"beta must be >= 0 .*got beta=-0\.5"),
        ({"alpha": np.nan}, r"alpha must be finite, got alpha=nan"),
        ({"beta": np.inf}, r"beta must be finite, got beta=inf"),
    ],
)
def test_step_and_rollout_refuse_gains_that_run_away(kwargs, match):
    args = {"alpha": 4.0, "beta": 1.0, **kwargs}
    with pytest.raises(ValueError, match=match):
        dmp.step(np.zeros(1), np.zeros(1), 1.0, args["alpha"], args["beta"])
    with pytest.raises(ValueError, match=match):
        dmp.rollout(np.zeros(1), np.zeros(1), 1.0, args["alpha"], args["beta"], steps=3)


@pytest.mark.parametrize("bad", ["10", None, b"1", [1.0, "x"], {"a": 1}])
@pytest.mark.parametrize("which", ["alpha", "beta"])
def test_non_numeric_gains_are_a_type_error_naming_the_argument(bad, which):
    args = {"alpha": 4.0, "beta": 1.0, which: bad}
    match = rf"{which} must be a real number or array, got {which}="
    with pytest.raises(TypeError, match=match):
        dmp.step(0.0, 0.0, 1.0, args["alpha"], args["beta"])
    with pytest.raises(TypeError, match=match):
        dmp.rollout(0.0, 0.0, 1.0, args["alpha"], args["beta"], steps=2)
    for fn in (dmp.classify, dmp.eigenvalues, dmp.damping_ratio, dmp.spectral_radius):
        with pytest.raises(TypeError, match=match):
            fn(args["alpha"], args["beta"])


def test_pure_damping_beta_zero_is_allowed():
    # β = 0: eigenvalues 1 and 1 − hα of the sub-step, ρ = 1 (bounded, not convergent)
    y, dy, _ = dmp.step(np.array([2.0]), np.array([1.0]), 0.0, 3.0, 0.0)
    assert np.isfinite(y).all() and abs(dy[0]) < 1.0
    with pytest.raises(ValueError, match=r"spectral radius of one step is 3\.5 > 1.*"
                                         r"bounded only for 0 < alpha < 4\b"):
        dmp.step(0.0, 1.0, 0.0, 9.0, 0.0, 0.5, "euler", 1)  # |1 − hα| = 3.5


def test_unstable_step_states_spectral_radius_and_bound():
    msg = (r"explicit Euler \(method='euler'\) with dt=0\.5 and substeps=1 is unstable for "
           r"alpha=25\.0, beta=6\.25: the spectral radius of one step is 5\.25 > 1.*"
           r"no alpha is stable \(h\*beta = 3\.125 >= 1.*allow_unstable=True")
    with pytest.raises(ValueError, match=msg):
        dmp.step(1.0, 0.0, 0.0, 25.0, 6.25, 0.5, "euler", 1)
    # a β with a stable range: the bound of max_stable_alpha is quoted
    bound = dmp.max_stable_alpha(1.0, 0.5, "semi_implicit", 1)
    with pytest.raises(ValueError, match=rf"stable only for 0 < alpha < {bound:.6g}"):
        dmp.step(1.0, 0.0, 0.0, 1.5 * bound, 1.0, 0.5, "semi_implicit", 1)
    # arrays: the worst pair is reported, and how many are unstable
    alphas = np.array([[1.0], [1.5 * bound], [3 * bound]])
    with pytest.raises(ValueError, match=rf"alpha={3 * bound!r}.*the worst of 2 unstable"):
        dmp.step(np.ones((3, 1)), np.zeros((3, 1)), 0.0, alphas, 1.0, 0.5, "semi_implicit", 1)
    # rk4 too
    with pytest.raises(ValueError, match=r"RK4 \(method='rk4'\)"):
        dmp.step(1.0, 0.0, 0.0, 25.0, 6.25, 0.5, "rk4", 1)


def test_allow_unstable_runs_with_one_warning_per_call():
    with pytest.warns(RuntimeWarning, match=r"5\.25 > 1") as record:
        r = dmp.rollout(np.ones(1), np.zeros(1), 0.0, 25.0, 6.25, 0.5, 8, "euler", 1,
                        allow_unstable=True)
    assert len([w for w in record if issubclass(w.category, RuntimeWarning)]) == 1
    assert abs(r.y[-1, 0]) > 1e5
    with pytest.warns(RuntimeWarning, match="allow_unstable=True") as record:
        y, _, _ = dmp.step(1.0, 0.0, 0.0, 25.0, 6.25, 0.5, "euler", 1, allow_unstable=True)
    assert len(record) == 1 and y == 1.0
    with pytest.raises(TypeError, match="allow_unstable must be True or False"):
        dmp.step(1.0, 0.0, 0.0, 1.0, 1.0, allow_unstable="yes")


def test_per_step_gains_are_checked_once_for_every_step():
    alphas = np.array([1.0, 2.0, 30.0, 1.0])  # step 2 leaves the stable range
    with pytest.raises(ValueError, match=r"alpha=30\.0"):
        dmp.rollout(0.0, 0.0, 1.0, alphas, 1.0, 0.5, 4, "euler", 1, per_step=("alpha",))
    with pytest.raises(ValueError, match=r"alpha must be > 0 .*got alpha=-1\.0"):
        dmp.rollout(0.0, 0.0, 1.0, np.array([1.0, -1.0]), 1.0, 0.5, 2, per_step=("alpha",))


@settings(max_examples=80, deadline=None)
@given(st.floats(0.05, 60, **finite), st.floats(0.01, 10, **finite),
       st.sampled_from(dmp.METHODS), st.integers(1, 4))
def test_step_check_agrees_with_the_spectral_radius(alpha, beta, method, substeps):
    rho = dmp.spectral_radius(alpha, beta, 0.5, method, substeps)
    if rho > 1 + 1e-9:
        with pytest.raises(ValueError, match="spectral radius"):
            dmp.step(1.0, 0.0, 0.0, alpha, beta, 0.5, method, substeps)
    elif rho < 1 - 1e-9:
        dmp.step(1.0, 0.0, 0.0, alpha, beta, 0.5, method, substeps)
        assert dmp.step_stable(alpha, beta, 0.5, method, substeps)


def test_learned_gain_box_never_trips_the_check():
    z = np.linspace(-40, 40, 81)
    za, zb = np.meshgrid(z, z)
    a, b = dmp.gains_from_logits(za.reshape(-1, 1), zb.reshape(-1, 1))
    n = a.shape[0]
    dmp.step(np.zeros((n, 2)), np.ones((n, 2)), np.ones((n, 2)), a, b)
    a, b = dmp.gains_from_logits(za.reshape(-1, 1), None, critically_damped=True)
    dmp.step(np.zeros((n, 2)), np.ones((n, 2)), np.ones((n, 2)), a, b)
    assert np.all(dmp.step_stable(a, b))


@pytest.mark.parametrize("name", ENGINES)
def test_traced_gains_are_not_checked(name):
    eng = engine(name)

    def loss(a):
        y, _, _ = dmp.step(eng.xp.ones(1), eng.xp.zeros(1), 0.0, a, 6.25, 0.5, "euler", 1,
                           xp=eng.xp)
        return eng.xp.sum(y)

    g = eng.grad(loss)(25.0)  # unstable concrete gains would raise; traced ones are not seen
    assert np.isfinite(float(g))
    if name == "jax":
        f = eng.jit(lambda a: dmp.rollout(eng.xp.ones(1), eng.xp.zeros(1), 0.0, a, 6.25, 0.5,
                                          3, "euler", 1, xp=eng.xp).y)
        assert abs(float(f(25.0)[-1, 0])) > 100


# --------------------------------------------------------------------------- boundaries


def test_explicit_euler_at_exactly_h_beta_one_is_not_stable():
    # dt = 0.5, one sub-step, β = 2: h β = 1 exactly; |1 + hλ|² = 1 − hα(1 − hβ) = 1
    alphas = np.linspace(0.01, 7.99, 2000)  # complex roots (α < 4β) up to hα(2 − hβ) < 4
    assert not np.any(dmp.step_stable(alphas, 2.0, 0.5, "euler", 1))
    assert dmp.max_stable_alpha(2.0, 0.5, "euler", 1) == 0.0
    assert np.allclose(dmp.spectral_radius(alphas, 2.0, 0.5, "euler", 1), 1.0, atol=1e-15)
    # marginal (ρ = 1): the step runs, the error neither grows nor decays
    r = dmp.rollout(1.0, 0.0, 0.0, 1.0, 2.0, 0.5, 200, "euler", 1)
    assert 0.1 < np.abs(r.y[-50:]).max() < 10
    # just below h β = 1: stable for α below the closed-form bound, not at it
    beta = 2.0 * (1 - 1e-9)
    bound = dmp.max_stable_alpha(beta, 0.5, "euler", 1)
    assert bound == pytest.approx(4 / (0.5 * (2 - 0.5 * beta)))
    assert dmp.step_stable(0.5 * bound, beta, 0.5, "euler", 1)
    assert not dmp.step_stable(bound, beta, 0.5, "euler", 1)
    # just above: nothing is stable
    assert not np.any(dmp.step_stable(alphas, 2.0 * (1 + 1e-12), 0.5, "euler", 1))
    assert dmp.max_stable_alpha(2.0 * (1 + 1e-12), 0.5, "euler", 1) == 0.0


@pytest.mark.parametrize("method", ["euler", "semi_implicit"])
def test_the_stable_bound_itself_is_not_stable(method):
    for beta in (0.1, 1.0, 1.9):
        bound = dmp.max_stable_alpha(beta, 0.5, method, 1)
        assert not dmp.step_stable(bound, beta, 0.5, method, 1)
        assert dmp.step_stable(bound * (1 - 1e-12), beta, 0.5, method, 1)
        assert not dmp.step_stable(bound * (1 + 1e-12), beta, 0.5, method, 1)


@pytest.mark.parametrize("alpha", [0.01, 1.0, 25.0, 1e6])
def test_classify_critical_band_is_relative(alpha):
    rt = dmp.CRITICAL_RTOL
    for zeta in (1 - 1e-12, 1.0, 1 + 1e-12):
        beta = alpha / (4 * zeta**2)
        assert dmp.classify(alpha, beta) == "critically damped", zeta
    # |α − 4β| = k · CRITICAL_RTOL · α on both sides of the band edge
    for k, expect in ((0.5, "critically damped"), (0.99, "critically damped"),
                      (1.01, None), (2.0, None)):
        for sign, outside in ((+1, "overdamped"), (-1, "underdamped")):
            beta = alpha * (1 - sign * k * rt) / 4  # α − 4β = sign · k · rt · α
            assert dmp.classify(alpha, beta) == (expect or outside), (k, sign)



def test_negative_gains_zeta_below_zero_run_only_when_allowed():
    with pytest.raises(ValueError, match=r"alpha must be > 0 .*allow_unstable=True"):
        dmp.rollout(np.ones(1), np.zeros(1), 0.0, -2.0, -0.5, 0.5, 10)
    with pytest.warns(RuntimeWarning, match=r"zeta=-1\b.*unstable") as record:
        r = dmp.rollout(np.ones(1), np.zeros(1), 0.0, -2.0, -0.5, 0.5, 10, allow_unstable=True)
    assert len(record) == 1
    assert dmp.damping_ratio(-2.0, -0.5) == pytest.approx(-1.0)
    assert abs(r.y[-1, 0]) > 100 * abs(r.y[0, 0])  # runs away from the goal

