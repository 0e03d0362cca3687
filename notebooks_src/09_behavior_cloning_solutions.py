# %% [markdown]
# # Chapter 9 — Graded exercises: the MANC step, the closed loop, a metric
#
# Modules used in this chapter: `minimanc.rollout`, `minimanc.metrics` and
# `minimanc.studies` (with `minimanc.models`, `minimanc.inputs`, `minimanc.world`).
#
# Five exercises, each checked by the grade cell below it:
#
# 1. **The MANC forward pass** from library pieces: CNN backbone → visual
#    predicates (eq. 7) → vAGN step (eqs. 8–9) → FC → one DMP step (eqs. 10–11).
# 2. **One closed-loop step**: observe from the ego's *own* pose, act, move.
# 3. **A metric**: the maximum acceleration of a trajectory.
# 4. **ADE split in two**: the error along the human's heading (speed, timing)
#    and across it (steering).
# 5. **% close encounters**: the share of steps with an ado box within 1 m;
# 6. **what replaying the human costs**: the error of the logged controls
#    replayed from a slightly wrong start, in closed form (the tutorial does not
#    derive it);
# 7. an open experiment: **a tracking controller** that closes the loop,
#    defended in writing.
#
# Replace each `raise NotImplementedError(...)` with your code.

# %%
import math

import matplotlib.pyplot as plt
import numpy as np

from minimanc import engine, inputs, layers, metrics, models, rollout, vagn, world
from minimanc.viz.exercises import plot_track_error_attempts

rng = np.random.default_rng(0)
eng = engine("numpy")
ds = world.generate(4, seed=0, raster=world.RasterConfig(size=32), workers=1)
cfg = models.ModelConfig(image_size=32, n_states=4)
params = models.init("manc", rng, cfg)  # untrained: the DMP head already follows the lane
print(ds)

# %% [markdown]
# ## Exercise 9.1 — the MANC forward pass
# Write one MANC step for a batch of observations (the dict built by
# `minimanc.inputs`: `bev` (B, H, W, 3), `lane_target` (B, K, 2), `motion`
# (B, 2)) and the previous q-distribution `q_prev` (B, N). Use the library
# pieces, in this order:
#
# * `models.backbone(params["backbone"], bev, cfg, eng)` — the shared CNN, features (B, h, w, C);
# * global average pooling over the two spatial axes, then
#   `layers.dense(params["predicates"], ·, xp=xp)` and a sigmoid (`eng.nn.sigmoid`, the
#   default `cfg.predicate_activation`: each predicate in (0, 1)) — the visual
#   predicates $p^v$ (eq. 7);
# * `vagn.step(q_prev, p, params["vagn"]["W"], xp=xp)` — the new q-distribution (eqs. 8–9);
# * `layers.dense(params["gains"], q, xp=xp)` — four gain logits, $\texttt{FC}(q)$ of eq. 11;
# * `models.dmp_head(logits, lane_target, motion, cfg, xp=xp)` — one DMP step towards
#   the lane target; it returns `(controls, aux)` with `aux["alpha"]`, `aux["beta"]`.
#
# Return `(controls, q, alpha, beta)`.

# %% solution id=ex09_1 title="The MANC forward pass" forbids="minimanc.models.step"
def manc_step(params, obs, q_prev, cfg, eng):
    xp = eng.xp
    ### BEGIN SOLUTION
    f = models.backbone(params["backbone"], xp.asarray(obs["bev"]), cfg, eng)
    p = eng.nn.sigmoid(layers.dense(params["predicates"], xp.mean(xp.mean(f, axis=1), axis=1),
                                    xp=xp))
    q = vagn.step(q_prev, p, params["vagn"]["W"], xp=xp)
    logits = layers.dense(params["gains"], q, xp=xp)
    controls, aux = models.dmp_head(logits, obs["lane_target"], obs["motion"], cfg, xp=xp)
    return controls, q, aux["alpha"], aux["beta"]
    ### END SOLUTION

# %% grade id=ex09_1_tests points=3
# expected values: literals computed once with models.step (float64 NumPy, the untrained
# seed-0 parameters above), rounded to 6 decimals
obs = inputs.from_dataset(ds, [0, 1, 2], [0, 5, 10], "paper", model=models.get("manc"))
q0 = np.full((3, 4), 0.25)
u, q, alpha, beta = manc_step(params, obs, q0, cfg, eng)
u_ref = [[10.584588, 0.007875], [10.15597, 0.052751], [10.990746, -0.005967]]
assert np.allclose(u, u_ref, atol=1e-5), f"controls [speed, yaw rate] should be {u_ref}, got {u}"
assert np.allclose(q.sum(-1), 1.0), "each row of q is a distribution: it should sum to 1"
assert np.allclose(q, [[0.082422, 0.062108, 0.505915, 0.349556],
                       [0.08691, 0.062907, 0.502352, 0.34783],
                       [0.087656, 0.060538, 0.502576, 0.349231]], atol=1e-5), (
    "q should be vagn.step(q_prev, p, W) with p = sigmoid(dense(GAP(backbone))) (eq. 7)")
