"""Tests for minimanc.dmp (chapter 3): the forcing term of eq. (1) — canonical system,
basis functions, weights fitted to a demonstration, generalisation to a new goal."""

from __future__ import annotations

import numpy as np
import pytest
from dmp_helpers import ENGINES, central_diff, finite
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import dmp, engine


@pytest.fixture(params=ENGINES)
def eng(request):
    return engine(request.param)


# --------------------------------------------------------------------------- forcing term (eq. 1)


def _min_jerk_demo(T=100, dt=0.01, g=(1.0, 2.0)):
    """A 2-D demonstration that starts and ends at rest, with its exact derivatives.

    Dimension 0 is minimum jerk plus a bump ``0.5 sin²(πs)``, dimension 1 plain
    minimum jerk, ``s = t / t_end``; returns ``(t, y, ẏ, ÿ)``, each sampled at ``k dt``.
    """
    t = np.arange(T + 1) * dt
    d = t[-1]
    s = t / d
    mj = np.stack([10 * s**3 - 15 * s**4 + 6 * s**5,
                   (30 * s**2 - 60 * s**3 + 30 * s**4) / d,
                   (60 * s - 180 * s**2 + 120 * s**3) / d**2])
    bump = np.stack([0.5 * np.sin(np.pi * s) ** 2,
                     0.5 * np.pi * np.sin(2 * np.pi * s) / d,
                     np.pi**2 * np.cos(2 * np.pi * s) / d**2])
    gains = np.asarray(g)
    y, dy, ddy = (np.stack([gains[0] * mj[i] + bump[i], gains[1] * mj[i]], -1)
                  for i in range(3))
    return t, y, dy, ddy


def test_canonical_system_is_the_exact_exponential_at_the_step_times():
    for steps, dt, alpha_x, tau in ((40, 0.5, 1.0, 1.0), (1000, 0.01, 4.6, 2.0),
                                    (7, 3.0, 2.0, 0.5)):
        x = dmp.canonical_system(steps, dt, alpha_x, tau)
        t = np.arange(steps + 1) * dt
        # each step multiplies by one rounded factor: relative error <= steps roundings
        assert x.shape == (steps + 1,) and x[0] == 1.0
        np.testing.assert_allclose(x, np.exp(-alpha_x * t / tau), rtol=4e-16 * (steps + 1))
        np.testing.assert_allclose(x, dmp.phase(t, alpha_x, tau), rtol=4e-16 * (steps + 1))
    # the exact map never changes sign, even where explicit Euler (1 - alpha_x dt) would
    assert np.all(dmp.canonical_system(5, 1.0, 3.0) > 0)


def test_basis_centres_follow_the_phase_and_overlap_at_the_next_centre():
    c, h = dmp.basis_centres(6, 2.0, 3.0, tau=1.5, overlap=0.5)
    np.testing.assert_allclose(c, np.exp(-2.0 * np.linspace(0, 3.0, 6) / 1.5))
    psi_next = np.exp(-h[:-1] * (c[1:] - c[:-1]) ** 2)  # ψ_i at c_{i+1}
    np.testing.assert_allclose(psi_next, 0.5)
    assert h[-1] == h[-2]
    psi = dmp.basis_functions(c, c, h)
    assert psi.shape == (6, 6) and np.allclose(np.diag(psi), 1.0)


def test_zero_weights_give_the_point_attractor_rollout_exactly():
    c, h = dmp.basis_centres(8, 3.0, 2.0)
    zero = dmp.Forcing(np.zeros((8, 2)), c, h, 3.0)
    y0, dy0, g = np.array([0.5, -1.0]), np.array([0.2, 0.0]), np.array([2.0, 1.0])
    for method in dmp.METHODS:
        ref = dmp.rollout(y0, dy0, g, 4.0, 1.0, 0.1, 30, method, 3)
        got = dmp.rollout(y0, dy0, g, 4.0, 1.0, 0.1, 30, method, 3, forcing=zero)
        for a, b in zip(ref, got):
            assert np.array_equal(a, b), method


def test_tau_scales_eq1_like_the_gain_alpha_over_tau():
    # τ ÿ = α (β (g − y) − ẏ) is eq. (10) with α / τ
    r = dmp.rollout(np.zeros(1), np.zeros(1), 1.0, 6.0, 1.0, 0.1, 30, tau=2.0)
    ref = dmp.rollout(np.zeros(1), np.zeros(1), 1.0, 3.0, 1.0, 0.1, 30)
    np.testing.assert_allclose(r.y, ref.y, rtol=1e-14, atol=1e-15)


