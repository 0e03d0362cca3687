"""Tests for minimanc.quaternion (chapter 4): eqs. 2-6, conversions, the quaternion DMP (eq. 10)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from minimanc import dmp, engine
from minimanc import quaternion as Q
from minimanc.autodiff.check import numerical_grad

ENGINES = ["numpy", "jax"]
ID = np.array([1.0, 0.0, 0.0, 0.0])
SETTINGS = settings(max_examples=40, deadline=None)
finite = dict(allow_nan=False, allow_infinity=False)


@pytest.fixture(params=ENGINES)
def eng(request):
    return engine(request.param)


def wrap(a):
    """Angle into (−π, π]."""
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


def central_diff(f, x, eps=1e-6):
    """Central differences of a scalar function of one array (the library's oracle)."""
    return numerical_grad(f, [x], 0, eps)[0]


@st.composite
def unit_quaternions(draw, shape=()):
    v = draw(hnp.arrays(np.float64, tuple(shape) + (4,),
                        elements=st.floats(-1, 1, allow_nan=False, allow_infinity=False)))
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    assume(np.all(n > 1e-3))
    return v / n


def vectors(bound=10.0, shape=(3,)):
    return hnp.arrays(np.float64, shape, elements=st.floats(-bound, bound, allow_nan=False,
                                                            allow_infinity=False))


def same_rotation(p, q, atol=1e-9):
    return np.allclose(p, q, atol=atol) or np.allclose(p, -q, atol=atol)


# --------------------------------------------------------------------------- algebra


@SETTINGS
@given(unit_quaternions(), unit_quaternions(), unit_quaternions())
def test_multiply_unit_norm_and_associativity(p, q, r):
    assert np.isclose(np.linalg.norm(Q.multiply(p, q)), 1.0)
    assert np.allclose(Q.multiply(Q.multiply(p, q), r), Q.multiply(p, Q.multiply(q, r)))
    assert np.allclose(Q.conjugate(Q.multiply(p, q)), Q.multiply(Q.conjugate(q), Q.conjugate(p)))


@SETTINGS
@given(unit_quaternions())
def test_q_times_conjugate_is_identity(q):
    assert np.allclose(Q.multiply(q, Q.conjugate(q)), ID)
    assert np.allclose(Q.multiply(Q.conjugate(q), q), ID)
    assert np.allclose(Q.multiply(ID, q), q) and np.allclose(Q.multiply(q, ID), q)


def test_multiply_matches_eq3_and_hamilton_units():
    i, j, k = np.eye(4)[1], np.eye(4)[2], np.eye(4)[3]
    assert np.allclose(Q.multiply(i, j), k) and np.allclose(Q.multiply(j, i), -k)
    assert np.allclose(Q.multiply(i, i), -ID)
    rng = np.random.default_rng(0)
    p, q = rng.normal(size=4), rng.normal(size=4)  # eq. 3 holds for any quaternions
    v1, u1, v2, u2 = p[0], p[1:], q[0], q[1:]
    expected = np.concatenate([[v1 * v2 - u1 @ u2], v1 * u2 + v2 * u1 + np.cross(u1, u2)])
    assert np.allclose(Q.multiply(p, q), expected)


def test_broadcasting_and_batches():
    rng = np.random.default_rng(1)
    p = Q.normalize(rng.normal(size=(5, 1, 4)))
    q = Q.normalize(rng.normal(size=(3, 4)))
    pq = Q.multiply(p, q)
    assert pq.shape == (5, 3, 4)
    assert np.allclose(pq[2, 1], Q.multiply(p[2, 0], q[1]))
    assert Q.log(pq).shape == (5, 3, 3) and Q.to_matrix(pq).shape == (5, 3, 3, 3)
    assert Q.rotate(pq, np.ones(3)).shape == (5, 3, 3)
    assert Q.identity((2, 3)).shape == (2, 3, 4)


# --------------------------------------------------------------------------- log and exp


@SETTINGS
@given(unit_quaternions())
def test_exp_log_roundtrip(q):
    assume(np.linalg.norm(q[1:]) > 1e-6)  # log(−1) is undefined (and −q for q ≈ 1)
    w = Q.log(q)
    assert np.linalg.norm(w) <= np.pi + 1e-12
    assert np.allclose(Q.exp(w), q, atol=1e-9)  # exactly q, not merely up to sign
    assert same_rotation(Q.exp(Q.log(-q)), q)


@SETTINGS
@given(vectors(np.pi))
def test_log_exp_roundtrip_and_wraparound(w):
    n = np.linalg.norm(w)
    assume(1e-6 < n < np.pi - 1e-6)
    q = Q.exp(w)
    assert np.isclose(np.linalg.norm(q), 1.0)
    assert np.allclose(Q.log(q), w, atol=1e-8)
    # beyond π: exp wraps, log returns ω − 2π ω/‖ω‖ (same quaternion, different vector)
    w_long = w / n * (2 * np.pi - n)
    assert np.allclose(Q.log(Q.exp(w_long)), w_long - 2 * np.pi * w / n, atol=1e-8)
    assert np.allclose(Q.exp(w + 2 * np.pi * w / n), q)  # exp has period 2π along each ray


def test_log_matches_arccos_form_of_eq4():
    rng = np.random.default_rng(2)
    q = Q.normalize(rng.normal(size=(20, 4)))
    u = q[:, 1:]
    ref = np.arccos(q[:, :1]) * u / np.linalg.norm(u, axis=1, keepdims=True)
    assert np.allclose(Q.log(q), ref)
    assert np.allclose(Q.log(ID), 0.0) and np.allclose(Q.exp(np.zeros(3)), ID)


def test_log_is_accurate_near_identity():
    eps = 1e-9
    q = np.array([np.cos(eps), np.sin(eps), 0.0, 0.0])
    assert np.isclose(Q.log(q)[0], eps, rtol=1e-12)  # arccos(w) would give 0 here
    tiny = np.array([1.0, 1e-14, -2e-14, 0.0])
    assert np.allclose(Q.log(Q.normalize(tiny)), tiny[1:], rtol=1e-12, atol=0)


def test_exp_at_pi_is_minus_one_and_log_minus_one_raises():
    assert np.allclose(Q.exp(np.array([0.0, 0.0, np.pi])), -ID)
    with pytest.raises(ValueError, match="q = -1"):
        Q.log(-ID)
    with pytest.raises(ValueError, match="q = -1"):
        Q.log(np.stack([ID, -ID]))
    # the orientation error never needs log(−1): −1 is the identity rotation
    assert np.allclose(Q.orientation_error(-ID, ID), 0.0)


def test_log_of_minus_one_on_traced_values_is_finite(eng):
    out = eng.grad(lambda q: Q.log(q, xp=eng.xp).sum())(-ID)
    val = Q.log(eng.xp.asarray(-ID), xp=eng.xp) if eng.name == "jax" else None
    assert np.all(np.isfinite(np.asarray(out)))
    if val is not None:  # jax arrays are not checked: documented value ≈ 0
        assert np.allclose(np.asarray(val), 0.0)


# --------------------------------------------------------------------------- rotations


@SETTINGS
@given(unit_quaternions(), unit_quaternions(), vectors())
def test_rotate_preserves_length_matches_matrix_and_composes(q, p, v):
    r = Q.rotate(q, v)
    R = Q.to_matrix(q)
    assert np.isclose(np.linalg.norm(r), np.linalg.norm(v))
    assert np.allclose(r, R @ v, atol=1e-9)
    assert np.allclose(R.T @ R, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
    assert np.allclose(Q.to_matrix(-q), R)
    assert np.allclose(Q.rotate(Q.multiply(p, q), v), Q.rotate(p, Q.rotate(q, v)), atol=1e-9)
    # q v q̄ with v as a pure quaternion
    pure = np.concatenate([[0.0], v])
    assert np.allclose(Q.multiply(Q.multiply(q, pure), Q.conjugate(q))[1:], r, atol=1e-9)


@SETTINGS
@given(vectors(1.0), st.floats(1e-3, np.pi - 1e-3))
def test_axis_angle_roundtrip(axis, angle):
    assume(np.linalg.norm(axis) > 1e-3)
    n = axis / np.linalg.norm(axis)
    q = Q.from_axis_angle(axis, angle)
    a2, ang2 = Q.to_axis_angle(q)
    assert np.allclose(a2, n) and np.isclose(ang2, angle)
    assert np.allclose(Q.to_rotation_vector(q), angle * n)
    assert np.allclose(Q.from_rotation_vector(angle * n), q)
    # rotating a perpendicular vector by `angle` about n
    perp = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    perp /= np.linalg.norm(perp)
    assert np.isclose(np.dot(Q.rotate(q, perp), perp), np.cos(angle))
    # the long way round (2π − angle) comes back as the short rotation about −n
    a3, ang3 = Q.to_axis_angle(Q.from_axis_angle(axis, 2 * np.pi - angle))
    assert np.allclose(a3, -n) and np.isclose(ang3, angle)


def test_axis_angle_at_identity():
    axis, angle = Q.to_axis_angle(ID)
    assert np.allclose(axis, [1.0, 0.0, 0.0]) and angle == 0.0


@SETTINGS
@given(st.floats(-20, 20))
def test_yaw_roundtrip(psi):
    q = Q.from_yaw(psi)
    assert np.isclose(np.cos(Q.to_yaw(q) - psi), 1.0)
    assert -np.pi < Q.to_yaw(q) <= np.pi
    heading = Q.rotate(q, np.array([1.0, 0.0, 0.0]))
    assert np.allclose(heading, [np.cos(psi), np.sin(psi), 0.0])


@SETTINGS
@given(unit_quaternions())
def test_to_yaw_is_heading_of_rotated_x_axis(q):
    x = Q.rotate(q, np.array([1.0, 0.0, 0.0]))
    assume(np.hypot(x[0], x[1]) > 1e-3)
    assert np.isclose(np.cos(Q.to_yaw(q) - np.arctan2(x[1], x[0])), 1.0)


# --------------------------------------------------------------------------- integration and error


@SETTINGS
@given(unit_quaternions(), vectors(3.0), st.integers(1, 50), st.floats(0.01, 0.5))
def test_integrating_constant_omega_is_exact(q, eta, n, dt):
    out = q
    for _ in range(n):
        out = Q.integrate(out, eta, dt)
        assert np.isclose(np.linalg.norm(out), 1.0, atol=1e-12)
    assert np.allclose(out, Q.multiply(Q.exp(n * dt * eta / 2), q), atol=1e-9)
    assert np.allclose(Q.integrate(q, eta, dt, tau=2.0), Q.integrate(q, eta / 2, dt))


@SETTINGS
@given(unit_quaternions(), unit_quaternions())
def test_orientation_error_rotates_q_onto_g_the_short_way(g, q):
    assume(abs(Q.multiply(g, Q.conjugate(q))[0]) > 1e-9)  # exactly 180°: both ways are short
    e = Q.orientation_error(g, q)
    assert np.linalg.norm(e) <= np.pi + 1e-9
    assert same_rotation(Q.multiply(Q.from_rotation_vector(e), q), g)
    assert np.allclose(Q.orientation_error(-g, q), e) and np.allclose(Q.orientation_error(g, -q), e)
    assert np.allclose(Q.orientation_error(q, q), 0.0, atol=1e-12)


@SETTINGS
@given(st.floats(-10, 10), st.floats(-10, 10))
def test_orientation_error_yaw_only_is_wrapped_yaw_difference(psi_g, psi):
    d = wrap(psi_g - psi)
    assume(abs(abs(d) - np.pi) > 1e-6)  # exactly ±π both ways are equally short
    e = Q.orientation_error(Q.from_yaw(psi_g), Q.from_yaw(psi))
    assert np.allclose(e, [0.0, 0.0, d], atol=1e-9)


# --------------------------------------------------------------------------- gradients


def test_gradients_at_identity_are_finite_and_exact(eng):
    xp = eng.xp
    J_log = np.stack([np.asarray(eng.grad(lambda q, i=i: Q.log(q, xp=xp)[i])(ID))
                      for i in range(3)])
    assert np.allclose(J_log, np.hstack([np.zeros((3, 1)), np.eye(3)]))
    J_exp = np.stack([np.asarray(eng.grad(lambda w, i=i: Q.exp(w, xp=xp)[i])(np.zeros(3)))
                      for i in range(4)])
    assert np.allclose(J_exp, np.vstack([np.zeros((1, 3)), np.eye(3)]))
    g = eng.grad(lambda q: xp.sum(Q.orientation_error(ID, q, xp=xp) ** 2))(ID)
    assert np.all(np.isfinite(np.asarray(g))) and np.allclose(np.asarray(g), 0.0)
    g = eng.grad(lambda q: xp.sum(Q.to_rotation_vector(q, xp=xp)))(ID)
    assert np.all(np.isfinite(np.asarray(g)))
    # a DMP that starts at its goal, at rest: every gradient finite
    g = eng.grad(lambda a: xp.sum(Q.quaternion_rollout(ID, np.zeros(3), ID, a, 1.0, steps=2,
                                                       substeps=2, xp=xp).q))(3.0)
    assert np.isfinite(float(g))


def _quat_loss(params, xp):
    q, omega, g = params
    qn = Q.normalize(q, xp=xp)
    e = Q.orientation_error(g, Q.multiply(Q.exp(omega, xp=xp), qn, xp=xp), xp=xp)
    r = Q.rotate(qn, xp.asarray(np.array([1.0, 2.0, 3.0])), xp=xp)
    return (xp.sum(e * xp.asarray(np.array([1.0, -2.0, 0.5])))
            + xp.sum(Q.log(qn, xp=xp) ** 2) + xp.sum(r * r * r) + xp.sum(Q.to_yaw(qn, xp=xp))
            + xp.sum(Q.to_matrix(g, xp=xp)[..., 0, :]))


def _quat_params():
    rng = np.random.default_rng(4)
    return [Q.normalize(rng.normal(size=(2, 4))), rng.normal(size=(2, 3)) * 0.5,
            Q.normalize(rng.normal(size=(2, 4)))]


def test_gradients_match_finite_differences():
    eng = engine("numpy")
    params = _quat_params()
    grads = eng.grad(lambda p: _quat_loss(p, eng.xp))(params)
    for i in range(3):
        def f(x, i=i):
            p = list(params)
            p[i] = Q.normalize(x) if i != 1 else x
            return float(_quat_loss(p, np))
        fd = central_diff(f, params[i])
        if i != 1:  # g and q enter only through their direction: compare tangent parts
            P = np.eye(4) - params[i][..., :, None] * params[i][..., None, :]
            got = np.einsum("...ij,...j->...i", P, np.asarray(grads[i]))
        else:
            got = np.asarray(grads[i])
        assert np.allclose(got, fd, rtol=1e-5, atol=1e-7)


def _rollout_loss(params, xp, q0, gq):
    za, zb, eta0 = params
    a, b = dmp.gains_from_logits(za, zb, xp=xp)
    r = Q.quaternion_rollout(q0, eta0, gq, a, b, 0.5, 2, substeps=10, per_step=("alpha", "beta"),
                             xp=xp)
    return xp.sum(r.eta[-1] ** 2) + xp.sum(r.q[-1] * xp.asarray(np.arange(4.0)))


def test_gradients_numpy_engine_equal_jax_and_finite_differences():
    np_eng, jax_eng = engine("numpy"), engine("jax")
    rng = np.random.default_rng(5)
    q0 = Q.normalize(rng.normal(size=(2, 4)))
    gq = Q.normalize(rng.normal(size=(2, 4)))
    params = [rng.normal(size=(2, 2, 1)), rng.normal(size=(2, 2, 1)), rng.normal(size=(2, 3))]
    g_np = np_eng.grad(lambda p: _rollout_loss(p, np_eng.xp, q0, gq))(params)
    g_jax = jax_eng.grad(lambda p: _rollout_loss(p, jax_eng.xp, q0, gq))(params)
    for a, b in zip(g_np, g_jax):
        assert np.allclose(a, np.asarray(b), rtol=1e-6, atol=1e-9)
    for i in range(3):
        def f(x, i=i):
            p = list(params)
            p[i] = x
            return float(_rollout_loss(p, np, q0, gq))
        assert np.allclose(g_np[i], central_diff(f, params[i]), rtol=1e-5, atol=1e-8)
    qp = _quat_params()
    g_np = np_eng.grad(lambda p: _quat_loss(p, np_eng.xp))(qp)
    g_jax = jax_eng.grad(lambda p: _quat_loss(p, jax_eng.xp))(qp)
    for a, b in zip(g_np, g_jax):
        assert np.allclose(a, np.asarray(b), rtol=1e-6, atol=1e-9)


# --------------------------------------------------------------------------- quaternion DMP


def test_quaternion_dmp_converges_with_learned_gains():
    """Random starts, goals, angular velocities and learned gains, plus the four corners
    of the gain box (the slowest and the stiffest systems), at the package's DT."""
    rng = np.random.default_rng(8)
    B = 64
    q0 = Q.normalize(rng.normal(size=(B, 4)))
    gq = Q.normalize(rng.normal(size=(B, 4)))
    eta0 = rng.normal(size=(B, 3))
    za, zb = rng.normal(scale=3, size=(2, B, 1))
    za[:4, 0], zb[:4, 0] = [-40, -40, 40, 40], [-40, 40, -40, 40]
    alpha, beta = dmp.gains_from_logits(za, zb)
    steps = 300
    r = Q.quaternion_rollout(q0, eta0, gq, alpha, beta, dmp.DT, steps=steps)
    err0 = np.linalg.norm(Q.orientation_error(gq, q0), axis=-1) + np.linalg.norm(eta0, axis=-1)
    err = np.linalg.norm(Q.orientation_error(gq, r.q[-1]), axis=-1)
    # slowest corner (α = 20, β = 0.05): the slow root is −0.050/s, e^(−0.05·150) = 5.5e-4
    assert np.all(err < 2e-3 * err0) and np.all(np.linalg.norm(r.eta[-1], axis=-1) < 2e-3 * err0)
    assert np.allclose(np.linalg.norm(r.q, axis=-1), 1.0)
    assert r.q.shape == (steps + 1, B, 4) and r.eta.shape == (steps + 1, B, 3)
    assert r.deta.shape == (steps, B, 3)


@SETTINGS
@given(st.floats(-np.pi, np.pi), st.floats(-np.pi, np.pi), st.floats(-2, 2),
       st.floats(0.5, 8), st.floats(0.1, 3), st.sampled_from(["euler", "semi_implicit"]),
       st.integers(1, 4))
def test_yaw_only_quaternion_dmp_equals_1d_dmp_on_wrapped_error(psi0, psi_g, w0, alpha, beta,
                                                                method, substeps):
    steps, dt = 12, 0.5
    assume(dmp.step_stable(alpha, beta, dt, method, substeps))  # unstable steps are refused
    r = Q.quaternion_rollout(Q.from_yaw(psi0), np.array([0.0, 0.0, w0]), Q.from_yaw(psi_g),
                             alpha, beta, dt, steps, method=method, substeps=substeps)
    # the 1-D DMP of chapter 3, one sub-step at a time, its goal re-chosen as the nearest
    # copy of ψ_g (i.e. the error wrapped into (−π, π])
    psi, w = psi0, w0
    yaws, rates = [psi], [w]
    h = dt / substeps
    for _ in range(steps):
        for _ in range(substeps):
            # at exactly ±π both turning directions are equally short (documented tie)
            assume(abs(wrap(psi_g - psi)) < np.pi - 1e-6)
            goal = psi + wrap(psi_g - psi)
            psi, w, _ = dmp.step(psi, w, goal, alpha, beta, h, method, 1)
        yaws.append(psi)
        rates.append(w)
    assert np.allclose(r.eta[:, :2], 0.0, atol=1e-12)
    assert np.allclose(r.eta[:, 2], rates, atol=1e-8)
    assert np.allclose(np.cos(Q.to_yaw(r.q) - np.array(yaws)), 1.0, atol=1e-12)


def test_yaw_dmp_turns_the_short_way_across_pi():
    """From ψ = 170° to ψ_g = −170° the DMP turns +20° through 180°, not −340°."""
    psi0, psi_g = np.deg2rad(170.0), np.deg2rad(-170.0)
    r = Q.quaternion_rollout(Q.from_yaw(psi0), np.zeros(3), Q.from_yaw(psi_g), 4.0, 1.0,
                             steps=30)
    yaw = np.rad2deg(np.unwrap(Q.to_yaw(r.q)))
    assert np.all(np.diff(yaw) >= -1e-9)  # critically damped from rest: monotone, anticlockwise
    assert np.isclose(yaw[0], 170.0) and np.isclose(yaw[-1], 190.0, atol=1e-3)


def test_quaternion_rollout_time_varying_goal_matches_steps():
    rng = np.random.default_rng(6)
    T = 5
    goals = Q.normalize(rng.normal(size=(T, 4)))
    alphas = rng.uniform(1, 5, size=(T, 1))
    r = Q.quaternion_rollout(ID, np.zeros(3), goals, alphas, 1.0, 0.5, T,
                             per_step=("g_q", "alpha"))
    q, eta = ID, np.zeros(3)
    for k in range(T):
        q, eta, deta = Q.quaternion_step(q, eta, goals[k], alphas[k], 1.0, 0.5)
        assert np.allclose(r.q[k + 1], q) and np.allclose(r.deta[k], deta)


# --------------------------------------------------------------------------- bad input


def test_unit_tolerance_normalises_small_errors_only():
    rng = np.random.default_rng(7)
    q = Q.normalize(rng.normal(size=4))
    v = np.array([0.3, -1.0, 2.0])
    tol = Q.unit_tolerance(np.float64)
    assert np.allclose(Q.rotate(q * (1 + 0.5 * tol), v), Q.rotate(q, v), atol=1e-12)
    with pytest.raises(ValueError, match="unit quaternion"):
        Q.rotate(q * (1 + 10 * tol), v)
    assert np.allclose(Q.normalize(3 * q), q)  # normalize itself accepts any non-zero q


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: Q.normalize(np.zeros(4)), "zero quaternion"),
        (lambda: Q.log(np.zeros(4)), "zero quaternion"),
        (lambda: Q.rotate(np.zeros((2, 4)), np.ones(3)), "zero quaternion"),
        (lambda: Q.log(np.array([2.0, 0, 0, 0])), "unit quaternion"),
        (lambda: Q.to_matrix(np.array([1.0, 1, 0, 0])), "unit quaternion"),
        (lambda: Q.integrate(np.array([0.5, 0, 0, 0]), np.zeros(3), 0.5), "unit quaternion"),
        (lambda: Q.orientation_error(ID, 2 * ID), "q must be a unit"),
        (lambda: Q.orientation_error(2 * ID, ID), "g must be a unit"),
        (lambda: Q.log(-ID), "q = -1"),
        (lambda: Q.multiply(np.ones(3), ID), r"p must have shape \(\.\.\., 4\)"),
        (lambda: Q.multiply(ID, np.ones((2, 5))), r"q must have shape"),
        (lambda: Q.exp(np.ones(4)), "omega must have shape"),
        (lambda: Q.exp(np.array([np.nan, 0, 0])), "omega must be finite"),
        (lambda: Q.rotate(ID, np.ones(2)), "v must have shape"),
        (lambda: Q.log(np.array([np.inf, 0, 0, 0])), "q must be finite"),
        (lambda: Q.integrate(ID, np.zeros(3), 0.0), "dt"),
        (lambda: Q.integrate(ID, np.zeros(3), 0.5, tau=-1.0), "tau"),
        (lambda: Q.from_axis_angle(np.zeros(3), 1.0), "axis"),
        (lambda: Q.quaternion_rollout(ID, np.zeros(3), ID, 1.0, 1.0, method="rk4"),
         "method='rk4'"),
        (lambda: Q.quaternion_rollout(ID, np.zeros(3), ID, 1.0, 1.0, steps=-2), "steps=-2"),
        (lambda: Q.quaternion_rollout(ID, np.zeros(3), ID, 1.0, 1.0, substeps=0), "substeps=0"),
        (lambda: Q.quaternion_rollout(ID, np.zeros(3), ID, 1.0, 1.0, dt=np.nan), "dt"),
        (lambda: Q.quaternion_rollout(ID, np.zeros(3), ID, np.nan, 1.0), "alpha"),
        (lambda: Q.quaternion_rollout(ID, np.zeros(4), ID, 1.0, 1.0), "eta0"),
        (lambda: Q.quaternion_rollout(ID, np.zeros(3), 3 * ID, 1.0, 1.0), "g_q"),
        (lambda: Q.quaternion_rollout(ID, np.zeros(3), ID, 1.0, 1.0, steps=3,
                                      per_step=("g_q",)), "leading axis"),
        (lambda: Q.quaternion_rollout(ID, np.zeros(3), ID, 1.0, 1.0, per_step=("goal",)),
         "goal"),
    ],
)
def test_bad_input_raises_value_error_naming_parameter(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# ------------------------------------------------------------- non-finite angles, broadcasting


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_constructors_refuse_non_finite_angles_naming_them(bad):
    with pytest.raises(ValueError, match=r"psi must be finite, got psi=(nan|inf|-inf)"):
        Q.from_yaw(bad)
    with pytest.raises(ValueError, match=r"psi must be finite"):
        Q.from_yaw(np.array([0.0, 1.0, bad]))
    with pytest.raises(ValueError, match=r"angle must be finite, got angle="):
        Q.from_axis_angle(np.array([0.0, 0.0, 1.0]), bad)
    with pytest.raises(ValueError, match=r"axis must be finite"):
        Q.from_axis_angle(np.array([0.0, bad, 1.0]), 0.3)
    with pytest.raises(ValueError, match=r"v must be finite"):
        Q.from_rotation_vector(np.array([bad, 0.0, 0.0]))


@pytest.mark.parametrize("bad", ["0.5", None])
def test_constructors_refuse_non_numeric_angles_with_a_type_error(bad):
    with pytest.raises(TypeError, match="psi must be a real number or array"):
        Q.from_yaw(bad)
    with pytest.raises(TypeError, match="angle must be a real number or array"):
        Q.from_axis_angle(np.array([0.0, 0.0, 1.0]), bad)


def test_traced_angles_still_differentiate(eng):
    z = eng.xp.asarray([0.0, 0.0, 0.0, 1.0])
    g = eng.grad(lambda a: eng.xp.sum(Q.from_yaw(a, xp=eng.xp) * z))(0.4)
    assert float(g) == pytest.approx(0.5 * np.cos(0.2))


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: Q.multiply(np.ones((2, 4)), np.ones((3, 4))),
         r"p with shape \(2, 4\), q with shape \(3, 4\) \(batch shapes p: \(2,\), q: \(3,\)\)"),
        (lambda: Q.rotate(Q.normalize(np.ones((2, 4))), np.ones((3, 3))),
         r"q with shape \(2, 4\), v with shape \(3, 3\)"),
        (lambda: Q.orientation_error(Q.normalize(np.ones((2, 4))), Q.normalize(np.ones((5, 4)))),
         r"g with shape \(2, 4\), q with shape \(5, 4\)"),
        (lambda: Q.from_axis_angle(np.ones((2, 3)), np.zeros(3)),
         r"axis with shape \(2, 3\), angle with shape \(3,\)"),
        (lambda: Q.integrate(Q.normalize(np.ones((2, 4))), np.zeros((4, 3)), 0.5),
         r"q with shape \(2, 4\), eta with shape \(4, 3\)"),
        (lambda: Q.quaternion_step(Q.normalize(np.ones((2, 4))), np.zeros((3, 3)), ID, 1.0, 1.0),
         r"q with shape \(2, 4\), eta with shape \(3, 3\), g_q with shape \(4,\)"),
        (lambda: Q.quaternion_rollout(Q.normalize(np.ones((3, 4))), np.zeros(3),
                                      Q.normalize(np.ones((2, 2, 4))), 1.0, 1.0, steps=2,
                                      per_step=("g_q",)),
         r"q0 with shape \(3, 4\), eta0 with shape \(3,\), g_q with shape \(2, 4\)"),
    ],
)
def test_broadcast_failures_name_both_arguments_and_shapes(call, match):
    with pytest.raises(ValueError, match=r"the batch shapes do not broadcast: " + match):
        call()


