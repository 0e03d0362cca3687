"""Tests for minimanc.cam (chapter 6): eq. 7, CAM, Grad-CAM, per-q-state saliency."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import cam, engine, vagn
from minimanc.autodiff.check import numerical_grad

ENGINES = ["numpy", "jax"]


@pytest.fixture(params=ENGINES)
def eng(request):
    return engine(request.param)


def _setup(seed=0, M=3, N=4, channels=(6, 8), size=12, batch=2):
    rng = np.random.default_rng(seed)
    params = cam.init_extractor(rng, 3, M, channels)
    params["head"]["b"] = rng.standard_normal(M)  # a non-zero bias, to catch mix-ups
    images = rng.integers(0, 256, (batch, size, size, 3), dtype=np.uint8)
    W = vagn.init_vagn(rng, M, N, scale=1.0)
    return rng, params, images, W


def _central_diff(f, x, eps=1e-6):
    """Central differences of a scalar function of one array (the library's oracle)."""
    return numerical_grad(f, [x], 0, eps)[0]


# --------------------------------------------------------------------- eq. 7
def test_extractor_shapes_uint8_and_engines_agree(eng):
    _, params, images, _ = _setup()
    p, f = cam.predicate_extractor(params, images, eng.nn, eng.xp, return_features=True)
    assert p.shape == (2, 3) and f.shape == (2, 6, 6, 8)  # strides (1, 2), padding 1
    p_float = cam.predicate_extractor(params, images.astype(float) / 255.0, eng.nn, eng.xp)
    np.testing.assert_allclose(np.asarray(p), np.asarray(p_float), rtol=1e-12)
    ref = cam.predicate_extractor(params, images, engine("numpy").nn, np)
    np.testing.assert_allclose(np.asarray(p), ref, rtol=1e-10)
    # features after ReLU are non-negative
    assert np.all(np.asarray(f) >= 0)


def test_extractor_is_conv_gap_linear():
    """Eq. 7 written out with a loop-based convolution as the oracle."""
    rng, params, images, _ = _setup(channels=(5,), size=7, batch=1)
    x = images[0].astype(float) / 255.0
    w, b = params["convs"][0]["w"], params["convs"][0]["b"]
    xpad = np.pad(x, ((1, 1), (1, 1), (0, 0)))
    f = np.zeros((7, 7, 5))
    for r in range(7):
        for c in range(7):
            f[r, c] = np.einsum("hwi,hwio->o", xpad[r:r + 3, c:c + 3], w) + b
    f = np.maximum(f, 0)
    p = f.mean(axis=(0, 1)) @ params["head"]["w"] + params["head"]["b"]
    got = cam.predicate_extractor(params, images, engine("numpy").nn, np, strides=(1,))
    np.testing.assert_allclose(got[0], p, rtol=1e-12)


def test_extractor_gradients_match_jax_and_finite_differences():
    _, params, images, _ = _setup(size=8)
    target = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.0]])

    def loss(prm, xp, nn):
        return xp.sum((cam.predicate_extractor(prm, images, nn, xp, activation="silu")
                       - target) ** 2)

    grads = {n: engine(n).grad(loss)(params, engine(n).xp, engine(n).nn) for n in ENGINES}
    for key in ("w", "b"):
        np.testing.assert_allclose(grads["numpy"]["head"][key], grads["jax"]["head"][key],
                                   atol=1e-9)
        np.testing.assert_allclose(grads["numpy"]["convs"][0][key],
                                   grads["jax"]["convs"][0][key], atol=1e-9)
    w0 = params["convs"][0]["b"]

    def f(b):
        prm = {**params, "convs": [{**params["convs"][0], "b": b}, params["convs"][1]]}
        return loss(prm, np, engine("numpy").nn)

    np.testing.assert_allclose(grads["numpy"]["convs"][0]["b"], _central_diff(f, w0), atol=1e-6)