assert np.allclose(alpha, [[1.081929, 0.79416], [1.08096, 0.797059], [1.081928, 0.7973]],
                   atol=1e-5), "alpha should be aux['alpha'] of models.dmp_head"
assert np.allclose(beta, [[1.044059, 1.685567], [1.031033, 1.693471], [1.029253, 1.704702]],
                   atol=1e-5), "beta should be aux['beta'] of models.dmp_head"
### BEGIN HIDDEN TESTS
q1 = vagn.random_state(np.random.default_rng(1), 4, size=3)  # its own generator
u1, qq, _, _ = manc_step(params, obs, q1, cfg, eng)
assert np.allclose(u1, [[9.183181, 0.013828], [12.091797, 0.05262], [10.630134, -0.006091]],
                   atol=1e-5), "from a random q_prev the controls change (literal values)"
assert np.allclose(qq, [[0.019958, 0.014246, 0.174789, 0.791007],
                        [0.058642, 0.045234, 0.678306, 0.217817],
                        [0.036887, 0.025957, 0.405365, 0.53179]], atol=1e-5), (
    "from a random q_prev, q = T(p) q_prev (literal values)")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 9.2 — one closed-loop step
# In closed loop the policy sees what *its own* driving produces. Given the
# current ego poses `pose` (B, 3) of the scenes `scenes`, the previous controls
# `motion` (B, 2), the policy's state and the time step `t`:
#
# 1. build the observation with `inputs.from_state(maps, pose, ado, ado_valid,
#    goal_world, ds.raster, policy.setting, motion=motion,
#    model=models.get(policy.model))`
#    — the ados at their *logged* boxes of step `t`, the goal is the human's
#    final pose `ds.ego[scenes, -1]`;
# 2. call `policy(obs, state, t, scenes)`, which returns `(controls, state, aux)`;
# 3. move the ego with `world.unicycle_step(pose, controls, world.DT)`.
#
# Return `(new_pose, controls, new_state)`.

# %% solution id=ex09_2 title="One closed-loop step" forbids="minimanc.rollout.simulate,minimanc.rollout.closed_loop"  # noqa: E501
def closed_loop_step(policy, ds, scenes, pose, motion, state, t):
    ### BEGIN SOLUTION
    obs = inputs.from_state([ds.maps[s] for s in scenes], pose, ds.ado[scenes, t],
                            ds.ado_valid[scenes, t], ds.ego[scenes, -1], ds.raster,
                            policy.setting, motion=motion, model=models.get(policy.model))
    controls, state, _ = policy(obs, state, t, scenes)
    return world.unicycle_step(pose, controls, world.DT), controls, state
    ### END SOLUTION

# %% grade id=ex09_2_tests points=3
policy = rollout.ModelPolicy("manc", params, cfg, eng, dtype=np.float64)
scenes = np.array([0, 2])
pose = ds.ego[scenes, 0].astype(np.float64)
motion = inputs.initial_motion(ds)[scenes]
state = policy.initial_state(scenes)
poses = [pose]
for t in range(4):
    pose, motion, state = closed_loop_step(policy, ds, scenes, pose, motion, state, t)
    poses.append(pose)
# literal values computed once with rollout.simulate (float64), rounded to 6 decimals
ref_ego = [[[-28.629559, 117.331696, -1.354028], [-27.491322, 112.163254, -1.350091],
            [-26.192252, 106.373147, -1.341743], [-24.696069, 99.955757, -1.333498],
            [-22.867245, 92.394116, -1.328385]],
           [[34.102661, -26.087149, -0.611898], [38.052006, -28.858591, -0.612614],
            [42.492112, -31.979176, -0.614123], [47.41143, -35.447655, -0.615609],
            [53.237619, -39.568524, -0.616532]]]
assert np.allclose(np.stack(poses, axis=1), ref_ego, atol=1e-4), (
    "four of your steps should give rollout.simulate's poses (observe from the ego's own "
    f"pose, ados of step t, goal ds.ego[scenes, -1]); expected {ref_ego}")
assert np.allclose(state["q"], [[0.123742, 0.085012, 0.37468, 0.416567],
                                [0.123492, 0.083988, 0.373862, 0.418658]], atol=1e-5), (
    "the policy's state should be carried from step to step")
### BEGIN HIDDEN TESTS
assert np.allclose(motion, [[15.559309, 0.010225], [14.272498, -0.001845]], atol=1e-4), (
    "the controls returned at the last step should be the rollout's last controls")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 9.3 — the maximum acceleration of a trajectory
# The comfort metric of Table I (`minimanc.metrics`): from poses `ego` (S, T, 3)
# recover the unicycle controls `v[t], ω[t]` that move pose `t` to `t + 1`
# (`world.controls_from_poses(ego[s], dt)` does it for one scene), then
#
# $$a_{lon}[t] = \frac{v[t+1]-v[t]}{\Delta t},\qquad a_{lat}[t] = v[t]\,\omega[t],\qquad
#   \text{max acceleration} = \max_t \sqrt{a_{lon}[t]^2 + a_{lat}[t]^2}$$
#
# for `t = 0 … T−3`. Return one number per scene, shape (S,).

