"""Tests for the masked auxiliary perception loss (:mod:`minimanc.train.perception`,
``TrainConfig.perception_weight``, ``train.fit(perception=)``) and its targets
(:func:`minimanc.diagnose.perception_targets`): gradients against central differences and
JAX, the mask removing the states without a leader, the targets against the expert's
features."""

from __future__ import annotations

import numpy as np
import pytest

from minimanc import diagnose, engine, models, train, tree, world
from minimanc.train.perception import init_perception_head, perception_term

CFG = models.ModelConfig(input_shape=(32, 32, 3), channels=(4, 8), n_predicates=4, n_states=3,
                         hidden=8)


@pytest.fixture(scope="module")
def ds():
    return world.generate(3, seed=0, raster=world.RasterConfig(size=32))


@pytest.fixture(scope="module")
def targets(ds):
    return diagnose.perception_targets(ds)


def _tc(**kw):
    base = dict(epochs=1, batch_size=8, seq_len=4, dmp_seq_len=4, dtype="float64",
                max_steps_per_epoch=3, perception_weight=0.5)
    base.update(kw)
    return train.TrainConfig(**base)


def _problem(rng, n=6, k=4):
    out = rng.normal(size=(n, k))
    logit = np.array([0.0, 1.0, 0.0, 1.0])[:k]
    z = np.where(logit > 0, rng.integers(0, 2, size=(n, k)), rng.normal(size=(n, k)))
    mask = (rng.random((n, k)) < 0.6).astype(np.float64)
    return out, z, mask, logit


# --------------------------------------------------------------------------- the loss


def test_the_loss_is_its_formula_by_hand():
    out, z, mask, logit = _problem(np.random.default_rng(0))
    p = 1.0 / (1.0 + np.exp(-out))
    bce = -(z * np.log(p) + (1 - z) * np.log(1 - p))
    want = np.sum(mask * np.where(logit > 0, bce, (out - z) ** 2)) / out.size
    got = train.masked_perception_loss(out, z, mask, logit)
    assert float(got) == pytest.approx(want, rel=1e-12)
    # a large logit of the right sign costs nothing, and does not overflow
    big = train.masked_perception_loss(np.array([[800.0]]), np.array([[1.0]]),
                                       np.array([[1.0]]), np.array([1.0]))
    assert float(big) == 0.0


def test_the_loss_gradient_matches_central_differences_and_jax():
    out, z, mask, logit = _problem(np.random.default_rng(1))
    eng = engine("numpy")
    g = np.asarray(eng.grad(lambda o: train.masked_perception_loss(o, z, mask, logit,
                                                                   xp=eng.xp))(out))
    h = 1e-6
    fd = np.zeros_like(out)
    for i in np.ndindex(out.shape):
        e = np.zeros_like(out)
        e[i] = h
        fd[i] = (train.masked_perception_loss(out + e, z, mask, logit)
                 - train.masked_perception_loss(out - e, z, mask, logit)) / (2 * h)
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-9)
    jeng = engine("jax")
    gj = np.asarray(jeng.grad(lambda o: train.masked_perception_loss(o, z, mask, logit,
                                                                     xp=jeng.xp))(out))
    np.testing.assert_allclose(g, gj, rtol=1e-10, atol=1e-12)
    assert np.all(g[mask == 0] == 0.0)


def _batch(name, ds, targets, st_values=None):
    s = np.array([[0, 0, 1, 1, 2, 2]])
    t = np.array([[3, 17, 5, 22, 2, 30]])
    batch = train.make_batch(name, ds, s, t, CFG, np.float64)
    z = train.standardised_targets(targets, [0, 1, 2]) if st_values is None else st_values
    batch["perception"] = z[s, t]
    batch["perception_mask"] = targets.mask[s, t].astype(np.float64)
    batch["perception_logit"] = np.asarray(targets.logit, dtype=np.float64)
    if models.spec(name).family == "vagn":
        batch["q0"] = np.full((6, CFG.n_states), 1.0 / CFG.n_states)
    return batch


def _params(name, k):
    params = models.init(name, np.random.default_rng(0), CFG)
    params["perception"] = init_perception_head(np.random.default_rng(1), CFG, k)
    return params


