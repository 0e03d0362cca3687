# %% [markdown]
# # Chapter 8 — Exercises: assembling MANC
#
# Modules built in this chapter: `minimanc.models`, `minimanc.inputs` and
# `minimanc.train`. Replace each `raise NotImplementedError(...)` with your
# code and run the grade cell below it; `minimanc grade exercises/08_manc.ipynb`
# scores the notebook.
#
# You will rebuild MANC's head (FC → DMP gains → one DMP step → controls,
# eqs. 10–11), count its parameters, and assemble the whole forward pass
# (eqs. 7–11) from the chapter modules. Every exercise is checked against the
# library's `models.step`.

# %%
import numpy as np

from minimanc import dmp, engine, inputs, models, vagn, world

np.set_printoptions(precision=3, suppress=True)
rng = np.random.default_rng(0)
ds = world.generate(3, seed=0, raster=world.RasterConfig(size=64))
cfg = models.ModelConfig()
eng = engine("numpy")
params = models.init("manc", np.random.default_rng(0), cfg)
obs = inputs.from_dataset(ds, [0, 1, 2, 2], [4, 17, 9, 33], model="manc")
q_prev = vagn.random_state(rng, cfg.n_states, size=4)
print({k: v.shape for k, v in obs.items()})

# %% [markdown]
# ## Exercise 8.1 — from FC(q) to DMP gains
# The FC layer maps q to four logits per sample, in the order
# `[α_y, β_y, α_q, β_q]` (position gains, then orientation gains). Each goes
# through a sigmoid into its range, `α = lo + (hi − lo) σ(z)` with
# `dmp.ALPHA_RANGE` and `dmp.BETA_RANGE`, so that the step stays stable at
# dt = 0.5 s. Return `alpha` and `beta` of shape `(B, 2)`, each as
# `[position, orientation]`. Use a stable sigmoid, `0.5 (1 + tanh(z / 2))`.

# %% solution id=ex08_1 title="FC(q) to DMP gains" forbids="minimanc.dmp.gains_from_logits"  # noqa: E501
def gains_from_q(q, w, b):
    ### BEGIN SOLUTION
    z = q @ w + b
    sig = 0.5 * (1.0 + np.tanh(0.5 * z))
    a_lo, a_hi = dmp.ALPHA_RANGE
    b_lo, b_hi = dmp.BETA_RANGE
    alpha = a_lo + (a_hi - a_lo) * sig[:, [0, 2]]
    beta = b_lo + (b_hi - b_lo) * sig[:, [1, 3]]
    return alpha, beta
    ### END SOLUTION

# %% grade id=ex08_1_tests points=2
q = vagn.step(q_prev, rng.random((4, cfg.n_predicates)), params["vagn"]["W"])
a, b = gains_from_q(q, params["gains"]["w"], params["gains"]["b"])
assert a.shape == (4, 2) and b.shape == (4, 2)
assert np.all((a > dmp.ALPHA_RANGE[0]) & (a < dmp.ALPHA_RANGE[1]))


def gains_reference(q, w, b):
    """Eq. 10 written out: logits (alpha_y, beta_y, alpha_q, beta_q), sigma = 1 / (1 + e^-z)."""
    (a_lo, a_hi), (b_lo, b_hi) = dmp.ALPHA_RANGE, dmp.BETA_RANGE
    sig = 1.0 / (1.0 + np.exp(-(q @ w + b)))
    return a_lo + (a_hi - a_lo) * sig[:, [0, 2]], b_lo + (b_hi - b_lo) * sig[:, [1, 3]]


a_ref, b_ref = gains_reference(q, params["gains"]["w"], params["gains"]["b"])
assert np.allclose(a[:, 0], a_ref[:, 0]) and np.allclose(b[:, 0], b_ref[:, 0]), "position gains"
### BEGIN HIDDEN TESTS
assert np.allclose(a, a_ref) and np.allclose(b, b_ref)
q2 = vagn.random_state(rng, cfg.n_states, size=6)
w2, c2 = rng.normal(size=(cfg.n_states, 4)) * 3, rng.normal(size=4)
a2, b2 = gains_from_q(q2, w2, c2)
a2_ref, b2_ref = gains_reference(q2, w2, c2)
assert np.allclose(a2, a2_ref) and np.allclose(b2, b2_ref)
assert np.allclose(gains_from_q(q2, np.zeros((cfg.n_states, 4)), np.zeros(4))[0],
                   np.mean(dmp.ALPHA_RANGE)), "zero logits: the middle of the range"