def test_extractor_bad_input():
    _, params, images, _ = _setup()
    nn = engine("numpy").nn
    with pytest.raises(ValueError, match=r"images must be NHWC with C = 3"):
        cam.predicate_extractor(params, images[..., :2], nn)
    with pytest.raises(ValueError, match=r"images must be NHWC"):
        cam.predicate_extractor(params, images[0], nn)
    with pytest.raises(ValueError, match="strides must have one entry per conv layer"):
        cam.predicate_extractor(params, images, nn, strides=(1,))
    with pytest.raises(ValueError, match="activation"):
        cam.predicate_extractor(params, images, nn, activation="tanh")
    with pytest.raises(ValueError, match="channels"):
        cam.init_extractor(np.random.default_rng(0), channels=())


@pytest.mark.parametrize("bad", [0, 3.0, True, None])
@pytest.mark.parametrize(
    "name,kwargs",
    [
        ("in_channels", lambda v: {"in_channels": v}),
        ("n_predicates", lambda v: {"n_predicates": v}),
        ("kernel_size", lambda v: {"kernel_size": v}),
        (r"channels\[1\]", lambda v: {"channels": (8, v)}),
    ],
)
def test_extractor_sizes_must_be_integers_at_least_one(name, kwargs, bad):
    """A size that is not an ``int`` >= 1 (a float such as 3.0, a bool, None) is refused."""
    with pytest.raises(ValueError, match=rf"{name} must be an integer >= 1, got {name}="):
        cam.init_extractor(np.random.default_rng(0), **kwargs(bad))


# --------------------------------------------------------------------- CAM
@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 4), st.integers(1, 5), st.integers(1, 6))
def test_cam_is_weighted_sum_and_averages_to_the_predicate(seed, M, K, H):
    rng = np.random.default_rng(seed)
    f = rng.standard_normal((2, H, H + 1, K))
    w = rng.standard_normal((K, M))
    b = rng.standard_normal(M)
    maps = cam.class_activation_maps(f, w)
    assert maps.shape == (2, M, H, H + 1)
    for i in range(M):
        np.testing.assert_allclose(maps[:, i], sum(w[k, i] * f[..., k] for k in range(K)),
                                   atol=1e-12)
    p = cam.global_average_pool(f) @ w + b
    np.testing.assert_allclose(maps.mean(axis=(-2, -1)) + b, p, atol=1e-12)
    np.testing.assert_allclose(cam.class_activation_maps(f, w.T, layout="MK"), maps)


def test_cam_bad_input():
    f = np.ones((1, 4, 4, 5))
    with pytest.raises(ValueError, match=r"weights with layout 'KM' must have K = 5"):
        cam.class_activation_maps(f, np.ones((3, 5)))
    with pytest.raises(ValueError, match="layout"):
        cam.class_activation_maps(f, np.ones((5, 3)), layout="CK")
    with pytest.raises(ValueError, match="features must have shape"):
        cam.class_activation_maps(np.ones((4, 5)), np.ones((5, 3)))


def test_global_average_pool_matches_nn(eng):
    f = np.random.default_rng(1).standard_normal((2, 5, 3, 4))
    np.testing.assert_allclose(np.asarray(cam.global_average_pool(f, xp=eng.xp)),
                               np.asarray(eng.nn.global_avg_pool(f)), rtol=1e-13)


@pytest.mark.parametrize("name", ENGINES)
def test_grad_cam_equals_cam_after_relu_and_minmax(name):
    """Zhou/Selvaraju: for conv → GAP → linear, Grad-CAM = normalised ReLU(CAM)."""
    e = engine(name)
    rng, params, images, _ = _setup(seed=3, size=10)
    w = rng.standard_normal(params["head"]["w"].shape)
    params["head"]["w"] = w - w.mean(axis=0)  # features are >= 0: zero-mean weights give maps
    #                                            of both signs, so ReLU matters
    p, f = cam.predicate_extractor(params, images, e.nn, e.xp, return_features=True)
    f = np.asarray(f)
    head = params["head"]
    maps = cam.class_activation_maps(f, head["w"])
    mixed = 0
    for c in range(3):
        def score(feat, c=c):
            pc = e.xp.matmul(cam.global_average_pool(feat, xp=e.xp), head["w"]) + head["b"]
            return e.xp.sum(pc[:, c])  # batch rows are independent

        grads = np.asarray(e.grad(score)(f))
        gc = cam.grad_cam(f, grads)
        expected = cam.minmax_normalize(np.maximum(maps[:, c], 0))
        np.testing.assert_allclose(cam.minmax_normalize(gc), expected, atol=1e-10)
        assert np.ptp(expected) > 0  # a real map, not a constant
        mixed += bool(np.any(maps[:, c] < 0) and np.any(maps[:, c] > 0))
    assert mixed >= 1  # at least one map where the ReLU has something to cut


