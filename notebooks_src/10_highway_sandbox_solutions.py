# %% [markdown]
# # Chapter 10 — Exercises: the controller in a real driving simulator
#
# Module built in this chapter: `minimanc.highway` (highway-env as a sandbox for the
# MANC controller). Replace each `raise NotImplementedError(...)` with your code and
# run the grade cell below it; `minimanc grade exercises/10_highway_sandbox.ipynb`
# scores the notebook.
#
# Four pieces connect a policy trained on BEV rasters to highway-env (1–4), and two
# exercises build on them (5–6):
#
# 1. an **action adapter**: the models output `[speed, yaw rate]`; highway-env's ego is
#    a kinematic bicycle driven by `[acceleration, steering]`;
# 2. the **BEV observation**: highway-env's vehicles drawn into the chapter-7 raster;
# 3. a **metric**: how often a driver collides;
# 4. the **logged controls** of a demonstration: what a perfect imitator must output
#    for the adapter to reproduce the expert;
# 5. **what the logs record in a turn** (transfer): the unicycle speed of the bicycle's
#    sub-steps, and the command that logs a given one;
# 6. an **open experiment**: a driver that yields at the roundabout, with a written
#    answer.
#
# Each function is graded on its own. The notebook ends with **your figure**: your
# driver's episode over the expert's.
#
# Frames: highway-env's $y$ axis points *down* its screen. `minimanc.highway` mirrors
# it, $x_w = x$, $y_w = -y$, $\psi_w = -\psi$, so that the world frame of chapter 7
# (right-handed, yaw counter-clockwise) and right-hand traffic are kept.

# %%
import matplotlib.pyplot as plt
import numpy as np

from minimanc import highway as hw
from minimanc import metrics, world
from minimanc.viz.highway import plot_episode_attempts

# %% [markdown]
# ## Exercise 10.1 — the action adapter
# highway-env moves the ego as a kinematic bicycle of length $L$: with steering
# angle $\delta$ the slip angle is $\beta = \arctan(\tan\delta / 2)$, the heading rate
# $\dot\psi = v \sin\beta / (L/2)$ and $\dot v = a$. An action is held for
# $\Delta t = 0.5$ s and integrated in sub-steps of $h = 0.1$ s (the heading uses
# the speed *before* each sub-step's update).
#
# Write `adapter(controls, speed)` that returns the normalised `ContinuousAction`
# `[a / a_max, delta / steer_max]`:
#
# * speed: a P-controller $a = (v^* - v)/\Delta t$, clipped to $\pm a_{max}$;
# * yaw rate: invert the bicycle at the mean speed of the sub-steps,
#   $\bar v = v + a(\Delta t - h)/2$: $\beta = \arcsin(\dot\psi^* L / (2\bar v))$
#   (clip the argument to $[-1, 1]$), $\delta = \arctan(2\tan\beta)$, clipped to
#   $\pm$ `steer_max`. **Mind the mirror**: the world yaw rate $\omega^*$ is
#   $-\dot\psi^*$ in highway-env.
# * If $|\bar v| < 0.1$ m/s no yaw rate is reachable: use $\delta = 0$.

# %% solution id=ex10_1 title="Action adapter" forbids="minimanc.highway.controls_to_action"  # noqa: E501
def adapter(controls, speed, length=5.0, dt=0.5, substep=0.1, a_max=5.0,
            steer_max=np.pi / 4):
    ### BEGIN SOLUTION
    v_cmd, omega = float(controls[0]), float(controls[1])
    a = float(np.clip((v_cmd - speed) / dt, -a_max, a_max))
    v_mean = speed + a * (dt - substep) / 2.0
    if abs(v_mean) < 0.1:
        delta = 0.0
    else:
        beta = np.arcsin(np.clip(-omega * length / (2.0 * v_mean), -1.0, 1.0))
        delta = float(np.clip(np.arctan(2.0 * np.tan(beta)), -steer_max, steer_max))
    return np.array([a / a_max, delta / steer_max])
    ### END SOLUTION

# %% grade id=ex10_1_tests points=3
out = adapter(np.array([11.0, 0.0]), 10.0)
assert np.allclose(out, [2.0 / 5.0, 0.0]), f"a = 2 m/s² and no steering: [0.4, 0], got {out}"
left = adapter(np.array([10.0, 0.2]), 10.0)
assert left[1] < 0, "a world left turn (omega > 0) is a negative highway-env steering"
beta = np.arctan(np.tan(left[1] * np.pi / 4) / 2)
assert np.isclose(10.0 * np.sin(beta) / 2.5, -0.2), "the bicycle must turn at 0.2 rad/s"
assert np.allclose(adapter(np.array([40.0, 3.0]), 10.0), [1.0, -1.0]), (
    "out of range: clip both to [1, -1] (full throttle, full steering to the world's left)")
# in the simulator: the yaw rate is tracked exactly, the speed reached at the end of a step
env = hw.make_env("highway-fast", steps=12, config={"vehicles_count": 0})
env.reset(seed=0)
yaw0 = hw.ego_pose(env)[2]
for _ in range(6):
    env.step(adapter(np.array([23.0, 0.1]), env.vehicle.speed).astype(np.float32))
    yaw1 = hw.ego_pose(env)[2]
    assert abs(world.wrap_angle(yaw1 - yaw0) / 0.5 - 0.1) < 1e-6, (
        "highway-env should turn at exactly 0.1 rad/s (world frame) over each 0.5 s step")
    yaw0 = yaw1