# %% solution id=ex09_3 title="Maximum acceleration" forbids="minimanc.metrics.max_acceleration"  # noqa: E501
def max_acceleration(ego, dt=0.5):
    ### BEGIN SOLUTION
    u = np.stack([world.controls_from_poses(e, dt) for e in np.asarray(ego, dtype=float)])
    v, w = u[..., 0], u[..., 1]
    a_lon = np.diff(v, axis=1) / dt
    a_lat = v[:, :-1] * w[:, :-1]
    return np.sqrt(a_lon**2 + a_lat**2).max(axis=1)
    ### END SOLUTION

# %% grade id=ex09_3_tests points=2
circle = [np.zeros(3)]
for _ in range(10):
    circle.append(world.unicycle_step(circle[-1], np.array([6.0, 0.3])))
circle = np.stack(circle)[None]
got9 = max_acceleration(circle)
assert np.allclose(got9, [1.8]), f"a circle at v·ω = 6 · 0.3: expected [1.8] m/s², got {got9}"
human = max_acceleration(ds.ego)
assert human.shape == (len(ds.ego),), \
    f"one number per scene: expected shape ({len(ds.ego)},), got {human.shape}"
assert np.all(human >= 0), f"a magnitude is never negative: got {human}"
### BEGIN HIDDEN TESTS
ramp = np.zeros((1, 6, 3))
ramp[0, :, 0] = np.cumsum([0, 1, 2, 3, 5, 7]) * 0.5
got9 = max_acceleration(ramp)
assert np.allclose(got9, [4.0]), f"speeds 1 2 3 5 7 m/s every 0.5 s: expected [4], got {got9}"
arc = [np.zeros(3)]
for v in (4.0, 6.0, 8.0, 8.0):
    arc.append(world.unicycle_step(arc[-1], np.array([v, 0.5])))
got9 = max_acceleration(np.stack(arc)[None])
assert np.allclose(got9, [5.0]), f"a_lon = 4, a_lat = 6 * 0.5: expected [5], got {got9}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 9.4 — ADE split along and across the human's path
# ADE mixes two different failures: driving too slowly or too fast (the policy is
# behind or ahead of the human on the same road) and steering off the human's line.
# Split each step's displacement $d[t] = p[t] - p_{human}[t]$ (policy position minus
# the human's at the same time) in the frame of the **human's** heading $\psi[t]$:
#
# $$\text{along}[t] = d[t]\cdot(\cos\psi[t], \sin\psi[t]),\qquad
#   \text{cross}[t] = d[t]\cdot(-\sin\psi[t], \cos\psi[t]).$$
#
# Positive *along* means the policy is ahead of the human, positive *cross* that it
# is to the human's left. It is a rotation, so
# $\text{along}^2 + \text{cross}^2 = \lVert d\rVert^2$ and
# $\text{mean}_t\sqrt{\text{along}^2+\text{cross}^2}$ is the ADE.
#
# Write `along_cross_track(ego, human)`: both `(S, T, 3)` poses `[x, y, yaw]`; return
# `(along, cross)`, each `(S, T)`. Only the human's yaw enters.

# %% solution id=ex09_4 title="Along-track and cross-track error" forbids="minimanc.metrics.along_cross_track"  # noqa: E501
def along_cross_track(ego, human):
    ### BEGIN SOLUTION
    ego, human = np.asarray(ego, dtype=float), np.asarray(human, dtype=float)
    d = ego[..., :2] - human[..., :2]
    c, s = np.cos(human[..., 2]), np.sin(human[..., 2])
    return d[..., 0] * c + d[..., 1] * s, -d[..., 0] * s + d[..., 1] * c
    ### END SOLUTION

# %% grade id=ex09_4_tests points=3
east = np.zeros((1, 5, 3))
east[0, :, 0] = 10.0 * np.arange(5)                       # the human drives east at 20 m/s
along, cross = along_cross_track(east + [0.0, 3.0, 0.0], east)
assert along.shape == (1, 5) and cross.shape == (1, 5), "one value per scene and step"
assert np.allclose(along, 0.0) and np.allclose(cross, 3.0), "3 m to the left: along 0, cross +3"
slow = east * [0.5, 1.0, 1.0]                              # half the speed, same line
along, cross = along_cross_track(slow, east)
assert np.allclose(along, [[0, -5, -10, -15, -20]]), "behind the human: along = -5 m per step"
assert np.allclose(cross, 0.0), "on the human's line: cross = 0"
north = np.array([[[0.0, 0.0, np.pi / 2]]])                # heading north, +x is its right
along, cross = along_cross_track(north + [1.0, 2.0, 0.7], north)
assert np.allclose(along, 2.0) and np.allclose(cross, -1.0), (
    "heading north: +y is ahead (along 2), +x is to the right (cross -1); the policy's yaw "
    "does not enter")