@pytest.mark.parametrize("name", ["cnn", "manc"])
def test_loss_fn_adds_the_weighted_term_of_the_flattened_features(name, ds, targets):
    """``loss_fn`` with ``perception_weight`` = Algorithm 1's loss + λ · the masked loss of a
    linear read-out of the backbone features that :func:`models.step` returns."""
    eng = engine("numpy")
    batch = _batch(name, ds, targets)
    params = _params(name, len(targets.names))
    inv = np.ones(2)
    plain = float(train.loss_fn(name, params, batch, CFG, eng, inv))
    with_p = float(train.loss_fn(name, params, batch, CFG, eng, inv, perception_weight=0.5))
    obs = {k: v[0] for k, v in batch.items() if k in ("bev", "goal", "lane_target", "motion")}
    state = models.initial_state(name, 6, CFG, dtype=np.float64)
    if models.spec(name).family == "vagn":
        state = {"q": batch["q0"]}
    _, _, aux = models.step(name, params, obs, state, CFG, eng)
    f = np.asarray(aux["features"]).reshape(6, -1)
    read = f @ params["perception"]["w"] + params["perception"]["b"]
    want = train.masked_perception_loss(read, batch["perception"][0],
                                        batch["perception_mask"][0], batch["perception_logit"])
    assert with_p - plain == pytest.approx(0.5 * float(want), rel=1e-9)


@pytest.mark.parametrize("name", ["cnn", "manc"])
def test_the_perception_gradient_is_equal_on_both_engines(name, ds, targets):
    """The gradient of the term through the read-out and the backbone: our engine against JAX
    (float64)."""
    batch = _batch(name, ds, targets)
    params = _params(name, len(targets.names))
    grads = []
    for which in ("numpy", "jax"):
        eng = engine(which)
        grads.append(eng.grad(lambda p, e=eng: perception_term(p, batch, CFG, e))(params))
    assert {"backbone", "perception"} <= set(grads[0])
    for a, b in zip(tree.leaves(grads[0]), tree.leaves(grads[1])):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-7, atol=1e-10)
    assert np.abs(np.asarray(grads[0]["perception"]["w"])).max() > 0
    assert np.abs(np.asarray(grads[0]["backbone"]["convs"][0]["w"])).max() > 0