assert abs(env.vehicle.speed - 23.0) < 1e-6, "the commanded 23 m/s should be reached"
### BEGIN HIDDEN TESTS
test_rng = np.random.default_rng(101)  # the tests' own draws, not the notebook's rng
for _ in range(30):
    u = np.array([test_rng.uniform(-2, 35), test_rng.uniform(-1, 1)])
    v = test_rng.uniform(-1, 30)
    out = np.asarray(adapter(u, v), dtype=float)
    case = f"command [{u[0]:.3f}, {u[1]:.3f}] at v = {v:.3f}"
    assert out.shape == (2,), (
        f"{case}: expected the action [a / a_max, delta / steer_max]; got {out}")
    a = np.clip((u[0] - v) / 0.5, -5.0, 5.0)                   # the P-controller
    assert np.isclose(out[0], a / 5.0), (
        f"{case}: expected the acceleration {a / 5.0:.4f} (clipped P-controller, / a_max); "
        f"got {out[0]:.4f}")
    v_mean = v + a * (0.5 - 0.1) / 2
    delta = out[1] * np.pi / 4
    if abs(v_mean) < 0.1:
        assert out[1] == 0.0, f"{case}: |v_mean| < 0.1 m/s, expected steering 0; got {out[1]}"
        continue
    # the bicycle realises omega = -v_mean sin(beta) / (L / 2), unless the steering saturates
    omega = -v_mean * np.sin(np.arctan(np.tan(delta) / 2)) / 2.5
    assert abs(out[1]) <= 1.0 + 1e-12, f"{case}: expected steering in [-1, 1]; got {out[1]}"
    if abs(out[1]) < 1.0 - 1e-9 and abs(u[1] * 2.5 / v_mean) < 1.0:
        assert np.isclose(omega, u[1], atol=1e-6), (
            f"{case}: expected the bicycle to turn at {u[1]:.4f} rad/s (world frame); your "
            f"steering {out[1]:.4f} turns it at {omega:.4f}")
    else:  # saturated: the closest reachable rate, turning the requested way
        assert np.sign(omega) == np.sign(u[1]) or u[1] == 0.0, (
            f"{case}, saturated: expected a turn to the requested side ({np.sign(u[1]):+.0f}); "
            f"your steering {out[1]:.4f} turns at {omega:.4f} rad/s")
out = np.asarray(adapter(np.array([0.0, 0.5]), 0.0), dtype=float)
assert np.allclose(out, [0.0, 0.0]), f"standing still, command [0, 0.5]: expected [0, 0]; got {out}"
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 10.2 — vehicles into the BEV
# The BEV observation is the chapter-7 raster of the road network seen from the ego,
# with the other vehicles drawn as yellow boxes. highway-env gives each vehicle's
# `position` $(x, y)$, `heading` $\psi$, `LENGTH` and `WIDTH` in *its* frame.
#
# Write `vehicle_boxes(ego, others, max_ado)`: `ego` is the ego's highway-env
# `(x, y, heading)`, `others` an `(n, 5)` array of highway-env
# `[x, y, heading, length, width]`. Return `(boxes, valid)`: `boxes` `(max_ado, 5)`
# world boxes `[x, y, yaw, length, width]` (mirrored frame, yaw wrapped to
# $(-\pi, \pi]$ with `world.wrap_angle`) of the `max_ado` vehicles nearest to the ego,
# nearest first (a stable sort on the distance); unused rows are zero with
# `valid` False.

# %% solution id=ex10_2 title="Vehicle boxes for the BEV" forbids="minimanc.highway.ado_boxes"  # noqa: E501
def vehicle_boxes(ego, others, max_ado=16):
    ### BEGIN SOLUTION
    others = np.asarray(others, dtype=float).reshape(-1, 5)
    boxes = np.zeros((max_ado, 5))
    valid = np.zeros(max_ado, dtype=bool)
    d = np.linalg.norm(others[:, :2] - np.asarray(ego[:2], float), axis=1)
    for row, i in enumerate(np.argsort(d, kind="stable")[:max_ado]):
        x, y, h, length, width = others[i]
        boxes[row] = [x, -y, world.wrap_angle(-h), length, width]
        valid[row] = True
    return boxes, valid
    ### END SOLUTION

# %% [markdown]
# A live roundabout scene for the test below: the BEV that the library's wrapper
# `hw.BEVObservation` draws after 1.5 s, and the highway-env state it was drawn from.

# %%
env = hw.BEVObservation(hw.make_env("roundabout", steps=4))
obs, _ = env.reset(seed=2)
for _ in range(3):
    obs, *_ = env.step(np.zeros(2, np.float32))
u = env.unwrapped
ego = (u.vehicle.position[0], u.vehicle.position[1], u.vehicle.heading)
others = np.array([[*o.position, o.heading, o.LENGTH, o.WIDTH]
                   for o in u.road.vehicles if o is not u.vehicle])
print(f"{len(others)} other vehicles; BEV {obs.shape}")

