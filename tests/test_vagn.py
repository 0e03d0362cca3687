"""Tests for minimanc.vagn (chapter 5): eqs. 8-9, rollouts, analysis (figures: test_viz.py)."""

from __future__ import annotations

import itertools

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from minimanc import checks, engine, vagn  # noqa: E402
from minimanc.autodiff.check import numerical_grad  # noqa: E402
from minimanc.viz.automaton import plot_q_heatmap  # noqa: E402

ENGINES = ["numpy", "jax"]


@pytest.fixture(params=ENGINES)
def eng(request):
    return engine(request.param)


def _oracle_T(p, W):
    """Eqs. 8-9 written out with loops, no max shift (values kept moderate)."""
    M, N, _ = W.shape
    A = sum(p[i] * W[i] for i in range(M))
    R = np.where(A > 0, A, 0.0)
    T = np.empty((N, N))
    for j in range(N):
        e = np.exp(R[:, j])
        T[:, j] = e / e.sum()
    return T


@st.composite
def problems(draw, max_m=5, max_n=5, scale=50.0):
    M = draw(st.integers(1, max_m))
    N = draw(st.integers(1, max_n))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    s = draw(st.floats(1e-3, scale))
    return rng.standard_normal(M) * s, rng.standard_normal((M, N, N)) * s, rng


# --------------------------------------------------------------------- eqs 8-9
@settings(max_examples=50, deadline=None)
@given(problems())
def test_columns_sum_to_one_and_entries_positive(prob):
    p, W, _ = prob
    T = vagn.transition_matrix(p, W)
    assert T.shape == W.shape[1:]
    np.testing.assert_allclose(T.sum(axis=0), 1.0, atol=1e-12)
    assert np.all(T >= 0) and np.all(np.isfinite(T))
    # strictly positive unless exp underflows (a column's ReLU logits spanning > ~700)
    R = np.maximum(vagn.combined_weights(p, W), 0)
    assert np.all(T[:, np.ptp(R, axis=0) < 700] > 0)


@settings(max_examples=40, deadline=None)
@given(problems(scale=3.0))
def test_transition_matrix_matches_loop_oracle(prob):
    p, W, _ = prob
    np.testing.assert_allclose(vagn.transition_matrix(p, W), _oracle_T(p, W), rtol=1e-12)


def test_batched_p_gives_batched_T():
    rng = np.random.default_rng(1)
    W = vagn.init_vagn(rng, 3, 4)
    ps = rng.standard_normal((2, 5, 3))
    T = vagn.transition_matrix(ps, W)
    assert T.shape == (2, 5, 4, 4)
    for a, b in itertools.product(range(2), range(5)):
        np.testing.assert_allclose(T[a, b], _oracle_T(ps[a, b], W), rtol=1e-12)


def test_relu_zero_still_gets_probability():
    # every entry of W^p negative → ReLU gives all zeros → e^0 = 1 everywhere → uniform
    W = -np.ones((2, 3, 3))
    T = vagn.transition_matrix(np.array([1.0, 0.5]), W)
    np.testing.assert_allclose(T, np.full((3, 3), 1 / 3), rtol=1e-14)
    # one big positive entry per column: the others keep exactly 1 / (e^a + N - 1)
    a = 5.0
    W = -np.ones((1, 3, 3))
    W[0, 0, :] = a
    T = vagn.transition_matrix(np.array([1.0]), W)
    np.testing.assert_allclose(T[1:], 1.0 / (np.exp(a) + 2), rtol=1e-13)
    assert vagn.min_transition_probability([1.0], W) == pytest.approx(1.0 / (np.exp(a) + 2))


def test_step_is_matrix_vector_product():
    rng = np.random.default_rng(2)
    W = vagn.init_vagn(rng, 4, 5)
    p = rng.standard_normal(4)
    q = vagn.random_state(rng, 5)
    np.testing.assert_allclose(vagn.step(q, p, W), vagn.transition_matrix(p, W) @ q, rtol=1e-13)
    qb = vagn.random_state(rng, 5, size=3)
    pb = rng.standard_normal((3, 4))
    out = vagn.step(qb, pb, W)
    for b in range(3):
        np.testing.assert_allclose(out[b], vagn.transition_matrix(pb[b], W) @ qb[b], rtol=1e-13)