def test_broadcasting_batches_still_work():
    rng = np.random.default_rng(11)
    p, q = Q.normalize(rng.normal(size=(3, 1, 4))), Q.normalize(rng.normal(size=(5, 4)))
    assert Q.multiply(p, q).shape == (3, 5, 4)
    assert Q.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.zeros((2, 3))).shape == (2, 3, 4)


# ------------------------------------------------------------------- dtype-scaled unit check


def test_unit_tolerance_fits_the_dtype():
    assert Q.unit_tolerance(np.float32) / Q.unit_tolerance(np.float64) == pytest.approx(2.0**29)
    v = np.array([0.3, -1.0, 2.0])
    q32 = np.array([0.5, 0.5, 0.5, 0.5], dtype=np.float32) * np.float32(1 + 2e-6)
    Q.rotate(q32, v)  # float32 rounding-sized error: accepted (refused at the old fixed 1e-6)
    with pytest.raises(ValueError, match="unit quaternion"):
        Q.rotate(np.array([0.5, 0.5, 0.5, 0.5], dtype=np.float32) * np.float32(1 + 1e-4), v)
    with pytest.raises(ValueError, match=r"q must be a unit quaternion .*got norm 1\.000000001"):
        Q.rotate(np.array([0.5, 0.5, 0.5, 0.5]) * (1 + 1e-9), v)  # accepted before


