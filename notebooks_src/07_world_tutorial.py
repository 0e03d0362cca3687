# %% [markdown]
# # Chapter 7 — A nuScenes-style driving world, made from scratch
#
# Module built in this chapter: `minimanc.world` (maps, traffic, the human
# driver, the BEV rasteriser and the dataset; paper section V, *Setup*).
#
# The paper trains MANC on **nuScenes**: 850 scenes of 20 s sampled at 2 Hz
# (40 steps), 650 for training and 200 for validation, each step seen as a
# semantic bird's-eye-view (BEV) raster. Nothing can be downloaded here, so we
# build a world that produces the same kind of data:
#
# | piece | module | what it does |
# |---|---|---|
# | frames, unicycle | `world.geometry` | ego frame, explicit-Euler unicycle at $\Delta t = 0.5$ s |
# | maps | `world.maps` | straight/curved roads, intersections, roundabouts, lanes, route |
# | traffic | `world.traffic` | ado vehicles on lanes: IDM, junction priority, cut-ins |
# | the human | `world.driver` | the ego driver, with a per-scene style |
# | raster | `world.raster` | ego-centric, heading-up BEV with the devkit's colours |
# | dataset | `world.generation`, `world.scenes` | generate the scenes; split, subset |
# | files | `world.datawriter`, `world.datareader` | save / load: sharded, checksummed |
#
# The data must make learning from images worth it: the human meets junctions,
# roundabouts, queues and vehicles cutting in, and different scenes are driven
# by differently styled humans.
#
# **Objectives.** After this chapter you can
# - convert between world and ego frames and step the unicycle at Δt = 0.5 s
# - generate maps, IDM traffic and a styled human driver
# - rasterise the bird's-eye view and build a split dataset
#
# **Prerequisites.** Chapter 0; plane geometry (frames, headings).
#
# **Time.** About 45 minutes for the tutorial and 90 for the exercises.

# %%
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from minimanc import world
from minimanc.viz.world import gallery, plot_map, scene_frames

np.set_printoptions(precision=3, suppress=True)
rng = np.random.default_rng(0)

# %% [markdown]
# ## 1. Frames and the unicycle
# World frame: $x$ east, $y$ north, yaw counter-clockwise from $+x$. The **ego
# frame** puts the ego at the origin facing $+x$, with $+y$ on its left:
# $p_{ego} = R(-\psi)(p - p_e)$. The models see everything in this frame: the
# goal (the human's final pose), the lane target, the raster.
#
# The ego moves as a **unicycle** with controls $u = [v, \omega]$ (speed and
# yaw rate), integrated with explicit Euler at $\Delta t = 0.5$ s as in the
# authors' environment — the position moves along the *old* heading. (The
# paper's text says its baselines output "speed and steering"; the released
# environment's second control is a yaw rate, and so is ours.)
#
# $$x' = x + v\cos\psi\,\Delta t,\quad y' = y + v\sin\psi\,\Delta t,\quad
#   \psi' = \psi + \omega\,\Delta t.$$

# %%
pose = np.array([10.0, 5.0, np.pi / 2])          # facing north
print(world.to_ego_frame(np.array([10.0, 15.0]), pose).round(3) + 0.0)   # 10 m ahead
print(world.to_ego_frame(np.array([0.0, 5.0]), pose).round(3) + 0.0)     # 10 m to the left
goal = np.array([30.0, 40.0, 0.0])
print(world.goal_in_ego_frame(goal, pose).round(3) + 0.0)  # [x, y, yaw] seen from the ego

traj = [pose]
for _ in range(8):                                          # 4 s of a gentle left turn
    traj.append(world.unicycle_step(traj[-1], np.array([8.0, 0.2]), world.DT))
traj = np.array(traj)
print(traj[-1].round(3))
# the controls can be read back from consecutive poses
assert np.allclose(world.controls_from_poses(traj), [8.0, 0.2])

# %% [markdown]
# ## 2. Maps
# A map is drawn in two steps. `random_recipe(rng)` picks a few numbers — the
# map kind, road shapes as `(length, curvature)` pieces, lanes per direction,
# arm angles, the roundabout radius, the ego's route choice — and
# `build_map(recipe)` turns them deterministically into geometry:
#
# * **lanes**: centrelines every 1 m with headings; right-hand traffic, 3.5 m
#   lanes, one or two per direction;
# * **lane connectors** through junctions: cubic Bézier curves tangent to the
#   incoming and outgoing lanes (straight, left and right turns; roundabout
#   entries and exits);
# * **drivable area** (road strips, the junction polygon, the roundabout disc
#   minus its island), **walkways** and **pedestrian crossings**;
# * a **conflict table**: where two junction lanes cross or merge, and over
#   which stretch of each;
# * the ego's **route**: a lane sequence, concatenated into one polyline.
#
# Datasets store only the recipes, so a map is a few hundred bytes on disk.

