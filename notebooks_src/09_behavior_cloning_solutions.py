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
# 5. **% close encounters**: the share of steps with an ado box within 1 m.
#
# Replace each `raise NotImplementedError(...)` with your code.

# %%
import numpy as np

from minimanc import engine, inputs, layers, metrics, models, rollout, vagn, world

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
assert np.allclose(max_acceleration(circle), [1.8]), "a circle at v·ω = 6 · 0.3 = 1.8 m/s²"
human = max_acceleration(ds.ego)
assert human.shape == (len(ds.ego),), f"one number per scene: shape ({len(ds.ego)},)"
assert np.all(human >= 0), "a magnitude is never negative"
### BEGIN HIDDEN TESTS
ramp = np.zeros((1, 6, 3))
ramp[0, :, 0] = np.cumsum([0, 1, 2, 3, 5, 7]) * 0.5
assert np.allclose(max_acceleration(ramp), [4.0]), "speeds 1 2 3 5 7 m/s every 0.5 s"
arc = [np.zeros(3)]
for v in (4.0, 6.0, 8.0, 8.0):
    arc.append(world.unicycle_step(arc[-1], np.array([v, 0.5])))
assert np.allclose(max_acceleration(np.stack(arc)[None]), [5.0]), "a_lon = 4, a_lat = 6 * 0.5"
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
                   atol=1e-4), "falls behind the human by 0.5 m per step and more"
assert np.allclose(cross, [[0.0, 0.0993, 0.1235, 0.078, -0.0267, -0.1755, -0.3497]],
                   atol=1e-4), "first left of the human's arc, then right of it"
# batched over scenes, each against its own human; the split reproduces the distance
shifted = ds.ego + [2.0, -1.0, 0.3]
along, cross = along_cross_track(shifted, ds.ego)
assert along.shape == ds.ego.shape[:2], f"shape (S, T) = {ds.ego.shape[:2]}"
assert np.allclose(along**2 + cross**2, 5.0), "along² + cross² = 2² + 1² at every step"
yaw = ds.ego[..., 2]
assert np.allclose(along, 2 * np.cos(yaw) - np.sin(yaw)), "along = d · (cos ψ, sin ψ)"
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
    "a step counts once however many ados are close")
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
assert np.allclose(close_encounters(ego_r, ado_r, val_r) * T, [6, 4, 5]), "gap 1 m"
assert np.allclose(close_encounters(ego_r, ado_r, val_r, gap=2.0) * T, [7, 7, 6]), "gap 2 m"
### END HIDDEN TESTS

# %% [markdown]
# The library versions: `models.step` (9.1), `rollout.simulate` /
# `rollout.closed_loop` (9.2), `metrics.max_acceleration` (9.3),
# `metrics.along_cross_track` (9.4) and `metrics.close_encounters` (9.5). The
# tutorial of this chapter uses them to reproduce Table I.