def test_forcing_term_matches_its_formula():
    rng = np.random.default_rng(1)
    c, h = dmp.basis_centres(5, 2.0, 1.0)
    f = dmp.Forcing(rng.normal(size=(5, 3)), c, h, 2.0)
    x = np.array([1.0, 0.6, 0.2, 0.01])
    g, y0 = np.array([1.0, -2.0, 0.5]), np.array([0.0, 1.0, 0.5])
    psi = np.exp(-h * (x[:, None] - c) ** 2)
    want = (psi @ f.weights) / psi.sum(1, keepdims=True) * x[:, None] * (g - y0)
    np.testing.assert_allclose(dmp.forcing_term(x, f, g, y0), want, rtol=1e-13)
    np.testing.assert_allclose(dmp.forcing_term(x, f, g, y0, gate=False),
                               want / x[:, None], rtol=1e-13)
    assert np.all(want[:, 2] == 0)  # g = y0: the scaled term cannot move that dimension


def test_fitted_dmp_reproduces_its_demonstration_within_the_forcing_bound():
    # Error bound. The rollout y and the demo y_d both solve τ ë... : e = y − y_d obeys
    # τ ë + α ė + αβ e = f_fit − f_true, e(0) = ė(0) = 0 (the demo starts at rest). For
    # ζ ≥ 1 the impulse response of 1/(τ s² + α s + αβ) is ≥ 0 and integrates to 1/(αβ),
    # so |e(t)| ≤ sup|f_fit − f_true| / (αβ). RK4 at h = 0.01 adds ~1e-9 (fourth order).
    t, y, dy, ddy = _min_jerk_demo()
    dt, alpha, beta = 0.01, 25.0, 25.0 / 4
    g, y0 = y[-1], y[0]
    for n_basis in (20, 50):
        fz = dmp.fit_forcing_weights(y, dt, alpha, beta, n_basis)
        assert fz.alpha_x == pytest.approx(-np.log(dmp.PHASE_END))  # x(1 s) = 0.01
        r = dmp.rollout(y0, np.zeros(2), g, alpha, beta, dt, len(t) - 1, "rk4", 1, forcing=fz)
        tf = np.arange(0, len(t) - 0.5, 0.5) * dt  # the points where RK4 evaluates f
        _, yf, dyf, ddyf = _min_jerk_demo(T=2 * (len(t) - 1), dt=dt / 2)
        f_true = ddyf - alpha * (beta * (g - yf) - dyf)
        f_fit = dmp.forcing_term(dmp.phase(tf, fz.alpha_x), fz, g, y0)
        bound = np.abs(f_fit - f_true).max(axis=0) / (alpha * beta)
        err = np.abs(r.y - y).max(axis=0)
        assert np.all(err <= bound + 1e-8), (n_basis, err, bound)
        assert np.all(err > 0.05 * bound)  # the bound is not vacuous
    assert np.all(err < 0.01)  # 50 basis functions: within 1 cm of a 1-2 m movement


def test_fitted_dmp_generalises_to_a_new_goal_and_converges():
    t, y, _, _ = _min_jerk_demo()
    fz = dmp.fit_forcing_weights(y, 0.01, 25.0, 25.0 / 4, 30)
    new_goal = np.array([-1.0, 3.0])
    r = dmp.rollout(y[0], np.zeros(2), new_goal, 25.0, 25.0 / 4, 0.01, 300, forcing=fz)
    np.testing.assert_allclose(r.y[-1], new_goal, atol=1e-3)  # 3 s: x = 1e-6, at rest
    assert np.abs(r.dy[-1]).max() < 1e-2


@settings(max_examples=30, deadline=None)
@given(st.floats(-5, 5, **finite), st.floats(-5, 5, **finite), st.floats(-5, 5, **finite))
def test_new_goal_rescales_the_motion_about_the_start(y0, g, g_new):
    # with u = (y − y0)/(g − y0), eq. (1) reads τ ü = α (β (1 − u) − u̇) + x Σψw/Σψ:
    # u does not depend on g, so y'(t) − y0 = k (y(t) − y0), k = (g' − y0)/(g − y0)
    if abs(g - y0) < 0.1:
        return
    c, h = dmp.basis_centres(6, 3.0, 1.0)
    fz = dmp.Forcing(np.linspace(-20, 20, 6)[:, None], c, h, 3.0)
    start = np.array([y0])
    r = dmp.rollout(start, np.zeros(1), g, 8.0, 2.0, 0.05, 30, forcing=fz)
    r2 = dmp.rollout(start, np.zeros(1), g_new, 8.0, 2.0, 0.05, 30, forcing=fz)
    k = (g_new - y0) / (g - y0)
    np.testing.assert_allclose(r2.y - y0, k * (r.y - y0), atol=1e-9 * (1 + abs(k)) * 50)