# %% grade id=ex10_2_tests points=3
b, v = vehicle_boxes((0.0, 0.0, 0.0), np.array([[10.0, 4.0, 0.5, 5.0, 2.0],
                                                 [3.0, 0.0, 0.0, 5.0, 2.0]]), max_ado=3)
assert b.shape == (3, 5), "boxes should have shape (max_ado, 5) = (3, 5)"
assert v.tolist() == [True, True, False], "two vehicles: two valid rows, then an unused one"
assert np.allclose(b[0], [3.0, 0.0, 0.0, 5.0, 2.0]), "nearest first"
assert np.allclose(b[1], [10.0, -4.0, -0.5, 5.0, 2.0]), "mirror y and the heading"
assert np.allclose(b[2], 0.0), "unused rows are zero"
# the raster drawn from your boxes equals the library's BEV observation
boxes, valid = vehicle_boxes(ego, others, 16)
mine = world.rasterize(env.map, hw.ego_pose(env), boxes, valid, env.cfg)
assert np.array_equal(mine, obs), "your BEV differs from BEVObservation's"
### BEGIN HIDDEN TESTS
# an oracle written out: Python's sort is stable, the mirror is (x, -y, -heading)
order = sorted(range(len(others)), key=lambda i: np.hypot(*(others[i, :2] - ego[:2])))[:16]
for row, i in enumerate(order):
    x, y, h, length, width = others[i]
    want = np.array([x, -y, world.wrap_angle(-h), length, width])
    assert np.allclose(boxes[row], want), (
        f"the roundabout scene, row {row}: expected vehicle {i} mirrored, "
        f"{np.round(want, 3).tolist()}; got {np.round(boxes[row], 3).tolist()}")
want = [True] * len(order) + [False] * (16 - len(order))
assert valid.tolist() == want, (
    f"the roundabout scene: expected {len(order)} valid rows, then unused ones; got "
    f"{valid.tolist()}")
# headings wrap to (-pi, pi]; equal distances keep the input order; max_ado cuts
tie = np.array([[0.0, 5.0, 3.5, 4.0, 2.0], [5.0, 0.0, -np.pi, 4.5, 1.8],
                [0.0, -5.0, np.pi, 5.0, 2.0], [9.0, 0.0, 0.0, 5.0, 2.0]])
b3, v3 = vehicle_boxes((0.0, 0.0, 0.0), tie, 3)
assert np.allclose(b3, [[0.0, -5.0, 2 * np.pi - 3.5, 4.0, 2.0],
                        [5.0, 0.0, np.pi, 4.5, 1.8],
                        [0.0, 5.0, np.pi, 5.0, 2.0]]), (
    f"three vehicles at 5 m, max_ado = 3: expected them in input order, yaw = wrap(-heading) "
    f"in (-pi, pi], the one at 9 m cut; got {np.round(b3, 3).tolist()}")
assert v3.all(), f"three vehicles, max_ado = 3: expected three valid rows; got {v3.tolist()}"
b0, v0 = vehicle_boxes((1.0, 1.0, 0.0), np.zeros((0, 5)), 4)
assert np.allclose(b0, 0.0) and not v0.any(), (
    f"no other vehicle: expected all rows zero and invalid; got {np.round(b0, 3).tolist()}, "
    f"{v0.tolist()}")
test_rng = np.random.default_rng(102)  # the tests' own draws, not the notebook's rng
rand = np.column_stack([test_rng.normal(size=(20, 2)) * 30, test_rng.uniform(-4, 4, 20),
                        np.full(20, 5.0), np.full(20, 2.0)])
b2, v2 = vehicle_boxes((1.0, 2.0, 0.3), rand, 8)
assert v2.sum() == 8 and np.all(np.abs(b2[:, 2]) <= np.pi), (
    f"20 random vehicles, max_ado = 8: expected 8 valid rows, yaw in (-pi, pi]; got "
    f"{int(v2.sum())} rows, yaws {np.round(b2[:, 2], 3).tolist()}")