@SETTINGS
@given(hnp.arrays(np.float64, 4, elements=st.floats(-10, 10, **finite)))
def test_float32_normalised_quaternions_pass_every_check(raw):
    assume(np.linalg.norm(raw) > 1e-3)
    q = Q.normalize(raw.astype(np.float32)).astype(np.float32)
    Q.to_matrix(q)
    Q.log(np.where(q[0] < 0, -q, q) if np.abs(q[1:]).max() < 1e-6 else q)
    Q.orientation_error(q, q)


# --------------------------------------------------------------------------- quaternion DMP gains


def test_quaternion_dmp_refuses_bad_and_unstable_gains():
    eta = np.zeros(3)
    g = Q.from_yaw(1.0)
    with pytest.raises(TypeError, match="alpha must be a real number or array, got alpha='10'"):
        Q.quaternion_step(ID, eta, g, "10", 1.0)
    with pytest.raises(TypeError, match="beta must be a real number or array, got beta=None"):
        Q.quaternion_rollout(ID, eta, g, 1.0, None)
    with pytest.raises(ValueError, match=r"beta must be >= 0 .*got beta=-1\.0"):
        Q.quaternion_step(ID, eta, g, 1.0, -1.0)
    with pytest.raises(ValueError, match=r"alpha must be > 0 .*got alpha=0\.0"):
        Q.quaternion_rollout(ID, eta, g, 0.0, 1.0)
    with pytest.raises(ValueError, match=r"spectral radius of one step is 5\.25 > 1"):
        Q.quaternion_rollout(ID, eta, g, 25.0, 6.25, 0.5, 5, "euler", 1)
    with pytest.warns(RuntimeWarning, match="allow_unstable=True") as record:
        r = Q.quaternion_rollout(ID, eta, g, 25.0, 6.25, 0.5, 5, "euler", 1,
                                 allow_unstable=True)
    assert len(record) == 1 and np.abs(r.eta[-1]).max() > 100