# %%
fig, axs = plt.subplots(1, 4, figsize=(16, 4))
for ax, kind in zip(axs, ["straight", "curved", "intersection", "roundabout"]):
    m = world.random_map(np.random.default_rng(3), kind)
    plot_map(m, ax)
    p0 = m.route_pose(m.start_s)[0]
    ax.plot(*p0, "r*", ms=12)
    lo = p0 - 90
    ax.set_xlim(lo[0], lo[0] + 180)
    ax.set_ylim(lo[1], lo[1] + 180)
    ax.set_title(f"{kind}: {len(m.lanes)} lanes, {len(m.conflicts) // 2} conflicts")
    print(f"{kind:12s} route {m.route_s[-1] - m.start_s:6.1f} m ahead of the start, "
          f"lanes on the route: {[m.lanes[i].kind for i in m.route]}")
plt.show()

# %% [markdown]
# The **moving lane target** gives the models the road ahead as numbers: $K =
# 10$ points on the route's centreline, every 4 m, *starting from the ego's own
# position* (its projection on the route). It is never indexed by the human's
# time — a target "where the human was 2 s later" would leak the human's speed
# into the inputs. In closed loop the same function is evaluated at the
# policy's pose.

# %%
m = world.random_map(np.random.default_rng(3), "roundabout")
s0 = m.start_s + 60.0
p, h = m.route_pose(s0)
ego_pose = np.array([p[0] - 0.5 * np.sin(h), p[1] + 0.5 * np.cos(h), h + 0.1])  # 0.5 m left
targets = world.lane_targets(m, ego_pose)
print(targets[:4].round(2))
print("spacing:", np.linalg.norm(np.diff(targets, axis=0), axis=1).round(2))

# %% [markdown]
# ## 3. The BEV raster
# The nuScenes devkit draws 500 × 500 px at 0.1 m/px: 40 m ahead, 10 m behind
# and 25 m to each side, the agent at row 400, column 250, heading up.
# `RasterConfig()` keeps these proportions at **64 × 64** px (0.78 m/px) for
# CPU training; `RasterConfig(size=250)` is the authors' 0.2 m/px.
#
# | layer | colour |
# |---|---|
# | drivable area | white (255, 255, 255) |
# | pedestrian crossing | (119, 136, 153) |
# | walkway | blue (0, 0, 255) |
# | lanes | hue from the heading relative to the ego: same direction cyan, opposite red |
# | ado vehicles | yellow (255, 255, 0) |
# | ego | red box 4.727 m × 1.907 m |
#
# Each frame is rendered by **inverse mapping**: every pixel centre is moved
# to the world with the ego's pose and looked up in a class grid of the map
# (drawn once per map); lane samples are scattered into the image; boxes are
# tested pixel by pixel in their own frame. All vectorised NumPy, any pose —
# the closed loop re-renders from the policy's own pose every step.
#
# `cfg.ego_to_pixel` gives the pixel that holds an ego-frame point (a world
# point goes through `world.to_ego_frame` first); exercise 7.2 derives it from
# the layout above.

# %%
cfg = world.RasterConfig()
print(f"{cfg.size}x{cfg.size} px, {cfg.res_row:.4f} m/px, ego pixel {cfg.ego_pixel}")
ado = np.array([[ego_pose[0] + 10 * np.cos(ego_pose[2]), ego_pose[1] + 10 * np.sin(ego_pose[2]),
                 ego_pose[2], 4.5, 1.9]])                  # one car 10 m straight ahead
img = world.rasterize(m, ego_pose, ado, np.array([True]), cfg)
car_pixel = tuple(int(i) for i in cfg.ego_to_pixel(np.array([10.0, 0.0])))
print("pixel of the point 10 m ahead:", car_pixel, img[car_pixel])
assert car_pixel == (38, 32) and np.array_equal(img[car_pixel], [255, 255, 0])
big = world.rasterize(m, ego_pose, ado, np.array([True]), world.RasterConfig(size=250))
fig, axs = plt.subplots(1, 2, figsize=(8, 4))
axs[0].imshow(img)
axs[0].set_title("64 x 64 (training)")
axs[1].imshow(big)
axs[1].set_title("250 x 250 (the authors' 0.2 m/px)")
plt.show()