@settings(max_examples=25, deadline=None)
@given(problems(max_n=6, scale=20.0))
def test_q_stays_a_distribution_over_long_rollouts(prob):
    _, W, rng = prob
    M, N = W.shape[0], W.shape[1]
    ps = rng.standard_normal((500, M)) * 10
    qs = vagn.rollout(vagn.random_state(rng, N), ps, W)
    assert qs.shape == (501, N)
    assert np.all(qs >= 0)
    np.testing.assert_allclose(qs.sum(axis=-1), 1.0, atol=1e-10)


def test_rollout_matches_repeated_steps_and_batches():
    rng = np.random.default_rng(3)
    W = vagn.init_vagn(rng, 3, 4)
    ps = rng.standard_normal((7, 2, 3))
    q0 = vagn.uniform_state(4)
    qs = vagn.rollout(q0, ps, W)
    assert qs.shape == (8, 2, 4)
    for b in range(2):
        q = q0
        np.testing.assert_allclose(qs[0, b], q0)
        for t in range(7):
            q = vagn.step(q, ps[t, b], W)
            np.testing.assert_allclose(qs[t + 1, b], q, rtol=1e-13)


def test_initial_states():
    np.testing.assert_allclose(vagn.uniform_state(4), [0.25] * 4)
    rng = np.random.default_rng(4)
    q = vagn.random_state(rng, 5, size=(100,))
    assert q.shape == (100, 5) and np.all(q > 0)
    np.testing.assert_allclose(q.sum(-1), 1.0, atol=1e-12)
    # flat Dirichlet: each coordinate has mean 1/N
    assert abs(q.mean() - 0.2) < 0.02
    W = vagn.init_vagn(np.random.default_rng(0), 2, 3, scale=0.1)
    assert W.shape == (2, 3, 3) and 0.03 < W.std() < 0.2


# --------------------------------------------------------------------- gradients
def _loss(W, p, q0, target, xp):
    qs = vagn.rollout(q0, p, W, xp=xp)
    return xp.sum((qs[1:] - target) ** 2)


def _central_diff(f, x, eps=1e-6):
    """Central differences of a scalar function of one array (the library's oracle)."""
    return numerical_grad(f, [x], 0, eps)[0]


def _away_from_kinks(ps, W, tol=1e-3):
    """True when no entry of W^p sits at ReLU's kink (where finite differences fail)."""
    return all(np.min(np.abs(vagn.combined_weights(p, W))) > tol for p in ps)