### BEGIN HIDDEN TESTS
# literal values for a curved human (8 m/s, 0.4 rad/s) and a slower, straighter policy,
# computed once with metrics.along_cross_track
h, e = [np.zeros(3)], [np.zeros(3)]
for _ in range(6):
    h.append(world.unicycle_step(h[-1], np.array([8.0, 0.4])))
    e.append(world.unicycle_step(e[-1], np.array([7.0, 0.3])))
h, e = np.stack(h)[None], np.stack(e)[None]
along, cross = along_cross_track(e, h)
assert np.allclose(along, [[0.0, -0.49, -0.9896, -1.5219, -2.1086, -2.7684, -3.5168]],
                   atol=1e-4), (
    "a slower, straighter policy falls behind: expected along [0, -0.49, -0.9896, -1.5219, "
    f"-2.1086, -2.7684, -3.5168], got {np.round(along, 4).tolist()}")
assert np.allclose(cross, [[0.0, 0.0993, 0.1235, 0.078, -0.0267, -0.1755, -0.3497]],
                   atol=1e-4), (
    "first left of the human's arc, then right of it: expected cross [0, 0.0993, 0.1235, "
    f"0.078, -0.0267, -0.1755, -0.3497], got {np.round(cross, 4).tolist()}")
# batched over scenes, each against its own human; the split reproduces the distance
shifted = ds.ego + [2.0, -1.0, 0.3]
along, cross = along_cross_track(shifted, ds.ego)
assert along.shape == ds.ego.shape[:2], \
    f"expected shape (S, T) = {ds.ego.shape[:2]}, got {along.shape}"
assert np.allclose(along**2 + cross**2, 5.0), (
    f"shifted by (2, -1): expected along² + cross² = 5 at every step, got values from "
    f"{np.min(along**2 + cross**2):.4f} to {np.max(along**2 + cross**2):.4f}")
yaw = ds.ego[..., 2]
want9 = 2 * np.cos(yaw) - np.sin(yaw)
assert np.allclose(along, want9), (
    f"shifted by (2, -1): expected along = d · (cos ψ, sin ψ) = {np.round(want9[0, :3], 4)}..., "
    f"got {np.round(along[0, :3], 4)}...")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 9.5 — % close encounters
# The safety metric of Table I: the share of the steps of a scene at which some
# valid ado's box is closer than `gap` metres to the ego's box (edge to edge, 0 when
# they overlap). A step counts once, however many ados are close; invalid ados
# never count.
#
# Write `close_encounters(ego, ado, ado_valid, gap=1.0)`: `ego` `(S, T, 3)`, `ado`
# `(S, T, A, 5)` boxes `[x, y, yaw, length, width]`, `ado_valid` `(S, T, A)`. Return
# the share in $[0, 1]$ per scene, shape `(S,)`. Use `metrics.ego_boxes(ego)` (the
# ego's boxes `(S, T, 5)`) and `metrics.box_gap(a, b)` (the gap between boxes, with
# broadcasting).

# %% solution id=ex09_5 title="Close encounters" forbids="minimanc.metrics.close_encounters,minimanc.metrics.ado_gaps"  # noqa: E501
def close_encounters(ego, ado, ado_valid, gap=1.0):
    ### BEGIN SOLUTION
    gaps = metrics.box_gap(metrics.ego_boxes(ego)[:, :, None, :], np.asarray(ado, float))
    close = (gaps < gap) & np.asarray(ado_valid, bool)                 # (S, T, A)
    return close.any(axis=-1).mean(axis=1)
    ### END SOLUTION

# %% grade id=ex09_5_tests points=3
ego = np.zeros((1, 11, 3))
ego[0, :, 0] = 2.0 * np.arange(11)                         # x = 0, 2, ..., 20, heading east
parked = np.tile(np.array([10.0, 2.5, 0.0, 4.0, 1.8]), (1, 11, 1, 1))   # next lane
valid = np.ones((1, 11, 1), bool)
# lateral gap 2.5 - 1.907/2 - 0.9 = 0.6465 m while the boxes overlap in x, corners otherwise
dx = np.maximum(np.abs(ego[0, :, 0] - 10.0) - (4.727 / 2 + 2.0), 0.0)
expected = np.mean(np.hypot(dx, 2.5 - 1.907 / 2 - 0.9) < 1.0)
share = close_encounters(ego, parked, valid)
assert share.shape == (1,), "one share per scene"
assert np.isclose(share[0], expected), f"expected {expected:.4f} of the steps"
assert close_encounters(ego, parked, valid, gap=0.5)[0] == 0.0, "0.6465 m is not < 0.5 m"
assert close_encounters(ego, parked, ~valid)[0] == 0.0, "invalid ados never count"
### BEGIN HIDDEN TESTS
two = np.concatenate([parked, parked + [0.0, 0.2, 0.0, 0.0, 0.0]], axis=2)  # two close ados
assert np.isclose(close_encounters(ego, two, np.ones((1, 11, 2), bool))[0], expected), (
    f"a step counts once however many ados are close: expected {expected:.4f}, got "
    f"{close_encounters(ego, two, np.ones((1, 11, 2), bool))[0]!r}")
