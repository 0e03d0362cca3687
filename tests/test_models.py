"""Tests for minimanc.models (chapter 8): shapes, gradients on both engines, the DMP head, vAGN."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from minimanc import cam, dmp, engine, inputs, models, quaternion, tree, vagn
from minimanc.world.traffic import B_MAX

B = 3
CFG = models.ModelConfig(input_shape=(16, 16, 3), channels=(4, 8), n_predicates=5, n_states=4,
                         hidden=8, k_targets=6)


def _obs(rng, cfg=CFG, lead=(B,)):
    straight = np.stack([4.0 * np.arange(1, cfg.k_targets + 1), np.zeros(cfg.k_targets)], -1)
    shape = cfg.bev_shape
    return {
        "bev": rng.random(lead + shape),
        "goal": rng.normal(size=lead + (3,)) * 20,
        "lane_target": straight + rng.normal(0, 0.5, lead + (cfg.k_targets, 2)),
        "motion": np.stack([rng.uniform(0, 12, lead), rng.normal(0, 0.1, lead)], -1),
        # a scene's raster: the same at every step of a window (lead (L, B))
        "goal_bev": np.broadcast_to(rng.random(lead[-1:] + shape), lead + shape).copy(),
    }


@pytest.mark.parametrize("setting", inputs.SETTINGS)
@pytest.mark.parametrize("name", models.names())
def test_shapes(name, setting, eng_np):
    cfg = models.ModelConfig(**{**CFG.to_dict(), "channels": CFG.channels, "setting": setting})
    rng = np.random.default_rng(0)
    params = models.init(name, rng, cfg)
    obs = inputs.select(_obs(rng, cfg), models.get(name), setting)
    state = models.initial_state(name, B, cfg)
    controls, new, aux = models.step(name, params, obs, state, cfg, eng_np)
    assert controls.shape == (B, 2) and np.all(np.isfinite(controls))
    assert set(new) == set(state)
    for k, v in state.items():
        assert new[k].shape == v.shape
    assert aux["features"].shape == (B, 4, 4, 8)  # 16 → 8 → 4
    if name in models.vagn_models():
        assert aux["q"].shape == (B, cfg.n_states)
    if name in models.dmp_models():
        assert aux["alpha"].shape == aux["beta"].shape == (B, 2)
    if name in ("manc", "vagn_only", "dmp_only"):
        assert aux["predicates"].shape == (B, cfg.n_predicates)


def _sum_tree(params):
    return sum(np.sum(np.asarray(x, dtype=np.float64) ** 2) for x in tree.leaves(params))


@pytest.mark.parametrize("name", models.names())
def test_gradients_numpy_equal_jax(name, eng_np, eng_jax):
    """The same model code differentiated by our engine and by JAX agrees to 1e-6 (float64)."""
    cfg = models.ModelConfig(**{**CFG.to_dict(), "channels": CFG.channels, "setting": "parity"})
    rng = np.random.default_rng(1)
    params = models.init(name, rng, cfg)
    L = 2 if name in models.lstm_models() + models.vagn_models() else 1
    obs = {k: v for k, v in _obs(rng, cfg, lead=(L, B)).items()}
    target = rng.normal(size=(L, B, 2))

    def loss(p, eng):
        state = models.initial_state(name, B, cfg, xp=eng.xp, dtype=np.float64)
        out, _ = models.sequence(name, p, obs, state, cfg, eng)
        return eng.xp.mean((out - target) ** 2)

    v_np, g_np = eng_np.value_and_grad(lambda p: loss(p, eng_np))(params)
    v_jx, g_jx = eng_jax.jit(eng_jax.value_and_grad(lambda p: loss(p, eng_jax)))(params)
    assert abs(float(v_np) - float(v_jx)) < 1e-9
    leaves_np, leaves_jx = tree.leaves(g_np), tree.leaves(g_jx)
    assert len(leaves_np) == len(leaves_jx) == len(tree.leaves(params))
    for a, b in zip(leaves_np, leaves_jx):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-6, atol=1e-9)
    assert _sum_tree(g_np) > 0.0  # gradients reach the parameters


@pytest.mark.parametrize("name", models.names())
def test_sequence_equals_repeated_steps(name, eng_np):
    rng = np.random.default_rng(2)
    params = models.init(name, rng, CFG)
    obs = _obs(rng, CFG, lead=(3, B))
    state = models.initial_state(name, B, CFG, dtype=np.float64)
    seq, final = models.sequence(name, params, inputs.select(obs, models.get(name)), state, CFG,
                                 eng_np)
    for t in range(3):
        one = inputs.select({k: v[t] for k, v in obs.items()}, models.get(name))
        out, state, _ = models.step(name, params, one, state, CFG, eng_np)
        np.testing.assert_allclose(seq[t], out, rtol=1e-12, atol=1e-12)
    for k in state:
        np.testing.assert_allclose(final[k], state[k], rtol=1e-12)


def test_sequence_encodes_the_goal_raster_once_per_window_and_refuses_one_that_changes(eng_np):
    """RvS-G's goal raster is a scene's: ``sequence`` runs the backbone on it once per
    window (equal to the steps, above); a raster that changes over the window is refused."""
    rng = np.random.default_rng(3)
    params = models.init("rvs_g", rng, CFG)
    obs = inputs.select(_obs(rng, CFG, lead=(3, B)), models.get("rvs_g"))
    state = models.initial_state("rvs_g", B, CFG, dtype=np.float64)
    models.sequence("rvs_g", params, obs, state, CFG, eng_np)
    obs["goal_bev"][2, 0, 0, 0, 0] += 0.5
    with pytest.raises(ValueError, match=r"obs_seq\['goal_bev'\] must be the same at every step"):
        models.sequence("rvs_g", params, obs, state, CFG, eng_np)


@pytest.mark.parametrize("name", models.dmp_models())
def test_sequence_feeds_the_dmp_its_own_motion(name, eng_np):
    """With feedback, step i > 0 starts the DMP from the model's own previous controls."""
    rng = np.random.default_rng(8)
    params = models.init(name, rng, CFG)
    obs = inputs.select(_obs(rng, CFG, lead=(3, B)), models.get(name))
    state = models.initial_state(name, B, CFG, dtype=np.float64)
    seq, _, aux = models.sequence(name, params, obs, state, CFG, eng_np, feedback_motion=True,
                                  return_aux=True)
    motion = obs["motion"][0]
    for t in range(3):
        one = {**{k: v[t] for k, v in obs.items()}, "motion": motion}
        out, state, a = models.step(name, params, one, state, CFG, eng_np)
        np.testing.assert_allclose(seq[t], out, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(aux["alpha"][t], a["alpha"], rtol=1e-12)
        motion = out
    plain, _ = models.sequence(name, params, obs, models.initial_state(name, B, CFG,
                               dtype=np.float64), CFG, eng_np)
    assert not np.allclose(plain[1:], seq[1:])  # the logged motion differs from the model's


@pytest.mark.parametrize("name", models.dmp_models())
def test_sequence_chooses_the_feedback_per_window(name, eng_np, eng_jax):
    """``feedback_motion`` as a ``(B,)`` array: each window is the whole-batch run of its
    own choice (fed back where True, the logged motion where False), on both engines."""
    rng = np.random.default_rng(9)
    params = models.init(name, rng, CFG)
    obs = inputs.select(_obs(rng, CFG, lead=(3, B)), models.get(name))

    def run(eng, fb):
        state = models.initial_state(name, B, CFG, dtype=np.float64)
        return np.asarray(models.sequence(name, params, obs, state, CFG, eng,
                                          feedback_motion=fb)[0])

    fed, logged = run(eng_np, True), run(eng_np, False)
    rows = np.arange(B) % 2 == 0
    for eng in (eng_np, eng_jax):
        mixed = run(eng, rows)
        np.testing.assert_allclose(mixed[:, rows], fed[:, rows], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(mixed[:, ~rows], logged[:, ~rows], rtol=1e-9, atol=1e-12)
    assert np.abs(fed[1:, ~rows] - logged[1:, ~rows]).max() > 1e-6


def test_step_under_jit(eng_jax):
    rng = np.random.default_rng(3)
    params = models.init("manc", rng, CFG, dtype=np.float32)
    obs = {k: v.astype(np.float32) for k, v in inputs.select(_obs(rng), models.get("manc")).items()}
    state = models.initial_state("manc", B, CFG)
    f = eng_jax.jit(lambda p, o, s: models.step("manc", p, o, s, CFG, eng_jax)[0])
    out = f(params, obs, state)
    assert out.dtype == np.float32  # no silent promotion to float64
    ref, _, _ = models.step("manc", params, obs, state, CFG, engine("numpy"))
    np.testing.assert_allclose(np.asarray(out), ref, rtol=1e-4, atol=1e-4)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(0.1, 30.0), steps=st.integers(1, 6))
def test_q_stays_a_distribution(seed, scale, steps):
    """Over many closed-loop steps q stays non-negative and sums to one (eq. 9)."""
    eng = engine("numpy")
    rng = np.random.default_rng(seed)
    params = models.init("manc", rng, CFG)
    params["vagn"]["W"] = params["vagn"]["W"] * scale
    state = models.initial_state("manc", B, CFG, rng=rng, mode="random", dtype=np.float64)
    for _ in range(steps):
        obs = inputs.select(_obs(rng), models.get("manc"))
        _, state, aux = models.step("manc", params, obs, state, CFG, eng)
        q = np.asarray(aux["q"])
        assert np.all(q >= 0.0)
        np.testing.assert_allclose(q.sum(axis=-1), 1.0, atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(0.0, 1e3))
def test_dmp_gains_in_the_stable_box(seed, scale):
    """Whatever the network outputs, the gains stay in the ranges where dt = 0.5 is stable."""
    rng = np.random.default_rng(seed)
    logits = rng.normal(size=(6, 4)) * scale
    obs = _obs(rng, lead=(6,))
    controls, aux = models.dmp_head(logits, obs["lane_target"], obs["motion"], CFG)
    a, b = aux["alpha"], aux["beta"]
    assert np.all((a >= dmp.ALPHA_RANGE[0]) & (a <= dmp.ALPHA_RANGE[1]))
    assert np.all((b >= dmp.BETA_RANGE[0]) & (b <= dmp.BETA_RANGE[1]))
    assert np.all(dmp.step_stable(a, b, dt=CFG.dt))
    assert np.all(np.isfinite(controls))


def test_dmp_head_orientation_forms_agree():
    """The yaw-angle orientation DMP equals the quaternion DMP of eq. 2 for yaw-only motion."""
    rng = np.random.default_rng(4)
    obs = _obs(rng, lead=(8,))
    obs["lane_target"][..., 1] += rng.normal(0, 3, (8, 1))  # sizeable turns
    logits = rng.normal(size=(8, 4)) * 2
    yaw, _ = models.dmp_head(logits, obs["lane_target"], obs["motion"], CFG)
    cfg_q = models.ModelConfig(**{**CFG.to_dict(), "channels": CFG.channels,
                                  "orientation": "quaternion"})
    quat, _ = models.dmp_head(logits, obs["lane_target"], obs["motion"], cfg_q)
    np.testing.assert_allclose(yaw, quat, rtol=1e-9, atol=1e-9)
    # and the quaternion module's own step agrees with the head's yaw rate
    _, aux = models.dmp_head(logits, obs["lane_target"], obs["motion"], CFG)
    a, b = aux["alpha"][:, 1:], aux["beta"][:, 1:]
    z = np.zeros(8)
    q1, _, _ = quaternion.quaternion_step(quaternion.identity((8,)),
                                          np.stack([z, z, obs["motion"][:, 1]], -1),
                                          quaternion.from_yaw(aux["psi_g"]), a, b)
    np.testing.assert_allclose(quaternion.to_yaw(q1) / CFG.dt, yaw[:, 1], atol=1e-9)


def _straight(offset, k=CFG.k_targets):
    """Lane target of a straight lane whose centre is ``offset`` m to the ego's left."""
    return np.stack([4.0 * np.arange(1, k + 1), np.full(k, offset)], -1)[None]


def test_dmp_head_keeps_speed_and_corrects_a_lateral_offset():
    zy = dmp.logits_from_gains(1.0, 1.0 / CFG.position_lookahead_time)
    zq = dmp.logits_from_gains(3.0, 1.0 / CFG.heading_horizon)
    logits = np.array([[zy[0], zy[1], zq[0], zq[1]]])
    motion = np.array([[8.0, 0.0]])
    centred, _ = models.dmp_head(logits, _straight(0.0), motion, CFG)
    # on the lane centre: no turn, and beta_y * tau_y = 1 nearly keeps the speed
    assert abs(centred[0, 1]) < 1e-12
    assert abs(centred[0, 0] - 8.0) < 1.5
    # lane centre 1 m to the right (ego is left of it): turn right, i.e. back to the lane
    left_of_lane, _ = models.dmp_head(logits, _straight(-1.0), motion, CFG)
    right_of_lane, _ = models.dmp_head(logits, _straight(1.0), motion, CFG)
    assert left_of_lane[0, 1] < -0.01 and right_of_lane[0, 1] > 0.01
    np.testing.assert_allclose(left_of_lane[0, 1], -right_of_lane[0, 1], rtol=1e-9)
    # larger position gain beta_y: faster
    fast, _ = models.dmp_head(logits + np.array([[0, 3.0, 0, 0]]), _straight(0.0), motion, CFG)
    assert fast[0, 0] > centred[0, 0] + 0.5



def test_dmp_head_gain_box_spans_a_hard_stop_and_a_hard_acceleration():
    # The head's range in one step, at the corners of the gain box (chapter 3): from 10 m/s
    # on a straight lane it can ask for a near stop (a deceleration beyond the world's
    # physical braking limit) and for far more than any speed of the world: what MANC asks
    # for is a matter of the gains it learns, not of the head.
    motion = np.array([[10.0, 0.0]])
    speeds = []
    for za in (-30.0, 30.0):
        for zb in (-30.0, 30.0):
            out, aux = models.dmp_head(np.array([[za, zb, 0.0, 0.0]]), _straight(0.0), motion,
                                       CFG)
            speeds.append(out[0, 0])
    assert (10.0 - min(speeds)) / CFG.dt > B_MAX and max(speeds) > 30.0

def test_predicates_match_cam(eng_np):
    """MANC's eq. 7 is the chapter-6 predicate extractor (then a sigmoid) with our backbone."""
    rng = np.random.default_rng(5)
    params = models.init("manc", rng, CFG)
    obs = inputs.select(_obs(rng), models.get("manc"))
    _, _, aux = models.step("manc", params, obs, models.initial_state("manc", B, CFG), CFG,
                            eng_np)
    ext = {"convs": params["backbone"]["convs"], "head": params["predicates"]}
    p = cam.predicate_extractor(ext, obs["bev"], eng_np.nn, xp=eng_np.xp, strides=(2, 2),
                                padding=1, activation="silu")
    np.testing.assert_allclose(aux["predicates"], 1.0 / (1.0 + np.exp(-p)), rtol=1e-10)


def test_the_heads_lane_spacing_is_the_worlds():
    from minimanc import world

    assert models.config.TARGET_SPACING == world.TARGET_SPACING
    ds = world.generate(1, seed=0, progress=False)
    lane = inputs.from_dataset(ds, 0, 5, model=models.get("manc"))["lane_target"]
    steps = np.linalg.norm(np.diff(lane, axis=-2), axis=-1)
    np.testing.assert_allclose(np.median(steps), models.config.TARGET_SPACING, rtol=0.05)


def test_param_count():
    cfg = CFG
    params = models.init("manc", np.random.default_rng(0), cfg)
    conv = (3 * 3 * 3 * 4 + 4) + (3 * 3 * 4 * 8 + 8)
    M, N = cfg.n_predicates, cfg.n_states
    assert models.param_count(params) == conv + (8 * M + M) + M * N * N + (N * 4 + 4)
    counts = models.param_counts(models.ModelConfig())
    assert set(counts) == set(models.names())
    # the paper's claim (Fig. 7b): MANC is much smaller than the comparison models
    for other in ("cnn", "cnn_lstm", "rvs_g"):
        assert counts["manc"] < 0.7 * counts[other]


def test_explain_saliency_identity():
    rng = np.random.default_rng(6)
    params = models.init("manc", rng, CFG)
    obs = _obs(rng)
    q_prev = np.full((B, CFG.n_states), 1.0 / CFG.n_states)
    ex = models.saliency(params, obs, q_prev, CFG, upsample_to_input=False)
    N, M = CFG.n_states, CFG.n_predicates
    assert ex["saliency"].shape == (B, N, 4, 4) and ex["cams"].shape == (B, M, 4, 4)
    # mean over pixels of S_j = sum_i J_ji (z_i - b_i), z the predicate logits (chapter 6)
    lhs = ex["saliency"].mean(axis=(-2, -1))
    rhs = np.einsum("bji,bi->bj", ex["jacobian"], ex["logits"] - params["predicates"]["b"])
    # and the Jacobian is dq/dlogits: compare with JAX
    import jax

    eng = engine("jax")

    def q_of(z):
        p = 1.0 / (1.0 + eng.xp.exp(-z))
        return vagn.step(q_prev[0], p, params["vagn"]["W"], xp=eng.xp)

    J = np.stack([jax.jacrev(q_of)(ex["logits"][i]) for i in range(B)])
    np.testing.assert_allclose(ex["jacobian"], J, rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(lhs, rhs, rtol=1e-9, atol=1e-12)
    up = models.saliency(params, obs, q_prev, CFG)
    assert up["saliency"].shape == (B, N, 16, 16)
    with pytest.raises(ValueError, match="vAGN"):
        models.saliency(models.init("cnn", rng, CFG), obs, q_prev, CFG)


def test_bad_input_raises(eng_np):
    rng = np.random.default_rng(7)
    with pytest.raises(ValueError, match="name"):
        models.init("transformer", rng, CFG)
    with pytest.raises(ValueError, match="rng"):
        models.initial_state("manc", 2, CFG, mode="random")
    with pytest.raises(ValueError, match="n_states"):
        models.ModelConfig(n_states=0)
    with pytest.raises(ValueError, match="heading_lookahead"):
        models.ModelConfig(heading_lookahead=2.0)
    params = models.init("cnn", rng, CFG)
    with pytest.raises(ValueError, match="goal"):
        models.step("cnn", params, {"bev": np.zeros((1, 16, 16, 3))}, {}, CFG, eng_np)
    with pytest.raises(ValueError, match="input_shape"):
        models.step("cnn", params, {"bev": np.zeros((1, 8, 8, 3)), "goal": np.zeros((1, 3))}, {},
                    CFG, eng_np)


@pytest.mark.parametrize("feedback", [False, True])
@pytest.mark.parametrize("name", models.names())
def test_sequence_scan_on_jax_equals_the_loop_on_numpy(name, feedback, eng_np, eng_jax):
    """On JAX the time loop of ``sequence`` is one ``lax.scan``: the same controls, final
    state and per-step aux as the Python loop, with and without the DMP's own-speed
    feedback."""
    cfg = models.ModelConfig(**{**CFG.to_dict(), "channels": CFG.channels, "setting": "parity"})
    rng = np.random.default_rng(4)
    params = models.init(name, rng, cfg)
    obs = inputs.select(_obs(rng, cfg, lead=(5, B)), models.get(name), "parity")
    state = models.initial_state(name, B, cfg, dtype=np.float64)
    a, sa, xa = models.sequence(name, params, obs, state, cfg, eng_np, feedback_motion=feedback,
                                return_aux=True)
    b, sb, xb = eng_jax.jit(lambda p, o, s: models.sequence(
        name, p, o, s, cfg, eng_jax, feedback_motion=feedback, return_aux=True))(params, obs,
                                                                                  state)
    np.testing.assert_allclose(np.asarray(b), a, rtol=1e-9, atol=1e-9)
    assert set(sa) == set(sb) and set(xa) == set(xb)
    for k in sa:
        np.testing.assert_allclose(np.asarray(sb[k]), sa[k], rtol=1e-9, atol=1e-9)
    for k in xa:
        np.testing.assert_allclose(np.asarray(xb[k]), xa[k], rtol=1e-9, atol=1e-9)
    if feedback and name in models.dmp_models():  # the feedback changes steps 1.. only
        c, _ = models.sequence(name, params, obs, state, cfg, eng_jax)
        np.testing.assert_allclose(np.asarray(c)[0], a[0], rtol=1e-9, atol=1e-9)
        assert np.abs(np.asarray(c)[1:] - a[1:]).max() > 1e-6


# --------------------------------------------------------------------------- dt and the gain box


def test_model_config_refuses_a_dt_for_which_the_dmp_head_is_unstable():
    # semi-implicit Euler, 10 sub-steps: stable iff h·α(2 + h·β) < 4 at the corner (20, 5),
    # i.e. h < (−40 + √3200) / 200, dt < 0.8284 s
    bound = 10 * (-40.0 + np.sqrt(3200.0)) / 200.0
    models.ModelConfig(dt=0.5)
    models.ModelConfig(dt=0.99 * bound)
    with pytest.raises(ValueError, match=r"dt=0\.9 makes the DMP head's integrator .*unstable"
                                         r".*alpha=20, beta=5.*use dt < 0\.8284"):
        models.ModelConfig(dt=0.9)
    with pytest.raises(ValueError, match="beta = alpha/4"):
        models.ModelConfig(dt=2.0, critically_damped=True)
    for bad in (0.0, -0.5, float("nan"), float("inf"), "0.5", True):
        with pytest.raises(ValueError, match="dt"):
            models.ModelConfig(dt=bad)


@settings(max_examples=40, deadline=None)
@given(dt=st.floats(0.01, 3.0), ua=st.floats(0.0, 1.0), ub=st.floats(0.0, 1.0),
       crit=st.booleans())
def test_an_accepted_dt_keeps_every_gain_of_the_box_stable(dt, ua, ub, crit):
    """Whatever gains the head's sigmoid produces, the DMP step of an accepted dt contracts."""
    try:
        models.ModelConfig(dt=dt, critically_damped=crit)
    except ValueError:
        corners = models.config.gain_box_corners(crit)
        assert max(dmp.spectral_radius(a, b, dt=dt) for a, b in corners) > 1.0
        return
    a = dmp.ALPHA_RANGE[0] + ua * (dmp.ALPHA_RANGE[1] - dmp.ALPHA_RANGE[0])
    b = a / 4.0 if crit else dmp.BETA_RANGE[0] + ub * (dmp.BETA_RANGE[1] - dmp.BETA_RANGE[0])
    assert dmp.spectral_radius(a, b, dt=dt) < 1.0