dist = np.linalg.norm(b2[:, :2] - [1.0, -2.0], axis=1)
assert np.all(np.diff(dist) >= 0), (
    f"20 random vehicles: expected rows sorted by distance to the (mirrored) ego; got "
    f"distances {np.round(dist, 2).tolist()}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 10.3 — the collision rate
# A closed-loop evaluation reports the share of episodes in which the ego hits
# another vehicle. Boxes are `[x, y, yaw, length, width]`; two oriented rectangles
# overlap unless some axis separates them (the separating-axis theorem: for
# rectangles, test the 4 edge directions of the two boxes — project both boxes'
# corners on each axis and check whether the intervals are disjoint).
#
# Write `collision_rate(ego, ado, ado_valid, length, width)`: `ego` `(E, T, 3)` poses,
# `ado` `(E, T, A, 5)` boxes, `ado_valid` `(E, T, A)`. Return the percentage of the
# `E` episodes in which the ego box (`length` × `width`) overlaps a valid ado box at
# some step. `world.box_corners(boxes)` gives the corners `(..., 4, 2)`.

# %% solution id=ex10_3 title="Collision rate" forbids="minimanc.metrics.collisions"  # noqa: E501
def collision_rate(ego, ado, ado_valid, length=world.EGO_LENGTH, width=world.EGO_WIDTH):
    ### BEGIN SOLUTION
    ego = np.asarray(ego, float)
    ego_box = np.concatenate([ego, np.broadcast_to([length, width], ego.shape[:-1] + (2,))],
                             axis=-1)[:, :, None, :]                     # (E, T, 1, 5)
    ca = world.box_corners(ego_box)
    cb = world.box_corners(np.asarray(ado, float))
    ca, cb = np.broadcast_arrays(ca, cb)
    overlap = np.ones(ca.shape[:-2], dtype=bool)
    for yaw in (np.broadcast_to(ego_box[..., 2], overlap.shape), np.asarray(ado)[..., 2]):
        for ang in (yaw, yaw + np.pi / 2):
            axis = np.stack([np.cos(ang), np.sin(ang)], axis=-1)[..., None, :]
            pa, pb = (ca * axis).sum(-1), (cb * axis).sum(-1)
            overlap &= ~((pa.max(-1) < pb.min(-1)) | (pb.max(-1) < pa.min(-1)))
    hit = (overlap & np.asarray(ado_valid, bool)).reshape(len(ego), -1).any(axis=1)
    return 100.0 * float(hit.mean())
    ### END SOLUTION

# %% grade id=ex10_3_tests points=3
ego = np.zeros((2, 3, 3))                               # two episodes, ego at the origin
ado = np.zeros((2, 3, 1, 5))
ado[..., :] = [20.0, 0.0, 0.0, 4.0, 2.0]                # far away
ado[1, 2, 0] = [4.0, 1.5, 0.7, 4.0, 2.0]                # episode 1 touches at t = 2
valid = np.ones((2, 3, 1), dtype=bool)
assert np.isclose(collision_rate(ego, ado, valid), 50.0), "one episode of two collides: 50 %"
assert np.isclose(collision_rate(ego, ado, np.zeros_like(valid)), 0.0), "invalid ados"
# a rotated box whose bounding box overlaps but which does not (SAT needed)
corner = np.zeros((1, 1, 1, 5))
corner[0, 0, 0] = [4.45, 2.45, np.pi / 4, 4.0, 1.0]
assert collision_rate(np.zeros((1, 1, 3)), corner, np.ones((1, 1, 1), bool)) == 0.0, (
    "the bounding boxes overlap but the rotated boxes do not: 0 %")
### BEGIN HIDDEN TESTS
r = np.random.default_rng(10)  # its own generator: the literal counts below depend on it
E, T, A = 12, 5, 4
ego_r = np.concatenate([r.normal(size=(E, T, 2)) * 3, r.uniform(-3, 3, (E, T, 1))], -1)
ado_r = np.concatenate([r.normal(size=(E, T, A, 2)) * 10, r.uniform(-3, 3, (E, T, A, 1)),
                        r.uniform(3, 6, (E, T, A, 1)), r.uniform(1.5, 2.5, (E, T, A, 1))],
                       -1)
val_r = r.random((E, T, A)) < 0.7
# literal values, computed once with metrics.collisions (episodes 5, 9 and 10 are clear)
got = collision_rate(ego_r, ado_r, val_r)
assert np.isclose(got, 75.0), (
    f"12 random episodes of 5 steps, 4 ados: expected 75.0 (9 of 12 collide; 5, 9 and 10 are "
    f"clear); got {got}")
per_step = [collision_rate(ego_r[:, t:t + 1], ado_r[:, t:t + 1], val_r[:, t:t + 1]) * E / 100
            for t in range(T)]
assert np.allclose(per_step, [1, 1, 3, 5, 4]), (
    f"12 random episodes, one step at a time: expected 1, 1, 3, 5, 4 colliding episodes; "
    f"got {per_step}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 10.4 — the logged controls of a demonstration
# Behaviour cloning learns the controls logged with each state. For a perfect imitator
# to reproduce the expert through the adapter of 10.1, the logged control of step $t$
# must be what the adapter *realises* over that step: the P-controller reaches the
# commanded speed at the **end** of the step, and the steering realises the **mean**
# yaw rate over it. So, from the recorded states $t = 0 \dots T$,
#
# $$u[t] = \big[\,v[t+1],\ \operatorname{wrap}(\psi_w[t+1] - \psi_w[t]) / \Delta t\,\big],
#   \qquad t = 0 \dots T-1,$$
#
# with the world yaw $\psi_w$ and the difference wrapped to $(-\pi, \pi]$
# (`world.wrap_angle`): a heading that crosses $\pm\pi$ turns by a small angle, not
# by almost $2\pi$. Speeds are highway-env's `vehicle.speed`, in m/s.
#
# Write `logged_controls(poses, speeds, dt=0.5)`: `poses` `(T+1, 3)` world poses,
# `speeds` `(T+1,)`; return `(T, 2)`. Taking the speed at the *start* of the step, or
# the unicycle speed `world.controls_from_poses`, is the natural wrong choice: the
# replay then lags the expert.

# %% solution id=ex10_4 title="Logged controls"
def logged_controls(poses, speeds, dt=0.5):
    ### BEGIN SOLUTION
    poses, speeds = np.asarray(poses, dtype=float), np.asarray(speeds, dtype=float)
    yaw_rate = world.wrap_angle(np.diff(poses[:, 2])) / dt
    return np.stack([speeds[1:], yaw_rate], axis=-1)
    ### END SOLUTION

# %% grade id=ex10_4_tests points=4
toy = logged_controls(np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.1], [10.0, 0.5, 0.0]]),
                      np.array([10.0, 10.0, 12.0]))