r = np.random.default_rng(10)  # its own generator: the literal counts below depend on it
S, T, A = 3, 8, 3
ego_r = np.concatenate([np.cumsum(r.normal(size=(S, T, 2)) * 2, axis=1),
                        r.uniform(-3, 3, (S, T, 1))], -1)
ado_r = np.concatenate([ego_r[:, :, None, :2] + r.normal(size=(S, T, A, 2)) * 4,
                        r.uniform(-3, 3, (S, T, A, 1)), r.uniform(3, 6, (S, T, A, 1)),
                        r.uniform(1.5, 2.5, (S, T, A, 1))], -1)
val_r = r.random((S, T, A)) < 0.7
# literal counts of close steps out of 8, computed once with metrics.close_encounters
# (every gap is at least 0.03 m away from the thresholds)
got9 = close_encounters(ego_r, ado_r, val_r) * T
assert np.allclose(got9, [6, 4, 5]), \
    f"3 random scenes, gap 1 m: expected [6, 4, 5] close steps of 8, got {got9}"
got9 = close_encounters(ego_r, ado_r, val_r, gap=2.0) * T
assert np.allclose(got9, [7, 7, 6]), \
    f"3 random scenes, gap 2 m: expected [7, 7, 6] close steps of 8, got {got9}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 9.6 — what replaying the human's controls costs
# Behaviour cloning at its most literal: a "policy" that outputs exactly the
# human's logged controls, step by step, without looking. From the human's
# own start it reproduces the human. Start it slightly wrong — the start pose
# moved by `delta = (d_along, d_cross, d_yaw)` in the frame of the human's
# start pose (metres ahead, metres to the left, radians counter-clockwise) —
# and it drives the logged controls from there.
#
# 1. `replay_positions(human, delta)`: the replay's positions, shape `(S, T, 2)`,
#    for the human's poses `human` `(S, T, 3)` (the controls that produced them
#    are the unicycle's of chapter 7). Compute them **without stepping the
#    unicycle**: `world.unicycle_step`, `rollout.simulate` and
#    `rollout.closed_loop` are switched off while this exercise is graded.
# 2. `heading_budget(human, ade_max)`: per scene, shape `(S,)`, the largest
#    heading error $|d_\text{yaw}|$ (no position error) for which the replay's
#    ADE (`metrics.ade`: the mean over all $T$ steps of the distance to the
#    human) stays at or below `ade_max`; $\pi$ when no heading error exceeds it.
#
# The two functions are graded separately, 2 points each.
#
# <details><summary>Hint 1 (the idea)</summary>
#
# The unicycle step commutes with rigid motions: move and turn the start pose,
# and every later pose is moved and turned the same way. What does that make
# of the replay's path?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# The rigid motion maps the human's start pose to the replay's. For a pure
# heading error, the distance to the human at step $t$ is the chord of a
# rotation by $d_\text{yaw}$ at radius $\lVert p_h[t] - p_h[0] \rVert$; average
# it over $t$ and solve for the angle.
# </details>

# %% solution id=ex09_6 title="What replaying the human's controls costs" forbids="minimanc.world.geometry.unicycle_step,minimanc.rollout.simulate,minimanc.rollout.closed_loop"  # noqa: E501
def replay_positions(human, delta):
    ### BEGIN SOLUTION
    human, d = np.asarray(human, dtype=float), np.asarray(delta, dtype=float)
    h0 = human[:, 0]
    c, s = np.cos(h0[:, 2]), np.sin(h0[:, 2])
    start = h0[:, :2] + np.stack([c * d[0] - s * d[1], s * d[0] + c * d[1]], axis=-1)
    # the unicycle is equivariant: the replay is the human's path turned by d_yaw about
    # the human's start, then moved to the replay's start
    rel = human[..., :2] - h0[:, None, :2]
    cr, sr = np.cos(d[2]), np.sin(d[2])
    turned = np.stack([cr * rel[..., 0] - sr * rel[..., 1], sr * rel[..., 0] + cr * rel[..., 1]],
                      axis=-1)
    return start[:, None, :] + turned
    ### END SOLUTION


def heading_budget(human, ade_max):
    ### BEGIN SOLUTION
    human = np.asarray(human, dtype=float)
    radius = np.linalg.norm(human[..., :2] - human[:, :1, :2], axis=-1).mean(axis=1)
    # ADE(d_yaw) = 2 sin(|d_yaw| / 2) * mean_t |p_h[t] - p_h[0]|, largest at d_yaw = pi
    with np.errstate(divide="ignore"):
        x = np.where(radius > 0, ade_max / (2.0 * radius), np.inf)
    return np.where(x >= 1.0, np.pi, 2.0 * np.arcsin(np.minimum(x, 1.0)))
    ### END SOLUTION

# %% grade id=ex09_6_positions_tests points=2
line9 = np.zeros((1, 41, 3))
line9[0, :, 0] = 5.0 * np.arange(41)                      # east at 10 m/s for 20 s
got = np.asarray(replay_positions(line9, (0.0, 1.0, 0.0)))
assert got.shape == (1, 41, 2), f"expected positions of shape (1, 41, 2), got {got.shape}"
assert np.allclose(got, line9[..., :2] + [0.0, 1.0]), (
    f"a straight human, start 1 m to the left: expected the human's line 1 m north, got "
    f"{np.round(got[0, :3], 3).tolist()} ...")