def test_a_forcing_term_that_never_fades_keeps_the_dmp_off_its_goal():
    t, y, _, _ = _min_jerk_demo()
    alpha, beta = 25.0, 25.0 / 4
    fz = dmp.fit_forcing_weights(y, 0.01, alpha, beta, 20)
    g, y0 = y[-1], y[0]
    kw = dict(dt=0.05, steps=400, method="semi_implicit", substeps=5, forcing=fz)
    gated = dmp.rollout(y0, np.zeros(2), g, alpha, beta, **kw)
    ungated = dmp.rollout(y0, np.zeros(2), g, alpha, beta, gate=False, **kw)
    np.testing.assert_allclose(gated.y[-1], g, atol=1e-6)
    # without x, f → f_∞ = Σψ(0)w/Σψ(0) (g − y0) and the rest point moves to g + f_∞/(αβ)
    f_inf = dmp.forcing_term(0.0, fz, g, y0, gate=False)
    rest = g + f_inf / (alpha * beta)
    x_end = dmp.phase(20.0, fz.alpha_x)
    assert x_end < 1e-30  # ψ(x_end) = ψ(0) to rounding
    np.testing.assert_allclose(ungated.y[-1], rest, rtol=1e-9, atol=1e-9)
    assert np.abs(ungated.y[-1] - g).max() > 0.05  # visibly off the goal


def test_rollout_gradient_with_respect_to_forcing_weights(eng):
    c, h = dmp.basis_centres(4, 3.0, 1.0)
    w = np.array([[1.0], [-2.0], [0.5], [3.0]])

    def loss(weights, xp=np):
        f = dmp.Forcing(weights, c, h, 3.0)
        r = dmp.rollout(xp.zeros(1), xp.zeros(1), 1.0, 4.0, 1.0, 0.05, 20, forcing=f, xp=xp)
        return xp.sum(r.y ** 2)

    g = np.asarray(eng.grad(lambda v: loss(v, eng.xp))(w))
    np.testing.assert_allclose(g, central_diff(loss, w), rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: dmp.phase(1.0, 0.0), "alpha_x=0.0"),
        (lambda: dmp.phase(-1.0, 1.0), "t=-1.0"),
        (lambda: dmp.phase(1.0, 1.0, tau=-2.0), "tau=-2.0"),
        (lambda: dmp.canonical_system(-1, 0.5, 1.0), "steps=-1"),
        (lambda: dmp.canonical_system(3, 0.0, 1.0), "dt=0.0"),
        (lambda: dmp.basis_centres(1, 1.0, 1.0), "n_basis=1"),
        (lambda: dmp.basis_centres(5, 1.0, 0.0), "duration=0.0"),
        (lambda: dmp.basis_centres(5, 1.0, 1.0, overlap=1.5), "overlap=1.5"),
        (lambda: dmp.basis_functions(0.5, [0.1, 0.2], [1.0]), "centres and widths"),
        (lambda: dmp.fit_forcing_weights(np.zeros((2, 1)), 0.1), r"shape \(2, 1\)"),
        (lambda: dmp.fit_forcing_weights(np.zeros((5, 1)), -0.1), "dt=-0.1"),
        (lambda: dmp.fit_forcing_weights(np.zeros((5, 1)), 0.1, alpha=-1.0), "alpha=-1.0"),
        (lambda: dmp.fit_forcing_weights(np.zeros((5, 1)), 0.1, n_basis=0), "n_basis=0"),
        (lambda: dmp.fit_forcing_weights([[0.0], [np.nan], [1.0]], 0.1), "demo"),
        (lambda: dmp.rollout(0.0, 0.0, 1.0, 1.0, 1.0, tau=0.0), "tau=0.0"),
    ],
)
def test_forcing_bad_input_raises_value_error_naming_parameter(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_forcing_type_errors():
    with pytest.raises(TypeError, match="forcing must be a dmp.Forcing"):
        dmp.rollout(0.0, 0.0, 1.0, 1.0, 1.0, forcing=np.zeros(3))
    with pytest.raises(TypeError, match="gate must be True or False"):
        dmp.rollout(0.0, 0.0, 1.0, 1.0, 1.0, gate="no")