assert toy.shape == (2, 2), "T + 1 = 3 states give T = 2 controls"
assert np.allclose(toy, [[10.0, 0.2], [12.0, -0.2]]), (
    "[speed at t + 1, yaw change / 0.5 s]: [[10, 0.2], [12, -0.2]]")
wrap = logged_controls(np.array([[0.0, 0.0, 3.1], [1.0, 0.0, -3.1]]), np.array([2.0, 2.0]))
assert np.allclose(wrap, [[2.0, (2 * np.pi - 6.2) / 0.5]]), (
    "3.1 -> -3.1 rad is a left turn of 2π - 6.2 = 0.083 rad, not -6.2 rad")
# in the simulator: drive an empty highway with commands the adapter can realise, log the
# states, and the logged controls give the commands back
env = hw.make_env("highway-fast", steps=12, config={"vehicles_count": 0})
env.reset(seed=0)
act = hw.ActionAdapter(env)
commands = np.array([(24.0, 0.0), (22.0, 0.05), (20.0, 0.1), (21.0, -0.08), (23.0, -0.05)])
states, speeds = [hw.ego_pose(env)], [env.vehicle.speed]
for c in commands:
    env.step(act(c))
    states.append(hw.ego_pose(env))
    speeds.append(env.vehicle.speed)
logged = logged_controls(np.array(states), np.array(speeds))
assert np.allclose(logged, commands, atol=1e-6), (
    f"the logged controls should be the commands the adapter realised:\n{commands}\ngot\n{logged}")
### BEGIN HIDDEN TESTS
ep = hw.run_episode("roundabout", 3, "expert", steps=12, record_bev=False)
u_ep = np.asarray(logged_controls(ep.poses, ep.speeds), dtype=float)
assert u_ep.shape == (12, 2), (
    f"an expert episode of 12 actions (13 states): expected controls (12, 2); got {u_ep.shape}")
assert np.array_equal(u_ep[:, 0], ep.speeds[1:]), (
    f"an expert episode: expected the speeds reached at the end of each step "
    f"{np.round(ep.speeds[1:4], 3).tolist()}...; got {np.round(u_ep[:3, 0], 3).tolist()}...")
yaw = world.wrap_angle(ep.poses[0, 2] + np.cumsum(u_ep[:, 1]) * 0.5)
gap = float(np.abs(world.wrap_angle(yaw - ep.poses[1:, 2])).max())
assert gap < 1e-9, (
    f"an expert episode: expected the yaw rates to integrate to every logged yaw; got a "
    f"largest difference of {gap:.3g} rad")
half = np.asarray(logged_controls(ep.poses, ep.speeds, dt=0.25), dtype=float)
assert np.allclose(half[:, 1], 2 * u_ep[:, 1]), (
    f"dt = 0.25: expected twice the yaw rates of dt = 0.5, {np.round(2 * u_ep[:3, 1], 4).tolist()}"
    f"...; got {np.round(half[:3, 1], 4).tolist()}...")
circle = np.stack([np.zeros(9), np.zeros(9), world.wrap_angle(0.9 * np.arange(9))], -1)
got = np.asarray(logged_controls(circle, np.ones(9)), dtype=float)[:, 1]
assert np.allclose(got, 1.8), (
    f"a steady turn of 0.9 rad per step, across ±π: expected 1.8 rad/s at every step; got "
    f"{np.round(got, 3).tolist()}")
### END HIDDEN TESTS

# %% [markdown]
# ## Exercise 10.5 — what the logs record in a turn (transfer)
# The tutorial measured that the *unicycle* speed — the displacement along the heading
# divided by $\Delta t$, what `world.controls_from_poses` and the chapter-7 logs record —
# is a little lower than the bicycle's speed in a turn, and explained it roughly. Derive
# it exactly for highway-env's integration. The ego already drives at the commanded
# speed $v$ ($a = 0$) and the adapter of 10.1 realises the yaw rate $\omega$ with the
# world-frame slip angle $\beta$, $\sin\beta = \omega L / (2v)$. Over the step, $n =
# \Delta t / h = 5$ Euler sub-steps: the position moves by $v h$ along $\psi_k + \beta$,
# then the heading turns by $\omega h$ ($\psi_{k+1} = \psi_k + \omega h$).
#
# 1. `unicycle_speed(v, omega)`: the unicycle speed the log records for that step, in
#    **closed form** (no loop over the sub-steps). Raise a `ValueError` naming `omega`
#    when $|\omega| L / (2v) > 1$ (no slip angle turns that fast) and naming `v` when
#    $v \le 0$.
# 2. `command_for(v_u, omega)`: the inverse, the speed $v$ to command so that the log
#    records the unicycle speed `v_u` at yaw rate `omega` — what a policy trained on
#    chapter-7 logs (unicycle speeds) should send to highway-env. Also in closed form.
#
# The two functions are graded separately, 2 points each (the tests of 2 use their own
# unicycle speed, not yours).
#
# <details><summary>Hint 1 (the idea)</summary>
#
# The displacement over the step is a sum of $n$ vectors of equal length $vh$ whose
# directions turn by the same angle $\omega h$ from one to the next. Their sum points
# along the *middle* direction. How long is it?
# </details>
#
# <details><summary>Hint 2 (the method)</summary>
#
# Write the directions as complex numbers $e^{i(\psi_0 + \beta + k\omega h)}$ and sum the
# geometric series; project the sum on the initial heading. For the inverse, notice
# that $v\sin\beta$ does not depend on $v$: expand $\cos$ of a sum.
# </details>