# %% [markdown]
# ## 4. Traffic: the Intelligent Driver Model and junction priority
# Every vehicle follows a path of lanes and chooses its acceleration with the
# **IDM** (Treiber et al., 2000):
#
# $$a = a_{max}\Big[1 - \Big(\frac{v}{v_0}\Big)^4 - \Big(\frac{s^*}{s}\Big)^2\Big],\qquad
#   s^* = s_0 + \max\Big(0,\; vT + \frac{v\,\Delta v}{2\sqrt{a_{max} b}}\Big)$$
#
# with gap $s$ to the leader and closing speed $\Delta v = v - v_{lead}$. The
# "leader" is the nearest vehicle whose box overlaps the vehicle's corridor
# ahead — a car in the lane, one merging or cutting in, one standing across.
# At junctions the conflict table tells where paths cross or merge; the
# vehicle without priority treats the conflict's entry as a stopped obstacle.
# Priority: whoever can no longer stop goes first; the roundabout ring before
# the entries; otherwise first come, first served — unless the other vehicle
# is far enough away (gap acceptance). Ados spawn at the map's entries with a
# per-scene density, and some **cut in**: faster, in the adjacent lane, they
# change into the ego's lane a few metres ahead of it.

# %%
gaps = np.linspace(2, 80, 200)
fig, ax = plt.subplots(figsize=(6, 3.5))
for v, dv in [(10.0, 0.0), (10.0, 5.0), (5.0, 0.0)]:
    a = world.idm_acceleration(v, 13.0, gaps, dv, a_max=1.5, b=2.0, s0=2.0, T=1.5)
    ax.plot(gaps, a, label=f"v = {v:.0f} m/s, closing at {dv:.0f} m/s")
ax.axhline(0, color="k", lw=0.5)
ax.set_xlabel("gap to the leader (m)")
ax.set_ylabel("IDM acceleration (m/s²)")
ax.set_ylim(-8, 2)
ax.legend()
plt.show()
print(f"free road at v0: {float(world.idm_acceleration(13.0, 13.0, np.inf, 0.0)):.3f} m/s²")
print(f"standing start:  {float(world.idm_acceleration(0.0, 13.0, np.inf, 0.0)):.3f} m/s²")

# %% [markdown]
# ## 5. The human
# The ego is driven by a "human" whose **style** is drawn per scene: desired
# speed $v_0$, time headway $T$, comfortable acceleration and deceleration,
# lateral acceleration accepted in curves, reaction delay, critical gap at
# junctions, jerk bound, and a lateral wander around the lane centre.
#
# * **Longitudinal**: the same IDM against the binding constraint (leader or
#   junction stop point), with a desired speed that slowly wanders and
#   anticipates curves ($v \le \sqrt{a_{lat}/|\kappa|}$, reached with a
#   comfortable deceleration). Commands reach the pedals after the reaction
#   delay — except hard braking.
# * **Lateral**: pure pursuit of a route point ahead, shifted by an
#   Ornstein–Uhlenbeck lateral offset: the ego drives the circular arc tangent
#   to its heading through that point, so its yaw rate is $\omega = v\kappa$
#   with $\kappa$ the arc's curvature (exercise 7.6 derives it from the point's
#   ego-frame coordinates), clipped to $|\kappa| \le 0.25$ m⁻¹, $|\omega| \le
#   1.2$ rad/s. On a circle the arc *is* the circle: $\kappa = 1/R$.
# * The controls are $[v, \omega]$ and the pose follows the unicycle above,
#   so **integrating the logged controls reproduces the logged trajectory**.
# * A scene in which the human would leave the drivable area or touch an ado
#   is drawn again from the next sub-seed: the data contain neither.

# %%
for k in range(3):
    st = world.random_style(np.random.default_rng(k))
    print(f"style {k}: v0 {st.v0:5.2f} m/s  T {st.T:4.2f} s  a {st.a_max:4.2f}  "
          f"b {st.b:4.2f} m/s²  reaction {st.reaction:4.2f} s  gap {st.gap_crit:4.2f} s  "
          f"lateral std {st.lat_sigma:4.2f} m")