big, _ = gains_from_q(np.eye(2), np.full((2, 4), 1e4), np.zeros(4))
assert np.all(np.isfinite(big)) and np.allclose(big, dmp.ALPHA_RANGE[1])
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 8.2 — one DMP step gives the speed
# The position DMP (eq. 10) starts in the ego frame at `y = (0, 0)` with
# velocity `(v0, 0)` and is pulled towards the lane point `g` (B, 2) with
# gains `alpha`, `beta` (each (B,)). Integrate one step of `dt = 0.5` s with
# **semi-implicit Euler** and `substeps = 10` sub-steps of `h = dt / 10`:
#
# $$\dot y \leftarrow \dot y + h\,\alpha\big(\beta (g - y) - \dot y\big),\qquad
#   y \leftarrow y + h\,\dot y\quad\text{(with the new }\dot y).$$
#
# The speed control is the forward (x) displacement over the step divided by
# `dt`. Return it, shape `(B,)`.

# %% solution id=ex08_2 title="One DMP step to a speed"
def dmp_speed(v0, g, alpha, beta, dt=0.5, substeps=10):
    ### BEGIN SOLUTION
    h = dt / substeps
    y = np.zeros_like(g)
    dy = np.stack([v0, np.zeros_like(v0)], axis=-1)
    a, b = alpha[:, None], beta[:, None]
    for _ in range(substeps):
        dy = dy + h * a * (b * (g - y) - dy)
        y = y + h * dy
    return y[:, 0] / dt
    ### END SOLUTION

# %% grade id=ex08_2_tests points=3
v0 = obs["motion"][:, 0].astype(float)
L_y = np.clip(cfg.position_lookahead + cfg.position_lookahead_time * v0, 4.0, 40.0)
g = models.lane_point(obs["lane_target"].astype(float), L_y)
controls, head = models.dmp_head(q_prev @ params["gains"]["w"] + params["gains"]["b"],
                                 obs["lane_target"], obs["motion"], cfg)
speed = dmp_speed(v0, g, head["alpha"][:, 0], head["beta"][:, 0])
assert speed.shape == (4,)
assert np.allclose(speed, controls[:, 0], atol=1e-4), "compare with models.dmp_head"
### BEGIN HIDDEN TESTS
y1, _, _ = dmp.step(np.zeros((4, 2)), np.stack([v0, 0 * v0], -1), g,
                    head["alpha"][:, :1], head["beta"][:, :1])
assert np.allclose(speed, y1[:, 0] / 0.5)
# at the goal speed beta*(g - y) the speed hardly changes
keep = dmp_speed(np.array([8.0]), np.array([[20.0, 0.0]]), np.array([0.5]), np.array([0.4]))
assert abs(keep[0] - 8.0) < 0.3
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 8.3 — the orientation goal: pure pursuit
# The yaw rate comes from the orientation DMP, whose goal is the heading after
# `τ = 1` s on the **pure-pursuit arc**: the circle that leaves the ego along
# its heading (+x) and passes through the lane point `p` at
# `L = clip(5 + 1·v0, 5, 22)` metres ahead. Its curvature is
# `κ = 2 p_y / (p_x² + p_y²)` and the goal is `ψ_g = clip(κ · v0 · τ, −π/2, π/2)`.
# Use `models.lane_point(lane_target, L)` for `p`. Return `ψ_g`, shape `(B,)`.

# %% solution id=ex08_3 title="Pure-pursuit orientation goal"
def orientation_goal(lane_target, v0, tau=1.0):
    ### BEGIN SOLUTION
    L = np.clip(5.0 + 1.0 * v0, 5.0, 22.0)
    p = models.lane_point(lane_target, L)
    kappa = 2.0 * p[:, 1] / np.maximum(p[:, 0] ** 2 + p[:, 1] ** 2, 1e-6)
    return np.clip(kappa * v0 * tau, -np.pi / 2, np.pi / 2)
    ### END SOLUTION

# %% grade id=ex08_3_tests points=2
psi = orientation_goal(obs["lane_target"].astype(float), v0)
assert psi.shape == (4,)
assert np.allclose(psi, head["psi_g"], atol=1e-5), "compare with models.dmp_head's psi_g"
left = np.stack([4.0 * np.arange(1, 11), np.full(10, 1.0)], -1)[None]
assert orientation_goal(left, np.array([10.0]))[0] > 0, "lane to the left: turn left"
### BEGIN HIDDEN TESTS
right = left * np.array([1.0, -1.0])
assert np.isclose(orientation_goal(right, np.array([10.0]))[0],
                  -orientation_goal(left, np.array([10.0]))[0])
assert orientation_goal(left, np.array([0.0]))[0] == 0.0
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 8.4 — counting parameters
# (a) `count(tree)`: the number of scalars in a parameter pytree (nested dicts
# and lists of arrays). (b) `manc_count(cfg)`: MANC's count from the
# configuration alone — 3×3 convolutions with biases (`cfg.channels`, 3 input
# channels), the predicate layer (K → M with bias, K the last channel count),
# vAGN's `M × N × N` weights, and the gains FC (N → 4 with bias).