@settings(max_examples=40, deadline=None)
@given(problems(max_m=3, max_n=4, scale=2.0))
def test_gradients_match_finite_differences(prob):
    _, W, rng = prob
    M, N = W.shape[0], W.shape[1]
    ps = rng.standard_normal((4, M))
    q0 = vagn.random_state(rng, N)
    target = vagn.random_state(rng, N, size=4)
    if not _away_from_kinks(ps, W):
        return
    fd = _central_diff(lambda w: _loss(w, ps, q0, target, np), W)
    e = engine("numpy")
    np.testing.assert_allclose(e.grad(_loss)(W, ps, q0, target, e.xp), fd, atol=1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gradients_numpy_engine_equal_jax(seed):
    rng = np.random.default_rng(seed)
    W = vagn.init_vagn(rng, 3, 4, scale=1.5)
    ps = rng.standard_normal((5, 2, 3))
    q0 = vagn.random_state(rng, 4, size=2)
    target = vagn.random_state(rng, 4, size=(5, 2))
    gw, gp = {}, {}
    for name in ENGINES:
        e = engine(name)
        gw[name], gp[name] = (np.asarray(g) for g in e.grad(
            lambda w, p, xp=e.xp: _loss(w, p, q0, target, xp), argnums=(0, 1))(W, ps))
    np.testing.assert_allclose(gw["numpy"], gw["jax"], atol=1e-10)
    np.testing.assert_allclose(gp["numpy"], gp["jax"], atol=1e-10)
    assert np.abs(gw["numpy"]).max() > 1e-3  # not a vacuous comparison


def test_gradient_wrt_predicates(eng):
    rng = np.random.default_rng(5)
    W = vagn.init_vagn(rng, 3, 3, scale=1.0)
    p = rng.standard_normal(3)
    q0 = vagn.uniform_state(3)

    def f(pp, xp=np):
        return vagn.step(q0, pp, W, xp=xp)[0]

    g = np.asarray(eng.grad(lambda pp: f(pp, eng.xp))(p))
    np.testing.assert_allclose(g, _central_diff(f, p), atol=1e-7)


def test_learning_W_from_teacher_sequences(eng):
    """Plain gradient descent recovers a teacher automaton's q trajectories."""
    rng = np.random.default_rng(6)
    W_true = vagn.init_vagn(rng, 2, 3, scale=2.0)
    ps = rng.random((12, 8, 2))
    q0 = vagn.random_state(rng, 3, size=8)
    target = vagn.rollout(q0, ps, W_true)[1:]
    W = vagn.init_vagn(np.random.default_rng(7), 2, 3, scale=0.1, mean=0.5)
    vg = eng.jit(eng.value_and_grad(lambda w: _loss(w, ps, q0, target, eng.xp) / 8))
    first = None
    for _ in range(150):
        loss, g = vg(W)
        first = float(loss) if first is None else first
        W = W - 2.0 * np.asarray(g)
    assert float(loss) < 0.002 * first


# --------------------------------------------------------------------- analysis
def test_stationary_distribution_two_state_closed_form():
    a, b = 0.3, 0.1
    T = np.array([[1 - a, b], [a, 1 - b]])
    np.testing.assert_allclose(vagn.stationary_distribution(T), [b / (a + b), a / (a + b)])


@settings(max_examples=30, deadline=None)
@given(problems(max_n=6, scale=3.0))
def test_stationary_distribution_is_fixed_point_and_limit(prob):
    p, W, rng = prob
    T = vagn.transition_matrix(p, W)
    pi = vagn.stationary_distribution(T)
    assert np.all(pi >= 0)
    np.testing.assert_allclose(pi.sum(), 1.0, atol=1e-12)
    np.testing.assert_allclose(T @ pi, pi, atol=1e-10)
    # T^k q -> pi for any start, at the rate of the second eigenvalue modulus;
    # large weights can make nearly periodic / absorbing chains that mix in > 1e9 steps
    lam2 = np.sort(np.abs(np.linalg.eigvals(T)))[-2] if T.shape[0] > 1 else 0.0
    if lam2 < 0.999:
        Tk = T
        for _ in range(20):  # T^(2^20) by repeated squaring
            Tk = Tk @ Tk
        np.testing.assert_allclose(Tk @ vagn.random_state(rng, W.shape[1]), pi, atol=1e-6)


def test_most_likely_states_is_argmax():
    qs = np.array([[0.2, 0.5, 0.3], [0.6, 0.3, 0.1]])
    np.testing.assert_array_equal(vagn.most_likely_states(qs), [1, 0])


@settings(max_examples=25, deadline=None)
@given(problems(max_m=2, max_n=3, scale=3.0))
def test_most_likely_path_matches_brute_force(prob):
    _, W, rng = prob
    M, N = W.shape[0], W.shape[1]
    Ts = vagn.transition_matrix(rng.standard_normal((4, M)), W)
    q0 = vagn.random_state(rng, N)
    path, logp = vagn.most_likely_path(q0, Ts)
    best = max(
        np.log(q0[s[0]]) + sum(np.log(Ts[t, s[t + 1], s[t]]) for t in range(4))
        for s in itertools.product(range(N), repeat=5)
    )
    assert logp == pytest.approx(best, abs=1e-10)
    recomputed = np.log(q0[path[0]]) + sum(np.log(Ts[t, path[t + 1], path[t]]) for t in range(4))
    assert recomputed == pytest.approx(best, abs=1e-10)


# --------------------------------------------------------------------- bad input
@pytest.mark.parametrize("bad", [0, -1, 3.0, 2.5, True, None, "3"])
@pytest.mark.parametrize(
    "name,call",
    [
        ("n_predicates", lambda n: vagn.init_vagn(np.random.default_rng(0), n, 2)),
        ("n_states", lambda n: vagn.init_vagn(np.random.default_rng(0), 2, n)),
        ("n_states", lambda n: vagn.uniform_state(n)),
        ("n_states", lambda n: vagn.random_state(np.random.default_rng(0), n)),
    ],
)
def test_sizes_must_be_integers_at_least_one(name, call, bad):
    """A size that is not an ``int`` >= 1 (a float such as 3.0, a bool, None) is refused."""
    with pytest.raises(ValueError, match=rf"{name} must be an integer >= 1, got {name}="):
        call(bad)
    assert call(np.int64(3)).shape[-1] in (2, 3)  # NumPy integers are integers


def test_bad_inputs_raise_value_errors_naming_the_problem():
    rng = np.random.default_rng(8)
    W = vagn.init_vagn(rng, 3, 4)
    q = vagn.uniform_state(4)
    with pytest.raises(ValueError, match=r"p must have shape \(\.\.\., M\) with M = 3"):
        vagn.transition_matrix(np.ones(2), W)
    with pytest.raises(ValueError, match="W must have shape"):
        vagn.transition_matrix(np.ones(3), np.ones((3, 4, 5)))
    with pytest.raises(ValueError, match="negative entry"):
        vagn.step(np.array([0.5, 0.7, -0.2, 0.0]), np.ones(3), W)
    with pytest.raises(ValueError, match="sum to 1.2"):
        vagn.step(np.array([0.5, 0.7, 0.0, 0.0]), np.ones(3), W)
    with pytest.raises(ValueError, match="q must have shape"):
        vagn.step(np.ones(3) / 3, np.ones(3), W)
    with pytest.raises(ValueError, match="q0 must be a probability distribution"):
        vagn.rollout(2 * q, np.ones((5, 3)), W)
    with pytest.raises(ValueError, match="ps must have shape"):
        vagn.rollout(q, np.ones((5, 2)), W)
    with pytest.raises(ValueError, match="p must be finite"):
        vagn.transition_matrix(np.array([1.0, np.nan, 0.0]), W)
    with pytest.raises(ValueError, match="T must be column-stochastic"):
        vagn.stationary_distribution(np.ones((3, 3)))
    with pytest.raises(ValueError, match="n_states"):
        vagn.init_vagn(rng, 2, 0)
    with pytest.raises(ValueError, match="rng"):
        vagn.init_vagn(0, 2, 2)
    # rounding of the dtype is tolerated, more is not (float64: ~1e-15 per term)
    vagn.step(q + 1e-16, np.ones(3), W)
    with pytest.raises(ValueError, match="sum to 1.000000004"):
        vagn.step(q + 1e-9, np.ones(3), W)


def test_traced_inputs_skip_value_checks_but_keep_shape_checks():
    import jax.numpy as jnp

    W = vagn.init_vagn(np.random.default_rng(9), 2, 3)
    # a JAX array is not inspected for values (it may be a tracer) ...
    vagn.step(jnp.array([2.0, 0.0, 0.0]), np.ones(2), W, xp=jnp)
    # ... but its shape still is
    with pytest.raises(ValueError, match="p must have shape"):
        vagn.step(jnp.ones(3) / 3, jnp.ones(4), W, xp=jnp)


# --------------------------------------------------------------------- dtype-scaled tolerance
def test_float32_feedback_loop_never_drifts_off_the_simplex():
    rng = np.random.default_rng(12)
    M, N = 4, 6
    W = vagn.init_vagn(rng, M, N, scale=4.0).astype(np.float32)
    q = vagn.uniform_state(N).astype(np.float32)[None].repeat(3, axis=0)
    tol = checks.float_tolerance(np.float32, N)
    worst = 0.0
    for _ in range(2000):
        p = rng.uniform(0.0, 1.0, size=(3, M)).astype(np.float32)
        q = vagn.step(q, p, W)  # its own output, fed back: never refused
        assert q.dtype == np.float32
        worst = max(worst, float(np.abs(q.astype(np.float64).sum(-1) - 1.0).max()))
    assert worst <= tol
    qs = vagn.rollout(q[0], rng.uniform(0, 1, size=(2000, M)).astype(np.float32), W)
    assert qs.dtype == np.float32
    assert np.abs(qs.astype(np.float64).sum(-1) - 1.0).max() <= tol


def test_q_tolerance_fits_the_dtype_of_the_input():
    rng = np.random.default_rng(13)
    W = vagn.init_vagn(rng, 3, 6)
    q32 = np.full(6, 1 / 6, dtype=np.float32)
    q32[0] -= np.float32(3e-7)
    assert abs(float(q32.astype(np.float64).sum()) - (1 - 3e-7)) < 5e-8
    vagn.step(q32, np.ones(3), W)  # float32 rounding: accepted
    q32[0] -= np.float32(1.5e-6)  # still within 8 · 6 · eps32 = 5.7e-6, refused at 1e-6 before
    vagn.step(q32, np.ones(3), W)
    q64 = np.full(6, 1 / 6)
    q64[0] -= 1e-3
    with pytest.raises(ValueError, match=r"q must be a probability distribution: entries sum to "
                                         r"0\.99899.*\|sum - 1\| = 0\.001 > tolerance 1\.07e-14"):
        vagn.step(q64, np.ones(3), W)
    q64 = np.full(6, 1 / 6)
    q64[0] -= 1e-8  # accepted at the old fixed 1e-6; far beyond float64 rounding
    with pytest.raises(ValueError, match="q must be a probability distribution"):
        vagn.step(q64, np.ones(3), W)
    with pytest.raises(ValueError, match="q0 must be a probability distribution"):
        vagn.rollout(q64, np.ones((2, 3)), W)
    with pytest.raises(ValueError, match=r"q0 must .* sum to 0\.99999998"):
        vagn.most_likely_path(q64, vagn.transition_matrix(np.ones((2, 3)), W))


def test_float32_values_converted_to_float64_are_held_to_float64_with_a_hint():
    # a float32 model's q checked in its own precision; converted to float64 it is a float64
    # distribution, checked as one, and the error says what probably happened
    rng = np.random.default_rng(14)
    W = vagn.init_vagn(rng, 3, 5).astype(np.float32)
    q = vagn.uniform_state(5).astype(np.float32)
    for _ in range(50):
        q = vagn.step(q, rng.uniform(size=3).astype(np.float32), W)
    vagn.check_state(q, 5)
    recorded = np.asarray(q, dtype=np.float64)
    if abs(recorded.sum() - 1.0) > 8 * np.finfo(np.float64).eps * 5:
        with pytest.raises(ValueError, match="float32 values converted to float64"):
            vagn.step(recorded, np.ones(3), W.astype(np.float64))
    vagn.step(recorded / recorded.sum(), np.ones(3), W.astype(np.float64))
    plot_q_heatmap(q[None])
    plt.close("all")


def test_step_renormalisation_keeps_gradients_and_both_engines(eng):
    rng = np.random.default_rng(15)
    W = vagn.init_vagn(rng, 3, 4)
    q0 = vagn.random_state(rng, 4)
    p = rng.uniform(size=3)
    # the renormalisation is the identity in exact arithmetic: same values as T q
    T = vagn.transition_matrix(p, W)
    assert np.allclose(vagn.step(q0, p, W), T @ q0, atol=1e-15, rtol=0)
    # and it changes no gradient with respect to p (Σ q_t does not depend on p)
    c = np.array([1.0, -2.0, 0.5, 3.0])

    def f(pp):
        return eng.xp.sum(vagn.step(q0, pp, W, xp=eng.xp) * eng.xp.asarray(c))

    g = np.asarray(eng.grad(f)(p))
    fd = numerical_grad(lambda pp: float(np.sum((vagn.transition_matrix(pp, W) @ q0) * c)),
                        [p], 0, 1e-6)[0]
    assert np.allclose(g, fd, atol=1e-7)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_analysis_refuses_non_finite_transitions_before_linear_algebra(bad):
    rng = np.random.default_rng(16)
    W = vagn.init_vagn(rng, 2, 3)
    Ts = vagn.transition_matrix(rng.uniform(size=(4, 2)), W)
    Ts[2, 1, 0] = bad
    with pytest.raises(ValueError, match=r"Ts must be finite; got Ts with 1 non-finite entry"):
        vagn.most_likely_path(vagn.uniform_state(3), Ts)
    T = Ts[0].copy()
    T[0, 0] = bad
    with pytest.raises(ValueError, match=r"T must be finite; got T with 1 non-finite entry"):
        vagn.stationary_distribution(T)
    with pytest.raises(ValueError, match=r"T must be finite"):
        vagn.stationary_distribution(np.full((3, 3), np.nan))