# --------------------------------------------------------------------- upsample / normalise
def test_upsample_nearest_is_repeat_and_bilinear_properties():
    rng = np.random.default_rng(2)
    m = rng.standard_normal((2, 3, 4, 5))
    np.testing.assert_allclose(cam.upsample(m, (8, 15), mode="nearest"),
                               m.repeat(2, axis=-2).repeat(3, axis=-1))
    up = cam.upsample(m, (8, 10))
    assert up.shape == (2, 3, 8, 10)
    np.testing.assert_allclose(cam.upsample(np.full((4, 5), 2.5), 17), np.full((17, 17), 2.5))
    # bilinear with half-pixel centres: a linear ramp stays linear away from the borders
    ramp = np.tile(np.arange(4.0), (4, 1))
    r = cam.upsample(ramp, (4, 8))
    np.testing.assert_allclose(r[0, 1:-1], (np.arange(1, 7) + 0.5) / 2 - 0.5)
    # linear in the maps, and the identity at the same size
    m2 = rng.standard_normal((2, 3, 4, 5))
    np.testing.assert_allclose(cam.upsample(2 * m - m2, (8, 10)),
                               2 * up - cam.upsample(m2, (8, 10)))
    np.testing.assert_allclose(cam.upsample(m, (4, 5)), m)
    with pytest.raises(ValueError, match="mode"):
        cam.upsample(m, 8, mode="cubic")
    with pytest.raises(ValueError, match="size"):
        cam.upsample(m, (0, 4))


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.01, 100), st.floats(-100, 100))
def test_minmax_normalize_range_and_affine_invariance(seed, a, c):
    s = np.random.default_rng(seed).standard_normal((3, 5, 6))
    n = cam.minmax_normalize(s)
    np.testing.assert_allclose(n.min(axis=(-2, -1)), 0.0, atol=1e-12)
    np.testing.assert_allclose(n.max(axis=(-2, -1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(cam.minmax_normalize(a * s + c), n, atol=1e-9)
    # the ranking of pixels is kept
    np.testing.assert_array_equal(np.argsort(n[0], axis=None), np.argsort(s[0], axis=None))


def test_minmax_constant_map_is_zero_and_works_on_engines(eng):
    np.testing.assert_array_equal(cam.minmax_normalize(np.full((2, 3, 3), 7.0)), 0.0)
    s = np.random.default_rng(0).standard_normal((2, 4, 4))
    np.testing.assert_allclose(np.asarray(cam.minmax_normalize(s, xp=eng.xp)),
                               cam.minmax_normalize(s), rtol=1e-13)


# --------------------------------------------------------------------- per-q-state saliency
@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 4), st.integers(1, 4))
def test_vagn_jacobian_closed_form_matches_finite_differences(seed, M, N):
    rng = np.random.default_rng(seed)
    W = vagn.init_vagn(rng, M, N, scale=1.5)
    p = rng.standard_normal(M)
    q = vagn.random_state(rng, N)
    if np.min(np.abs(vagn.combined_weights(p, W))) < 1e-3:
        return  # ReLU kink
    J = cam.vagn_jacobian(q, p, W)
    fd = np.stack([_central_diff(lambda pp, j=j: vagn.step(q, pp, W)[j], p) for j in range(N)])
    np.testing.assert_allclose(J, fd, atol=1e-7)


def test_vagn_jacobian_engines_match_closed_form(eng):
    rng = np.random.default_rng(4)
    W = vagn.init_vagn(rng, 3, 4, scale=1.5)
    p = rng.standard_normal((5, 3))
    q = vagn.random_state(rng, 4, size=5)
    J = cam.vagn_jacobian(q, p, W)
    assert J.shape == (5, 4, 3) and np.abs(J).max() > 1e-3
    Je = np.asarray(cam.vagn_jacobian(q, p, W, grad=eng.grad, xp=eng.xp))
    np.testing.assert_allclose(Je, J, atol=1e-12)
    # q stays a distribution, so every column of J sums to zero
    np.testing.assert_allclose(J.sum(axis=-2), 0.0, atol=1e-12)


def test_q_state_saliency_is_gradient_times_feature(eng):
    """S_j(x, y) = H·W · Σ_k f_k(x, y) ∂q_j/∂f_k(x, y), and mean_xy S_j = Σ_i J_ji (p_i − b_i)."""
    _, params, images, W = _setup(seed=5)
    q_prev = vagn.random_state(np.random.default_rng(6), 4)
    p, f = cam.predicate_extractor(params, images, engine("numpy").nn, np, return_features=True)
    head = params["head"]
    maps = cam.class_activation_maps(f, head["w"])
    J = cam.vagn_jacobian(q_prev, p, W)
    S = cam.q_state_saliency(maps, J)
    assert S.shape == (2, 4, 6, 6)
    H, Wd = f.shape[1:3]
    for j in range(4):
        def qj(feat, j=j):
            pp = eng.xp.matmul(cam.global_average_pool(feat, xp=eng.xp), head["w"]) + head["b"]
            return eng.xp.sum(vagn.step(q_prev, pp, W, xp=eng.xp)[:, j])

        gf = np.asarray(eng.grad(qj)(f))
        np.testing.assert_allclose(S[:, j], H * Wd * np.sum(f * gf, axis=-1), atol=1e-10)
    np.testing.assert_allclose(S.mean(axis=(-2, -1)),
                               np.einsum("bji,bi->bj", J, p - head["b"]), atol=1e-12)


def test_explain_bundles_a_frame():
    _, params, images, W = _setup(seed=7)
    q_prev = vagn.uniform_state(4)
    out = cam.explain(params, images, q_prev, W, engine("numpy").nn)
    assert out["cams"].shape == (2, 3, 12, 12) and out["saliency"].shape == (2, 4, 12, 12)
    np.testing.assert_allclose(out["q"], vagn.step(q_prev, out["p"], W))
    np.testing.assert_allclose(out["q"].sum(-1), 1.0)
    small = cam.explain(params, images, q_prev, W, engine("numpy").nn, upsample_to_input=False)
    np.testing.assert_allclose(out["saliency"], cam.upsample(small["saliency"], 12))


def test_explain_baseline_is_subtracted_before_the_saliency():
    _, params, images, W = _setup(seed=9)
    q_prev = vagn.uniform_state(4)
    nn = engine("numpy").nn
    raw = cam.explain(params, images, q_prev, W, nn, upsample_to_input=False)
    base = raw["cams"].mean(axis=0)
    out = cam.explain(params, images, q_prev, W, nn, upsample_to_input=False,
                      baseline_cams=base)
    np.testing.assert_allclose(out["cams"], raw["cams"] - base)
    np.testing.assert_allclose(out["saliency"], cam.q_state_saliency(raw["cams"] - base,
                                                                     raw["jacobian"]))
    np.testing.assert_allclose(out["p"], raw["p"])  # the prediction itself is untouched
    with pytest.raises(ValueError, match="baseline_cams must have shape"):
        cam.explain(params, images, q_prev, W, nn, baseline_cams=base[0])


def test_q_state_saliency_bad_input():
    with pytest.raises(ValueError, match="must agree on M"):
        cam.q_state_saliency(np.ones((3, 4, 4)), np.ones((2, 5)))


def test_peak_location():
    m = np.zeros((2, 5, 6))
    m[0, 3, 4] = 1
    m[1, 0, 5] = 2
    np.testing.assert_array_equal(cam.peak_location(m), [[3, 4], [0, 5]])