# %% solution id=ex08_4 title="Parameter count" forbids="minimanc.models.param_count,minimanc.models.param_counts"  # noqa: E501
def count(tree):
    ### BEGIN SOLUTION
    if isinstance(tree, dict):
        return sum(count(v) for v in tree.values())
    if isinstance(tree, (list, tuple)):
        return sum(count(v) for v in tree)
    return int(np.size(tree))
    ### END SOLUTION


def manc_count(cfg):
    ### BEGIN SOLUTION
    total, c_in = 0, 3
    for c in cfg.channels:
        total += 3 * 3 * c_in * c + c
        c_in = c
    M, N = cfg.n_predicates, cfg.n_states
    return total + (c_in * M + M) + M * N * N + (N * 4 + 4)
    ### END SOLUTION

# %% grade id=ex08_4_tests points=2
assert count({"a": np.zeros((2, 3)), "b": [np.zeros(4), {"c": np.zeros(())}]}) == 11
# convs 448 + 4640 + 9248, predicates 32 * 8 + 8, vAGN 8 * 6 * 6, gains 6 * 4 + 4
assert count(params) == 14916 == 14336 + 264 + 288 + 28
assert manc_count(cfg) == 14916
### BEGIN HIDDEN TESTS
# by hand: (8, 16) channels: 224 + 1168 + 136 + 72 + 16; n_predicates=4: 14336 + 132 + 576 + 52;
# the CNN totals were computed once with models.param_count
for c, manc_total, cnn_total in ((models.ModelConfig(n_states=3, channels=(8, 16)), 1616, 263922),
                                 (models.ModelConfig(n_states=12, n_predicates=4), 15096, 145794)):
    assert manc_count(c) == manc_total
    assert count(models.init("manc", rng, c)) == manc_total
    assert count(models.init("cnn", rng, c)) == cnn_total
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 8.5 — the whole MANC step
# Assemble one control step from the pieces (paper eqs. 7–11):
#
# 1. features `f = models.backbone(params["backbone"], bev, cfg, eng)`;
# 2. predicate logits `z = GAP(f) @ w + b` with `params["predicates"]`, then
#    `p = sigmoid(z)` (eq. 7; GAP is the mean over the two spatial axes);
# 3. `q = vagn.step(q_prev, p, params["vagn"]["W"])` (eqs. 8–9);
# 4. the gain logits `FC(q)` with `params["gains"]`;
# 5. `models.dmp_head(logits, lane_target, motion, cfg)` (eqs. 10–11).
#
# Return `(controls (B, 2), q (B, N))`.

# %% solution id=ex08_5 title="The MANC forward pass"
def manc_step(params, obs, q_prev, cfg):
    ### BEGIN SOLUTION
    f = models.backbone(params["backbone"], obs["bev"], cfg, eng)
    z = f.mean(axis=(1, 2)) @ params["predicates"]["w"] + params["predicates"]["b"]
    p = 0.5 * (1.0 + np.tanh(0.5 * z))
    q = vagn.step(q_prev, p, params["vagn"]["W"])
    logits = q @ params["gains"]["w"] + params["gains"]["b"]
    controls, _ = models.dmp_head(logits, obs["lane_target"], obs["motion"], cfg)
    return controls, q
    ### END SOLUTION

# %% grade id=ex08_5_tests points=3
u, q = manc_step(params, obs, q_prev, cfg)
u_ref, state, _ = models.step("manc", params, obs, {"q": q_prev}, cfg, eng)
assert u.shape == (4, 2) and q.shape == (4, cfg.n_states)
assert np.allclose(q.sum(axis=1), 1.0)
assert np.allclose(u, u_ref, atol=1e-6) and np.allclose(q, state["q"])
### BEGIN HIDDEN TESTS
p2 = models.init("manc", np.random.default_rng(5), cfg)
u2, q2 = manc_step(p2, obs, state["q"], cfg)
u2_ref, s2, _ = models.step("manc", p2, obs, state, cfg, eng)
assert np.allclose(u2, u2_ref, atol=1e-6) and np.allclose(q2, s2["q"])
### END HIDDEN TESTS

# %% [markdown]
# ## Check
# The library's MANC drives a logged scene step by step (q carried over);
# every control is finite and every q a distribution.

# %%
tr = models.replay("manc", params, ds, 1, cfg)
print("controls at steps 0-4:\n", tr["controls"][:5])
assert np.all(np.isfinite(tr["controls"])) and np.allclose(tr["q"].sum(axis=1), 1.0)