def test_the_mask_removes_the_states_without_a_leader(ds, targets):
    """Any value of the gap and the closing speed where there is no leader leaves the loss and
    its gradient unchanged; the same change where there is one does not."""
    eng = engine("numpy")
    z = train.standardised_targets(targets, [0, 1, 2])
    batch = _batch("cnn", ds, targets, z)
    lead = batch["perception"][0][:, targets.names.index("has_leader")] > 0
    assert lead.any() and (~lead).any(), "the batch must hold states with and without a leader"
    params = _params("cnn", len(targets.names))
    cols = [targets.names.index("gap"), targets.names.index("dv")]

    def moved(where):
        b = {**batch, "perception": batch["perception"].copy()}
        for c in cols:
            b["perception"][0, where, c] += 37.0
        return b

    def value_and_grad(b):
        return eng.value_and_grad(lambda p: perception_term(p, b, CFG, eng))(params)

    l0, g0 = value_and_grad(batch)
    l1, g1 = value_and_grad(moved(~lead))
    assert float(l1) == float(l0)
    for a, b in zip(tree.leaves(g0), tree.leaves(g1)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    l2, _ = value_and_grad(moved(lead))
    assert float(l2) > float(l0) + 1.0


# --------------------------------------------------------------------------- fit


def test_fit_trains_with_the_loss_and_returns_the_controller(ds, targets):
    tc = _tc()
    res = train.fit("cnn", ds, CFG, tc, engine="numpy", progress=False, perception=targets)
    plain = train.fit("cnn", ds, CFG, _tc(perception_weight=0.0), engine="numpy",
                      progress=False)
    assert set(res.params) == set(plain.params) == set(models.init("cnn",
                                                                   np.random.default_rng(0),
                                                                   CFG))
    assert np.all(np.isfinite(res.history))
    assert res.history[0] > plain.history[0]  # the auxiliary term adds to Algorithm 1's loss
    w0 = np.asarray(res.params["backbone"]["convs"][0]["w"])
    assert not np.allclose(w0, plain.params["backbone"]["convs"][0]["w"])


def test_fit_ignores_what_the_mask_removes(ds, targets):
    """Two runs whose targets differ only in the masked values train the same parameters."""
    noisy = targets.values.copy()
    rng = np.random.default_rng(3)
    noisy[~targets.mask] += rng.normal(0.0, 50.0, size=int((~targets.mask).sum()))
    other = train.PerceptionTargets(targets.names, noisy, targets.mask, targets.logit)
    a = train.fit("cnn", ds, CFG, _tc(), engine="numpy", progress=False, perception=targets)
    b = train.fit("cnn", ds, CFG, _tc(), engine="numpy", progress=False, perception=other)
    np.testing.assert_array_equal(a.history, b.history)
    for x, y in zip(tree.leaves(a.params), tree.leaves(b.params)):
        np.testing.assert_array_equal(x, y)


def test_fit_refuses_targets_that_do_not_fit(ds, targets):
    with pytest.raises(ValueError, match="needs perception targets"):
        train.fit("cnn", ds, CFG, _tc(), engine="numpy", progress=False)
    with pytest.raises(ValueError, match="perception_weight is 0"):
        train.fit("cnn", ds, CFG, _tc(perception_weight=0.0), engine="numpy", progress=False,
                  perception=targets)
    short = train.PerceptionTargets(targets.names, targets.values[:2], targets.mask[:2],
                                    targets.logit)
    with pytest.raises(ValueError, match=r"cover \(S, T\)"):
        train.fit("cnn", ds, CFG, _tc(), engine="numpy", progress=False, perception=short)
    with pytest.raises(ValueError, match="PerceptionTargets"):
        train.fit("cnn", ds, CFG, _tc(), engine="numpy", progress=False,
                  perception=targets.values)
    warm = _params("cnn", len(targets.names) - 1)
    with pytest.raises(ValueError, match="reads 11 targets"):
        train.fit("cnn", ds, CFG, _tc(), engine="numpy", progress=False, perception=targets,
                  params=warm)
    with pytest.raises(ValueError, match="perception_weight must be"):
        train.TrainConfig(perception_weight=-1.0)
    with pytest.raises(ValueError, match="needs perception targets"):
        train.fit_many("cnn", ds, CFG, [_tc(), _tc(seed=1)], engine="jax", progress=False)


def test_perception_targets_refuse_bad_arrays(targets):
    v, m, names, logit = targets.values, targets.mask, targets.names, targets.logit
    with pytest.raises(ValueError, match="values must have shape"):
        train.PerceptionTargets(names[:-1], v, m, logit[:-1])
    with pytest.raises(ValueError, match="mask must be bool"):
        train.PerceptionTargets(names, v, m.astype(float), logit)
    with pytest.raises(ValueError, match="finite"):
        train.PerceptionTargets(names, v * np.nan, m, logit)
    bad = v.copy()
    bad[..., names.index("has_leader")] = 0.5
    with pytest.raises(ValueError, match="0 or 1"):
        train.PerceptionTargets(names, bad, m, logit)


def test_standardised_targets_use_the_masked_states_of_the_scenes(targets):
    z = train.standardised_targets(targets, [0, 1])
    for k in range(len(targets.names)):
        if targets.logit[k]:
            np.testing.assert_array_equal(z[..., k], targets.values[..., k])
            continue
        seen = z[:2][..., k][targets.mask[:2][..., k]]
        if seen.std() > 1e-3:
            assert abs(seen.mean()) < 1e-9 and seen.std() == pytest.approx(1.0, rel=1e-9)


# --------------------------------------------------------------------------- the targets


def test_the_targets_are_the_expert_s_features_with_their_masks(ds, targets):
    assert targets.names == diagnose.TARGETS and "a_prev" not in targets.names
    np.testing.assert_array_equal(targets.values, diagnose.perceived(ds, diagnose.TARGETS))
    f = {n: targets.values[..., k] for k, n in enumerate(targets.names)}
    m = {n: targets.mask[..., k] for k, n in enumerate(targets.names)}
    np.testing.assert_array_equal(m["gap"], f["has_leader"] > 0)
    np.testing.assert_array_equal(m["dv"], f["has_leader"] > 0)
    np.testing.assert_array_equal(m["stop"], f["has_stop"] > 0)
    assert m["v"].all() and m["has_leader"].all()
    assert (f["has_leader"] > 0).any() and (f["has_leader"] == 0).any()
    assert targets.logit == tuple(n in ("has_leader", "has_stop") for n in targets.names)


def test_a_view_keeps_the_leaders_it_shows(ds, targets):
    box = diagnose.leader_boxes(ds)
    lead = targets.values[..., targets.names.index("has_leader")] > 0
    np.testing.assert_array_equal(np.isfinite(box[..., 0]), lead)
    view = world.RasterConfig(metres_ahead=12.0)
    near = diagnose.perception_targets(ds, view=view)
    seen = near.values[..., near.names.index("has_leader")] > 0
    assert (seen <= lead).all() and seen.sum() < lead.sum()
    # asked state by state (the expert's situation names its leader), the same leaders as the
    # logged traffic's own perception in every logged state
    np.testing.assert_array_equal(seen, diagnose.in_view(box, view))
    gap = targets.values[..., targets.names.index("gap")]
    assert np.all(gap[seen] < 30.0)  # its rear within 12 m ahead: a short gap along the path
    np.testing.assert_array_equal(near.mask[..., near.names.index("gap")], seen)
    with pytest.raises(ValueError, match="view must be"):
        diagnose.perception_targets(ds, view=40.0)