# %% [markdown]
# ## 6. A small dataset
# `world.generate(n_scenes, seed)` draws scene $i$ from its own random stream
# `default_rng([seed, i, attempt])`, so the data do not depend on the number
# of worker processes, and the first 650 scenes of an 850-scene run are the
# 650-scene run. Here 24 scenes; the full 850 need roughly 80–120 s of CPU,
# which `minimanc data generate` splits over two worker processes.

# %%
ds = world.generate(24, seed=0, progress=False, workers=1)
print(ds)
for name in ("bev", "ego", "controls", "goal", "lane_target", "ado", "ado_valid", "goal_bev"):
    a = getattr(ds, name)
    print(f"{name:12s} {str(a.dtype):8s} {a.shape}")
train, val = ds.split(n_train=18)
print(len(train), len(val), ds.content_hash()[:16])

# %% [markdown]
# ### A gallery
# Rasters at mid-scene with the human's future path (red) and the lane target
# (blue dots) on top.

# %%
fig = gallery(ds, range(12), cols=6)
plt.show()

# %% [markdown]
# ### One scene, step by step
# A roundabout or junction scene, every fourth step (2 s apart). The magenta
# dot is the goal — the human's final pose — in the current ego frame.

# %%
scene = next(i for i, t in enumerate(ds.tags) if t["has_roundabout"])
frames = scene_frames(ds, scene, scale=2)
fig, axs = plt.subplots(2, 5, figsize=(15, 6.5))
for ax, t in zip(axs.flat, range(0, 40, 4)):
    ax.imshow(frames[t])
    ax.set_title(f"t = {t * world.DT:.0f} s, v = {ds.controls[scene, t, 0]:.1f} m/s")
    ax.axis("off")
plt.show()
print(ds.tags[scene]["kind"], ds.tags[scene]["turn"],
      "yield steps:", ds.tags[scene]["yield_steps"])
fig, ax = plt.subplots(figsize=(5, 5))
plot_map(ds.maps[scene], ax, ego=ds.ego[scene], ado=ds.ado[scene],
         ado_valid=ds.ado_valid[scene])
plt.show()

# %% [markdown]
# ### The same scene as a learner reads it: binary channels
# The coloured raster is the devkit's picture for people. A network has to undo it:
# the other vehicles' past is a fade blended into one image, and the ego's route
# through a junction is not drawn at all. `RasterConfig(encoding="channels")` draws
# the same frame as separate 0/1 planes — the map layers, lanes by direction, the
# ego's **route ahead** (`route=True`) and the ego and the other vehicles at
# t, t−1, t−2 (`history=2`), each in its own plane — as the field's closed-loop
# raster drivers do; `world.encodings.to_rgb` paints them back for people.
# `research/seeing_the_leader` measures what this does for reading the car ahead,
# and chapter 12 why that matters.

# %%
learner = world.RasterConfig(encoding="channels", route=True, history=2)
lds = world.generate(1, seed=0, raster=learner, progress=False, workers=1)
planes = world.encodings.planes(lds.bev[0, 20], lds.raster)
print("stored:", lds.bev.shape, lds.bev.dtype, "(8 planes to a byte); planes:", planes.shape)
print("planes:", ", ".join(learner.channel_names))
assert planes.shape == (64, 64, len(learner.channel_names)) and set(np.unique(planes)) <= {0, 1}
fig, axs = plt.subplots(2, 7, figsize=(15, 4.6))
axs[0, 0].imshow(world.encodings.to_rgb(lds.bev[0, 20], lds.raster))
axs[0, 0].set_title("to_rgb (for people)", fontsize=8)
for ax, k in zip(axs.flat[1:], range(planes.shape[-1])):
    ax.imshow(planes[..., k], cmap="gray", vmin=0, vmax=1)
    ax.set_title(learner.channel_names[k], fontsize=8)
for ax in axs.flat:
    ax.axis("off")
plt.show()

# %% [markdown]
# ## 7. Statistics
# Speeds, yaw rates and accelerations of the humans, and how often scenes
# contain junctions, roundabouts and cut-ins.

# %%
v = ds.controls[..., 0]
w = ds.controls[..., 1]
acc = np.diff(v, axis=1) / world.DT
fig, axs = plt.subplots(1, 3, figsize=(14, 3.5))
axs[0].hist(v.ravel(), bins=30)
axs[0].set_xlabel("speed (m/s)")
axs[1].hist(w.ravel(), bins=30)
axs[1].set_xlabel("yaw rate (rad/s)")
axs[2].hist(acc.ravel(), bins=30)
axs[2].set_xlabel("acceleration (m/s²)")
plt.show()
print(f"speed: mean {v.mean():.2f}, std {v.std():.2f}, max {v.max():.2f} m/s; "
      f"stopped {100 * (v < 0.3).mean():.1f} % of steps")
