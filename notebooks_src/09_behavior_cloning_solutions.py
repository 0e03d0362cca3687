# %% [markdown]
# # Chapter 9 — Graded exercises: the MANC step, the closed loop, a metric
#
# Modules used in this chapter: `minimanc.rollout`, `minimanc.metrics` and
# `minimanc.studies` (with `minimanc.models`, `minimanc.inputs`, `minimanc.world`).
#
# Three exercises, each checked by the grade cell below it:
#
# 1. **The MANC forward pass** from library pieces: CNN backbone → visual
#    predicates (eq. 7) → vAGN step (eqs. 8–9) → FC → one DMP step (eqs. 10–11).
# 2. **One closed-loop step**: observe from the ego's *own* pose, act, move.
# 3. **A metric**: the maximum acceleration of a trajectory.
#
# Replace each `raise NotImplementedError(...)` with your code.

# %%
import numpy as np

from minimanc import engine, inputs, layers, models, rollout, vagn, world

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

# %% solution id=ex09_1 title="The MANC forward pass"
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
obs = inputs.from_dataset(ds, [0, 1, 2], [0, 5, 10], "paper", model="manc")
q0 = np.full((3, 4), 0.25)
u, q, alpha, beta = manc_step(params, obs, q0, cfg, eng)
u_ref, state_ref, aux_ref = models.step("manc", params, obs, {"q": q0}, cfg, eng)
assert np.allclose(u, u_ref, atol=1e-8), (u, u_ref)
assert np.allclose(q, state_ref["q"]) and np.allclose(q.sum(-1), 1.0)
assert np.allclose(alpha, aux_ref["alpha"]) and np.allclose(beta, aux_ref["beta"])
### BEGIN HIDDEN TESTS
q1 = vagn.random_state(rng, 4, size=3)
u1, qq, _, _ = manc_step(params, obs, q1, cfg, eng)
u1_ref, s1, _ = models.step("manc", params, obs, {"q": q1}, cfg, eng)
assert np.allclose(u1, u1_ref, atol=1e-8) and np.allclose(qq, s1["q"])
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 9.2 — one closed-loop step
# In closed loop the policy sees what *its own* driving produces. Given the
# current ego poses `pose` (B, 3) of the scenes `scenes`, the previous controls
# `motion` (B, 2), the policy's state and the time step `t`:
#
# 1. build the observation with `inputs.from_state(maps, pose, ado, ado_valid,
#    goal_world, ds.raster, policy.setting, motion=motion, model=policy.model)`
#    — the ados at their *logged* boxes of step `t`, the goal is the human's
#    final pose `ds.ego[scenes, -1]`;
# 2. call `policy(obs, state, t, scenes)`, which returns `(controls, state, aux)`;
# 3. move the ego with `world.unicycle_step(pose, controls, world.DT)`.
#
# Return `(new_pose, controls, new_state)`.

# %% solution id=ex09_2 title="One closed-loop step"
def closed_loop_step(policy, ds, scenes, pose, motion, state, t):
    ### BEGIN SOLUTION
    obs = inputs.from_state([ds.maps[s] for s in scenes], pose, ds.ado[scenes, t],
                            ds.ado_valid[scenes, t], ds.ego[scenes, -1], ds.raster,
                            policy.setting, motion=motion, model=policy.model)
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
ref = rollout.simulate(policy, ds, scenes=scenes, steps=4, progress=False)
assert np.allclose(np.stack(poses, axis=1), ref.ego, atol=1e-6)
assert np.allclose(state["q"], ref.aux["q"][:, -1], atol=1e-6)
### BEGIN HIDDEN TESTS
assert np.allclose(motion, ref.controls[:, -1], atol=1e-6)
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
assert np.allclose(max_acceleration(circle), [1.8])  # v·ω = 6 · 0.3
human = max_acceleration(ds.ego)
assert human.shape == (len(ds.ego),) and np.all(human >= 0)
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
# The library versions: `models.step` (9.1), `rollout.simulate` /
# `rollout.closed_loop` (9.2) and `metrics.max_acceleration` (9.3). The
# tutorial of this chapter uses them to reproduce Table I.