got = np.asarray(replay_positions(line9, (0.0, 0.0, np.pi / 2)))
assert np.allclose(got[0, 4], [0.0, 20.0]), (
    f"a straight human, start turned by 90 degrees: 2 s later expected (0, 20) (20 m north), "
    f"got {np.round(got[0, 4], 3).tolist()}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(960)  # the tests' own draws, not the notebook's rng


def unicycle9(pose, u, dt=0.5):   # the tests' own explicit-Euler unicycle
    return np.stack([pose[..., 0] + u[..., 0] * np.cos(pose[..., 2]) * dt,
                     pose[..., 1] + u[..., 0] * np.sin(pose[..., 2]) * dt,
                     pose[..., 2] + u[..., 1] * dt], axis=-1)


def log9(rng_, S, T):
    """Random humans: a start pose and random controls integrated by the tests' unicycle."""
    u = np.stack([rng_.uniform(0, 14, (S, T - 1)), rng_.normal(0, 0.3, (S, T - 1))], -1)
    poses = [np.concatenate([rng_.uniform(-200, 200, (S, 2)), rng_.uniform(-4, 4, (S, 1))], 1)]
    for t in range(T - 1):
        poses.append(unicycle9(poses[-1], u[:, t]))
    return np.stack(poses, 1), u


humans9, controls9 = log9(test_rng, 5, 30)
for delta in ((0.0, 0.0, 0.2), (-2.0, 1.5, -0.3), (3.0, -0.5, 2.5)):
    c0, s0 = np.cos(humans9[:, 0, 2]), np.sin(humans9[:, 0, 2])
    p = humans9[:, 0] + np.stack([c0 * delta[0] - s0 * delta[1], s0 * delta[0] + c0 * delta[1],
                                  np.full(5, delta[2])], -1)
    want = [p[:, :2]]
    for t in range(29):
        p = unicycle9(p, controls9[:, t])
        want.append(p[:, :2])
    want = np.stack(want, 1)
    got = np.asarray(replay_positions(humans9, delta))
    assert got.shape == want.shape, f"delta = {delta}: expected shape {want.shape}, got {got.shape}"
    worst = np.abs(got - want).max()
    assert worst < 1e-8, (
        f"5 random humans, delta = {delta}: expected the replay of the logged controls, got "
        f"positions up to {worst:.3g} m away from it")
### END HIDDEN TESTS

# %% grade id=ex09_6_budget_tests points=2
def rotated_ade9(human, d_yaw):
    """The tests' own ADE of the replay with a heading error: the human's path turned by
    d_yaw about its start (the result of 9.6.1, written out)."""
    rel = human[..., :2] - human[:, :1, :2]
    c, s = np.cos(d_yaw), np.sin(d_yaw)
    turned = np.stack([c * rel[..., 0] - s * rel[..., 1], s * rel[..., 0] + c * rel[..., 1]], -1)
    return np.linalg.norm(turned - rel, axis=-1).mean(axis=1)


b9 = np.asarray(heading_budget(line9, 1.0))
assert b9.shape == (1,), f"one budget per scene: expected shape (1,), got {b9.shape}"
for d_yaw, ok in ((b9[0], True), (1.02 * b9[0], False)):
    ade9 = rotated_ade9(line9, d_yaw)[0]
    assert (ade9 <= 1.0 + 1e-9) == ok, (
        f"straight human for 20 s: your budget {b9[0]:.6f} rad; a heading error of "
        f"{d_yaw:.6f} rad gives an ADE of {ade9:.4f} m, expected {'<=' if ok else '>'} 1 m")
assert np.asarray(heading_budget(line9, 1e3))[0] == np.pi, (
    f"ade_max = 1000 m, more than any heading error costs: expected pi, got "
    f"{np.asarray(heading_budget(line9, 1e3))[0]!r}")
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(961)  # the tests' own draws, not the notebook's rng
humans9b = log9(test_rng, 6, 41)[0]
got = np.asarray(heading_budget(humans9b, 0.5))
for k in range(6):
    lo, hi = 0.0, np.pi        # bisection on the tests' own ADE, increasing on [0, pi]
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if rotated_ade9(humans9b[k:k + 1], mid)[0] <= 0.5 else (lo, mid)
    assert math.isclose(got[k], lo, rel_tol=1e-6), (
        f"random human {k}, ade_max = 0.5 m: expected a budget of {lo:.6g} rad, got {got[k]!r}")
logged9 = np.asarray(heading_budget(ds.ego.astype(float), 2.0))
for k in range(len(ds.ego)):
    ade9 = rotated_ade9(ds.ego[k:k + 1].astype(float), logged9[k])[0]
    assert abs(ade9 - 2.0) < 1e-6, (
        f"logged scene {k}, ade_max = 2 m: expected an ADE of 2 m at your budget "
        f"{logged9[k]:.6f} rad, got {ade9:.6f} m")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 9.7 — an open experiment: close the loop
# Replaying cannot correct anything. Write a **tracking controller**
# `tracking_controller(pose, human_pose, human_control)`: the current ego poses
# `(B, 3)`, the human's logged poses at the same step `(B, 3)` and the human's
# logged controls of that step `(B, 2)`; return the controls `[speed, yaw rate]`,
# `(B, 2)`. In closed loop on the scenes of `ds` (the helper below drives it),
# started from the human's start moved by `(0, 1 m, 0.1 rad)` and by
# `(-2 m, -0.5 m, -0.05 rad)`, it must
#
# * stay close: an ADE below 0.4 m in every scene;
# * end on the human: within 0.1 m of the human's last position;
# * drive plausibly: speed in [0, 20] m/s and |yaw rate| ≤ 1.2 rad/s at every step.
#
# Use your 9.4 (3 points; the grade cell drives its own unicycle). Then defend
# your controller in the written answer below.

# %%
def drive_on_log(controller, human, controls, delta):
    """Closed loop on the log: start from the human's start moved by ``delta`` (its
    frame), then each step ``controller(pose, human[:, t], controls[:, t])`` -> poses."""
    h0 = human[:, 0]
    c, s = np.cos(h0[:, 2]), np.sin(h0[:, 2])
    pose = h0 + np.stack([c * delta[0] - s * delta[1], s * delta[0] + c * delta[1],
                          np.full(len(h0), delta[2])], axis=-1)
    poses = [pose]
    for t in range(human.shape[1] - 1):
        pose = world.unicycle_step(pose, controller(pose, human[:, t], controls[:, t]), world.DT)
        poses.append(pose)
    return np.stack(poses, axis=1)


human_log, controls_log = ds.ego.astype(np.float64), ds.controls.astype(np.float64)
replayed = drive_on_log(lambda p, h, u: u, human_log, controls_log, (0.0, 1.0, 0.1))
print("ADE of the replay from (0, 1 m, 0.1 rad):", metrics.ade(replayed, human_log).round(1))
assert np.all(metrics.ade(replayed, human_log) > 2.0)

# %% solution id=ex09_7 title="A tracking controller that closes the loop"
def tracking_controller(pose, human_pose, human_control):
    ### BEGIN SOLUTION
    pose, human_pose = np.asarray(pose, dtype=float), np.asarray(human_pose, dtype=float)
    along, cross = along_cross_track(pose[:, None], human_pose[:, None])
    heading = np.mod(pose[:, 2] - human_pose[:, 2] + np.pi, 2 * np.pi) - np.pi
    # feed-forward the human's controls; feed back the errors in the human's frame
    speed = np.clip(human_control[:, 0] - 0.5 * along[:, 0], 0.0, 20.0)
    yaw_rate = np.clip(human_control[:, 1] - 0.1 * cross[:, 0] - 1.0 * heading, -1.2, 1.2)
    return np.stack([speed, yaw_rate], axis=-1)
    ### END SOLUTION

# %% grade id=ex09_7_tests points=3
def track9(controller, human, controls, delta):
    """The tests' own closed loop: explicit-Euler unicycle, the controller's controls
    checked at every step; returns the poses (S, T, 3)."""
    h0 = human[:, 0]
    c, s = np.cos(h0[:, 2]), np.sin(h0[:, 2])
    pose = h0 + np.stack([c * delta[0] - s * delta[1], s * delta[0] + c * delta[1],
                          np.full(len(h0), delta[2])], axis=-1)
    poses = [pose]
    for t in range(human.shape[1] - 1):
        u = np.asarray(controller(pose, human[:, t], controls[:, t]), dtype=float)
        assert u.shape == (len(h0), 2), f"step {t}: expected controls (S, 2), got {u.shape}"
        assert np.all((u[:, 0] >= 0) & (u[:, 0] <= 20)) and np.all(np.abs(u[:, 1]) <= 1.2), (
            f"delta = {delta}, step {t}: expected speed in [0, 20] and |yaw rate| <= 1.2, got "
            f"{np.round(u, 3).tolist()}")
        pose = np.stack([pose[:, 0] + u[:, 0] * np.cos(pose[:, 2]) * 0.5,
                         pose[:, 1] + u[:, 0] * np.sin(pose[:, 2]) * 0.5,
                         pose[:, 2] + u[:, 1] * 0.5], axis=-1)
        poses.append(pose)
    return np.stack(poses, axis=1)


def check_tracker9(controller, human, controls, deltas):
    for delta in deltas:
        run = track9(controller, human, controls, delta)
        dist = np.linalg.norm(run[..., :2] - human[..., :2], axis=-1)
        assert np.all(dist.mean(axis=1) < 0.4), (
            f"start moved by {delta}: expected an ADE below 0.4 m in every scene, got "
            f"{np.round(dist.mean(axis=1), 3).tolist()} m")
        assert np.all(dist[:, -1] < 0.1), (
            f"start moved by {delta}: expected to end within 0.1 m of the human, got "
            f"{np.round(dist[:, -1], 3).tolist()} m")


check_tracker9(tracking_controller, human_log, controls_log,
               ((0.0, 1.0, 0.1), (-2.0, -0.5, -0.05)))
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(970)  # the tests' own draws, not the notebook's rng
k9 = np.arange(40)[None, :]
phase9 = test_rng.uniform(0, 2 * np.pi, (2, 3, 1))
controls9 = np.stack([6.0 + 4.0 * np.sin(0.1 * k9 + phase9[0]),       # smooth, 2 to 10 m/s
                      0.25 * np.sin(0.15 * k9 + phase9[1])], axis=-1)  # and up to 0.25 rad/s
human9 = [np.concatenate([test_rng.uniform(-100, 100, (3, 2)), test_rng.uniform(-3, 3, (3, 1))],
                         axis=1)]
for t in range(40):
    h = human9[-1]
    human9.append(np.stack([h[:, 0] + controls9[:, t, 0] * np.cos(h[:, 2]) * 0.5,
                            h[:, 1] + controls9[:, t, 0] * np.sin(h[:, 2]) * 0.5,
                            h[:, 2] + controls9[:, t, 1] * 0.5], axis=-1))
human9 = np.stack(human9, axis=1)
check_tracker9(tracking_controller, human9, np.concatenate([controls9, controls9[:, -1:]], 1),
               ((1.0, 1.5, -0.1), (0.0, -1.0, 0.08)))
### END HIDDEN TESTS

# %% [markdown]
# **Written question (graded by hand, 2 points).** Defend your controller: why
# does the replay's error grow with the distance driven after a heading error
# but stay constant after a lateral offset (9.6)? What limits your gains at
# $\Delta t = 0.5$ s (try doubling them)? Behaviour cloning trains open loop on
# the human's own states: what does that mean for a learned policy that finds
# itself 1 m off the human's line, and where does MANC's head get the feedback
# that your controller has?

# %% [markdown] answer id=ex09_w title="Defend the tracking controller" points=2
# ### BEGIN SOLUTION
# Mine feeds the human's controls forward and feeds back the errors in the human's
# frame: speed $v_h - 0.5\,\text{along}$, yaw rate $\omega_h - 0.1\,\text{cross} -
# 1.0\,\Delta\psi$. ADE 0.19–0.23 m from (0, 1 m, 0.1 rad), against 4.7–8.9 m for the
# replay. The unicycle commutes with rigid motions, so the replay is the human's
# path moved and turned: a lateral offset is a translation, a constant error; a
# heading error turns the path about its start, and the error at step $t$ is
# $2\sin(|d\psi|/2)\lVert p_h[t] - p_h[0]\rVert$, growing with the distance driven
# (1 m of ADE costs only 0.7° to 1.5° of heading on these 20 s scenes). The gains are
# limited by the 0.5 s step as in 7.7: alone, the heading loop is
# $\Delta\psi' = (1 - k_\psi\Delta t)\Delta\psi$ and the along loop
# $(1 - k_a\Delta t)$, stable only for $k\,\Delta t < 2$ (at $k_\psi = 4.5$ or
# $k_a = 4.5$ the runs ring and end metres off); doubling all three gains still works
# (ADE 0.11–0.15 m), but the cross gain acts through the heading, and at
# $k_c = 0.5$ with $k_\psi = 1$ the loop diverges (ADE 1.3–26 m). Behaviour cloning only
# ever sees states on the human's line, where the right output is the human's
# control; 1 m off, the policy is outside its data (covariate shift), and nothing in
# the open-loop loss taught it to come back, so like the replay its error can
# compound. MANC's head gets feedback by construction: its goals are read from the
# lane target in the current ego frame (8.3, 8.6), so an offset or heading error
# changes the goal and the DMP steers back to the lane (chapter 7's pure pursuit);
# the error it corrects is to the lane centre, not to the human.
# ### END SOLUTION

# %% [markdown]
# The library versions: `models.step` (9.1), `rollout.simulate` /
# `rollout.closed_loop` (9.2), `metrics.max_acceleration` (9.3),
# `metrics.along_cross_track` (9.4) and `metrics.close_encounters` (9.5); 9.6
# and 9.7 have no library version. The
# tutorial of this chapter uses them to reproduce Table I.

# %% [markdown]
# ## Your figure
# How far behind or ahead of the human (left) and beside the human's line
# (right) two closed-loop runs are, from the start moved by (0, 1 m, 0.1 rad):
# the replay of the human's controls and **your** tracker (9.7), both measured
# by **your** `along_cross_track` (9.4, solid) over the library's (dashed),
# mean over the scenes of `ds`. A wrong split shows as solid lines off the
# dashed ones (swapped signs or axes move them between the panels); a
# function that still raises is named in the title.

# %%
plot_track_error_attempts(
    {"replay": lambda: replayed,
     "your tracker": lambda: drive_on_log(tracking_controller, human_log, controls_log,
                                          (0.0, 1.0, 0.1))},
    human_log, along_cross_track)
plt.show()
