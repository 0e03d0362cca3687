# %% [markdown]
# # Chapter 7 — Exercises: frames, boxes in the raster, the IDM
#
# Module built in this chapter: `minimanc.world` (the tutorial
# `tutorials/07_world.ipynb` walks through it). Three pieces of the world, each
# checked against the library:
#
# 1. a **pose in the ego frame** — the goal input of every model;
# 2. **rasterising a rotated box** — how ado vehicles get into the BEV;
# 3. the **Intelligent Driver Model** — how every vehicle picks its
#    acceleration.
#
# Replace each `raise NotImplementedError(...)` with your code and run the
# grade cell below it; `minimanc grade exercises/07_world.ipynb` scores the
# whole notebook.

# %%
import math

import matplotlib.pyplot as plt
import numpy as np

from minimanc import world

rng = np.random.default_rng(0)
np.set_printoptions(precision=3, suppress=True)

# %% [markdown]
# ## Exercise 7.1 — a pose in the ego frame
# Every step, the models receive the human's **final pose** re-expressed in
# the current ego frame (+x forward, +y left). For a world pose
# $g = (x_g, y_g, \psi_g)$ and the ego pose $e = (x_e, y_e, \psi_e)$:
#
# $$\begin{pmatrix}x\\y\end{pmatrix} = R(-\psi_e)\begin{pmatrix}x_g - x_e\\ y_g - y_e\end{pmatrix},
#   \qquad \psi = \operatorname{wrap}(\psi_g - \psi_e) \in (-\pi, \pi].$$
#
# Work on batches: `goal` and `ego` have shape `(..., 3)` (they broadcast).
# Wrap angles with `np.mod(a + np.pi, 2 * np.pi) - np.pi` and map $-\pi$ to $\pi$.

# %% solution id=ex07_1 title="A pose in the ego frame" forbids="minimanc.world.geometry.goal_in_ego_frame,minimanc.world.geometry.to_ego_frame"  # noqa: E501
def pose_in_ego_frame(goal, ego):
    ### BEGIN SOLUTION
    goal = np.asarray(goal, dtype=float)
    ego = np.asarray(ego, dtype=float)
    c, s = np.cos(ego[..., 2]), np.sin(ego[..., 2])
    dx = goal[..., 0] - ego[..., 0]
    dy = goal[..., 1] - ego[..., 1]
    yaw = np.mod(goal[..., 2] - ego[..., 2] + np.pi, 2 * np.pi) - np.pi
    yaw = np.where(yaw == -np.pi, np.pi, yaw)
    return np.stack([c * dx + s * dy, -s * dx + c * dy, yaw], axis=-1)
    ### END SOLUTION

# %% grade id=ex07_1_tests points=2
ego = np.array([10.0, 5.0, np.pi / 2])                      # facing north
out = pose_in_ego_frame(np.array([10.0, 15.0, np.pi / 2]), ego)
assert np.allclose(out, [10.0, 0.0, 0.0]), out               # 10 m ahead, same heading
out = pose_in_ego_frame(np.array([0.0, 5.0, -np.pi / 2]), ego)
assert np.allclose(out, [0.0, 10.0, np.pi]), out             # 10 m left, facing back
### BEGIN HIDDEN TESTS
g = rng.normal(size=(50, 3)) * [40, 40, 4]
e = rng.normal(size=(50, 3)) * [40, 40, 4]
got = pose_in_ego_frame(g, e)
assert got.shape == (50, 3)
# the inverse map: rotating (x, y) back by the ego yaw and adding the ego position
# gives the goal position again; the heading differs from psi_g - psi_e by a turn
back_x = e[:, 0] + np.cos(e[:, 2]) * got[:, 0] - np.sin(e[:, 2]) * got[:, 1]
back_y = e[:, 1] + np.sin(e[:, 2]) * got[:, 0] + np.cos(e[:, 2]) * got[:, 1]
assert np.allclose(back_x, g[:, 0], atol=1e-9) and np.allclose(back_y, g[:, 1], atol=1e-9)
turns = (g[:, 2] - e[:, 2] - got[:, 2]) / (2 * np.pi)
assert np.allclose(turns, np.round(turns), atol=1e-9)
assert np.allclose(np.hypot(got[:, 0], got[:, 1]), np.hypot(*(g[:, :2] - e[:, :2]).T))
assert np.all(got[:, 2] > -np.pi) and np.all(got[:, 2] <= np.pi)
assert np.allclose(pose_in_ego_frame(e, e), 0.0)
### END HIDDEN TESTS