print(f"|yaw rate| > 0.1 rad/s in {100 * (np.abs(w) > 0.1).mean():.1f} % of steps")
for key in ("has_junction", "has_roundabout", "has_cut_in"):
    print(f"{key:15s} {np.mean([t[key] for t in ds.tags]):.2f}")
v0 = np.array([t["style"]["v0"] for t in ds.tags])
print(f"corr(style v0, mean speed) = {np.corrcoef(v0, v.mean(axis=1))[0, 1]:.2f}")
assert v.std() > 2.0 and (v < 0.3).any()

# %% [markdown]
# ## 8. Checks the rest of the course relies on
# * the logged controls reproduce the logged trajectory (the closed loop uses
#   the same integrator);
# * re-rendering from a stored pose gives exactly the stored raster (the
#   closed loop re-renders from the policy's pose);
# * files carry a version and checksums of the arrays and of the metadata
#   (seed, `dt`, raster, tags, recipes): a corrupt, truncated, altered or
#   wrong-version file is refused with an error naming the file. Scenes are
#   stored in shards, so `minimanc data generate` writes any number of them
#   with the memory of one shard.

# %%
ego = ds.ego.astype(np.float64)
pose = ego[:, 0]
for t in range(world.T_STEPS - 1):
    pose = world.unicycle_step(pose, ds.controls[:, t].astype(np.float64), world.DT)
print(f"max drift after 39 integrated steps: {np.abs(pose[:, :2] - ego[:, -1, :2]).max():.4f} m")
again = world.rasterize(ds.maps[3], ego[3, 17], ds.ado[3, 17].astype(np.float64),
                        ds.ado_valid[3, 17], ds.raster)
assert np.array_equal(again, ds.bev[3, 17])
with tempfile.TemporaryDirectory() as tmp:
    path = world.save(ds, Path(tmp) / "world.npz")
    assert world.load(path).content_hash() == ds.content_hash()
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) // 2])
    try:
        world.load(path)
    except world.DatasetFileError as e:
        print("refused:", type(e).__name__, "— message names the file:", path.name in str(e))

# %% [markdown]
# ## 9. Real nuScenes, side by side
# If you have nuScenes on disk, `minimanc data import-nuscenes DATAROOT --version
# v1.0-mini` turns it into this chapter's dataset format (same arrays, same raster,
# the official splits in each scene's tags). To try the importer without the download,
# `minimanc.world.nuscenes.sample.write_sample` writes a tiny **made-up** DATAROOT in the
# exact nuScenes schema (JSON tables and a map expansion with one T junction; not real
# data). Three of its five scenes are skipped on purpose, each with its reason: too few
# keyframes, a dropped keyframe, an ego that drives on no lane.

# %%
from minimanc.world.nuscenes import import_nuscenes
from minimanc.world.nuscenes.sample import write_sample

with tempfile.TemporaryDirectory() as tmp:
    root = Path(tmp) / "nuscenes"
    write_sample(root)
    report = import_nuscenes(root, "v1.0-mini", Path(tmp) / "sample.npz", raster=ds.raster)
    real = world.load(report.path)
print(f"imported: {', '.join(report.imported)}")
for name, reason in report.skipped:
    print("skipped:", name, "-", reason)
print("bev", real.bev.shape, "same raster as the generated data:", real.raster == ds.raster)
print("source:", real.meta["source"], "| splits:", [t["split"] for t in real.tags])
assert real.bev.shape[1:] == ds.bev.shape[1:]

# %% [markdown]
# The imported scene-0061 (the ego turns left at the T junction) next to a generated
# left turn at an intersection, every sixth step:

# %%
gen = next(i for i, t in enumerate(ds.tags) if t["kind"] == "intersection"
           and t["turn"] == "left")
fig, axs = plt.subplots(2, 4, figsize=(12, 6.4))
for j, t in enumerate((2, 8, 14, 20)):
    for row, (data, i, label) in enumerate(((real, 0, "imported"), (ds, gen, "generated"))):
        axs[row, j].imshow(data.bev[i, t])
        axs[row, j].set_title(f"{label}, t = {t * world.DT:.0f} s")
        axs[row, j].axis("off")
plt.show()