# %% solution id=ex10_5 title="What the logs record in a turn"
def unicycle_speed(v, omega, length=5.0, dt=0.5, substep=0.1):
    ### BEGIN SOLUTION
    if v <= 0:
        raise ValueError(f"v must be positive, got v={v!r}")
    if abs(omega) * length / (2.0 * v) > 1.0:
        raise ValueError(f"omega={omega!r} needs |omega| L / (2 v) <= 1 at v={v!r}")
    n = int(round(dt / substep))
    half = omega * substep / 2.0
    beta = np.arcsin(omega * length / (2.0 * v))
    chord = n if half == 0.0 else np.sin(n * half) / np.sin(half)  # |sum of n unit steps|
    return float(v * substep * chord * np.cos(beta + (n - 1) * half) / dt)
    ### END SOLUTION


def command_for(v_u, omega, length=5.0, dt=0.5, substep=0.1):
    ### BEGIN SOLUTION
    n = int(round(dt / substep))
    half = omega * substep / 2.0
    gain = substep * (n if half == 0.0 else np.sin(n * half) / np.sin(half)) / dt
    side, turn = omega * length / 2.0, (n - 1) * half     # v sin(beta), the middle turn
    along = (v_u / gain + side * np.sin(turn)) / np.cos(turn)  # v cos(beta)
    return float(np.hypot(along, side))
    ### END SOLUTION

# %%
def logged_speed(command, env_seed=0):
    """Drive an empty highway at ``command[0]`` until the speed is reached, then hold
    ``command`` for one step: the unicycle speed that step logs (and the start speed)."""
    sim = hw.make_env("highway-fast", steps=8, config={"vehicles_count": 0})
    sim.reset(seed=env_seed)
    act = hw.ActionAdapter(sim)
    for _ in range(4):
        sim.step(act(np.array([command[0], 0.0])))
    before, speed = hw.ego_pose(sim), sim.vehicle.speed
    sim.step(act(np.asarray(command, dtype=float)))
    return world.controls_from_poses(np.array([before, hw.ego_pose(sim)]))[0, 0], speed


v_log, v_start = logged_speed((20.0, 0.3))
print(f"command [20 m/s, 0.3 rad/s] from {v_start:.1f} m/s: the log records "
      f"{v_log:.2f} m/s")

# %% grade id=ex10_5_speed_tests points=2
got = unicycle_speed(15.0, 0.0)
assert np.isclose(got, 15.0), f"v = 15, omega = 0 (straight): expected 15.0; got {got}"
got = unicycle_speed(20.0, 0.3)
assert abs(got - v_log) < 1e-5, (
    f"v = 20, omega = 0.3: expected the simulator's logged {v_log:.6f} m/s; got {got}")
got = unicycle_speed(20.0, -0.3)
assert np.isclose(got, unicycle_speed(20.0, 0.3), rtol=1e-12), (
    f"v = 20, omega = -0.3: expected the speed of the left turn of the same rate, "
    f"{unicycle_speed(20.0, 0.3):.6f}; got {got}")
### BEGIN HIDDEN TESTS
def substeps(v, omega, length=5.0, dt=0.5, h=0.1):  # the sub-steps written out
    beta = np.arcsin(omega * length / (2.0 * v))
    x = y = yaw = 0.0
    for _ in range(int(round(dt / h))):
        x, y = x + v * h * np.cos(yaw + beta), y + v * h * np.sin(yaw + beta)
        yaw += v * np.sin(beta) / (length / 2.0) * h
    return x / dt


for command in ((15.0, 0.5), (25.0, -0.2), (18.0, 1.0)):
    want, start = logged_speed(command)
    got = unicycle_speed(*command)
    assert abs(start - command[0]) < 1e-9 and abs(got - want) < 1e-5, (
        f"command {command} in the simulator: expected {want:.6f} m/s; got {got!r}")
for v, omega, length, dt, h in ((10.0, 0.8, 5.0, 0.5, 0.1), (3.0, 1.1, 5.0, 0.5, 0.1),
                                (12.0, 0.4, 4.0, 1.0, 0.05), (30.0, -0.05, 5.0, 0.5, 0.25)):
    want = substeps(v, omega, length, dt, h)
    got = unicycle_speed(v, omega, length, dt, h)
    assert type(got) is float and np.isclose(got, want, rtol=1e-12), (
        f"v = {v}, omega = {omega}, L = {length}, dt = {dt}, h = {h}: expected the float "
        f"{want:.9f}; got {got!r}")