# %% [markdown]
# In the dataset the goal at step $t$ is exactly this transform of the last
# logged pose (the reference implementation is `world.goal_in_ego_frame`):

# %%
ds = world.generate(3, seed=0, progress=False, workers=1)
ego_log = ds.ego[0].astype(np.float64)
goal_ref = world.goal_in_ego_frame(np.broadcast_to(ego_log[-1], ego_log.shape), ego_log)
assert np.allclose(goal_ref, ds.goal[0], atol=1e-4)
print(ds.goal[0, ::10].round(2))

# %% [markdown]
# ## Exercise 7.2 — rasterising a rotated box
# The raster is drawn by **inverse mapping**: instead of drawing the box's
# outline, ask every pixel whether its centre lies inside the box. With the
# box $[x_b, y_b, \psi_b, l, w]$ and the pixel centres $(X, Y)$ — all in the
# ego frame — rotate each centre into the box's own frame,
#
# $$u = \cos\psi_b (X - x_b) + \sin\psi_b (Y - y_b),\qquad
#   v = -\sin\psi_b (X - x_b) + \cos\psi_b (Y - y_b),$$
#
# and keep the pixels with $|u| \le l/2$ and $|v| \le w/2$. `cfg.pixel_centres()`
# returns `(X, Y)`, each `(H, W)`; row 0 is 40 m ahead, the ego sits at
# row 51, column 32 (heading up, +y to the left). Return a boolean `(H, W)`
# mask — no Python loop over pixels.

# %% solution id=ex07_2 title="Rasterising a rotated box" forbids="minimanc.world.raster.box_mask"  # noqa: E501
def box_pixels(box, cfg):
    ### BEGIN SOLUTION
    X, Y = cfg.pixel_centres()
    xb, yb, yaw, length, width = box
    c, s = np.cos(yaw), np.sin(yaw)
    u = c * (X - xb) + s * (Y - yb)
    v = -s * (X - xb) + c * (Y - yb)
    return (np.abs(u) <= length / 2) & (np.abs(v) <= width / 2)
    ### END SOLUTION

# %% grade id=ex07_2_tests points=3
cfg = world.RasterConfig()
mask = box_pixels(np.array([10.0, 0.0, 0.0, 4.5, 1.9]), cfg)   # a car 10 m straight ahead
assert mask.shape == (64, 64) and mask.dtype == bool
assert mask[38, 32]                                             # floor((40 - 10) / 0.78125)
assert not mask[51, 32] and mask.sum() < 30
side = box_pixels(np.array([0.0, 10.0, np.pi / 2, 4.5, 1.9]), cfg)  # 10 m left, turned
assert side[51, 19] and side[51, 17] and not side[48, 19] and not side[51, 23]
### BEGIN HIDDEN TESTS
def slow_box(b, cfg):
    """The box test with complex numbers: (p - c) e^{-i yaw} is p in the box frame.
    Returns the mask and where a pixel centre is within 1e-9 m of an edge (a tie)."""
    X, Y = cfg.pixel_centres()
    z = ((X + 1j * Y) - (b[0] + 1j * b[1])) * np.exp(-1j * b[2])
    inside = (np.abs(z.real) <= b[3] / 2) & (np.abs(z.imag) <= b[4] / 2)
    tie = (np.abs(np.abs(z.real) - b[3] / 2) < 1e-9) | (np.abs(np.abs(z.imag) - b[4] / 2) < 1e-9)
    return inside, tie


for _ in range(20):
    b = np.array([*rng.uniform(-20, 30, 2), rng.uniform(-4, 4), *rng.uniform([1, 0.5], [12, 3])])
    want, tie = slow_box(b, cfg)
    assert np.array_equal(box_pixels(b, cfg)[~tie], want[~tie])
big = world.RasterConfig(size=128)
b = np.array([5.0, -3.0, 0.7, 4.7, 1.9])
want, tie = slow_box(b, big)
assert np.array_equal(box_pixels(b, big)[~tie], want[~tie]) and want.sum() > 20
### END HIDDEN TESTS

# %% [markdown]
# The library's `world.box_mask` is the same test; `world.rasterize` applies it
# to every visible ado. A box turned by 35° at three resolutions:

# %%
fig, axs = plt.subplots(1, 3, figsize=(10, 3.4))
for ax, size in zip(axs, (32, 64, 250)):
    c = world.RasterConfig(size=size)
    Xc, Yc = c.pixel_centres()
    m = world.box_mask(Xc, Yc, np.array([12.0, -4.0, np.deg2rad(35), 4.7, 1.9]))
    ax.imshow(m, cmap="gray")
    ax.set_title(f"{size} px: {int(m.sum())} pixels")
    print(f"{size:4d} px at {c.resolution:.3f} m/px: area {m.sum() * c.resolution ** 2:.2f} m² "
          f"(true {4.7 * 1.9:.2f} m²)")
plt.show()

# %% [markdown]
# ## Exercise 7.3 — the IDM acceleration
# Every vehicle in the world — ados and the human — picks its acceleration
# with the Intelligent Driver Model:
#
# $$a = a_{max}\Big[1 - \Big(\frac{v}{v_0}\Big)^{\delta} - \Big(\frac{s^*}{s}\Big)^2\Big],\qquad
#   s^* = s_0 + \max\Big(0,\; vT + \frac{v\,\Delta v}{2\sqrt{a_{max} b}}\Big),$$
#
# with own speed $v$, desired speed $v_0$, gap $s$ to the leader (bumper to
# bumper; `np.inf` on a free road), closing speed $\Delta v = v - v_{lead}$,
# $\delta = 4$. Inputs may be arrays (broadcast). Return the raw value (no
# clipping).

# %% solution id=ex07_3 title="The IDM acceleration" forbids="minimanc.world.traffic.idm_acceleration"  # noqa: E501
def idm(v, v0, gap, dv, a_max=1.5, b=2.0, s0=2.0, T=1.5, delta=4.0):
    ### BEGIN SOLUTION
    v = np.asarray(v, dtype=float)
    s_star = s0 + np.maximum(0.0, v * T + v * dv / (2.0 * np.sqrt(a_max * b)))
    return a_max * (1.0 - (v / v0) ** delta - (s_star / np.asarray(gap, dtype=float)) ** 2)
    ### END SOLUTION

# %% grade id=ex07_3_tests points=2
assert np.isclose(idm(0.0, 13.0, np.inf, 0.0), 1.5)             # standing start, free road
assert np.isclose(idm(13.0, 13.0, np.inf, 0.0), 0.0)            # cruising at v0
a_close = idm(10.0, 13.0, 10.0, 5.0)                              # closing in fast
assert a_close < -5.0, a_close
### BEGIN HIDDEN TESTS
v = rng.uniform(0, 15, 100)
v0 = rng.uniform(5, 15, 100)
gap = rng.uniform(1, 80, 100)
dv = rng.uniform(-5, 5, 100)
kw = dict(a_max=1.2, b=2.5, s0=1.5, T=1.1)
# the formula, one vehicle at a time with Python floats
ref = [1.2 * (1 - (vi / v0i) ** 4
              - ((1.5 + max(0.0, vi * 1.1 + vi * dvi / (2 * math.sqrt(1.2 * 2.5)))) / gi) ** 2)
       for vi, v0i, gi, dvi in zip(v, v0, gap, dv)]
assert np.allclose(idm(v, v0, gap, dv, **kw), ref)
gaps = np.linspace(3, 60, 50)
assert np.all(np.diff(idm(8.0, 12.0, gaps, 0.0)) > 0)            # more room, more throttle
### END HIDDEN TESTS

# %% [markdown]
# With the reference `world.idm_acceleration`: a follower behind a leader that
# brakes to a stop. The follower settles at the jam distance $s_0$ without
# touching it.

# %%
dt = 0.1
xl, vl = 40.0, 10.0
xf, vf = 0.0, 10.0
gaps = []
for _ in range(400):
    al = -2.0 if vl > 0 else 0.0
    af = float(world.idm_acceleration(vf, 13.0, xl - xf - 4.5, vf - vl))
    vl = max(vl + al * dt, 0.0)
    vf = max(vf + max(af, -8.0) * dt, 0.0)
    xl += vl * dt
    xf += vf * dt
    gaps.append(xl - xf - 4.5)
print(f"closest gap {min(gaps):.2f} m, final gap {gaps[-1]:.2f} m, final speed {vf:.3f} m/s")
assert min(gaps) > 1.5
plt.plot(np.arange(len(gaps)) * dt, gaps)
plt.xlabel("time (s)")
plt.ylabel("gap (m)")
plt.show()