# %% tags=["nbval-ignore-output"]
colours = {"drivable": (255, 255, 255), "walkway": (0, 0, 255), "crossing": (119, 136, 153)}
share = {name: [float(np.all(d.bev[i] == c, axis=-1).mean()) for d, i in ((real, 0), (ds, gen))]
         for name, c in colours.items()}
for name, (a, b) in share.items():
    print(f"{name:9s} imported {100 * a:4.1f} %   generated {100 * b:4.1f} % of the pixels")
ados = [int(d.ado_valid[i].any(axis=0).sum()) for d, i in ((real, 0), (ds, gen))]
print(f"vehicles seen in the scene: imported {ados[0]}, generated {ados[1]}")
assert all(a > 0 for a, _ in share.values())  # the sample has all three layers in view
assert share["walkway"][1] > share["walkway"][0]  # walkways on both sides vs one
assert ados[1] > ados[0] == 3  # the sample's car_lead, car_oncoming and bicycle

# %% [markdown]
# What differs: the sample's roads have **one lane per direction** and a walkway on one
# side only, and beside the road lies a drivable **plaza** (in nuScenes maps car parks
# and plazas are drivable area too), so the drivable area is not just the road; the
# generated roads have two lanes per direction, walkways on both sides, crossings at
# the junction and many more ados. The lanes' colours (heading relative to the ego) and
# the boxes are drawn by the same rasteriser in both, so a model sees the same kind of
# image; what it must generalise over is the map's shape, which real maps vary in ways
# the generator does not draw. (The sample is invented: a real scene has its own map.)

# %% [markdown]
# ## Summary
# * `world.generate(850, seed=0)` gives the paper's data layout: `bev`,
#   `ego`, `controls`, `goal`, `lane_target`, `ado`, with `split(650)`.
# * `world.rasterize` / `rasterize_batch` render any pose; the closed loop of
#   chapter 9 uses them with the ados replayed from the log.
# * From the command line: `minimanc data generate --scenes 850 --seed 0 --out
#   data` and `minimanc data show --out data/show` (a gallery PNG and a GIF).
#
# Limitations, honestly: vehicles only (no pedestrians), the ego never
# changes lanes, junctions are unsignalised, and the human is a controller —
# richer than constant speed on straight roads, but simpler than people.
#
# ## Paper vs. this course
# Where this chapter departs from the paper's set-up (section V-A) and why:
#
# * **Not nuScenes.** The paper trains on nuScenes: 850 real scenes of 20 s
#   at 2 Hz from Boston and Singapore, 23 object classes, HD maps with 11
#   layers, 650 scenes for training and 200 for validation. Nothing can be
#   downloaded here, and the devkit pins `numpy < 2` and needs the map files,
#   so our data are **self-generated nuScenes-style scenes**: the same 2 Hz,
#   always exactly 40 steps (nuScenes has "a max of 40"), the same 650 / 200
#   split of `world.generate(850)`, the devkit's raster layers and colours.
#   Vehicles only (no pedestrians), right-hand traffic only (Singapore drives
#   on the left), unsignalised junctions; the map has drivable area,
#   walkways, crossings and lanes, not 11 layers.
# * **The human is a controller.** nuScenes' drivers are people; ours is the
#   IDM plus pure pursuit with a per-scene style, and scenes where it would
#   leave the road or touch an ado are drawn again, so the data contain
#   neither.
# * **Raster size and resolution.** The paper's text gives none. The
#   authors' released environment uses 3 × 250 × 250 px at 0.2 m/px; the
#   devkit 500 × 500 at 0.1 m/px. We keep the devkit's proportions (40 m
#   ahead, 10 m behind, 25 m each side) and train on **64 × 64 px at
#   0.78 m/px** for CPU budgets; `RasterConfig(size=250)` is the authors'
#   0.2 m/px. In closed loop there is no history, as in their environment.
# * **Controls and goal.** The text says "speed and steering"; like the
#   released environment we use speed and **yaw rate** on a unicycle with
#   explicit Euler at Δt = 0.5 s. The text never defines the goal pose; we
#   take the environment's: the human's last pose, re-expressed in the
#   current ego frame every step (section 1; exercise 7.1 asks how it moves).
# * **The ados in closed loop.** The paper says "all agents are rolled out
#   synchronously" and, in the next paragraph, that the ados "move according
#   to the trajectories recorded in the dataset": a replay that does not
#   react to the ego. Chapter 9 does the same: its closed loop replays the
#   ados from the log, so they react to the human who was there, not to the
#   policy (a reactive protocol with IDM ados, as nuPlan has, is not built).