for bad in ((2.0, 1.0), (10.0, -4.1), (0.0, 0.0), (-3.0, 0.1)):
    try:
        unicycle_speed(*bad)
    except ValueError:
        pass
    else:
        raise AssertionError(f"unicycle_speed{bad}: expected a ValueError (no slip angle "
                             f"realises it, or v <= 0)")
### END HIDDEN TESTS

# %% grade id=ex10_5_command_tests points=2
got = command_for(15.0, 0.0)
assert np.isclose(got, 15.0), f"v_u = 15, omega = 0 (straight): expected 15.0; got {got}"
got = command_for(v_log, 0.3)
assert abs(got - 20.0) < 1e-4, (
    f"omega = 0.3: the simulator logged {v_log:.4f} m/s for a command of 20 m/s; expected "
    f"20.0; got {got}")
### BEGIN HIDDEN TESTS
for v, omega, length, dt, h in ((10.0, 0.8, 5.0, 0.5, 0.1), (3.0, 1.1, 5.0, 0.5, 0.1),
                                (12.0, 0.4, 4.0, 1.0, 0.05), (30.0, -0.05, 5.0, 0.5, 0.25),
                                (6.0, -1.0, 5.0, 0.5, 0.1)):
    v_u = substeps(v, omega, length, dt, h)
    got = command_for(v_u, omega, length, dt, h)
    assert type(got) is float and np.isclose(got, v, rtol=1e-9), (
        f"v_u = {v_u:.6f}, omega = {omega}, L = {length}, dt = {dt}, h = {h}: expected the "
        f"float {v:.6f} (the command that logs v_u); got {got!r}")
### END HIDDEN TESTS

# %% [markdown]
# ## Using the pieces: does a driver that ignores traffic crash?
# From here on the notebook uses the library (`hw.controls_to_action`,
# `hw.BEVObservation`, `metrics.collisions`, `hw.Episode.controls`), so it runs even
# with unfinished exercises. A *lane follower* drives the lane target at a constant 10 m/s with
# pure pursuit, blind to other vehicles; the expert (highway-env's IDM/MOBIL, which
# also yields at the roundabout entry) sees them. Same seeds, same roundabout.

# %%
def lane_follower(obs):
    x, y = obs["lane_target"][2]                       # the target point 12 m ahead
    curvature = 2.0 * y / (x * x + y * y)              # pure pursuit
    return np.array([10.0, 10.0 * curvature])


seeds = [100_000 + i for i in range(6)]
runs = {"expert": [hw.run_episode("roundabout", s, "expert", steps=16, record_bev=False)
                   for s in seeds],
        "lane follower": [hw.run_episode("roundabout", s, lane_follower, steps=16,
                                         record_bev=False) for s in seeds]}
rates = {}
for name, eps in runs.items():
    ego = np.stack([ep.poses for ep in eps])
    ado = np.stack([ep.ado for ep in eps])
    valid = np.stack([ep.ado_valid for ep in eps])
    rates[name] = 100.0 * np.mean([ep.collided for ep in eps])
    overlap = 100.0 * metrics.collisions(ego, ado, valid).mean()
    close = 100.0 * metrics.close_encounters(ego, ado, valid).mean()
    print(f"{name:<14} crashed (highway-env) {rates[name]:5.1f} %   box overlap at 2 Hz "
          f"{overlap:5.1f} %   close encounters {close:5.1f} % of steps")
assert rates["lane follower"] > rates["expert"]

# %% [markdown]
# The blind lane follower crashes in most episodes, the expert in none — yet the box
# overlap of exercise 10.3, computed on the states logged every 0.5 s, finds no
# collision at all. highway-env tests contacts every 0.1 s and, when two boxes are
# about to intersect, pushes them apart (`impact`) and marks both `crashed`: logged
# states never overlap. On the chapter-7 logs (ados replayed, nothing pushes back) the
# overlap test is the right one; in highway-env the simulator's `crashed` flag is the
# collision measure (`hw.ClosedLoopResult.metrics["collision_rate"]`), and the box-gap
# metric `metrics.close_encounters` still sees the near misses. Avoiding the other
# vehicles is what the BEV is for: the tutorial trains MANC and a CNN on the expert's
# demonstrations and compares them in closed loop.

# %% [markdown]
# ## Exercise 10.6 — open experiment: a driver that yields
# The lane follower crashes because it never looks at the other vehicles. Design a
# driver that does, with the same pure-pursuit steering: `careful_driver(obs)` returns
# `[speed, yaw rate]` for one observation of `hw.run_episode` — `obs["pose"]` the ego's
# world pose `[x, y, yaw]`, `obs["ado"]` the other vehicles' world boxes
# `[x, y, yaw, length, width]` (`(A, 5)`, rows where `obs["ado_valid"]`),
# `obs["lane_target"]` `(K, 2)` in the ego frame (12 m ahead: row 2), `obs["speed"]`.
# A rule of your own: when to slow down or wait, how far ahead and how wide to look,
# how fast to drive when the way is clear. The grade cell drives it on the six seeds
# above and checks that it crashes **at most once and less often than the lane
# follower**, with a **mean speed of at least 4 m/s** (waiting forever is not driving);
# the hidden tests drive it on four roundabout seeds of their own with the same bar (at
# most one crash, 4 m/s). Then answer the written question.

