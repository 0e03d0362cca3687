"""Tests for minimanc.dmp (chapter 3): eqs. 10, 12, 13, integrators, step stability, gains."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import dmp, engine
from minimanc.autodiff.check import numerical_grad

ENGINES = ["numpy", "jax"]
finite = dict(allow_nan=False, allow_infinity=False)


@pytest.fixture(params=ENGINES)
def eng(request):
    return engine(request.param)


def central_diff(f, x, eps=1e-6):
    """Central differences of a scalar function of one array (the library's oracle)."""
    return numerical_grad(f, [x], 0, eps)[0]


def critically_damped_solution(e0, v0, omega, t):
    """Analytic solution of ë + 2ωė + ω²e = 0 (β = α/4, ω = α/2)."""
    c = v0 + omega * e0
    decay = np.exp(-omega * t)
    return (e0 + c * t) * decay, (v0 - omega * c * t) * decay


# --------------------------------------------------------------------------- continuous system


@settings(max_examples=50, deadline=None)
@given(st.floats(0.01, 100, **finite), st.floats(0.01, 100, **finite))
def test_damping_ratio_is_half_sqrt_alpha_over_beta(alpha, beta):
    zeta = dmp.damping_ratio(alpha, beta)
    assert np.isclose(zeta, 0.5 * np.sqrt(alpha / beta), rtol=1e-12)
    lam = dmp.eigenvalues(alpha, beta)
    # ω_n² = αβ = product of roots, 2ζω_n = α = −sum of roots
    assert np.isclose(np.prod(lam).real, alpha * beta, rtol=1e-9)
    assert np.isclose(-np.sum(lam).real, 2 * zeta * np.sqrt(alpha * beta), rtol=1e-9)


def test_damping_ratio_known_values_and_negative_zeta():
    assert dmp.damping_ratio(4.0, 1.0) == pytest.approx(1.0)
    assert dmp.damping_ratio(1.0, 1.0) == pytest.approx(0.5)
    assert dmp.damping_ratio(-4.0, -1.0) == pytest.approx(-1.0)  # the paper's ζ < 0
    assert dmp.classify(-4.0, -1.0) == "unstable"
    z = dmp.damping_ratio(np.array([1.0, 16.0]), np.array([[1.0], [4.0]]))
    assert z.shape == (2, 2) and np.allclose(z, [[0.5, 2.0], [0.25, 1.0]])


@settings(max_examples=50, deadline=None)
@given(st.floats(-50, 50, **finite), st.floats(-50, 50, **finite))
def test_eigenvalues_solve_characteristic_polynomial(alpha, beta):
    lam = dmp.eigenvalues(alpha, beta)
    resid = lam**2 + alpha * lam + alpha * beta
    assert np.all(np.abs(resid) <= 1e-9 * (1 + alpha**2 + abs(alpha * beta)))


gain = st.floats(-30, 30, **finite).filter(lambda x: x == 0 or abs(x) > 1e-6)


@settings(max_examples=50, deadline=None)
@given(gain, gain)
def test_classify_agrees_with_eigenvalues(alpha, beta):
    kind = dmp.classify(alpha, beta)
    lam = dmp.eigenvalues(alpha, beta)
    scale = abs(alpha) + 1e-300
    if kind == "unstable":
        # not asymptotically stable: some root has a non-negative real part
        assert lam.real.max() >= 0
        return
    assert lam.real.max() < 0
    gap = abs(lam[0] - lam[1]) / scale
    if kind == "underdamped":
        assert np.all(np.abs(lam.imag) > 0) and np.isclose(lam[0].real, -alpha / 2)
    elif kind == "overdamped":
        assert np.all(lam.imag == 0) and gap > 0
    else:
        assert kind == "critically damped"
        assert gap < 1e-4 and np.allclose(lam, -alpha / 2, rtol=1e-4)


@settings(max_examples=30, deadline=None)
@given(st.floats(0.01, 100, **finite))
def test_classify_boundaries(alpha):
    assert dmp.classify(alpha, alpha / 4) == "critically damped"
    assert dmp.classify(alpha, alpha / 4 * 1.01) == "underdamped"
    assert dmp.classify(alpha, alpha / 4 * 0.99) == "overdamped"
    assert dmp.classify(alpha, 0.0) == "unstable"
    assert dmp.classify(0.0, alpha) == "unstable"
    assert dmp.classify(alpha, -alpha) == "unstable"


def test_classify_arrays():
    out = dmp.classify(np.array([1.0, 4.0, 9.0, -1.0]), 1.0)
    assert list(out) == ["underdamped", "critically damped", "overdamped", "unstable"]
    assert isinstance(dmp.classify(4.0, 1.0), str)


# --------------------------------------------------------------------------- integrators


@pytest.mark.parametrize("e0, v0", [(1.0, 0.0), (-2.0, 3.0), (0.5, -4.0)])
def test_rk4_matches_critically_damped_analytic_solution(e0, v0):
    alpha = 4.0
    goal = 2.0
    steps, dt = 20, dmp.DT
    r = dmp.rollout(np.array([goal + e0]), np.array([v0]), goal, alpha, alpha / 4, dt, steps,
                    method="rk4", substeps=20)
    t = np.arange(steps + 1) * dt
    e, v = critically_damped_solution(e0, v0, alpha / 2, t)
    assert np.max(np.abs(r.y[:, 0] - goal - e)) < 1e-6
    assert np.max(np.abs(r.dy[:, 0] - v)) < 1e-6


@pytest.mark.parametrize("method", ["euler", "semi_implicit"])
def test_first_order_methods_converge_to_analytic_solution(method):
    """Halving h halves the error: both Euler variants are first order."""
    alpha, e0, v0 = 3.0, 1.0, 0.5
    errs = []
    for substeps in (20, 40, 80):
        r = dmp.rollout(np.array([e0]), np.array([v0]), 0.0, alpha, alpha / 4, 0.5, 8,
                        method=method, substeps=substeps)
        e, _ = critically_damped_solution(e0, v0, alpha / 2, np.arange(9) * 0.5)
        errs.append(np.max(np.abs(r.y[:, 0] - e)))
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert np.all((ratios > 1.8) & (ratios < 2.2)), ratios


@pytest.mark.parametrize("method", dmp.METHODS)
@pytest.mark.parametrize("substeps", [1, 3])
def test_step_matrix_is_the_step_map(method, substeps):
    rng = np.random.default_rng(0)
    alpha, beta, goal = 2.5, 0.7, 1.3
    y, dy = rng.normal(size=5), rng.normal(size=5)
    y1, dy1, ddy = dmp.step(y, dy, goal, alpha, beta, 0.5, method, substeps)
    M = dmp.step_matrix(alpha, beta, 0.5, method, substeps)
    pred = M @ np.stack([y - goal, dy])
    assert np.allclose(pred[0], y1 - goal) and np.allclose(pred[1], dy1)
    assert np.allclose(dy1, dy + 0.5 * ddy)


def test_euler_single_step_acceleration_is_eq10():
    y, dy, goal, a, b = 1.0, -0.5, 3.0, 2.0, 0.75
    y1, dy1, ddy = dmp.step(y, dy, goal, a, b, 0.5, "euler", 1)
    assert ddy == pytest.approx(a * (b * (goal - y) - dy))
    assert y1 == pytest.approx(y + 0.5 * dy)
    _, _, ddy_si = dmp.step(y, dy, goal, a, b, 0.5, "semi_implicit", 1)
    assert ddy_si == pytest.approx(ddy)  # velocity update identical; position differs


def test_rollout_shapes_batch_and_broadcast():
    rng = np.random.default_rng(1)
    B, D, T = 4, 3, 7
    y0, dy0, goal = rng.normal(size=(B, D)), rng.normal(size=(B, D)), rng.normal(size=(B, D))
    alpha = rng.uniform(1, 4, size=(B, 1))
    r = dmp.rollout(y0, dy0, goal, alpha, 1.0, steps=T)
    assert r.y.shape == (T + 1, B, D) and r.dy.shape == (T + 1, B, D) and r.ddy.shape == (T, B, D)
    for b in range(B):  # batch entries are independent
        rb = dmp.rollout(y0[b], dy0[b], goal[b], alpha[b], 1.0, steps=T)
        assert np.allclose(rb.y, r.y[:, b])
    # one start, many goals: the initial state is broadcast to the batch
    r2 = dmp.rollout(np.zeros(D), np.zeros(D), goal, 2.0, 1.0, steps=T)
    assert r2.y.shape == (T + 1, B, D) and np.all(r2.y[0] == 0)
    r0 = dmp.rollout(y0, dy0, goal, 2.0, 1.0, steps=0)
    assert r0.y.shape == (1, B, D) and r0.ddy.shape == (0, B, D)


def test_rollout_time_varying_goal_and_gains_match_manual_steps():
    rng = np.random.default_rng(2)
    T, D = 12, 2
    goals = np.cumsum(rng.normal(size=(T, D)), axis=0)  # a moving goal
    alphas = rng.uniform(1, 8, size=(T, 1))
    betas = rng.uniform(0.2, 2, size=(T, 1))
    r = dmp.rollout(np.zeros(D), np.zeros(D), goals, alphas, betas, 0.5, T, method="rk4",
                    substeps=2, per_step=("goal", "alpha", "beta"))
    y, dy = np.zeros(D), np.zeros(D)
    for k in range(T):
        y, dy, ddy = dmp.step(y, dy, goals[k], alphas[k], betas[k], 0.5, "rk4", 2)
        assert np.allclose(r.y[k + 1], y) and np.allclose(r.ddy[k], ddy)


def test_moving_goal_is_tracked_with_constant_lag():
    """A goal moving at speed c is followed at speed c and a constant lag.

    For the continuous ramp g = c t, eq. (10) settles at ẏ = c with lag c/β.
    The per-step goal g_k = c (k + 1) dt is held over each step, on average
    c dt/2 ahead of the ramp, so the lag behind the ramp is about c/β − c dt/2.
    """
    T, c, beta, dt = 80, 2.0, 1.0, 0.5
    goals = c * dt * np.arange(1, T + 1)[:, None]
    r = dmp.rollout(np.zeros(1), np.zeros(1), goals, 6.0, beta, dt, T, per_step=("goal",))
    assert np.allclose(np.diff(r.y[-10:, 0]), c * dt, atol=1e-6)
    lag = c * dt * np.arange(T + 1) - r.y[:, 0]
    assert np.allclose(lag[-10:], lag[-1], atol=1e-6)
    assert abs(lag[-1] - (c / beta - c * dt / 2)) < 0.1


# --------------------------------------------------------------------------- discrete stability


def test_textbook_gains_diverge_with_explicit_euler_at_half_a_second():
    assert dmp.damping_ratio(25.0, 25.0 / 4) == pytest.approx(1.0)
    assert dmp.spectral_radius(25.0, 25.0 / 4, 0.5, "euler", 1) == pytest.approx(5.25)
    assert not dmp.step_stable(25.0, 25.0 / 4, 0.5, "euler", 1)
    with pytest.raises(ValueError, match=r"spectral radius of one step is 5\.25 > 1"):
        dmp.rollout(np.ones(1), np.zeros(1), 0.0, 25.0, 25.0 / 4, 0.5, 10, "euler", 1)
    with pytest.warns(RuntimeWarning, match=r"5\.25 > 1.*allow_unstable=True"):
        r = dmp.rollout(np.ones(1), np.zeros(1), 0.0, 25.0, 25.0 / 4, 0.5, 10, "euler", 1,
                        allow_unstable=True)
    assert abs(r.y[-1, 0]) > 1e6
    # sub-stepping restores stability: h α = 3.125 < 4
    assert dmp.step_stable(25.0, 25.0 / 4, 0.5, "euler", 4)
    r = dmp.rollout(np.ones(1), np.zeros(1), 0.0, 25.0, 25.0 / 4, 0.5, 10, "euler", 4)
    assert abs(r.y[-1, 0]) < 1e-6


@settings(max_examples=40, deadline=None)
@given(st.floats(0.1, 30, **finite), st.floats(0.05, 10, **finite),
       st.sampled_from(dmp.METHODS), st.integers(1, 4))
def test_spectral_radius_matches_numerical_eigenvalues(alpha, beta, method, substeps):
    if abs(dmp.damping_ratio(alpha, beta) - 1) < 1e-3:
        return  # defective matrix: the numerical eigensolver loses half the digits
    M = dmp.step_matrix(alpha, beta, 0.5, method, substeps)
    rho = np.abs(np.linalg.eigvals(M)).max()
    assert np.isclose(dmp.spectral_radius(alpha, beta, 0.5, method, substeps), rho,
                      rtol=1e-6, atol=1e-12)


@pytest.mark.parametrize("method", dmp.METHODS)
@pytest.mark.parametrize("beta", [0.05, 0.5, 1.5, 5.0])
@pytest.mark.parametrize("substeps", [1, 2])
def test_max_stable_alpha_is_the_stability_boundary(method, beta, substeps):
    a_max = dmp.max_stable_alpha(beta, 0.5, method, substeps)
    h = 0.5 / substeps
    if method == "euler" and h * beta >= 1:
        assert a_max == 0.0
        grid = np.linspace(0.01, 40, 400)
        assert not np.any(dmp.step_stable(grid, beta, 0.5, method, substeps))
        return
    assert a_max > 0
    inside = np.linspace(1e-3, 0.999, 300) * a_max
    assert np.all(dmp.step_stable(inside, beta, 0.5, method, substeps))
    assert dmp.spectral_radius(a_max * 1.002, beta, 0.5, method, substeps) > 1.0


def test_max_stable_alpha_closed_forms():
    # reference facts: critically damped explicit Euler needs α·dt < 4; β = 0.5 → α·dt ≈ 2.29
    assert dmp.max_stable_alpha(0.5, 0.5, "euler", 1) * 0.5 == pytest.approx(16 / 7)
    for alpha in (2.0, 7.9):
        assert dmp.step_stable(alpha, alpha / 4, 0.5, "euler", 1)
    assert not dmp.step_stable(8.1, 8.1 / 4, 0.5, "euler", 1)
    assert dmp.max_stable_alpha(1.0, 0.5, "semi_implicit", 1) == pytest.approx(4 / (0.5 * 2.5))


# --------------------------------------------------------------------------- learned gains


def test_default_gain_box_is_stable_everywhere():
    """Proof over the whole box, not a sample.

    Semi-implicit Euler's sub-step matrix has det = 1 − hα and trace
    2 − hα − h²αβ; by Jury's test it is stable iff 0 < hα < 2 and
    4 − 2hα − h²αβ > 0. Both conditions get harder as α or β grow, so the
    corner (α_max, β_max) is the worst case; check it with a margin, then
    confirm on a dense grid.
    """
    assert dmp.DEFAULT_METHOD == "semi_implicit"
    h = dmp.DT / dmp.DEFAULT_SUBSTEPS
    a_max, b_max = dmp.ALPHA_RANGE[1], dmp.BETA_RANGE[1]
    assert h * a_max < 2 * 0.6
    assert 4 - 2 * h * a_max - h * h * a_max * b_max > 1.0
    assert a_max < dmp.max_stable_alpha(b_max, dmp.DT)
    A, B = np.meshgrid(np.linspace(*dmp.ALPHA_RANGE, 300), np.linspace(*dmp.BETA_RANGE, 300))
    rho = dmp.spectral_radius(A, B, dmp.DT)
    assert rho.max() < 0.98
    # ... which the explicit Euler single step at DT would not be
    assert not np.all(dmp.step_stable(A, B, dmp.DT, "euler", 1))


@settings(max_examples=40, deadline=None)
@given(st.floats(-1e4, 1e4, **finite), st.floats(-1e4, 1e4, **finite))
def test_gains_from_logits_stay_in_range_and_zeta_positive(za, zb):
    a, b = dmp.gains_from_logits(np.float64(za), np.float64(zb))
    assert dmp.ALPHA_RANGE[0] <= a <= dmp.ALPHA_RANGE[1]
    assert dmp.BETA_RANGE[0] <= b <= dmp.BETA_RANGE[1]
    zeta = dmp.damping_ratio(a, b)
    assert zeta >= 0.5 * np.sqrt(dmp.ALPHA_RANGE[0] / dmp.BETA_RANGE[1]) - 1e-12
    a_c, b_c = dmp.gains_from_logits(np.float64(za), None, critically_damped=True)
    assert b_c == a_c / 4 and dmp.classify(a_c, b_c) == "critically damped"
    assert dmp.BETA_RANGE[0] <= b_c <= dmp.BETA_RANGE[1]


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_rollouts_with_learned_gains_converge_at_package_dt(seed):
    rng = np.random.default_rng(seed)
    B, D = 32, 2
    za, zb = rng.normal(scale=4, size=(2, B, 1))
    alpha, beta = dmp.gains_from_logits(za, zb)
    y0 = rng.uniform(-50, 50, size=(B, D))
    dy0 = rng.uniform(-10, 10, size=(B, D))
    goal = rng.uniform(-50, 50, size=(B, D))
    r = dmp.rollout(y0, dy0, goal, alpha, beta, dmp.DT, steps=400)
    scale = np.abs(y0 - goal).max() + np.abs(dy0).max()
    assert np.all(np.isfinite(r.y))
    assert np.abs(r.y[-1] - goal).max() < 1e-3 * scale
    assert np.abs(r.dy[-1]).max() < 1e-3 * scale


def test_logits_from_gains_inverts_gains_from_logits():
    z = np.linspace(-5, 5, 11)
    a, b = dmp.gains_from_logits(z, -z)
    za, zb = dmp.logits_from_gains(a, b)
    assert np.allclose(za, z) and np.allclose(zb, -z)


def test_zeta_penalty_values():
    assert dmp.zeta_penalty(np.array([4.0, 8.0]), np.array([1.0, 1.0])) == 0.0
    # ζ = 0.25 for α = β/4: penalty (0.5 − 0.25)² averaged with a zero
    p = dmp.zeta_penalty(np.array([1.0, 4.0]), np.array([4.0, 1.0]), zeta_min=0.5)
    assert p == pytest.approx(0.25**2 / 2)


# --------------------------------------------------------------------------- gradients


def _bc_loss(params, xp):
    """A behaviour-cloning-like loss through a rollout with learned, time-varying gains."""
    za, zb, goal = params
    alpha, beta = dmp.gains_from_logits(za, zb, xp=xp)
    y0 = xp.asarray(np.array([[0.0, 1.0], [2.0, -1.0]]))
    r = dmp.rollout(y0, xp.zeros((2, 2)), goal, alpha, beta, 0.5, 4, substeps=10,
                    per_step=("alpha", "beta"), xp=xp)
    target = xp.asarray(np.linspace(0, 1, 4 * 2 * 2).reshape(4, 2, 2))
    return xp.mean((r.dy[1:] - target) ** 2) + 0.1 * dmp.zeta_penalty(alpha, beta, xp=xp)


def _params():
    rng = np.random.default_rng(3)
    return [rng.normal(size=(4, 2, 1)), rng.normal(size=(4, 2, 1)) - 3.0,
            rng.normal(size=(2, 2))]


@pytest.mark.parametrize("method", dmp.METHODS)
def test_rollout_gradients_numpy_engine_equal_jax(method):
    np_eng, jax_eng = engine("numpy"), engine("jax")
    params = [p[:2] if p.ndim == 3 else p for p in _params()]

    def loss(p, xp):
        za, zb, goal = p
        alpha, beta = dmp.gains_from_logits(za, zb, xp=xp)
        r = dmp.rollout(xp.zeros(2), xp.ones(2), goal, alpha, beta, 0.5, 2, method=method,
                        substeps=2, per_step=("alpha", "beta"), xp=xp)
        return xp.sum(r.y[-1] ** 2) + xp.sum(r.ddy**2)

    g_np = np_eng.grad(lambda p: loss(p, np_eng.xp))(params)
    g_jax = jax_eng.grad(lambda p: loss(p, jax_eng.xp))(params)
    for a, b in zip(g_np, g_jax):
        assert np.allclose(a, np.asarray(b), rtol=1e-6, atol=1e-9)


def test_rollout_gradients_match_finite_differences():
    eng = engine("numpy")
    params = _params()
    grads = eng.grad(lambda p: _bc_loss(p, eng.xp))(params)
    for i in range(3):
        def f(x, i=i):
            p = list(params)
            p[i] = x
            return float(_bc_loss(p, np))
        assert np.allclose(np.asarray(grads[i]), central_diff(f, params[i]), rtol=1e-5,
                           atol=1e-8)


def test_zeta_penalty_gradient(eng):
    a = np.array([0.5, 1.0, 8.0])
    b = np.array([4.0, 1.5, 1.0])
    g = eng.jit(eng.grad(lambda a: dmp.zeta_penalty(a, b, xp=eng.xp, zeta_min=0.8)))(a)
    fd = central_diff(lambda x: dmp.zeta_penalty(x, b, zeta_min=0.8), a)
    assert np.allclose(np.asarray(g), fd, atol=1e-8)
    assert g[0] < 0 and g[1] < 0 and g[2] == 0  # raising α raises ζ; satisfied entries inert


def test_jit_rollout_matches_numpy():
    jax_eng = engine("jax")
    f = jax_eng.jit(lambda a: dmp.rollout(jax_eng.xp.zeros(2), jax_eng.xp.zeros(2), 1.0, a, 1.0,
                                          0.5, 3, xp=jax_eng.xp).y)
    assert np.allclose(np.asarray(f(3.0)), dmp.rollout(np.zeros(2), np.zeros(2), 1.0, 3.0, 1.0,
                                                       0.5, 3).y)


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


def test_negative_gains_zeta_below_zero_run_only_when_allowed():
    with pytest.raises(ValueError, match=r"alpha must be > 0 .*allow_unstable=True"):
        dmp.rollout(np.ones(1), np.zeros(1), 0.0, -2.0, -0.5, 0.5, 10)
    with pytest.warns(RuntimeWarning, match=r"zeta=-1\b.*unstable") as record:
        r = dmp.rollout(np.ones(1), np.zeros(1), 0.0, -2.0, -0.5, 0.5, 10, allow_unstable=True)
    assert len(record) == 1
    assert dmp.damping_ratio(-2.0, -0.5) == pytest.approx(-1.0)
    assert abs(r.y[-1, 0]) > 100 * abs(r.y[0, 0])  # runs away from the goal