# %% solution id=ex10_6 title="Open experiment: a driver that yields"
def careful_driver(obs):
    ### BEGIN SOLUTION
    x, y = obs["lane_target"][2]
    curvature = 2.0 * y / (x * x + y * y)                 # pure pursuit, as the lane follower
    px, py, yaw = obs["pose"]
    ado = np.asarray(obs["ado"])[np.asarray(obs["ado_valid"], bool)]
    dx, dy = ado[:, 0] - px, ado[:, 1] - py
    ahead = dx * np.cos(yaw) + dy * np.sin(yaw)            # along the ego's heading
    side = -dx * np.sin(yaw) + dy * np.cos(yaw)
    in_path = (ahead > 0.0) & (ahead < 20.0) & (np.abs(side) < 8.0)
    too_close = (np.hypot(dx, dy) < 12.0) & (ahead > -2.0)
    speed = 0.0 if np.any(in_path | too_close) else 7.0
    return np.array([speed, speed * curvature])
    ### END SOLUTION

# %% grade id=ex10_6_tests points=2
careful = [hw.run_episode("roundabout", s, careful_driver, steps=16, record_bev=False)
           for s in seeds]                                   # the six seeds above, about 8 s
careful_speed = float(np.mean([ep.speeds.mean() for ep in careful]))
crashes = int(sum(ep.collided for ep in careful))
follower = int(sum(ep.collided for ep in runs["lane follower"]))
assert crashes <= 1 and crashes < follower, (
    f"the six seeds: expected at most one crash and fewer than the lane follower's "
    f"{follower}; got {crashes}")
assert careful_speed >= 4.0, (
    f"the six seeds: expected a mean speed of at least 4 m/s; got {careful_speed:.2f} m/s")
### BEGIN HIDDEN TESTS
held_out = [hw.run_episode("roundabout", 200_000 + i, careful_driver, steps=16,
                           record_bev=False) for i in range(4)]
crashed = [ep.seed for ep in held_out if ep.collided]
mean_speed = float(np.mean([ep.speeds.mean() for ep in held_out]))
assert len(crashed) <= 1, (
    f"four held-out roundabout seeds: expected at most one crash; got crashes in seeds {crashed}")
assert mean_speed >= 4.0, (
    f"four held-out roundabout seeds: expected a mean speed of at least 4 m/s; got "
    f"{mean_speed:.2f} m/s")
### END HIDDEN TESTS

# %% [markdown]
# **Written question (10.6).** (a) Describe your rule and one episode where it still
# fails or nearly fails (a crash, a near miss in `metrics.close_encounters`, or a long
# wait): what did it not see? (b) Your rule reads the other vehicles' exact boxes. The
# BEV-trained MANC of the tutorial sees them only as yellow pixels: what must it learn
# from the expert's demonstrations to reproduce your rule, and why do six
# collision-free demonstrations at the roundabout entry teach little of it? (c) Why is
# "no crash" not enough to call a driver good here — name two numbers of
# `hw.drive_episodes` you would also report.

# %% [markdown] answer id=ex10_6_w title="What a yielding rule needs to see" points=3
# ### BEGIN SOLUTION
# (a) The rule keeps pure pursuit and sets the speed to 0 when a vehicle is in a box
# 20 m ahead and ±8 m sideways, or within 12 m and not behind; otherwise 7 m/s. On
# the six seeds it does not crash (the lane follower crashes in four) at about 5 m/s.
# It fails when the danger does not come from the box it watches: a vehicle
# approaching fast from the side at the entry (its box enters the window too late, at
# 2 Hz a vehicle moves 5 m between decisions) or a follower that does not expect the
# ego to stop dead in the ring; waiting until a far-away vehicle on the ring has
# passed also makes the entry slow. It sees positions only, never speeds or intentions.
# (b) MANC sees the vehicles as pixels of a 64 × 64 raster: it must learn from the
# demonstrations that yellow pixels in a region ahead and to the left at the entry
# mean "slow down", which is a rule about the geometry of the raster, with a threshold
# on distance — and it sees no speed of the others (one frame, unless the raster draws
# the history). Six collision-free demonstrations contain only a few entries, mostly
# with the way clear: the expert yields in a handful of states, so the learner has
# almost no examples of "wait" and none of what happens when it does not wait (the
# covariate shift that chapter 11's DAgger addresses).
# (c) A driver that never moves never crashes. Report also the mean speed and the
# progress along the route (or the goal distance) and the ADE to the expert, the
# off-road rate, and the close encounters (near misses) — `hw.drive_episodes`'
# `mean_speed`, `ade`, `off_road_rate`.
# ### END SOLUTION

# %% [markdown]
# ## Your figure
# **Your** `careful_driver` on the first of the six seeds (solid), over the library's
# expert and the lane follower of the same seed (dashed): the paths through the
# roundabout (a cross marks the first crashed step) and the speeds. A driver that
# yields should slow down near the entry as the expert does and reach the exit without
# a cross; a function that raises is named in the title and only the library's
# episodes are drawn.

# %%
plot_episode_attempts(
    {"your careful_driver": lambda: hw.run_episode("roundabout", seeds[0], careful_driver,
                                                   steps=16, record_bev=False)},
    {"expert": runs["expert"][0], "lane follower": runs["lane follower"][0]})
plt.tight_layout()
plt.show()
